//! The BRDF models behind `Stack.eval(model=...)`. A model is prepared from the stack and its options (per-channel
//! constants, distributions, tables), then evaluated for many direction pairs; each evaluation writes one value per
//! channel. The last few prepared models are kept, so that repeated calls on one material (a renderer's loop, a
//! notebook's sweep) build their tables once.

pub mod belcour;
pub mod microfacet;
pub mod single_pass;
pub mod steinberg;
pub mod weidlich_wilkie;

use crate::optics::fresnel::FresnelForm;
use crate::optics::microfacet::{Distribution, G2Form};
use crate::stack::{value_error, Result, Stack};
use glam::DVec3;
use std::sync::{Arc, Mutex};

/// Rows per evaluation block (`Evaluator::eval_block`).
pub const BLOCK: usize = 64;

/// Names accepted by `model=`, in the order `lamina.MODELS` lists them.
pub const MODELS: &[&str] = &["microfacet", "belcour", "steinberg", "weidlich_wilkie"];

#[derive(Clone, Copy, Debug)]
pub struct Options {
    pub distribution: Distribution,
    pub g2: G2Form,
    pub fresnel: FresnelForm,
    /// Belcour's symmetric (reciprocal) variant: statistics at |wo·h| instead of cos θo.
    pub symmetric: bool,
    /// Belcour 2018 choices where the paper and the reference code differ (see models/belcour.rs).
    pub belcour: belcour::Variant,
    /// Belcour 2018: interpolate the adding-doubling results from a table over cos θ (fast), built when the model
    /// is prepared, instead of running it for every evaluation.
    pub belcour_table: bool,
    /// Steinberg: the fitted closed forms instead of the tabulated integrals.
    pub steinberg_fitted: bool,
    /// Weidlich–Wilkie / Elek: Elek's precomputed Fresnel and Beckmann tables.
    pub elek_precomputed: bool,
    /// Single-pass models: each layer at least as rough as the one above (Elek's m₂ ≥ m₁).
    pub clamp_roughness: bool,
    /// Single-pass models: the radiance compression 1/η² through each dielectric interface.
    pub eta2: bool,
}

impl Default for Options {
    fn default() -> Self {
        Options {
            distribution: Distribution::Ggx,
            g2: G2Form::HeightCorrelated,
            fresnel: FresnelForm::Exact,
            symmetric: false,
            belcour: belcour::Variant::default(),
            belcour_table: true,
            steinberg_fitted: false,
            elek_precomputed: false,
            clamp_roughness: true,
            eta2: true,
        }
    }
}

impl Options {
    /// The defaults of `model`: Weidlich–Wilkie / Elek use Beckmann with the V-cavity G (Torrance–Sparrow); the
    /// other models GGX with height-correlated Smith.
    pub fn for_model(model: &str) -> Self {
        match model {
            "weidlich_wilkie" => {
                Options { distribution: Distribution::Beckmann, g2: G2Form::VCavity, ..Options::default() }
            }
            _ => Options::default(),
        }
    }
}

/// A model prepared for one stack: evaluates f(wi, wo) for unit directions in the local frame.
pub enum Evaluator {
    Microfacet(microfacet::Prepared),
    Belcour(belcour::Prepared),
    Steinberg(steinberg::Prepared),
    WeidlichWilkie(weidlich_wilkie::Prepared),
}

/// How many prepared models `prepare` keeps (most recently used first).
const CACHED: usize = 16;

/// Prepares `model` for `stack`, or explains why the model cannot represent the stack; a model prepared by one of
/// the last CACHED calls with equal arguments is reused.
pub fn prepare(model: &str, stack: &Stack, opts: &Options) -> Result<Arc<Evaluator>> {
    static CACHE: Mutex<Vec<(String, Arc<Evaluator>)>> = Mutex::new(Vec::new());
    // Debug prints every f64 in its shortest round-trip form: equal keys mean equal arguments.
    let key = format!("{model}|{stack:?}|{opts:?}");
    let hit = {
        let mut cache = CACHE.lock().unwrap_or_else(|e| e.into_inner());
        let k = cache.iter().position(|(k, _)| *k == key);
        k.map(|k| {
            let entry = cache.remove(k);
            let evaluator = entry.1.clone();
            cache.insert(0, entry);
            evaluator
        })
    };
    if let Some(evaluator) = hit {
        return Ok(evaluator);
    }
    let evaluator = Arc::new(prepare_uncached(model, stack, opts)?);
    let mut cache = CACHE.lock().unwrap_or_else(|e| e.into_inner());
    cache.insert(0, (key, evaluator.clone()));
    cache.truncate(CACHED);
    Ok(evaluator)
}

