//! `model="belcour"`: Belcour 2018, "Efficient rendering of layered materials using an atomic decomposition with
//! statistical operators" — per-lobe energy, mean (as a cosine) and variance (in the projected disc, through the
//! roughness map h) carried through the stack by adding-doubling, in the form of the published reference loop;
//! one GGX lobe per interface, all centred on the mirror direction.
//!
//! Anisotropy (Yamaguchi et al. 2019): every variance is a symmetric 2x2 covariance Σ in the projected disc,
//! expressed in the stack's local tangent frame; an interface of roughness (αx, αy) whose tangent frame is rotated by
//! `angle` contributes Σ = R(angle) diag(h(αx), h(αy)) R(angle)ᵀ, and the adding-doubling combines covariances with
//! the same (scalar) energy weights and first-order Jacobians as the scalar model. Each output lobe is eigen-
//! decomposed into an anisotropic GGX lobe: α along the eigenvectors, its tangent angle that of the first one. FGD is
//! looked up at the roughness the lobe has along the viewing azimuth. An isotropic stack keeps every Σ = σI, which
//! reproduces the scalar model (to rounding). The Jacobians stay the scalar first-order ones (J ∝ I); the
//! hemispherical reflectance R̄↑ seen by a diffuse base is computed at azimuth 0.
//!
//! Statistics are computed for the viewing direction wo (or for |wo·h| with `symmetric`, Belcour §6, which makes
//! the BRDF reciprocal). Slabs are medium steps (Beer–Lambert absorption and forward Henyey–Greenstein scattering,
//! no lobe). A diffuse base contributes ρ/π · T↓(θi) T↑(θo) / ((1 − ρ R̄↑) η²) — lamina's choice, which is exact
//! for a smooth coat (Mitsuba's `plastic`): the energies transmitted down from wi and up to wo (one adding pass
//! each), the inter-reflections with the stack's hemispherical reflectance from below R̄↑ (precomputed by
//! quadrature, 1 under total internal reflection), and the radiance compression η² of the medium above the base.

//!
//! | Parameter   | Type   | Default             | Description                                                          |
//! |-------------|--------|---------------------|----------------------------------------------------------------------|
//! | `g2`        | string | `height_correlated` | masking-shadowing of the output GGX lobes                            |
//! | `symmetric` | bool   | `false`             | statistics at |wo·h| (Belcour §6): a reciprocal BRDF                 |
//! | `cosines`   | string | `frozen`            | transmission scale at normal incidence (code) or `real` (paper)      |
//! | `jacobian`  | string | `j12`               | `j12` (code) or `j21` (paper) in the transmitted variance terms      |
//! | `energy`    | string | `fgd`               | energies from FGD or the exact `fresnel` at the mean cosine          |
//! | `tir`       | string | `off`               | the code's TIR step: `off`, `transmittance` or `fraction`            |
//! | `interpolated` | bool | `true`             | interpolate the adding-doubling from a table built once per stack    |
//! | `microfacet_transmission` | bool | `false` | lamina's correction: T of a rough interface from lamina's table, not 1 − R |
//! | `transport_fit` | bool | `false`           | lamina's correction: f ← s f + a fitted to the stack's adding-doubling (corrections/transport_fit.rs) |
//! | `variant`   | string | `published`         | `improved`: lamina's corrections (`transport_fit`)                   |
//!
//! Layout: `cov.rs` (covariances, roughness maps), `adding.rs` (the adding-doubling), `table.rs` (its table and
//! the block evaluator). Sampling: each rough lobe by its GGX visible normals, weighted by its energy, and the
//! diffuse base by the cosine; lobes of roughness 0 are Dirac (`specular`). Parameter gradients (`Stack.eval_grad`)
//! run the same adding-doubling in Duals (src/dual.rs): at the table's nodes, interpolated as `eval` interpolates
//! them, or per evaluation with `interpolated=False`; exact for the model `eval` evaluates, the FGD table's
//! multilinear interpolant included.

mod adding;
mod cov;
mod lanes;
mod table;

