//! Per-element queries on the device: a model's kernel prepared once per stack and options (kept, with its arrays
//! uploaded on first use), the pairs in dispatches of at most CHUNK, and the results read back.

use super::device::{
    buffer, gpu, group, init, read_back, scoped, wait, Buffers, Gpu, Specialization, Uploaded, STORAGE,
};
use super::{bytes, half, kernel, Kernel, Query};
use crate::error::{value_error, Result};
use crate::models::Args;
use crate::render::Texture;
use crate::stack::Stack;
use crate::tables::adding_doubling::NODES;
use std::sync::{Arc, OnceLock};

/// Pairs per dispatch: 2^21 (32768 workgroups of 64, within every adapter's dispatch limit).
pub(crate) const CHUNK: usize = 1 << 21;

/// Lobes of a sampling mixture on the GPU (MAX_LOBES in shaders/sample.wgsl).
pub(crate) const MAX_LOBES: usize = 16;

/// Whether the GPU's sampling mixture holds every lobe a model proposes for `stack`: at most two per layer (a
/// single-pass model's dielectric: its reflection and its slab's cosine term).
pub(crate) fn fits_the_mixture(stack: &Stack) -> Result<()> {
    if 2 * stack.layers.len() > MAX_LOBES {
        return value_error(format!(
            "sampling on the GPU (sample, pdf, environment lights) takes stacks of at most {} layers, got {}; use \
             device='cpu'",
            MAX_LOBES / 2,
            stack.layers.len()
        ));
    }
    Ok(())
}

impl Uploaded {
    fn buffers(&self, gpu: &Gpu) -> &Buffers {
        self.buffers.get_or_init(|| batched(gpu, &[&self.kernel]).1)
    }
}

/// inputs.wgsl's MAX_MODEL_INPUTS.
const MAX_MODEL_INPUTS: usize = 4;

/// The per-element inputs as inputs.wgsl reads them, on the device: its MAX_MODEL_INPUTS texture records (at, width,
/// height, comps; comps 0: not given) and their texels.
pub(crate) fn input_buffers(gpu: &Gpu, textures: &[Option<Texture>]) -> [wgpu::Buffer; 2] {
    let (mut records, mut texels) = (vec![0u32; 4 * MAX_MODEL_INPUTS], Vec::new());
    for (record, t) in records.chunks_exact_mut(4).zip(textures) {
        if let Some(t) = t {
            record.copy_from_slice(&[texels.len() as u32, t.width as u32, t.height as u32, t.comps as u32]);
            texels.extend(t.data.iter().map(|&x| x as f32));
        }
    }
    texels.push(0.0); // storage buffers may not be empty
    [
        init(gpu, "input textures", bytemuck::cast_slice(&records), STORAGE),
        init(gpu, "inputs", bytemuck::cast_slice(&texels), STORAGE),
    ]
}

/// Rows `range` of per-element inputs (one row of an element per texel).
fn input_rows(inputs: &[Option<Texture>], range: std::ops::Range<usize>) -> Vec<Option<Texture>> {
    let rows = |t: &Texture| Texture {
        width: range.len(),
        height: 1,
        comps: t.comps,
        data: t.data[range.start * t.comps..range.end * t.comps].to_vec(),
    };
    inputs.iter().map(|t| t.as_ref().map(rows)).collect()
}

/// One model's kernels for stacks that one dispatch serves: their `Params`, one after the other, each holding its
/// arrays' offsets; and group 0's read-only buffers.
pub(crate) fn batched(gpu: &Gpu, kernels: &[&Kernel]) -> (Vec<u32>, Buffers) {
    let mut words = Vec::new();
    let mut arrays = vec![Vec::new(); kernels[0].arrays.len()];
    // fit.wgsl's `Fit` per stack (on, base, added_base, pad) and the values they index.
    let (mut records, mut values) = (Vec::new(), Vec::new());
    for kernel in kernels {
        let mut own = kernel.words.clone();
        for ((array, word), all) in kernel.arrays.iter().zip(&mut arrays) {
            own[*word] = all.len() as u32;
            all.extend_from_slice(array);
        }
        words.extend(own);
        let base = values.len() as u32;
        match &kernel.fit {
            Some(fit) => {
                let added = base + (fit.len() - NODES) as u32;
                records.extend([1, base, added, 0]);
                values.extend_from_slice(fit);
            }
            None => records.extend([0u32; 4]),
        }
    }
    // Storage buffers may not be empty: an array that no stack has (Belcour's diffuse base) gets an unused value.
    let storage =
        |label, a: &[f32]| init(gpu, label, bytemuck::cast_slice(if a.is_empty() { &[0.0] } else { a }), STORAGE);
    let arrays =
        arrays.iter().map(|a| storage("array", a)).chain(kernels[0].tables.iter().map(|t| table(gpu, t))).collect();
    let fit = [init(gpu, "fit", bytemuck::cast_slice(&records), STORAGE), storage("fit values", &values)];
    (words, Buffers { arrays, fit })
}

