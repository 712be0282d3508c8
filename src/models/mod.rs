//! The BRDF models behind `Stack.eval(model=...)`, as one catalogue. Each model is one module that opens with its
//! parameter table and ends in an `INFO`: name, summary, options, per-element inputs, properties and `prepare`. A
//! prepared model evaluates f for blocks of direction pairs, proposes lobes for importance sampling (`sample.rs`
//! turns them into `sample` and `pdf`) and reports its Dirac (mirror) reflection. Adding a model: one module and one
//! line in `CATALOGUE`.
//!
//! The last few prepared models are kept, so that repeated calls on one material (a renderer's loop, a notebook's
//! sweep) build their tables once.

pub mod albedo_scaling;
pub mod belcour;
pub mod microfacet;
pub mod options;
pub mod sample;
pub mod single_pass;
pub mod steinberg;
pub mod tabulated;
pub mod transport_fit;
pub mod weidlich_wilkie;

pub use options::{OptionKind, OptionSpec, Options, Value};

use crate::error::{value_error, Result};
use crate::optics::distribution::Microfacet;
use crate::stack::Stack;
use glam::DVec3;
use std::sync::{Arc, Mutex};

/// Rows per evaluation block (`Model::eval_block`).
pub const BLOCK: usize = 64;

/// The models, in the order `lamina.MODELS` lists them.
pub const CATALOGUE: &[&ModelInfo] = &[
    &microfacet::INFO,
    &belcour::INFO,
    &steinberg::INFO,
    &weidlich_wilkie::INFO,
    &albedo_scaling::INFO,
    &tabulated::INFO,
];

/// A per-element input a model accepts beside the directions (a texture's values, flake normals).
#[derive(Clone, Copy, Debug)]
pub struct InputSpec {
    pub name: &'static str,
    /// Values per element: 1 (a scalar map) or 3 (a vector).
    pub width: usize,
    /// Allowed range of every value (closed).
    pub range: (f64, f64),
    pub doc: &'static str,
}

/// What a user chooses a model by.
#[derive(Clone, Copy, Debug)]
pub struct Properties {
    /// f(wi, wo) = f(wo, wi) for every stack.
    pub reciprocal: bool,
    /// Directional albedo ≤ 1 for every stack.
    pub energy_conserving: bool,
    /// Anisotropic roughness and rotated tangent frames.
    pub anisotropic: bool,
    /// Per-wavelength optical constants (spectral evaluation) as well as RGB.
    pub spectral: bool,
}

/// One model of the catalogue.
pub struct ModelInfo {
    pub name: &'static str,
    pub summary: &'static str,
    pub options: &'static [OptionSpec],
    pub inputs: &'static [InputSpec],
    pub properties: Properties,
    pub prepare: fn(&Stack, &Options) -> Result<Box<dyn Model>>,
}

/// The per-element input columns of one block, in the order of the model's `inputs`: None where not given; a
/// scalar input fills column 0.
pub type Inputs<'a> = [Option<[&'a [f64]; 3]>];

/// A lobe of the sampling mixture of a model: a GGX/Beckmann reflection lobe sampled by its visible normals, or the
/// cosine-weighted hemisphere (diffuse terms).
#[derive(Clone, Copy, Debug)]
pub enum Proposal {
    Reflection(Microfacet),
    Cosine,
}

/// A model prepared for one stack and its options.
pub trait Model: Send + Sync {
    /// f for a block of n ≤ BLOCK direction pairs given as columns (wi[c][r] is component c of row r) and the
    /// block's per-element inputs, into `out` (n rows of one value per channel, zeroed by the caller).
    fn eval_block(&self, wi: [&[f64]; 3], wo: [&[f64]; 3], inputs: &Inputs, out: &mut [f64]);

