//! The BRDF models behind `Stack.eval(model=...)`, as one catalogue. Each model is one module that opens with its
//! parameter table and ends in an `INFO`: name, summary, options, per-element inputs, properties and `prepare`,
//! which reads the model's own options struct from `Args` (common/options.rs). A prepared model evaluates f for
//! blocks of direction pairs, proposes lobes for importance sampling (common/mixture.rs turns them into `sample` and
//! `pdf`) and reports its Dirac (mirror) reflection. Adding a model: one module and one line in `CATALOGUE`.
//!
//! `common/` holds what the models share (options, sampling mixtures, the single-pass walk, block evaluation);
//! `corrections/` lamina's corrections of the published models.
//!
//! The last few prepared models are kept, so that repeated calls on one material (a renderer's loop, a notebook's
//! sweep) build their tables once.

pub mod albedo_scaling;
pub mod belcour;
pub mod common;
pub mod corrections;
pub mod microfacet;
pub mod steinberg;
pub mod tabulated;
pub mod weidlich_wilkie;

pub use crate::stack::Field;
pub use common::block::{eval_fan, eval_one, BLOCK, MAX_INPUTS};
pub use common::options::{Args, OptionKind, OptionSpec, Value};

use crate::dual::Dual;
use crate::engine::Rows;
use crate::error::{py, py_list, value_error, Result};
use crate::optics::distribution::Microfacet;
use crate::stack::Stack;
use crate::transport::Microsurface;
use common::options::{microsurface, DISTRIBUTION, G2};
pub use corrections::transport_fit::FitLanes;
use glam::DVec3;
use std::sync::{Arc, Mutex};

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

/// A catalogue entry's preparation for `Stack.eval_grad` alone (`ModelInfo::prepare_gradient`).
pub type PrepareGradient = fn(&Stack, &Args) -> Result<Box<dyn Differentiable>>;

/// One model of the catalogue.
pub struct ModelInfo {
    pub name: &'static str,
    pub summary: &'static str,
    pub options: &'static [OptionSpec],
    pub inputs: &'static [InputSpec],
    pub properties: Properties,
    /// The layer fields (`Field::NAMES`) whose gradients `Differentiable::gradient` returns, exact (forward-mode,
    /// src/dual.rs).
    pub gradients: &'static [&'static str],
    /// The model for a stack, its options read from `Args` into the model's own options struct.
    pub prepare: fn(&Stack, &Args) -> Result<Box<dyn Model>>,
    /// What `Stack.eval_grad` differentiates, where it needs less than `prepare` builds (tabulated: the solve in
    /// Duals without the float64 table that `eval` reads); None: `prepare`'s model.
    pub prepare_gradient: Option<PrepareGradient>,
    /// The model's GPU half (common/gpu.rs), if it has one.
    #[cfg(feature = "gpu")]
    pub gpu: Option<&'static common::gpu::GpuHalf>,
}

/// The Monte Carlo reference's entry: its options (the microsurface of every rough boundary) and properties. It is
/// an estimator (reference.rs), which `prepare` does not take.
pub const REFERENCE: ModelInfo = ModelInfo {
    name: "reference",
    summary: "unbiased Monte Carlo random walk through the stack (the ground truth), with standard errors",
    options: &[DISTRIBUTION, G2],
    inputs: &[],
    properties: Properties { reciprocal: true, energy_conserving: true, anisotropic: true, spectral: true },
    gradients: &[],
    prepare: |_, _| value_error("model 'reference' is a Monte Carlo estimator (Stack.reference), not a prepared model"),
    prepare_gradient: None,
    #[cfg(feature = "gpu")]
    gpu: None,
};

/// Every entry a user can name: the analytic models, then the reference.
pub fn entries() -> impl Iterator<Item = &'static ModelInfo> {
    CATALOGUE.iter().copied().chain([&REFERENCE])
}

/// The per-element input columns of one block, in the order of the model's `inputs`: None where not given; a
/// scalar input fills column 0.
pub type Inputs<'a> = [Option<[&'a [f64]; 3]>];

/// A layer parameter that `Stack.eval_grad` differentiates f with respect to: gradient `param` of the output is
/// the derivative by the `layer`'s `field` in `channel` (None: in every channel), times `scale`, the derivative of the
/// value the model sees by the parameter (1/η above for an IOR or κ, which the model sees relative to the medium
/// above; 1 otherwise). Several seeds may feed one parameter (a roughness: both αx and αy).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Seed {
    pub param: usize,
    pub layer: usize,
    pub field: Field,
    pub channel: Option<usize>,
    pub scale: f64,
}

/// The most parameters one gradient takes.
pub const MAX_PARAMS: usize = 8;

/// Number `v` of `layer`'s `field` in `channel` as a Dual carrying the derivatives that `seeds` give it.
pub fn seeded<const N: usize>(seeds: &[Seed], layer: usize, field: Field, channel: usize, v: f64) -> Dual<N> {
    let mut x = Dual::<N>::from(v);
    for s in seeds.iter().filter(|s| s.layer == layer && s.field == field && s.channel.is_none_or(|c| c == channel)) {
        x.d[s.param] += s.scale;
    }
    x
}