pub use adding::Tir;
pub use cov::{alpha_from_variance, hg_variance, variance_from_alpha, Cov, Lobe};

use super::common::block::eval_rows;
use super::common::options::{choice, flag, variant, G2, MICROFACET_TRANSMISSION, TRANSPORT_FIT};
use super::corrections::transport_fit;
use super::{
    Args, Differentiable, Field, Gradient, InputSpec, Inputs, Model, ModelInfo, OptionSpec, Properties, Proposal, Seed,
};
use crate::bsdf;
use crate::dual::{Dual, Real};
use crate::engine::Rows;
use crate::error::{value_error, Result};
use crate::models::FitLanes;
use crate::optics::distribution::{Distribution, G2Form, Microfacet};
use crate::stack::{Layer, Stack};
use adding::{mean, DiffuseBase, Step};
use glam::DVec3;
use std::f64::consts::FRAC_1_PI;
use table::{azimuth, eval_table, LobeTable};

pub const INFO: ModelInfo = ModelInfo {
    name: "belcour",
    summary: "Belcour 2018 adding-doubling of lobe statistics, with Yamaguchi et al. 2019's anisotropic covariances",
    options: &[
        G2,
        flag("symmetric", false, "statistics at |wo·h| instead of cos θo (Belcour §6): a reciprocal BRDF"),
        choice("cosines", &["frozen", "real"], "frozen", "transmission scale with cosines frozen at normal incidence (code) or the real ones (paper: exact Jacobians at the lobe mean)"),
        choice("jacobian", &["j12", "j21"], "j12", "Jacobian in the transmitted and back-reflected variance terms: j12 (code) or j21 (paper)"),
        choice("energy", &["fgd", "fresnel"], "fgd", "lobe energies from the FGD table or the exact Fresnel at the mean cosine"),
        choice("tir", &Tir::NAMES, "off", "the reference code's TIR step: off, its table (repeats the Fresnel factor) or the totally reflected fraction"),
        flag("interpolated", true, "interpolate the adding-doubling from a table over the viewing direction, built once per stack; False: run it per evaluation"),
        MICROFACET_TRANSMISSION,
        TRANSPORT_FIT,
        variant(&["transport_fit"], "published: Belcour 2018; improved: with lamina's correction transport_fit"),
    ] as &[OptionSpec],
    inputs: &[] as &[InputSpec],
    properties: Properties { reciprocal: false, energy_conserving: false, anisotropic: true, spectral: true },
    gradients: &["ior", "k", "roughness_x", "roughness_y", "angle", "albedo", "thickness", "sigma_a", "sigma_s", "g"],
    prepare: |stack, args| {
        let opts = Options::parse(args)?;
        transport_fit::apply(opts.transport_fit, Box::new(prepare(stack, &opts)?), stack)
    },
    prepare_gradient: None,
    #[cfg(feature = "gpu")]
    gpu: Some(&gpu::HALF),
};

/// Belcour's options (the table above). Where the paper and the reference code disagree, each choice is an option,
/// measured against the reference in docs/validation.md; the defaults are the reference code's.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Options {
    pub g2: G2Form,
    /// Statistics at |wo·h| instead of cos θo (Belcour §6).
    pub symmetric: bool,
    /// Transmission roughness scale s with the real cosines (paper) instead of cosines frozen to 1 (code).
    pub real_cosines: bool,
    /// J21 (paper) instead of j12 (code) in the transmitted and back-reflected variance terms.
    pub jacobian_j21: bool,
    /// Energies from the exact Fresnel at the mean cosine instead of the FGD table.
    pub fresnel_energy: bool,
    /// The reference code's TIR step before each interface below the first.
    pub tir: Tir,
    /// Interpolate the adding-doubling from a table over the viewing direction (`table.rs`).
    pub interpolated: bool,
    /// lamina's correction: a rough dielectric transmits T (tables::steinberg, the single-scattering microfacet
    /// transmission with its masking) instead of 1 − R: R + T < 1, as for the microsurface itself.
    pub microfacet_transmission: bool,
    pub transport_fit: bool,
}

