//! The device: the adapter and its device (created on first use and again after it is lost), the pipelines compiled
//! on first use, what lives on the device per device (kernels, tables, Oat's pipelines), and the helpers every
//! dispatch uses (buffers, bind groups, errors as values).

use super::{compose, compose_raster, compose_render, Query, CATALOGUE, RENDER_KERNELS};
use crate::error::{Error, Result};
use std::sync::atomic::{AtomicBool, AtomicI64, Ordering};
use std::sync::{Arc, Mutex, OnceLock};
use wgpu::util::DeviceExt;

/// The adapter, its device, per model (in the order of CATALOGUE) its per-element pipelines (Query) and its render
/// pipelines (RENDER_KERNELS), each compiled on first use (drivers take seconds per kernel), the mesh's
/// rasterization in uv space and through the camera, and what lives on this device: the prepared kernels with
/// their arrays, the shared tables, Oat's pipelines (src/oat/gpu.rs). A device that is lost takes all of it along;
/// `gpu()` then creates the next one.
pub struct Gpu {
    pub info: wgpu::AdapterInfo,
    pub(crate) device: wgpu::Device,
    pub(crate) queue: wgpu::Queue,
    pipelines: Vec<[[OnceLock<wgpu::ComputePipeline>; 4]; 3]>,
    renderers: Vec<[[OnceLock<wgpu::ComputePipeline>; 4]; 4]>,
    pub(crate) raster: [wgpu::RenderPipeline; 2],
    pub(crate) kernels: Mutex<Vec<(String, Arc<Uploaded>)>>,
    pub(crate) tables: Mutex<Vec<((usize, usize), wgpu::Buffer)>>,
    pub(crate) oat: OnceLock<Vec<wgpu::ComputePipeline>>,
    /// Set by the device-lost callback.
    lost: Arc<AtomicBool>,
    /// Fault injection for lamina's tests: dispatches left before the device is destroyed (negative: never).
    lose_after: AtomicI64,
}

/// The visibility targets' format: (triangle, b1, b2, covered) per texel.
pub(crate) const VISIBILITY: wgpu::TextureFormat = wgpu::TextureFormat::Rgba32Float;
pub(crate) const DEPTH: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;

/// The rasterization pipeline of `entry` (raster.wgsl): no culling, the nearest fragment by depth where `depth`.
pub(crate) fn raster_pipeline(
    device: &wgpu::Device,
    module: &wgpu::ShaderModule,
    entry: &str,
    depth: bool,
) -> wgpu::RenderPipeline {
    device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some(entry),
        layout: None,
        vertex: wgpu::VertexState {
            module,
            entry_point: Some(entry),
            compilation_options: Default::default(),
            buffers: &[],
        },
        primitive: wgpu::PrimitiveState::default(),
        depth_stencil: depth.then(|| wgpu::DepthStencilState {
            format: DEPTH,
            depth_write_enabled: Some(true),
            depth_compare: Some(wgpu::CompareFunction::Less),
            stencil: Default::default(),
            bias: Default::default(),
        }),
        multisample: Default::default(),
        fragment: Some(wgpu::FragmentState {
            module,
            entry_point: Some("visibility"),
            compilation_options: Default::default(),
            targets: &[Some(wgpu::ColorTargetState {
                format: VISIBILITY,
                blend: None,
                write_mask: wgpu::ColorWrites::ALL,
            })],
        }),
        multiview_mask: None,
        cache: None,
    })
}

/// How to get an adapter, for the error when there is none.
pub(crate) const NO_ADAPTER: &str =
    "no GPU adapter found through wgpu (Vulkan). Install a Vulkan driver for your GPU; on a \
    machine without one, Mesa's lavapipe (Debian/Ubuntu: apt install mesa-vulkan-drivers) is a CPU adapter";