/// Writes f and its N derivatives, channel c of a `Gradient`'s output.
pub fn store<const N: usize>(out: &mut [f64], c: usize, f: Dual<N>) {
    out[c * (N + 1)] = f.v;
    out[c * (N + 1) + 1..(c + 1) * (N + 1)].copy_from_slice(&f.d);
}

/// `g::<N>(args)` with the Dual width N = `n` (1 to MAX_PARAMS): one monomorphised gradient per parameter count.
macro_rules! dual_width {
    ($n:expr, $g:ident($($arg:expr),*)) => {
        match $n {
            1 => $g::<1>($($arg),*),
            2 => $g::<2>($($arg),*),
            3 => $g::<3>($($arg),*),
            4 => $g::<4>($($arg),*),
            5 => $g::<5>($($arg),*),
            6 => $g::<6>($($arg),*),
            7 => $g::<7>($($arg),*),
            8 => $g::<8>($($arg),*),
            n => $crate::error::value_error(format!(
                "gradients take 1 to {} parameters, got {n}",
                $crate::models::MAX_PARAMS
            )),
        }
    };
}
pub(crate) use dual_width;

/// f and its parameter gradient over a block of direction pairs given as columns (wi, wo: x, y and z), one output row
/// per pair: per channel, f and then ∂f/∂p of each parameter.
pub type Gradient<'a> = Box<dyn Fn([&[f64]; 3], [&[f64]; 3], &mut [f64]) + Send + Sync + 'a>;

/// A `Gradient` of a function of one pair (wi, wo), evaluated row by row.
pub fn per_pair<'a>(g: impl Fn(DVec3, DVec3, &mut [f64]) + Send + Sync + 'a) -> Gradient<'a> {
    Box::new(move |wi, wo, out| common::block::eval_rows(wi, wo, out, |_, wi, wo, o| g(wi, wo, o)))
}

/// A lobe of the sampling mixture of a model: a GGX/Beckmann reflection lobe sampled by its visible normals, or the
/// cosine-weighted hemisphere (diffuse terms).
#[derive(Clone, Copy, Debug)]
pub enum Proposal {
    Reflection(Microfacet),
    Cosine,
}

/// What `Stack.eval_grad` asks of a prepared model: f and its parameter gradient.
pub trait Differentiable: Send + Sync {
    /// f and its gradient with respect to `n_params` parameters fed by `seeds` (`Gradient`), or a ValueError where the
    /// model does not differentiate one of the seeds' fields (`ModelInfo::gradients` lists the fields it does).
    fn gradient(&self, _seeds: &[Seed], _n_params: usize) -> Result<Gradient<'_>> {
        value_error("this model has no parameter gradients")
    }
}

/// A model prepared for one stack and its options.
pub trait Model: Differentiable {
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

    /// f of float32 (n, 3) direction rows into `out` (n rows of one value per channel) by the float32 engine
    /// (engine/), corrected by `fit` in the same pass if given (the improved variants), if the model has a lane
    /// kernel for this stack and these options; false sends the call to `eval_block` (no lane kernel, per-element
    /// inputs, or a row the engine does not take).
    fn eval_f32(&self, _wi: Rows, _wo: Rows, _fit: Option<&FitLanes>, _out: &mut [f32]) -> bool {
        false
    }

    /// `Stack.sample`'s rows (wi, weight per channel, pdf) of float32 viewing directions and uniform numbers by the
    /// float32 engine, where the model has a lane sampler (the same lobe and direction as `mixture::sample` from the
    /// same u, to float32); false sends the call to the float64 sampler.
    fn sample_f32(&self, _wo: Rows, _u: Rows, _out: &mut [f32]) -> bool {
        false
    }

    /// The model's transport_fit correction, if it has one (what the GPU applies after the model's own f).
    fn transport_fit(&self) -> Option<&corrections::transport_fit::TransportFit> {
        None
    }
}

/// The catalogue entry of `name` (the reference's included), or a ValueError listing every model.
pub fn info(name: &str) -> Result<&'static ModelInfo> {
    entries().find(|m| m.name == name).ok_or_else(|| {
        let names: Vec<&str> = entries().map(|m| m.name).collect();
        crate::error::Error::Value(format!("model must be one of {}, got {}", py_list(&names), py(name)))
    })
}

/// `name`'s entry and its options from the values given, each checked against its table (Args::parse).
pub fn parse(name: &str, given: &[(String, Value)]) -> Result<(&'static ModelInfo, Args)> {
    let info = info(name)?;
    Ok((info, Args::parse(info, given)?))
}

impl ModelInfo {
    /// The index of per-element input `name` among the model's inputs, or a TypeError listing them.
    pub fn input(&self, name: &str) -> Result<usize> {
        self.inputs.iter().position(|s| s.name == name).ok_or_else(|| {
            let names: Vec<&str> = self.inputs.iter().map(|s| s.name).collect();
            crate::error::Error::Type(format!(
                "model {} has no per-element input {}; its inputs are {}",
                py(self.name),
                py(name),
                py_list(&names)
            ))
        })
    }
}