fn prepare_uncached(model: &str, stack: &Stack, opts: &Options) -> Result<Evaluator> {
    match model {
        "microfacet" => Ok(Evaluator::Microfacet(microfacet::prepare(stack, opts)?)),
        "belcour" => Ok(Evaluator::Belcour(belcour::prepare(stack, opts)?)),
        "steinberg" => Ok(Evaluator::Steinberg(steinberg::prepare(stack, opts)?)),
        "weidlich_wilkie" => Ok(Evaluator::WeidlichWilkie(weidlich_wilkie::prepare(stack, opts)?)),
        _ => value_error(format!("model must be one of {MODELS:?}, got {model:?}")),
    }
}

impl Evaluator {
    /// f(wi, wo) for every channel into `out` (length = number of channels).
    pub fn eval(&self, wi: DVec3, wo: DVec3, out: &mut [f64]) {
        match self {
            Evaluator::Microfacet(p) => p.eval(wi, wo, out),
            Evaluator::Belcour(p) => p.eval(wi, wo, out),
            Evaluator::Steinberg(p) => p.eval(wi, wo, out),
            Evaluator::WeidlichWilkie(p) => p.eval(wi, wo, out),
        }
    }

    /// f for a block of n ≤ BLOCK direction pairs given as columns (wi[c][r] is component c of row r) into `out`
    /// (n rows of one value per channel), compiled for AVX2 + FMA when the CPU has them (4 f64 lanes in the loops
    /// that vectorize). Rust never contracts a * b + c into an FMA by itself, so both paths give identical bits.
    pub fn eval_block(&self, wi: [&[f64]; 3], wo: [&[f64]; 3], out: &mut [f64]) {
        #[cfg(target_arch = "x86_64")]
        if has_avx2() {
            // SAFETY: the CPU supports every feature the function is compiled for.
            return unsafe { self.eval_block_avx2(wi, wo, out) };
        }
        self.eval_block_portable(wi, wo, out)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    unsafe fn eval_block_avx2(&self, wi: [&[f64]; 3], wo: [&[f64]; 3], out: &mut [f64]) {
        self.eval_block_portable(wi, wo, out)
    }

    #[inline(always)]
    fn eval_block_portable(&self, wi: [&[f64]; 3], wo: [&[f64]; 3], out: &mut [f64]) {
        match self {
            Evaluator::Microfacet(p) => p.eval_block(wi, wo, out),
            Evaluator::Belcour(p) => p.eval_block(wi, wo, out),
            _ => eval_rows(wi, wo, out, |wi, wo, o| self.eval(wi, wo, o)),
        }
    }
}

/// Row r of a block's direction columns.
#[inline(always)]
pub fn row(w: [&[f64]; 3], r: usize) -> DVec3 {
    DVec3::new(w[0][r], w[1][r], w[2][r])
}

/// A block evaluated row by row with `eval(wi, wo, out_row)`: the block path of what has no vectorized form.
#[inline(always)]
pub fn eval_rows(wi: [&[f64]; 3], wo: [&[f64]; 3], out: &mut [f64], eval: impl Fn(DVec3, DVec3, &mut [f64])) {
    let k = out.len() / wi[0].len();
    for (r, o) in out.chunks_exact_mut(k).enumerate() {
        eval(row(wi, r), row(wo, r), o);
    }
}

/// Whether the CPU has AVX2 and FMA (checked once, then cached by std).
#[cfg(target_arch = "x86_64")]
#[inline]
pub fn has_avx2() -> bool {
    std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma")
}