/// The process's GPU, created on first use (the best adapter: a discrete or integrated GPU before a CPU one) and again
/// after it is lost. Without an adapter, the error says how to get one, and stays (adapters do not appear); a device
/// the adapter refused is asked for again on the next call.
pub fn gpu() -> Result<Arc<Gpu>> {
    static GPU: Mutex<Option<std::result::Result<Arc<Gpu>, String>>> = Mutex::new(None);
    let mut slot = GPU.lock().unwrap_or_else(|e| e.into_inner());
    match &*slot {
        Some(Ok(g)) if !g.lost.load(Ordering::Relaxed) => return Ok(g.clone()),
        Some(Err(why)) => return Err(Error::Device(why.clone())),
        _ => {}
    }
    let created = pollster::block_on(create()).map(Arc::new);
    match &created {
        Err(why) if why != NO_ADAPTER => *slot = None,
        _ => *slot = Some(created.clone()),
    }
    created.map_err(Error::Device)
}

/// Fault injection for lamina's tests (tests/faults.py): the current device destroys itself after `dispatches` more
/// dispatches, as a lost device would stop.
pub fn lose_after(dispatches: i64) -> Result<()> {
    gpu()?.lose_after.store(dispatches, Ordering::Relaxed);
    Ok(())
}

async fn create() -> std::result::Result<Gpu, String> {
    let instance = wgpu::Instance::new(wgpu::InstanceDescriptor {
        backends: wgpu::Backends::VULKAN,
        ..wgpu::InstanceDescriptor::new_without_display_handle()
    });
    let mut adapters = instance.enumerate_adapters(wgpu::Backends::VULKAN).await;
    // Hardware first: discrete, integrated, virtual, then CPU (lavapipe).
    let rank = |t: wgpu::DeviceType| match t {
        wgpu::DeviceType::DiscreteGpu => 0,
        wgpu::DeviceType::IntegratedGpu => 1,
        wgpu::DeviceType::VirtualGpu => 2,
        wgpu::DeviceType::Cpu => 3,
        wgpu::DeviceType::Other => 4,
    };
    adapters.sort_by_key(|a| rank(a.get_info().device_type));
    let adapter = adapters.into_iter().next().ok_or_else(|| NO_ADAPTER.to_string())?;
    let limits = adapter.limits();
    let (device, queue) = adapter
        .request_device(&wgpu::DeviceDescriptor {
            label: Some("lamina"),
            required_limits: limits,
            ..Default::default()
        })
        .await
        .map_err(|e| format!("the GPU adapter refused a device: {e}"))?;
    let pipelines = CATALOGUE.iter().map(|_| std::array::from_fn(|_| Default::default())).collect();
    let renderers = CATALOGUE.iter().map(|_| std::array::from_fn(|_| Default::default())).collect();
    let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some("raster"),
        source: wgpu::ShaderSource::Wgsl(compose_raster().into()),
    });
    let raster = [("uv_vertex", false), ("camera_vertex", true)].map(|(e, d)| raster_pipeline(&device, &module, e, d));
    let lost = Arc::new(AtomicBool::new(false));
    let flag = lost.clone();
    device.set_device_lost_callback(move |_, _| flag.store(true, Ordering::Relaxed));
    Ok(Gpu {
        info: adapter.get_info(),
        device,
        queue,
        pipelines,
        renderers,
        raster,
        kernels: Mutex::new(Vec::new()),
        tables: Mutex::new(Vec::new()),
        oat: OnceLock::new(),
        lost,
        lose_after: AtomicI64::new(-1),
    })
}

pub(crate) fn compute_module(device: &wgpu::Device, name: &str, source: String) -> wgpu::ShaderModule {
    device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some(name),
        source: wgpu::ShaderSource::Wgsl(source.into()),
    })
}

pub(crate) fn compute_pipeline(
    device: &wgpu::Device,
    module: &wgpu::ShaderModule,
    entry: &str,
) -> wgpu::ComputePipeline {
    layout_pipeline(device, module, entry, None, &[])
}

/// What a model's kernel is compiled for, as pipeline-overridable constants: fit.wgsl's `FITTED` (some stack of the
/// dispatch has transport_fit) and inputs.wgsl's `INPUTS` (some per-element input is given). The code of a feature
/// that no element uses is compiled out rather than skipped per element (it halved microfacet's speed on lavapipe).
#[derive(Clone, Copy, Default)]
pub(crate) struct Specialization {
    pub fitted: bool,
    pub inputs: bool,
}