/// The microsurface of the reference's defaults (`REFERENCE`'s options), which transport_fit solves with.
pub fn reference_surface() -> Microsurface {
    match microsurface(&Args::defaults(REFERENCE.options)) {
        Ok(surface) => surface,
        Err(_) => unreachable!("the reference's defaults are among its choices"),
    }
}

/// How many prepared models `prepare` keeps (most recently used first).
const CACHED: usize = 16;

/// The prepared models, most recently used first.
static CACHE: Mutex<Vec<(String, Arc<dyn Model>)>> = Mutex::new(Vec::new());

/// The cache's key of a model, stack and options: Debug prints every f64 in its shortest round-trip form, so equal
/// keys mean equal arguments.
fn key(model: &str, stack: &Stack, args: &Args) -> String {
    format!("{model}|{stack:?}|{args:?}")
}

/// `model` as one of the last CACHED calls of `prepare` with equal arguments prepared it, if any.
pub fn cached(model: &str, stack: &Stack, args: &Args) -> Option<Arc<dyn Model>> {
    let key = key(model, stack, args);
    let mut cache = CACHE.lock().unwrap_or_else(|e| e.into_inner());
    let k = cache.iter().position(|(k, _)| *k == key)?;
    let entry = cache.remove(k);
    let prepared = entry.1.clone();
    cache.insert(0, entry);
    Some(prepared)
}

/// Prepares `model` for `stack`, or explains why the model cannot represent the stack; a model prepared by one of
/// the last CACHED calls with equal arguments is reused.
pub fn prepare(model: &str, stack: &Stack, args: &Args) -> Result<Arc<dyn Model>> {
    if let Some(prepared) = cached(model, stack, args) {
        return Ok(prepared);
    }
    let prepared: Arc<dyn Model> = Arc::from((info(model)?.prepare)(stack, args)?);
    let mut cache = CACHE.lock().unwrap_or_else(|e| e.into_inner());
    cache.insert(0, (key(model, stack, args), prepared.clone()));
    cache.truncate(CACHED);
    Ok(prepared)
}

/// What `Stack.eval_grad` differentiates for `model`, `stack` and options: a model prepared with equal arguments by
/// one of the last CACHED calls of `prepare`, else the entry's `prepare_gradient` (not cached: each fit step is a new
/// stack), else `prepare`'s.
pub fn prepare_gradient(model: &str, stack: &Stack, args: &Args) -> Result<Arc<dyn Differentiable>> {
    if let Some(prepared) = cached(model, stack, args) {
        return Ok(prepared);
    }
    match info(model)?.prepare_gradient {
        Some(prepare_gradient) => Ok(Arc::from(prepare_gradient(stack, args)?)),
        None => Ok(prepare(model, stack, args)?),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Each entry's source, whose `//!` parameter table documents its options.
    const SOURCES: &[(&str, &str)] = &[
        ("microfacet", include_str!("microfacet.rs")),
        ("belcour", include_str!("belcour/mod.rs")),
        ("steinberg", include_str!("steinberg.rs")),
        ("weidlich_wilkie", include_str!("weidlich_wilkie.rs")),
        ("albedo_scaling", include_str!("albedo_scaling.rs")),
        ("tabulated", include_str!("tabulated.rs")),
        ("reference", include_str!("../reference.rs")),
    ];

    /// An option as a parameter table writes it: name, type and default.
    fn documented(spec: &OptionSpec) -> [String; 3] {
        let quoted = |s: &str| format!("`{s}`");
        let (kind, default) = match (spec.kind, spec.default()) {
            (OptionKind::Choice { .. } | OptionKind::Variant { .. }, Value::Text(t)) => ("string", quoted(&t)),
            (OptionKind::Flag { .. }, Value::Flag(b)) => ("bool", quoted(&b.to_string())),
            (OptionKind::Number { default, .. }, _) => ("float", default.to_string()),
            (OptionKind::Channels { default, .. }, _) => ("floats", default.to_string()),
            (kind, value) => unreachable!("{kind:?} with default {value:?}"),
        };
        [quoted(spec.name), kind.into(), default]
    }

    #[test]
    fn every_parameter_table_lists_the_options_of_the_catalogue_entry() {
        for info in entries() {
            let (_, src) = SOURCES.iter().find(|(n, _)| *n == info.name).expect("a source for every entry");
            // The table's rows that name a parameter: (name, type, default) from their first three cells.
            let rows: Vec<[String; 3]> = src
                .lines()
                .filter_map(|l| l.strip_prefix("//! | `"))
                .map(|l| {
                    let cells: Vec<String> =
                        format!("| `{l}").split('|').skip(1).take(3).map(|c| c.trim().into()).collect();
                    [cells[0].clone(), cells[1].clone(), cells[2].clone()]
                })
                .collect();
            let options: Vec<[String; 3]> = info.options.iter().map(documented).collect();
            assert_eq!(rows, options, "{}'s //! table against its catalogue entry", info.name);
        }
    }
}