/// A table that every stack shares (Steinberg's, the FGD, Elek's Beckmann table), uploaded once per device.
pub(crate) fn table(gpu: &Gpu, data: &'static [f32]) -> wgpu::Buffer {
    // Static data never moves: its address and length name it.
    let key = (data.as_ptr() as usize, data.len());
    let mut tables = gpu.tables.lock().unwrap_or_else(|e| e.into_inner());
    if let Some((_, b)) = tables.iter().find(|(k, _)| *k == key) {
        return b.clone();
    }
    let b = init(gpu, "table", bytemuck::cast_slice(data), STORAGE);
    tables.push((key, b.clone()));
    b
}

pub(crate) const CACHED: usize = 16;

/// `model` prepared for `stack` and `args` for the GPU: kept for the next calls with equal arguments (as the CPU
/// keeps its prepared models), so that its tables are built once and, for per-element queries, uploaded once
/// (`Uploaded::arrays`).
pub(crate) fn cached_kernel(gpu: &Gpu, model: &str, stack: &Stack, args: &Args) -> Result<Arc<Uploaded>> {
    // Debug prints every f64 in its shortest round-trip form: equal keys mean equal arguments (models::prepare).
    let key = format!("{model}|{stack:?}|{args:?}");
    let mut cache = gpu.kernels.lock().unwrap_or_else(|e| e.into_inner());
    if let Some(k) = cache.iter().position(|(k, _)| *k == key) {
        let entry = cache.remove(k);
        let found = entry.1.clone();
        cache.insert(0, entry);
        return Ok(found);
    }
    let up = Arc::new(Uploaded { kernel: kernel(model, stack, args)?, buffers: OnceLock::new() });
    cache.insert(0, (key, up.clone()));
    cache.truncate(CACHED);
    Ok(up)
}

/// One dispatch: its parameters and pairs on the device, its output buffer and their bind group.
pub(crate) struct Batch {
    bind: wgpu::BindGroup,
    out: wgpu::Buffer,
    pairs: usize,
}

/// Uploads the pairs (float32 rows of two vectors: wi and wo, or wo and u) of one dispatch of `up`'s kernel for
/// `query`, and their per-element inputs.
pub(crate) fn batch(
    gpu: &Gpu,
    up: &Uploaded,
    pipeline: &wgpu::ComputePipeline,
    query: Query,
    pairs: &[f32],
    inputs: &[Option<Texture>],
) -> Batch {
    let kernel = &up.kernel;
    let m = pairs.len() / 6;
    let mut words = kernel.words.clone();
    words[kernel.count_word] = m as u32;
    let params = init(gpu, "params", bytemuck::cast_slice(&words), STORAGE);
    let pair_buf = init(gpu, "pairs", bytemuck::cast_slice(pairs), STORAGE);
    let out = buffer(gpu, "f", (4 * m * query.width(kernel.channels)) as u64, STORAGE | wgpu::BufferUsages::COPY_SRC);
    let inputs = input_buffers(gpu, inputs);
    let resources = up.buffers(gpu).resources(&params, Some(&pair_buf), &out, &inputs);
    Batch { bind: group(gpu, pipeline, 0, &resources), out, pairs: m }
}

/// Submits one dispatch of a batch, then (with `read`) the copy of its output into `read`.
pub(crate) fn dispatch_batch(gpu: &Gpu, pipeline: &wgpu::ComputePipeline, b: &Batch, read: Option<&wgpu::Buffer>) {
    gpu.count_dispatch();
    let mut encoder = gpu.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: None });
    {
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor { label: None, timestamp_writes: None });
        pass.set_pipeline(pipeline);
        pass.set_bind_group(0, &b.bind, &[]);
        pass.dispatch_workgroups(b.pairs.div_ceil(64) as u32, 1, 1);
    }
    if let Some(read) = read {
        encoder.copy_buffer_to_buffer(&b.out, 0, read, 0, b.out.size());
    }
    gpu.queue.submit([encoder.finish()]);
}

/// The model on the device, its pipeline, and the pairs per dispatch (CHUNK, or fewer where the adapter's
/// storage-buffer limit requires).
pub(crate) fn prepared<'g>(
    gpu: &'g Gpu,
    model: &str,
    stack: &Stack,
    args: &Args,
    query: Query,
    pairs: &[f32],
    inputs: bool,
) -> Result<(Arc<Uploaded>, &'g wgpu::ComputePipeline, usize)> {
    if !pairs.len().is_multiple_of(6) {
        return value_error("pairs must be float32 (n, 6) rows of two vectors");
    }
    let up = cached_kernel(gpu, model, stack, args)?;
    let (k, _) = half(up.kernel.shader)?;
    let limit = gpu.device.limits().max_storage_buffer_binding_size as usize;
    let chunk = CHUNK.min((limit / (4 * query.width(up.kernel.channels).max(6))).max(64));
    let spec = Specialization { fitted: up.kernel.fit.is_some(), inputs };
    let pipeline = gpu.query_pipeline(k, query, up.buffers(gpu).arrays.len(), spec);
    Ok((up, pipeline, chunk))
}