impl Options {
    pub fn parse(args: &Args) -> Result<Options> {
        Ok(Options {
            g2: args.choice("g2")?,
            symmetric: args.flag("symmetric")?,
            real_cosines: args.is("cosines", "real")?,
            jacobian_j21: args.is("jacobian", "j21")?,
            fresnel_energy: args.is("energy", "fresnel")?,
            tir: args.choice("tir")?,
            interpolated: args.flag("interpolated")?,
            microfacet_transmission: args.flag("microfacet_transmission")?,
            transport_fit: args.flag("transport_fit")?,
        })
    }
}

impl Default for Options {
    /// The table's defaults.
    fn default() -> Self {
        Options::parse(&Args::defaults(INFO.options)).expect("the table's defaults parse")
    }
}

pub struct Prepared {
    steps: Vec<Step>,
    anisotropic: bool,
    diffuse: Option<DiffuseBase>,
    table: Option<LobeTable>,
    /// The table in float32, for float32 inputs (lanes.rs).
    table_f32: Option<lanes::TableF32>,
    opts: Options,
    channels: usize,
    /// The stack, for gradients (which run the adding-doubling in Duals).
    stack: Stack,
}

/// A stack's steps and its Lambertian base.
type Layers<T> = (Vec<Step<T>>, Option<DiffuseBase<T>>);

/// The steps of `stack` and its base (with R̄↑ under `opts`), each number through `value(layer, field, channel,
/// number)`: the identity, or a Dual seeded for gradients. With `every_slab`, each dielectric gets a slab step, even
/// one that does nothing (a gradient by the thickness or σ where they are 0).
fn layers<T: Real>(
    stack: &Stack,
    opts: &Options,
    value: impl Fn(usize, Field, usize, f64) -> T,
    every_slab: bool,
) -> Result<Layers<T>> {
    let channels = |i: usize, field: Field, v: &[f64]| -> Vec<T> {
        v.iter().enumerate().map(|(c, &x)| value(i, field, c, x)).collect()
    };
    let mut steps = Vec::new();
    let mut diffuse = None;
    for (i, (layer, rel)) in stack.layers.iter().zip(stack.interfaces()).enumerate() {
        let (alpha, angle) = match layer {
            Layer::Dielectric { alpha, angle, .. } | Layer::Conductor { alpha, angle, .. } => (*alpha, *angle),
            Layer::Diffuse { roughness, .. } if *roughness > 0.0 => {
                return value_error("model 'belcour' takes a Lambertian diffuse base (roughness 0)");
            }
            Layer::Diffuse { .. } => ((0.0, 0.0), 0.0),
        };
        let interface = |conductor: bool| Step::Interface {
            eta: channels(i, Field::Ior, &rel.eta),
            kappa: channels(i, Field::K, &rel.kappa),
            alpha: (value(i, Field::RoughnessX, 0, alpha.0), value(i, Field::RoughnessY, 0, alpha.1)),
            angle: value(i, Field::Angle, 0, angle),
            conductor,
        };
        match layer {
            Layer::Dielectric { thickness, sigma_a, sigma_s, g, .. } => {
                steps.push(interface(false));
                let extinct = sigma_a.iter().chain(sigma_s).any(|&s| s > 0.0);
                if (*thickness > 0.0 && extinct) || every_slab {
                    steps.push(Step::Medium {
                        thickness: value(i, Field::Thickness, 0, *thickness),
                        sigma_a: channels(i, Field::SigmaA, sigma_a),
                        sigma_s: channels(i, Field::SigmaS, sigma_s),
                        g: value(i, Field::G, 0, *g),
                    });
                }
            }
            Layer::Conductor { .. } => steps.push(interface(true)),
            Layer::Diffuse { albedo, .. } => {
                diffuse = Some((channels(i, Field::Albedo, albedo), mean(&channels(i, Field::Ior, &rel.eta))));
            }
        }
    }
    let diffuse = diffuse.map(|(albedo, eta)| {
        let r_up = adding::hemispherical_reflectance_from_below(&steps, opts, stack.channels, eta);
        DiffuseBase { albedo, eta, r_up }
    });
    Ok((steps, diffuse))
}