    /// The sampling mixture for the viewing direction wo (unit, above the surface): (weight, lobe) pairs, weights
    /// roughly the lobes' energies. Any mixture is unbiased (the sample weight is f·cos/pdf); a good one is cheap.
    fn proposals(&self, wo: DVec3) -> Vec<(f64, Proposal)>;

    /// The Dirac (mirror) reflection at wo per channel: what smooth interfaces reflect, which f does not contain.
    fn specular(&self, wo: DVec3, out: &mut [f64]);

    /// Checks which per-element inputs are given (in the order of the model's `inputs`) before an evaluation.
    fn check_inputs(&self, _given: &[bool]) -> Result<()> {
        Ok(())
    }
}

/// The catalogue entry of `name`, or a ValueError listing every model.
pub fn info(name: &str) -> Result<&'static ModelInfo> {
    CATALOGUE.iter().copied().find(|m| m.name == name).ok_or_else(|| {
        let names: Vec<&str> = CATALOGUE.iter().map(|m| m.name).chain(["reference"]).collect();
        crate::error::Error::Value(format!("model must be one of {names:?}, got {name:?}"))
    })
}

/// How many prepared models `prepare` keeps (most recently used first).
const CACHED: usize = 16;

/// Prepares `model` for `stack`, or explains why the model cannot represent the stack; a model prepared by one of
/// the last CACHED calls with equal arguments is reused.
pub fn prepare(model: &str, stack: &Stack, opts: &Options) -> Result<Arc<dyn Model>> {
    type Cache = Mutex<Vec<(String, Arc<dyn Model>)>>;
    static CACHE: Cache = Mutex::new(Vec::new());
    let info = info(model)?;
    // Debug prints every f64 in its shortest round-trip form: equal keys mean equal arguments.
    let key = format!("{model}|{stack:?}|{opts:?}");
    let hit = {
        let mut cache = CACHE.lock().unwrap_or_else(|e| e.into_inner());
        let k = cache.iter().position(|(k, _)| *k == key);
        k.map(|k| {
            let entry = cache.remove(k);
            let prepared = entry.1.clone();
            cache.insert(0, entry);
            prepared
        })
    };
    if let Some(prepared) = hit {
        return Ok(prepared);
    }
    if opts.tint.len() != 1 && opts.tint.len() != stack.channels {
        return value_error(format!(
            "tint has {} values but the stack has {} channels",
            opts.tint.len(),
            stack.channels
        ));
    }
    let mut prepared = (info.prepare)(stack, opts)?;
    if opts.transport_fit {
        prepared = transport_fit::fit(prepared, stack)?;
    }
    let prepared: Arc<dyn Model> = Arc::from(prepared);
    let mut cache = CACHE.lock().unwrap_or_else(|e| e.into_inner());
    cache.insert(0, (key, prepared.clone()));
    cache.truncate(CACHED);
    Ok(prepared)
}

/// The most per-element inputs a model declares.
pub const MAX_INPUTS: usize = 4;

/// f(wi, wo) of one pair (a block of one row) with the pair's per-element input values (at most MAX_INPUTS).
pub fn eval_one(model: &dyn Model, wi: DVec3, wo: DVec3, inputs: &[Option<[f64; 3]>], out: &mut [f64]) {
    let cols: [[[f64; 1]; 3]; MAX_INPUTS] =
        std::array::from_fn(|j| inputs.get(j).copied().flatten().unwrap_or_default().map(|x| [x]));
    let block: [Option<[&[f64]; 3]>; MAX_INPUTS] =
        std::array::from_fn(|j| inputs.get(j).copied().flatten().map(|_| cols[j].each_ref().map(|c| &c[..])));
    out.fill(0.0);
    model.eval_block([&[wi.x], &[wi.y], &[wi.z]], [&[wo.x], &[wo.y], &[wo.z]], &block[..inputs.len()], out);
}