/// `query` of `model` for n elements given as float32 rows of two unit vectors, (wi, wo) or for Sample (wo, u), and
/// the model's per-element inputs (catalogue order; one row of n texels each, or None): n·query.width(channels)
/// float32 values.
pub fn run(
    query: Query,
    model: &str,
    stack: &Stack,
    args: &Args,
    pairs: &[f32],
    inputs: &[Option<Texture>],
) -> Result<Vec<f32>> {
    let gpu = gpu()?;
    let n = pairs.len() / 6;
    let what = format!("running {model} on {n} elements ({})", bytes(4 * n * (6 + query.width(stack.channels))));
    scoped(&gpu, &what, || run_scoped(&gpu, query, model, stack, args, pairs, inputs))
}

pub(crate) fn run_scoped(
    gpu: &Gpu,
    query: Query,
    model: &str,
    stack: &Stack,
    args: &Args,
    pairs: &[f32],
    inputs: &[Option<Texture>],
) -> Result<Vec<f32>> {
    if !matches!(query, Query::Eval) {
        fits_the_mixture(stack)?;
    }
    let (up, pipeline, chunk) = prepared(gpu, model, stack, args, query, pairs, inputs.iter().any(Option::is_some))?;
    let c = query.width(up.kernel.channels);
    let mut out = vec![0f32; pairs.len() / 6 * c];
    for (k, (rows, dst)) in pairs.chunks(6 * chunk).zip(out.chunks_mut(chunk * c)).enumerate() {
        let b = batch(gpu, &up, pipeline, query, rows, &input_rows(inputs, k * chunk..k * chunk + rows.len() / 6));
        let read = buffer(gpu, "readback", b.out.size(), wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST);
        dispatch_batch(gpu, pipeline, &b, Some(&read));
        dst.copy_from_slice(&read_back(gpu, &read)?);
    }
    Ok(out)
}

/// Seconds per evaluation of all the pairs with inputs and outputs resident on the device (uploaded once, nothing
/// read back): the mean over `repeats` rounds after a warm-up round. For benchmarks.
pub fn resident_seconds(model: &str, stack: &Stack, args: &Args, pairs: &[f32], repeats: usize) -> Result<f64> {
    let gpu = gpu()?;
    let what = format!("timing {model} on {} resident pairs", pairs.len() / 6);
    scoped(&gpu, &what, || {
        let gpu = &*gpu;
        let (up, pipeline, chunk) = prepared(gpu, model, stack, args, Query::Eval, pairs, false)?;
        let batches: Vec<Batch> =
            pairs.chunks(6 * chunk).map(|rows| batch(gpu, &up, pipeline, Query::Eval, rows, &[])).collect();
        mean_seconds(repeats, || {
            batches.iter().for_each(|b| dispatch_batch(gpu, pipeline, b, None));
            wait(gpu)
        })
    })
}

/// Seconds to copy `bytes` from a storage buffer into a mappable one and map it for the CPU: what a call's read-back
/// of that size costs. The mean of `repeats` after a warm-up. For benchmarks (transfers reported apart from the work).
pub fn readback_seconds(bytes: usize, repeats: usize) -> Result<f64> {
    let gpu = gpu()?;
    let what = format!("timing the read-back of {}", super::bytes(bytes));
    scoped(&gpu, &what, || {
        let size = bytes.max(4).next_multiple_of(4) as u64;
        let src = buffer(&gpu, "result", size, STORAGE | wgpu::BufferUsages::COPY_SRC);
        mean_seconds(repeats, || {
            let read = buffer(&gpu, "readback", size, wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST);
            let mut encoder = gpu.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: None });
            encoder.copy_buffer_to_buffer(&src, 0, &read, 0, size);
            gpu.queue.submit([encoder.finish()]);
            read_back(&gpu, &read).map(|_| ())
        })
    })
}

/// The mean seconds of `repeats` (at least one) runs of `once` after a warm-up run.
fn mean_seconds(repeats: usize, mut once: impl FnMut() -> Result<()>) -> Result<f64> {
    once()?;
    let start = std::time::Instant::now();
    for _ in 0..repeats.max(1) {
        once()?;
    }
    Ok(start.elapsed().as_secs_f64() / repeats.max(1) as f64)
}