/// Whether an interface of the steps is anisotropic (in Duals: or a parameter moves its two roughnesses apart).
fn anisotropic<T: Real>(steps: &[Step<T>]) -> bool {
    steps.iter().any(|s| matches!(s, Step::Interface { alpha, .. } if alpha.0 != alpha.1))
}

pub fn prepare(stack: &Stack, opts: &Options) -> Result<Prepared> {
    let (steps, diffuse) = layers(stack, opts, |_, _, _, v| v, false)?;
    let anisotropic = anisotropic(&steps);
    let mut p = Prepared {
        steps,
        anisotropic,
        diffuse,
        table: None,
        table_f32: None,
        opts: *opts,
        channels: stack.channels,
        stack: stack.clone(),
    };
    if opts.interpolated {
        let t = LobeTable::new(&p.steps, &p.opts, p.channels, p.anisotropic);
        p.table_f32 = Some(lanes::TableF32::new(&p, &t));
        p.table = Some(t);
    }
    Ok(p)
}

/// The gradient of the model `eval` evaluates (`Differentiable::gradient`: its table, or its adding-doubling per
/// evaluation) with respect to N parameters: f and ∂f/∂p per channel, through every step (IOR, κ, roughness, tangent
/// angle, thickness, σa, σs, g, the base's albedo), the FGD table's interpolant included. The reference code's TIR
/// step and `microfacet_transmission` read tables without derivatives: they are refused (and so is `transport_fit`).
fn gradient<const N: usize>(p: &Prepared, seeds: &[Seed]) -> Result<Gradient<'static>> {
    if p.opts.tir != Tir::Off || p.opts.microfacet_transmission {
        return value_error("gradients of model 'belcour' take tir='off' and microfacet_transmission=False");
    }
    let value =
        |layer: usize, field: Field, channel: usize, v: f64| super::seeded::<N>(seeds, layer, field, channel, v);
    let (steps, diffuse) = layers(&p.stack, &p.opts, value, true)?;
    let opts = p.opts;
    // With a table (interpolated=True), the gradient of the model that `eval` interpolates: the table's runs in
    // Duals. An isotropic table holds one roughness per lobe, which a parameter of one axis would make two: then the
    // adding-doubling per evaluation.
    let table = p
        .table
        .as_ref()
        .filter(|_| anisotropic(&steps) == p.anisotropic)
        .map(|_| LobeTable::new(&steps, &opts, p.channels, p.anisotropic));
    let channels = p.channels;
    Ok(Box::new(move |wi, wo, out| {
        let mut f = vec![Dual::<N>::from(0.0); channels];
        eval_rows(wi, wo, out, |_, wi, wo, out| {
            match &table {
                Some(t) => eval_table(t, diffuse.as_ref(), &opts, wi, wo, &mut f),
                None => eval_exact(&steps, diffuse.as_ref(), &opts, wi, wo, &mut f),
            }
            f.iter().enumerate().for_each(|(c, &x)| super::store(out, c, x));
        })
    }))
}

/// f by the adding-doubling run for this pair (`interpolated=False`), in f64 or in Duals: each lobe's GGX at its
/// energy, and the diffuse base.
fn eval_exact<T: Real>(
    steps: &[Step<T>],
    diffuse: Option<&DiffuseBase<T>>,
    opts: &Options,
    wi: DVec3,
    wo: DVec3,
    out: &mut [T],
) {
    out.fill(T::from(0.0));
    if wi.z <= 0.0 || wo.z <= 0.0 {
        return;
    }
    let channels = out.len();
    let cos_theta = if opts.symmetric { symmetric_cosine(wi, wo) } else { wo.z };
    let (cos_phi, sin_phi) = azimuth(wo);
    let (lobes, view) = adding::adding(steps, opts, channels, T::from(cos_theta), cos_phi, sin_phi);
    for lobe in &lobes {
        add_lobe(opts.g2, lobe.roughness(), |ch| lobe.energy[ch], wi, wo, out);
    }
    if diffuse.is_some() {
        // T↓ at θi and T↑ at θo (not at |wo·h|): symmetric under exchange, since T0i = Ti0 in this model.
        let (ci, si) = azimuth(wi);
        let light = adding::adding(steps, opts, channels, T::from(wi.z), ci, si).1;
        let view = if opts.symmetric {
            adding::adding(steps, opts, channels, T::from(wo.z), cos_phi, sin_phi).1
        } else {
            view
        };
        add_diffuse(diffuse, |ch| light.t0i[ch], |ch| view.ti0[ch], out);
    }
}