/// f(wi, wo) for many wi and one wo with one set of per-element input values: out[k] is f at wis[k] (3 channels),
/// evaluated in blocks of BLOCK rows (a renderer's samples at one pixel).
pub fn eval_fan(model: &dyn Model, wo: DVec3, inputs: &[Option<[f64; 3]>], wis: &[DVec3], out: &mut [[f64; 3]]) {
    if wis.len() <= 4 {
        // A few directions (a pixel under point lights): one row at a time, without zeroing a block's scratch.
        for (wi, o) in wis.iter().zip(out.iter_mut()) {
            eval_one(model, *wi, wo, inputs, o);
        }
        return;
    }
    let mut cols = [[[0.0; BLOCK]; 3]; 2];
    let inputs_cols: [[[f64; BLOCK]; 3]; MAX_INPUTS] =
        std::array::from_fn(|j| inputs.get(j).copied().flatten().unwrap_or_default().map(|x| [x; BLOCK]));
    (0..3).for_each(|c| cols[1][c] = [wo[c]; BLOCK]);
    let mut f = [0.0; 3 * BLOCK];
    for (chunk, dst) in wis.chunks(BLOCK).zip(out.chunks_mut(BLOCK)) {
        let n = chunk.len();
        for (r, w) in chunk.iter().enumerate() {
            (0..3).for_each(|c| cols[0][c][r] = w[c]);
        }
        let block: [Option<[&[f64]; 3]>; MAX_INPUTS] = std::array::from_fn(|j| {
            inputs.get(j).copied().flatten().map(|_| inputs_cols[j].each_ref().map(|c| &c[..n]))
        });
        f[..3 * n].fill(0.0);
        model.eval_block(
            cols[0].each_ref().map(|c| &c[..n]),
            cols[1].each_ref().map(|c| &c[..n]),
            &block[..inputs.len()],
            &mut f[..3 * n],
        );
        for (d, v) in dst.iter_mut().zip(f.chunks_exact(3)) {
            *d = [v[0], v[1], v[2]];
        }
    }
}

/// Row r of a block's direction columns.
#[inline(always)]
pub fn row(w: [&[f64]; 3], r: usize) -> DVec3 {
    DVec3::new(w[0][r], w[1][r], w[2][r])
}

/// A block evaluated row by row with `eval(r, wi, wo, out_row)`: the block path of what has no vectorized form.
#[inline(always)]
pub fn eval_rows(wi: [&[f64]; 3], wo: [&[f64]; 3], out: &mut [f64], eval: impl Fn(usize, DVec3, DVec3, &mut [f64])) {
    let k = out.len() / wi[0].len();
    for (r, o) in out.chunks_exact_mut(k).enumerate() {
        eval(r, row(wi, r), row(wo, r), o);
    }
}

/// The body of a `Model::eval_block` that runs `$p.eval_columns(wi, wo, out)` (an `#[inline(always)]` method of
/// type `$ty`) compiled for AVX2 + FMA when the CPU has them (4 f64 lanes in the loops that vectorize), else as is.
/// Rust never contracts a * b + c into an FMA by itself, so both paths give identical bits.
macro_rules! simd_columns {
    ($ty:ty, $p:expr, $wi:expr, $wo:expr, $out:expr) => {{
        #[cfg(target_arch = "x86_64")]
        if $crate::models::has_avx2() {
            #[target_feature(enable = "avx2,fma")]
            unsafe fn avx2(p: &$ty, wi: [&[f64]; 3], wo: [&[f64]; 3], out: &mut [f64]) {
                p.eval_columns(wi, wo, out)
            }
            // SAFETY: the CPU supports every feature the function is compiled for.
            return unsafe { avx2($p, $wi, $wo, $out) };
        }
        $p.eval_columns($wi, $wo, $out)
    }};
}
pub(crate) use simd_columns;

/// Whether the CPU has AVX2 and FMA (checked once, then cached by std).
#[cfg(target_arch = "x86_64")]
#[inline]
pub fn has_avx2() -> bool {
    std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma")
}