impl Specialization {
    fn index(self) -> usize {
        self.fitted as usize + 2 * self.inputs as usize
    }

    fn constants(self) -> [(&'static str, f64); 2] {
        [("FITTED", self.fitted as u8 as f64), ("INPUTS", self.inputs as u8 as f64)]
    }
}

/// A pipeline with the given layout, or (None) the one its entry point's bindings imply, and the values of the
/// module's pipeline-overridable constants.
pub(crate) fn layout_pipeline(
    device: &wgpu::Device,
    module: &wgpu::ShaderModule,
    entry: &str,
    layout: Option<&wgpu::PipelineLayout>,
    constants: &[(&str, f64)],
) -> wgpu::ComputePipeline {
    device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
        label: Some(entry),
        layout,
        module,
        entry_point: Some(entry),
        compilation_options: wgpu::PipelineCompilationOptions { constants, ..Default::default() },
        cache: None,
    })
}

impl Gpu {
    /// Model k's (CATALOGUE order) pipeline for `query` and `spec`, compiled on first use, with one layout for all three
    /// queries
    /// (what eval binds: the parameters, the model's `arrays` read-only arrays, the pairs, the output, the fit and the
    /// per-element inputs), so that one
    /// bind group serves each though pdf reads fewer.
    pub(crate) fn query_pipeline(
        &self,
        k: usize,
        query: Query,
        arrays: usize,
        spec: Specialization,
    ) -> &wgpu::ComputePipeline {
        self.pipelines[k][query as usize][spec.index()].get_or_init(|| {
            let name = CATALOGUE[k].name;
            let entry = |binding: u32, ty: wgpu::BufferBindingType| wgpu::BindGroupLayoutEntry {
                binding,
                visibility: wgpu::ShaderStages::COMPUTE,
                ty: wgpu::BindingType::Buffer { ty, has_dynamic_offset: false, min_binding_size: None },
                count: None,
            };
            let read = wgpu::BufferBindingType::Storage { read_only: true };
            let entries: Vec<wgpu::BindGroupLayoutEntry> = (0..=arrays as u32 + 1)
                .map(|b| entry(b, read))
                .chain([entry(arrays as u32 + 2, wgpu::BufferBindingType::Storage { read_only: false })])
                .chain([FIT_BINDING, FIT_BINDING + 1, INPUTS_BINDING, INPUTS_BINDING + 1].map(|b| entry(b, read)))
                .collect();
            let group = self
                .device
                .create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor { label: None, entries: &entries });
            let layout = self.device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                label: Some(query.entry()),
                bind_group_layouts: &[Some(&group)],
                immediate_size: 0,
            });
            let module = compute_module(&self.device, name, compose(name).expect("listed"));
            layout_pipeline(&self.device, &module, query.entry(), Some(&layout), &spec.constants())
        })
    }

    /// Model k's render pipeline RENDER_KERNELS[kernel] for `spec`, compiled on first use.
    pub(crate) fn render_pipeline(&self, k: usize, kernel: usize, spec: Specialization) -> &wgpu::ComputePipeline {
        self.renderers[k][kernel][spec.index()].get_or_init(|| {
            let name = CATALOGUE[k].name;
            let module = compute_module(&self.device, name, compose_render(name).expect("listed"));
            layout_pipeline(&self.device, &module, RENDER_KERNELS[kernel], None, &spec.constants())
        })
    }
}

pub(crate) const STORAGE: wgpu::BufferUsages = wgpu::BufferUsages::STORAGE;

/// The binding of fit.wgsl's `fit_stacks` (`fit_values` follows).
pub(crate) const FIT_BINDING: u32 = 14;
/// The binding of inputs.wgsl's `input_textures` (`input_texels` follows).
pub(crate) const INPUTS_BINDING: u32 = 16;

/// Group 0's read-only buffers of a dispatch: each array of every stack concatenated, then the shared tables
/// (bindings 1, 2, …), and the stacks' transport_fit records and values (fit.wgsl, bindings FIT_BINDING and the next).
pub(crate) struct Buffers {
    pub(crate) arrays: Vec<wgpu::Buffer>,
    pub(crate) fit: [wgpu::Buffer; 2],
}