/// Adds one GGX lobe of roughness (αx, αy, tangent angle) with per-channel `energy`; a lobe of roughness 0 is a Dirac
/// delta, not part of f.
fn add_lobe<T: Real>(
    g2: G2Form,
    roughness: (T, T, T),
    energy: impl Fn(usize) -> T,
    wi: DVec3,
    wo: DVec3,
    out: &mut [T],
) {
    let shape = lobe_shape(g2, roughness, wi, wo);
    for (ch, o) in out.iter_mut().enumerate() {
        *o = *o + energy(ch) * shape;
    }
}

/// A GGX lobe's D G2 / (4 cos θi cos θo) (Walter et al. 2007 eq. 20), 0 for a Dirac one. In Duals it runs with the
/// partials by the lobe's own roughness (one for an isotropic lobe, three otherwise), composed into T's N
/// derivatives: fewer than N to carry through the geometry.
fn lobe_shape<T: Real>(g2: G2Form, (ax, ay, angle): (T, T, T), wi: DVec3, wo: DVec3) -> T {
    fn shape<R: Real>(g2: G2Form, ax: R, ay: R, angle: R, wi: DVec3, wo: DVec3) -> R {
        let mf = Microfacet::<R>::with_parameters(Distribution::Ggx, ax, ay, angle);
        bsdf::reflection_geometry(&mf, g2, wi, wo).map_or(R::from(0.0), |(geo, _)| geo)
    }
    if T::DERIVATIVES == 0 {
        return T::from(shape(g2, ax.value(), ay.value(), angle.value(), wi, wo));
    }
    if ax.same(ay) && angle.same(T::from(0.0)) {
        let a = Dual::<1>::seeded(ax.value(), 0, 1.0);
        return T::compose(shape(g2, a, a, Dual::from(0.0), wi, wo), [ax]);
    }
    let [x, y, phi] = [ax, ay, angle].map(|v| v.value());
    let d = |v: f64, k: usize| Dual::<3>::seeded(v, k, 1.0);
    T::compose(shape(g2, d(x, 0), d(y, 1), d(phi, 2), wi, wo), [ax, ay, angle])
}

/// Adds the diffuse base ρ/π · T↓ T↑ / ((1 − ρ R̄↑) η²) from the energies transmitted down and up per channel.
fn add_diffuse<T: Real>(d: Option<&DiffuseBase<T>>, down: impl Fn(usize) -> T, up: impl Fn(usize) -> T, out: &mut [T]) {
    let Some(d) = d else { return };
    for (ch, o) in out.iter_mut().enumerate() {
        let rho = d.albedo[ch];
        *o = *o + rho * FRAC_1_PI * down(ch) * up(ch) / ((T::from(1.0) - rho * d.r_up[ch]) * d.eta * d.eta);
    }
}

impl Differentiable for Prepared {
    fn gradient(&self, seeds: &[Seed], n_params: usize) -> Result<Gradient<'_>> {
        super::dual_width!(n_params, gradient(self, seeds))
    }
}

impl Model for Prepared {
    fn eval_block(&self, wi: [&[f64]; 3], wo: [&[f64]; 3], _: &Inputs, out: &mut [f64]) {
        super::common::block::simd_columns!(Prepared, self, wi, wo, out)
    }

    fn eval_f32(&self, wi: Rows, wo: Rows, fit: Option<&FitLanes>, out: &mut [f32]) -> bool {
        lanes::eval(self, wi, wo, fit, out)
    }

    fn sample_f32(&self, wo: Rows, u: Rows, out: &mut [f32]) -> bool {
        lanes::sample(self, wo, u, out)
    }

    fn proposals(&self, wo: DVec3) -> Vec<(f64, Proposal)> {
        // Each lobe's energy and roughness, and T↑ for the diffuse base: from the table when there is one.
        let (lobes, t_up) = match &self.table {
            Some(t) => {
                let c = t.corner_of(wo.z, wo);
                (t.lobes_at(&c), (0..self.channels).map(|ch| t.energy_at(&t.t_up, &c, ch)).collect())
            }
            None => {
                let (cos_phi, sin_phi) = azimuth(wo);
                let (lobes, view) = self.adding(wo.z, cos_phi, sin_phi);
                (lobes.iter().map(|l| (l.roughness(), l.energy.clone())).collect(), view.ti0)
            }
        };
        let mut out: Vec<(f64, Proposal)> = lobes
            .iter()
            .filter_map(|&((ax, ay, angle), ref energy)| {
                let mf = Microfacet::new(Distribution::Ggx, ax, ay, angle);
                (!mf.is_smooth()).then(|| (mean(energy), Proposal::Reflection(mf)))
            })
            .collect();
        if let Some(d) = &self.diffuse {
            let e = (0..self.channels).map(|c| d.albedo[c] * t_up[c] * t_up[c] / (1.0 - d.albedo[c] * d.r_up[c]));
            out.push((e.sum::<f64>() / self.channels as f64, Proposal::Cosine));
        }
        out.retain(|(w, _)| *w > 0.0);
        out
    }

    fn specular(&self, wo: DVec3, out: &mut [f64]) {
        out.fill(0.0);
        if wo.z <= 0.0 {
            return;
        }
        for lobe in self.lobes(wo) {
            if Microfacet::new(Distribution::Ggx, lobe.roughness().0, lobe.roughness().1, 0.0).is_smooth() {
                out.iter_mut().zip(&lobe.energy).for_each(|(o, e)| *o += e);
            }
        }
    }
}

/// What the GPU evaluator (src/gpu, shaders/belcour.wgsl) needs of an interpolated stack: the table's shape and
/// arrays, and the diffuse base as (albedo, R̄↑) per channel and η.
pub struct GpuData<'a> {
    /// lobes, nodes, azimuths, width, channels.
    pub shape: [usize; 5],
    pub record: &'a [f64],
    pub t_down: &'a [f64],
    pub t_up: &'a [f64],
    pub g2: G2Form,
    pub symmetric: bool,
    pub diffuse: Option<(Vec<[f64; 2]>, f64)>,
}

impl Prepared {
    /// The table and parameters for the GPU; None without a table (`interpolated=False` runs on the CPU only).
    pub fn gpu_data(&self) -> Option<GpuData<'_>> {
        let t = self.table.as_ref()?;
        Some(GpuData {
            shape: [t.lobes, t.nodes, t.azimuths, t.width, self.channels],
            record: &t.record,
            t_down: &t.t_down,
            t_up: &t.t_up,
            g2: self.opts.g2,
            symmetric: self.opts.symmetric,
            diffuse: self
                .diffuse
                .as_ref()
                .map(|d| (d.albedo.iter().zip(&d.r_up).map(|(a, r)| [*a, *r]).collect(), d.eta)),
        })
    }

    /// The lobes for a viewing direction `wo` (unit, above the surface).
    pub fn lobes(&self, wo: DVec3) -> Vec<Lobe> {
        let (cos_phi, sin_phi) = azimuth(wo);
        self.adding(wo.z, cos_phi, sin_phi).0
    }

    pub fn eval(&self, wi: DVec3, wo: DVec3, out: &mut [f64]) {
        if self.table.is_some() && wi.z > 0.0 && wo.z > 0.0 {
            out.fill(0.0);
            return self.eval_columns([&[wi.x], &[wi.y], &[wi.z]], [&[wo.x], &[wo.y], &[wo.z]], out);
        }
        eval_exact(&self.steps, self.diffuse.as_ref(), &self.opts, wi, wo, out)
    }

    /// The adding-doubling of this stack for a viewing direction (`adding::adding`).
    fn adding(&self, cos_theta: f64, cos_phi: f64, sin_phi: f64) -> (Vec<Lobe>, adding::State) {
        adding::adding(&self.steps, &self.opts, self.channels, cos_theta, cos_phi, sin_phi)
    }
}