impl Buffers {
    /// Group 0's resources: `params` at 0, the arrays, the pairs (a render has none) and `out`, then the fit and the
    /// per-element inputs (`input_buffers`).
    pub(crate) fn resources<'a>(
        &'a self,
        params: &'a wgpu::Buffer,
        pairs: Option<&'a wgpu::Buffer>,
        out: &'a wgpu::Buffer,
        inputs: &'a [wgpu::Buffer; 2],
    ) -> Vec<(u32, Res<'a>)> {
        let n = self.arrays.len() as u32;
        let arrays = self.arrays.iter().enumerate().map(|(j, b)| (j as u32 + 1, b));
        let fit = self.fit.iter().enumerate().map(|(k, b)| (FIT_BINDING + k as u32, b));
        let inputs = inputs.iter().enumerate().map(|(k, b)| (INPUTS_BINDING + k as u32, b));
        std::iter::once((0, params))
            .chain(arrays)
            .chain(pairs.map(|p| (n + 1, p)))
            .chain([(n + 2, out)])
            .chain(fit)
            .chain(inputs)
            .map(|(k, b)| (k, Res::Buffer(b)))
            .collect()
    }
}

/// A prepared kernel, and its buffers on the device as dispatch.rs's `batched` binds them for it alone: uploaded on
/// the first per-element query and kept (a render batches the kernels of its stacks instead).
pub(crate) struct Uploaded {
    pub(crate) kernel: crate::models::common::gpu::Kernel,
    pub(crate) buffers: OnceLock<Buffers>,
}

impl Gpu {
    /// Counts a dispatch against the fault injection of `lose_after`, destroying the device when its count runs out.
    pub(crate) fn count_dispatch(&self) {
        if self.lose_after.fetch_sub(1, Ordering::Relaxed) == 0 {
            self.device.destroy();
        }
    }

    /// The error of work on this device that failed: it names the device and the work (with its size), and says
    /// what comes next.
    pub(crate) fn failure(&self, what: &str, why: &str) -> Error {
        let lost = self.lost.load(Ordering::Relaxed);
        let next = if lost { "the device was lost; the next call creates it again" } else { "the device is kept" };
        Error::Device(format!("the GPU ({}) failed while {what}: {why}; {next}", self.info.name))
    }
}

/// Runs `work` (`what`: the work and its size, for the message) with the device's validation and out-of-memory errors
/// caught, instead of wgpu's default handler, which panics (nothing may panic across the FFI boundary); an error, or
/// the device lost meanwhile, becomes a Device error (RuntimeError) naming the device and the work.
pub(crate) fn scoped<T>(gpu: &Gpu, what: &str, work: impl FnOnce() -> Result<T>) -> Result<T> {
    let memory = gpu.device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);
    let validation = gpu.device.push_error_scope(wgpu::ErrorFilter::Validation);
    let out = work();
    let errors = [pollster::block_on(validation.pop()), pollster::block_on(memory.pop())];
    if let Some(e) = errors.into_iter().flatten().next() {
        return Err(gpu.failure(what, &e.to_string()));
    }
    match out {
        Err(Error::Device(why)) => Err(gpu.failure(what, &why)),
        Ok(_) if gpu.lost.load(Ordering::Relaxed) => Err(gpu.failure(what, "the device was lost")),
        out => out,
    }
}

/// Waits for the submitted work; an error of the device's (lost) as a Device error.
pub(crate) fn wait(gpu: &Gpu) -> Result<()> {
    gpu.device.poll(wgpu::PollType::wait_indefinitely()).map(|_| ()).map_err(|e| Error::Device(e.to_string()))
}

/// A size in bytes as text: "3.0 GiB", "45.8 MiB", "12 KiB".
pub(crate) fn bytes(n: usize) -> String {
    match n {
        n if n >= 1 << 30 => format!("{:.1} GiB", n as f64 / (1u64 << 30) as f64),
        n if n >= 1 << 20 => format!("{:.1} MiB", n as f64 / (1u64 << 20) as f64),
        n => format!("{} KiB", n.div_ceil(1 << 10)),
    }
}