/// |wo·h| with h the half vector (Belcour 2018 §6): where wi + wo is too short to normalise (a grazing mirror pair,
/// whose half vector is the normal), wo·n.
#[inline(always)]
fn symmetric_cosine(wi: DVec3, wo: DVec3) -> f64 {
    let c = wo.dot((wi + wo).normalize()).abs();
    if c.is_finite() {
        c
    } else {
        wo.z
    }
}

/// The GPU half (shaders/belcour.wgsl): the interpolated adding-doubling (`interpolated=True`).
#[cfg(feature = "gpu")]
pub mod gpu {
    use super::{prepare, Options};
    use crate::error::{value_error, Result};
    use crate::models::common::gpu::{g2_code, params, word, words, GpuHalf, Kernel};
    use crate::models::Args;
    use crate::stack::Stack;

    pub const HALF: GpuHalf = GpuHalf {
        shader: &[include_str!("../../gpu/shaders/belcour.wgsl")],
        refusal: |args| {
            (args.flag("interpolated") == Ok(false))
                .then(|| "model 'belcour' with interpolated=False runs on the CPU only; use device='cpu'".into())
        },
        kernel,
    };

    params! {
        /// belcour.wgsl's `Params`.
        n: u32,
        channels: u32,
        lobes: u32,
        nodes: u32,
        azimuths: u32,
        width: u32,
        g2: u32,
        symmetric: u32,
        has_diffuse: u32,
        diffuse_eta: f32,
        pad0: u32,
        pad1: u32,
        record_base: u32,
        t_down_base: u32,
        t_up_base: u32,
        diffuse_base: u32,
    }

    /// The kernel: the parameters, the table and the diffuse base.
    fn kernel(stack: &Stack, args: &Args) -> Result<Kernel> {
        let p = prepare(stack, &Options::parse(args)?)?;
        let Some(d) = p.gpu_data() else {
            return value_error("model 'belcour' with interpolated=False runs on the CPU only; use device='cpu'");
        };
        let [lobes, nodes, azimuths, width, channels] = d.shape.map(|x| x as u32);
        let (diffuse, eta) = d.diffuse.unwrap_or((vec![], 1.0));
        let f32s = |v: &[f64]| v.iter().map(|&x| x as f32).collect::<Vec<f32>>();
        let params = Params {
            n: 0,
            channels,
            lobes,
            nodes,
            azimuths,
            width,
            g2: g2_code(d.g2),
            symmetric: d.symmetric as u32,
            has_diffuse: !diffuse.is_empty() as u32,
            diffuse_eta: eta as f32,
            pad0: 0,
            pad1: 0,
            record_base: 0,
            t_down_base: 0,
            t_up_base: 0,
            diffuse_base: 0,
        };
        let diffuse: Vec<f32> = diffuse.iter().flatten().map(|&x| x as f32).collect();
        Ok(Kernel {
            shader: "belcour",
            words: words(&params),
            count_word: word!(Params, n),
            arrays: vec![
                (f32s(d.record), word!(Params, record_base)),
                (f32s(d.t_down), word!(Params, t_down_base)),
                (f32s(d.t_up), word!(Params, t_up_base)),
                (diffuse, word!(Params, diffuse_base)),
            ],
            tables: vec![],
            channels: channels as usize,
            fit: None,
        })
    }

    #[cfg(test)]
    #[test]
    fn params_mirror_the_wgsl_struct() {
        crate::gpu::tests::assert_mirrors("belcour", Params::FIELDS, std::mem::size_of::<Params>());
    }
}

#[cfg(test)]
mod tests {
    use super::table::{direction_of_pseudo_angle, pseudo_angle};
    use super::*;
    use crate::models::common::testing;
    use crate::tables;

    #[test]
    fn smooth_coat_over_lambert_is_the_closed_form() {
        let stack = testing::stack(vec![testing::dielectric(1.5, 0.0, 0.0, 0.0, 0.0), testing::lambert(0.7)]);
        let p = prepare(&stack, &Options { interpolated: false, ..Options::default() }).unwrap();
        let f_int = crate::optics::fresnel::diffuse_reflectance(1.0 / 1.5);
        for (wi, wo) in [(DVec3::new(0.3, 0.1, 0.9), DVec3::new(-0.6, 0.2, 0.5)), (DVec3::new(0.9, 0.0, 0.2), DVec3::Z)]
        {
            let (wi, wo) = (wi.normalize(), wo.normalize());
            let mut out = [0.0];
            p.eval(wi, wo, &mut out);
            let exact = crate::models::microfacet::smooth_coat_lambert(0.7, 1.5, f_int, wi.z, wo.z);
            assert!((out[0] - exact).abs() < 1e-9 * exact, "{} vs {exact}", out[0]);
        }
    }

    #[test]
    fn covariance_eigen_decomposition_round_trips() {
        let c = Cov::oriented(0.3, 0.05, 0.7);
        let (l1, l2, angle) = c.eigen();
        assert!((l1 - 0.3).abs() < 1e-12 && (l2 - 0.05).abs() < 1e-12);
        let back = Cov::oriented(l1, l2, angle);
        assert!((back.xx - c.xx).abs() < 1e-12 && (back.xy - c.xy).abs() < 1e-12 && (back.yy - c.yy).abs() < 1e-12);
        assert_eq!(Cov::iso(0.2).eigen(), (0.2, 0.2, 0.0));
        assert!((c.along(0.7f64.cos(), 0.7f64.sin()) - 0.3).abs() < 1e-12);
    }

    #[test]
    fn pseudo_angle_is_monotonic_in_the_azimuth_and_round_trips() {
        let mut last = -1.0;
        for k in 0..3600 {
            let phi = std::f64::consts::PI * k as f64 / 3600.0;
            let p = pseudo_angle(phi.cos(), phi.sin());
            assert!(p > last && (p - phi).abs() < 4e-3, "φ = {phi}: {p} after {last}");
            assert_eq!(pseudo_angle(-phi.cos(), -phi.sin()), p, "period π");
            let (c, s) = direction_of_pseudo_angle(p);
            assert!((c - phi.cos()).abs() < 1e-12 && (s - phi.sin()).abs() < 1e-12);
            last = p;
        }
        assert_eq!(pseudo_angle(0.0, 0.0), 0.0);
    }

    #[test]
    fn variance_map_round_trips() {
        for a in [0.0, 0.01, 0.1, 0.5, 0.9] {
            assert!((alpha_from_variance(variance_from_alpha(a)) - a).abs() < 1e-12);
        }
    }

    #[test]
    fn single_conductor_has_one_lobe_of_its_roughness_and_fgd_energy() {
        let stack =
            Stack::new(vec![Layer::Conductor { ior: vec![0.2], k: vec![3.0], alpha: (0.3, 0.3), angle: 0.0 }], 1.0)
                .unwrap();
        let p = prepare(&stack, &Options::default()).unwrap();
        let lobes = p.lobes(DVec3::new((1.0f64 - 0.49).sqrt(), 0.0, 0.7));
        assert_eq!(lobes.len(), 1);
        let (ax, ay, angle) = lobes[0].roughness();
        assert!((ax - 0.3).abs() < 1e-9 && ax == ay && angle == 0.0);
        assert!((lobes[0].energy[0] - tables::fgd().lookup(0.7, 0.3, 0.2, 3.0)).abs() < 1e-12);
    }
}