pub(crate) fn init(gpu: &Gpu, label: &str, contents: &[u8], usage: wgpu::BufferUsages) -> wgpu::Buffer {
    gpu.device.create_buffer_init(&wgpu::util::BufferInitDescriptor { label: Some(label), contents, usage })
}

pub(crate) fn buffer(gpu: &Gpu, label: &str, size: u64, usage: wgpu::BufferUsages) -> wgpu::Buffer {
    gpu.device.create_buffer(&wgpu::BufferDescriptor { label: Some(label), size, usage, mapped_at_creation: false })
}

/// The workgroups of 64 threads covering `threads`, as (x, y) within the per-dimension limit of 65535 (the
/// kernels' `thread_index`).
pub(crate) fn workgroups(threads: usize) -> (u32, u32) {
    let groups = threads.div_ceil(64).max(1);
    let x = groups.min(65535);
    (x as u32, groups.div_ceil(x) as u32)
}

/// A resource of a bind group.
#[derive(Clone, Copy)]
pub(crate) enum Res<'a> {
    Buffer(&'a wgpu::Buffer),
    View(&'a wgpu::TextureView),
}

/// A bind group of `layout_of`'s group `g` with the resources at their bindings (none: an unused group).
pub(crate) fn group(gpu: &Gpu, layout_of: &wgpu::ComputePipeline, g: u32, resources: &[(u32, Res)]) -> wgpu::BindGroup {
    group_of(gpu, &layout_of.get_bind_group_layout(g), resources)
}

/// A bind group of `layout` with the resources at their bindings.
pub(crate) fn group_of(gpu: &Gpu, layout: &wgpu::BindGroupLayout, resources: &[(u32, Res)]) -> wgpu::BindGroup {
    let entries: Vec<wgpu::BindGroupEntry> = resources
        .iter()
        .map(|(binding, r)| wgpu::BindGroupEntry {
            binding: *binding,
            resource: match r {
                Res::Buffer(b) => b.as_entire_binding(),
                Res::View(v) => wgpu::BindingResource::TextureView(v),
            },
        })
        .collect();
    gpu.device.create_bind_group(&wgpu::BindGroupDescriptor { label: None, layout, entries: &entries })
}

/// Records one dispatch of `pipeline` over `threads` with its bind groups 0, 1 and 2.
pub(crate) fn dispatch(
    encoder: &mut wgpu::CommandEncoder,
    pipeline: &wgpu::ComputePipeline,
    groups: &[&wgpu::BindGroup],
    threads: usize,
) {
    let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor { label: None, timestamp_writes: None });
    pass.set_pipeline(pipeline);
    for (g, bind) in groups.iter().enumerate() {
        pass.set_bind_group(g as u32, *bind, &[]);
    }
    let (x, y) = workgroups(threads);
    pass.dispatch_workgroups(x, y, 1);
}

/// Submits `encoder` and reads the float32 buffer `read` back.
pub(crate) fn finish(gpu: &Gpu, encoder: wgpu::CommandEncoder, read: &wgpu::Buffer) -> Result<Vec<f32>> {
    gpu.queue.submit([encoder.finish()]);
    read_back(gpu, read)
}

/// The float32 values of the mappable buffer `read`, once the submitted work has written them; a Device error when
/// they cannot be read (a lost device).
pub(crate) fn read_back(gpu: &Gpu, read: &wgpu::Buffer) -> Result<Vec<f32>> {
    let slice = read.slice(..);
    let (tx, rx) = std::sync::mpsc::channel();
    slice.map_async(wgpu::MapMode::Read, move |r| {
        let _ = tx.send(r);
    });
    wait(gpu)?;
    match rx.try_recv() {
        Ok(Ok(())) => {}
        Ok(Err(e)) => return Err(Error::Device(e.to_string())),
        Err(_) => return Err(Error::Device("the results were never mapped".into())),
    }
    let view = slice.get_mapped_range().map_err(|e| Error::Device(e.to_string()))?;
    Ok(bytemuck::cast_slice(&view).to_vec())
}
