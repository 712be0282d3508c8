//! `model="albedo_scaling"`: the coat model of today's production shading standards (OpenPBR Surface, Autodesk
//! Standard Surface, Adobe's openpbr-bsdf, MaterialX): every interface is a single-scattering microfacet lobe, and
//! what lies beneath it is scaled by the energy the lobe does not reflect, 1 − E(μ), with E its directional albedo
//! (lamina's FGD table), and by the Beer–Lambert transmittance of the slab under it, exp(−σt d (1/μi′ + 1/μo′)) along
//! the refracted directions (OpenPBR's view-dependent absorption). Recursively, top to bottom:
//! f = f_interface(wi, wo) + S(wi, wo) f_below(wi, wo), with the layers below evaluated at the same outside
//! directions (no refraction, as the standards do).
//!
//! | Parameter | Type   | Default             | Description                                                     |
//! |-----------|--------|---------------------|-----------------------------------------------------------------|
//! | `g2`      | string | `separable`         | masking-shadowing of the lobes (separable: as in the E table)   |
//! | `roughening` | bool | `true`               | OpenPBR's roughening of each layer under a rough one:           |
//! |           |        |                     | r′ = min(1, r⁴ + 2 r_c⁴)^{1/4} with r = √α: α′ = √min(1, α² + 2α_c²) |
//! | `scaling` | string | `reciprocal`        | S = T (1 − E(μi))(1 − E(μo)) (Adobe's openpbr-bsdf: reciprocal) |
//! |           |        |                     | or `view`: S = T (1 − E(μo)) (the OpenPBR text, Standard        |
//! |           |        |                     | Surface, MaterialX: energy-conserving for a view, not reciprocal) |
//!
//! What the standards add and lamina leaves out: OpenPBR's coat darkening Δ = (1 − K)/(1 − E_b K) (the light the
//! coat reflects back onto the base), coat colour as the square of the normal-incidence transmittance, and the
//! weights that blend a coat in and out. The roughening is applied down the stack, each layer against the already
//! roughened one above it. E is the FGD table's (separable Smith, like the lobes by default), at the
//! geometric-mean roughness √(αx αy) for anisotropic interfaces. The layers are the single-pass models' (their
//! Fresnel terms, refraction and Beer–Lambert too). Sampling: each rough lobe by its visible normals, weighted by
//! its share of the energy, the diffuse base by the cosine, and the layered models' defensive cosine share.
//! Float32 inputs run in lanes (`Lanes`), with 1 − E sliced from the FGD table at each interface's α, η and κ: linear
//! interpolation in μ of the slice is the table's quadrilinear lookup exactly.

use super::common::block::eval_rows;
use super::common::mixture::defensive_mixture;
use super::common::mixture_lanes::{self, mean, LaneMixture, Proposals, MAX_TERMS};
use super::common::options::{choice, flag, g2};
use super::common::single_pass::{self, beer_lambert, refracted_up, SpInterface, SpLayer};
use super::common::walk_lanes::{self, MAX_CHANNELS};
use super::{
    per_pair, seeded, store, Args, Differentiable, Field, Gradient, InputSpec, Inputs, Model, ModelInfo, OptionSpec,
    Properties, Proposal, Seed,
};
use crate::bsdf;
use crate::dual::{dir, Dual, Real};
use crate::engine::{self, Floats, Rows, V3};
use crate::error::Result;
use crate::models::FitLanes;
use crate::optics::distribution::{Distribution, G2Form, Microfacet};
use crate::optics::fresnel::{self, FresnelForm};
use crate::optics::lanes::{dielectric_transmittance, ConductorIor, Lobe, Visible};
use crate::optics::{diffuse, sin_theta};
use crate::stack::Stack;
use crate::tables::{self, fgd, lerp_lanes, node_lanes};
use glam::DVec3;

pub const INFO: ModelInfo = ModelInfo {
    name: "albedo_scaling",
    summary: "the production coat model (OpenPBR, Standard Surface): lobes stacked with 1 − E(μ) albedo scaling",
    options: &[
        g2("separable", "masking-shadowing of the lobes; separable, as in the FGD table behind E"),
        flag("roughening", true, "OpenPBR's roughening of each layer under a rough one, α′ = √min(1, α² + 2α_c²)"),
        choice(
            "scaling",
            &["reciprocal", "view"],
            "reciprocal",
            "what lies beneath scaled by (1 − E(μi))(1 − E(μo)) (Adobe openpbr-bsdf) or by 1 − E(μo) (OpenPBR text, \
             Standard Surface)",
        ),
    ] as &[OptionSpec],
    inputs: &[] as &[InputSpec],
    properties: Properties { reciprocal: true, energy_conserving: true, anisotropic: true, spectral: true },
    gradients: &Field::NAMES,
    prepare: |stack, args| Ok(Box::new(prepare(stack, &Options::parse(args)?)?)),
    prepare_gradient: None,
    #[cfg(feature = "gpu")]
    gpu: Some(&gpu::HALF),
};

/// Albedo scaling's options (the table above).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Options {
    pub g2: G2Form,
    pub roughening: bool,
    /// (1 − E(μi))(1 − E(μo)) instead of 1 − E(μo).
    pub reciprocal: bool,
}

impl Options {
    pub fn parse(args: &Args) -> Result<Options> {
        Ok(Options {
            g2: args.choice("g2")?,
            roughening: args.flag("roughening")?,
            reciprocal: args.is("scaling", "reciprocal")?,
        })
    }
}

pub struct Prepared {
    /// The stack as the single-pass models see it (models/common/single_pass.rs), roughened.
    pub layers: Vec<SpLayer>,
    pub g2: G2Form,
    pub reciprocal: bool,
    pub channels: usize,
    /// The stack and the roughening, which the gradient takes in Duals.
    stack: Stack,
    roughening: bool,
    /// The float32 kernel, where the lanes cover the stack (`Lanes::new`).
    lanes: Option<Lanes>,
}

/// OpenPBR's roughening of what lies under a rough coat, r′ = min(1, r⁴ + 2 r_c⁴)^{1/4} in its roughness r = √α,
/// i.e. α′ = √min(1, α² + 2 α_c²), per tangent axis.
pub fn roughened<T: Real>(alpha: T, coat: T) -> T {
    (alpha * alpha + coat * 2.0 * coat).min_c(1.0).sqrt()
}

/// OpenPBR's roughening (`roughened`) applied down the stack, each interface against the already roughened one above.
fn roughen<T: Real>(layers: &mut [SpLayer<T>]) {
    let mut above: Option<Microfacet<T>> = None;
    for layer in layers {
        if let SpLayer::Dielectric { iface, .. } | SpLayer::Conductor { iface, .. } = layer {
            if let Some(coat) = above.filter(|c| !c.is_smooth()) {
                let mf = iface.mf;
                let (ax, ay) = if mf.is_smooth() { (T::from(0.0), T::from(0.0)) } else { (mf.alpha_x, mf.alpha_y) };
                iface.mf = mf.with_alpha(roughened(ax, coat.alpha_x), roughened(ay, coat.alpha_y));
            }
            above = Some(iface.mf);
        }
    }
}

pub fn prepare(stack: &Stack, opts: &Options) -> Result<Prepared> {
    let mut layers = single_pass::layers(stack, Distribution::Ggx, false);
    if opts.roughening {
        roughen(&mut layers);
    }
    tables::fgd(); // generate or load the table outside the parallel evaluation
    let lanes = Lanes::new(&layers, opts, stack.channels);
    let (g2, reciprocal, channels, roughening) = (opts.g2, opts.reciprocal, stack.channels, opts.roughening);
    Ok(Prepared { layers, g2, reciprocal, channels, stack: stack.clone(), roughening, lanes })
}

/// The gradient of `eval` with respect to N parameters: the roughened layers in Duals, through the FGD table's
/// interpolant (exact Fresnel, as the model's).
fn gradient<'a, const N: usize>(p: &'a Prepared, seeds: &[Seed]) -> Result<Gradient<'a>> {
    let value = |layer: usize, field: Field, channel: usize, v: f64| seeded::<N>(seeds, layer, field, channel, v);
    let mut layers = single_pass::layers_with(&p.stack, Distribution::Ggx, false, value);
    if p.roughening {
        roughen(&mut layers);
    }
    Ok(per_pair(move |wi, wo, out| {
        let mut f = vec![Dual::<N>::from(0.0); p.channels];
        eval(&layers, p.g2, p.reciprocal, wi, wo, &mut f);
        f.into_iter().enumerate().for_each(|(c, x)| store(out, c, x));
    }))
}

/// Fresnel reflectance of channel c at cosine `cos` (exact dielectric or conductor).
fn fresnel<T: Real>(i: &SpInterface<T>, cos: f64, c: usize) -> T {
    match i.conductor {
        true => fresnel::conductor(cos, i.eta[c], i.kappa[c]),
        false => fresnel::dielectric(cos, i.eta[c]),
    }
}

/// E(μ): the directional albedo of the interface's lobe (FGD table; the Fresnel reflectance itself when smooth).
fn albedo<T: Real>(i: &SpInterface<T>, mu: f64, c: usize) -> T {
    if i.mf.is_smooth() {
        return fresnel(i, mu, c);
    }
    let alpha = (i.mf.alpha_x * i.mf.alpha_y).sqrt();
    tables::fgd().lookup(T::from(mu), alpha, i.eta[c], i.kappa[c])
}

/// 1 − E(μ): what the interface's lobe does not reflect (a smooth interface's without cancellation at grazing
/// incidence, where F → 1).
fn unreflected<T: Real>(i: &SpInterface<T>, mu: f64, c: usize) -> T {
    match (i.mf.is_smooth(), i.conductor) {
        (true, false) => fresnel::dielectric_transmittance(mu, i.eta[c]),
        (true, true) => T::from(1.0) - fresnel(i, mu, c),
        (false, _) => T::from(1.0) - albedo(i, mu, c),
    }
}

/// The interfaces top to bottom, each with the slab beneath it (thickness, σt per channel); None for the base.
fn interfaces<T: Real>(layers: &[SpLayer<T>]) -> impl Iterator<Item = (&SpInterface<T>, Option<(T, &[T])>)> {
    layers.iter().filter_map(|layer| match layer {
        SpLayer::Dielectric { iface, thickness, sigma_t, .. } => Some((iface, Some((*thickness, &sigma_t[..])))),
        SpLayer::Conductor { iface, .. } => Some((iface, None)),
        SpLayer::Diffuse { .. } => None,
    })
}

/// The scale S of what lies beneath interface `i` (over its slab) for channel c: 1 − E per direction (of wo alone
/// unless `reciprocal`) and the slab's Beer–Lambert transmittance along the refracted directions.
fn scale<T: Real>(i: &SpInterface<T>, slab: (T, &[T]), reciprocal: bool, wi: DVec3, wo: DVec3, c: usize) -> T {
    let (thickness, sigma_t) = slab;
    let view = unreflected(i, wo.z, c);
    let light = if reciprocal { unreflected(i, wi.z, c) } else { T::from(1.0) };
    let down = |w: DVec3| refracted_up(dir::<T>(w), T::from(sin_theta(w)) / i.eta[c])[2];
    (light * view).max_c(0.0) * beer_lambert(sigma_t[c], thickness, down(wi), down(wo))
}

/// f(wi, wo) of `layers` per channel into `out`, in f64 or in Duals (the gradient); zero below the horizon.
fn eval<T: Real>(layers: &[SpLayer<T>], g2: G2Form, reciprocal: bool, wi: DVec3, wo: DVec3, out: &mut [T]) {
    out.fill(T::from(0.0));
    if wi.z <= 0.0 || wo.z <= 0.0 {
        return;
    }
    let mut weight = vec![T::from(1.0); out.len()];
    for (i, slab) in interfaces(layers) {
        if let Some((geo, cos_h)) = bsdf::reflection_geometry(&i.mf, g2, wi, wo) {
            for (c, o) in out.iter_mut().enumerate() {
                *o = *o + weight[c] * geo * fresnel(i, cos_h, c);
            }
        }
        let Some(slab) = slab else { return };
        for (c, w) in weight.iter_mut().enumerate() {
            *w = *w * scale(i, slab, reciprocal, wi, wo, c);
        }
    }
    if let Some(SpLayer::Diffuse { albedo, sigma, .. }) = layers.last() {
        let shape = diffuse::oren_nayar_shape(*sigma, wi, wo);
        for (c, o) in out.iter_mut().enumerate() {
            *o = *o + weight[c] * albedo[c] * shape;
        }
    }
}

impl Prepared {
    /// Each term's energy at wo (its albedo times the scales above, mean over channels) with its lobe, and the
    /// Dirac reflection of smooth interfaces reached through smooth ones (`mirror`, per channel).
    fn terms(&self, wo: DVec3, mirror: &mut [f64]) -> Vec<(f64, Proposal)> {
        mirror.fill(0.0);
        let mean = |f: &dyn Fn(usize) -> f64| (0..self.channels).map(f).sum::<f64>() / self.channels as f64;
        let mut weight = vec![1.0; self.channels];
        let mut smooth_above = true;
        let mut out = Vec::new();
        for (i, slab) in interfaces(&self.layers) {
            if i.mf.is_smooth() {
                if smooth_above {
                    (0..self.channels).for_each(|c| mirror[c] += weight[c] * fresnel(i, wo.z, c));
                }
            } else {
                out.push((mean(&|c| weight[c] * albedo(i, wo.z, c)), Proposal::Reflection(i.mf)));
                smooth_above = false;
            }
            let Some(slab) = slab else { return out };
            for (c, w) in weight.iter_mut().enumerate() {
                *w *= scale(i, slab, self.reciprocal, wo, wo, c);
            }
        }
        if let Some(SpLayer::Diffuse { albedo, .. }) = self.layers.last() {
            out.push((mean(&|c| weight[c] * albedo[c]), Proposal::Cosine));
        }
        out
    }
}

/// An interface as the lanes take it.
enum LaneInterface {
    /// The lobe (None: smooth), the relative IOR, the refraction's d = 1 − 1/η (walk_lanes::refracted_up), and per
    /// channel σt·d of the slab below; `unreflected`: 1 − E(μ) per μ node of the FGD table and channel (empty for a
    /// smooth interface, whose 1 − E is the Fresnel transmittance).
    Dielectric { lobe: Option<Lobe>, eta: f64, d: f32, depth: Vec<f32>, unreflected: Vec<f32> },
    /// The lobe, the IOR per channel, and E(μ) per μ node and channel (the sampling mixture's weight; empty when
    /// smooth).
    Conductor { lobe: Option<Lobe>, ior: Vec<ConductorIor>, albedo: Vec<f32> },
}

/// Albedo scaling in float32 lanes (`Prepared::eval`, term by term).
struct Lanes {
    interfaces: Vec<LaneInterface>,
    /// Per interface the lobe it proposes to the sampling mixture (None: smooth); None where the mixture has more
    /// than MAX_TERMS terms.
    sampled: Option<Vec<Option<Visible>>>,
    /// ρ/π per channel of a Lambertian base (empty: no diffuse base).
    base: Vec<f32>,
    reciprocal: bool,
    channels: usize,
}

impl Lanes {
    /// The lanes' form of the prepared layers; None where they do not cover it: dispersion, an Oren–Nayar base, more
    /// than MAX_CHANNELS channels (a Lobe covers every distribution and G2 that albedo scaling takes: GGX).
    fn new(layers: &[SpLayer], opts: &Options, channels: usize) -> Option<Lanes> {
        if channels > MAX_CHANNELS || !single_pass::shared_eta(layers) {
            return None;
        }
        let lobe = |i: &SpInterface| if i.mf.is_smooth() { Some(None) } else { Lobe::new(&i.mf, opts.g2).map(Some) };
        let mut interfaces = Vec::new();
        let mut base = Vec::new();
        for layer in layers {
            match layer {
                SpLayer::Dielectric { iface, thickness, sigma_t, .. } => {
                    let eta = iface.eta[0];
                    let unreflected = fgd_slice(iface, channels, |e| 1.0 - e);
                    interfaces.push(LaneInterface::Dielectric {
                        lobe: lobe(iface)?,
                        eta,
                        d: (1.0 - 1.0 / eta) as f32,
                        depth: sigma_t.iter().map(|s| (s * thickness) as f32).collect(),
                        unreflected,
                    });
                }
                SpLayer::Conductor { iface, .. } => {
                    let ior =
                        (0..channels).map(|c| ConductorIor::new(FresnelForm::Exact, iface.eta[c], iface.kappa[c]));
                    let albedo = fgd_slice(iface, channels, |e| e);
                    interfaces.push(LaneInterface::Conductor { lobe: lobe(iface)?, ior: ior.collect(), albedo });
                    break;
                }
                SpLayer::Diffuse { albedo, sigma, .. } if *sigma == 0.0 => {
                    base = albedo.iter().map(|a| (a * std::f64::consts::FRAC_1_PI) as f32).collect();
                }
                SpLayer::Diffuse { .. } => return None,
            }
        }
        let sampled: Vec<Option<Visible>> =
            layers.iter().filter_map(SpLayer::interface).take(interfaces.len()).map(|i| Visible::new(&i.mf)).collect();
        let terms = sampled.iter().flatten().count() + !base.is_empty() as usize + 1;
        let sampled = (terms <= MAX_TERMS).then_some(sampled);
        Some(Lanes { interfaces, sampled, base, reciprocal: opts.reciprocal, channels })
    }
}

/// `g(E(μ))` of a rough interface per μ node of the FGD table and channel (channels fastest), sliced at its α, η and κ
/// (κ and, for a conductor, η per channel); empty for a smooth interface.
fn fgd_slice(iface: &SpInterface, channels: usize, g: impl Fn(f64) -> f64) -> Vec<f32> {
    if iface.mf.is_smooth() {
        return vec![];
    }
    let alpha = (iface.mf.alpha_x * iface.mf.alpha_y).sqrt();
    let mu = |k: usize| k as f64 / (fgd::N_MU - 1) as f64;
    let e = |k: usize, c: usize| fgd().lookup(mu(k), alpha, iface.eta[c], iface.kappa[c]);
    (0..fgd::N_MU).flat_map(|k| (0..channels).map(move |c| (k, c))).map(|(k, c)| g(e(k, c)) as f32).collect()
}

/// 1 − E(μ) of channel c in lanes: the interface's FGD slice, or the Fresnel transmittance of a smooth interface.
#[inline(always)]
fn unreflected_lanes(unreflected: &[f32], channels: usize, eta: f64, mu: Floats, c: usize) -> Floats {
    match unreflected.is_empty() {
        true => dielectric_transmittance(mu, eta),
        false => lerp_lanes(unreflected, channels, &node_lanes(mu, fgd::N_MU), c),
    }
}

impl engine::Kernel for Lanes {
    #[inline(always)]
    fn eval(&self, wi: V3, wo: V3, out: &mut [Floats]) {
        let (zero, one) = (Floats::splat(0.0), Floats::splat(1.0));
        let out = &mut out[..self.channels];
        out.fill(zero);
        let alive = wi.z.gt(zero) & wo.z.gt(zero);
        let mut weight = [one; MAX_CHANNELS];
        let weight = &mut weight[..self.channels];
        for interface in &self.interfaces {
            match interface {
                LaneInterface::Dielectric { lobe, eta, d, depth, unreflected } => {
                    if let Some(lobe) = lobe {
                        walk_lanes::add_dielectric_lobe(out, weight, alive, lobe, *eta, wi, wo);
                    }
                    let d = Floats::splat(*d);
                    let (down_i, down_o) = (walk_lanes::refracted_up(wi, d), walk_lanes::refracted_up(wo, d));
                    let path = 1.0 / down_i.z.max(Floats::splat(1e-9)) + 1.0 / down_o.z.max(Floats::splat(1e-9));
                    for (c, (w, &depth)) in weight.iter_mut().zip(depth).enumerate() {
                        let view = unreflected_lanes(unreflected, self.channels, *eta, wo.z, c);
                        let light = match self.reciprocal {
                            true => unreflected_lanes(unreflected, self.channels, *eta, wi.z, c),
                            false => one,
                        };
                        let beer = if depth == 0.0 { one } else { (-(path * depth)).exp() };
                        *w = *w * (light * view).max(zero) * beer;
                    }
                }
                LaneInterface::Conductor { lobe, ior, .. } => {
                    if let Some(lobe) = lobe {
                        walk_lanes::add_conductor_lobe(out, weight, alive, lobe, ior, wi, wo);
                    }
                    return;
                }
            }
        }
        for ((o, w), &rho) in out.iter_mut().zip(weight.iter()).zip(&self.base) {
            *o = *o + Floats::and(alive, *w * rho);
        }
    }
}

/// `Prepared::proposals` in lanes: each rough interface's lobe by its albedo E(μo) times the scales S above it, the
/// diffuse base by its albedo times them, and the defensive share.
impl Proposals for Lanes {
    #[inline(always)]
    fn proposals(&self, wo: V3) -> LaneMixture {
        let (zero, one) = (Floats::splat(0.0), Floats::splat(1.0));
        let c = self.channels;
        let mut mix = LaneMixture::new();
        let Some(sampled) = &self.sampled else { return mix };
        let (mut weight, mut term) = ([one; MAX_CHANNELS], [zero; MAX_CHANNELS]);
        for (interface, lobe) in self.interfaces.iter().zip(sampled) {
            match interface {
                LaneInterface::Dielectric { eta, d, depth, unreflected, .. } => {
                    let mut view = [zero; MAX_CHANNELS];
                    for (ch, v) in view[..c].iter_mut().enumerate() {
                        *v = unreflected_lanes(unreflected, c, *eta, wo.z, ch);
                    }
                    if lobe.is_some() {
                        for ch in 0..c {
                            term[ch] = weight[ch] * (one - view[ch]);
                        }
                        mix.push(mean(&term[..c]), *lobe);
                    }
                    let down = walk_lanes::refracted_up(wo, Floats::splat(*d));
                    let path = 2.0 / down.z.max(Floats::splat(1e-9));
                    for ch in 0..c {
                        let light = if self.reciprocal { view[ch] } else { one };
                        let beer = if depth[ch] == 0.0 { one } else { (-(path * depth[ch])).exp() };
                        weight[ch] = weight[ch] * (light * view[ch]).max(zero) * beer;
                    }
                }
                LaneInterface::Conductor { albedo, .. } => {
                    if lobe.is_some() {
                        let at = node_lanes(wo.z, fgd::N_MU);
                        for ch in 0..c {
                            term[ch] = weight[ch] * lerp_lanes(albedo, c, &at, ch);
                        }
                        mix.push(mean(&term[..c]), *lobe);
                    }
                    mix.add_defensive_share();
                    return mix;
                }
            }
        }
        if !self.base.is_empty() {
            for ch in 0..c {
                term[ch] = weight[ch] * (self.base[ch] * std::f32::consts::PI);
            }
            mix.push(mean(&term[..c]), None);
        }
        mix.add_defensive_share();
        mix
    }
}

impl Differentiable for Prepared {
    fn gradient(&self, seeds: &[Seed], n_params: usize) -> Result<Gradient<'_>> {
        super::dual_width!(n_params, gradient(self, seeds))
    }
}

impl Model for Prepared {
    fn eval_block(&self, wi: [&[f64]; 3], wo: [&[f64]; 3], _: &Inputs, out: &mut [f64]) {
        eval_rows(wi, wo, out, |_, wi, wo, o| eval(&self.layers, self.g2, self.reciprocal, wi, wo, o))
    }

    fn eval_f32(&self, wi: Rows, wo: Rows, fit: Option<&FitLanes>, out: &mut [f32]) -> bool {
        self.lanes.as_ref().is_some_and(|k| engine::eval(k, fit, self.channels, wi, wo, out))
    }

    fn sample_f32(&self, wo: Rows, u: Rows, out: &mut [f32]) -> bool {
        let lanes = self.lanes.as_ref().filter(|k| k.sampled.is_some());
        lanes.is_some_and(|k| mixture_lanes::sample(k, self.channels, wo, u, out))
    }

    fn proposals(&self, wo: DVec3) -> Vec<(f64, Proposal)> {
        defensive_mixture(self.terms(wo, &mut vec![0.0; self.channels]))
    }

    fn specular(&self, wo: DVec3, out: &mut [f64]) {
        if wo.z > 0.0 {
            self.terms(wo, out);
        } else {
            out.fill(0.0);
        }
    }
}

/// The GPU half (shaders/albedo_scaling.wgsl, after the single-pass layers).
#[cfg(feature = "gpu")]
pub mod gpu {
    use super::{prepare, Options};
    use crate::error::Result;
    use crate::models::common::gpu::{fresnel_code, g2_code, params, word, words, GpuHalf, Kernel, LAYERS};
    use crate::models::common::single_pass::gpu_layers;
    use crate::models::Args;
    use crate::optics::fresnel::FresnelForm;
    use crate::stack::Stack;
    use crate::tables::fgd::{fgd, ETA_MAX, ETA_MIN, KAPPA_MAX, N_ALPHA, N_ETA, N_KAPPA, N_MU};

    pub const HALF: GpuHalf =
        GpuHalf { shader: &[LAYERS, include_str!("../gpu/shaders/albedo_scaling.wgsl")], refusal: |_| None, kernel };

    params! {
        /// albedo_scaling.wgsl's `Params`.
        n: u32,
        channels: u32,
        layers: u32,
        g2: u32,
        reciprocal: u32,
        fresnel: u32,
        fresnel_samples: u32,
        pad0: u32,
        fgd_dims: [u32; 4],
        eta_min: f32,
        eta_max: f32,
        kappa_max: f32,
        layers_base: u32,
    }

    /// The kernel: the parameters, the layers and the FGD table.
    fn kernel(stack: &Stack, args: &Args) -> Result<Kernel> {
        let p = prepare(stack, &Options::parse(args)?)?;
        let (layers, fresnel_samples, _) = gpu_layers(&p.layers, p.channels);
        let params = Params {
            n: 0,
            channels: p.channels as u32,
            layers: p.layers.len() as u32,
            g2: g2_code(p.g2),
            reciprocal: p.reciprocal as u32,
            fresnel: fresnel_code(FresnelForm::Exact),
            fresnel_samples,
            pad0: 0,
            fgd_dims: [N_MU, N_ALPHA, N_ETA, N_KAPPA].map(|x| x as u32),
            eta_min: ETA_MIN as f32,
            eta_max: ETA_MAX as f32,
            kappa_max: KAPPA_MAX as f32,
            layers_base: 0,
        };
        Ok(Kernel {
            shader: "albedo_scaling",
            words: words(&params),
            count_word: word!(Params, n),
            arrays: vec![(layers, word!(Params, layers_base))],
            tables: vec![fgd().data()],
            channels: p.channels,
            fit: None,
        })
    }

    #[cfg(test)]
    #[test]
    fn params_mirror_the_wgsl_struct() {
        crate::gpu::tests::assert_mirrors("albedo_scaling", Params::FIELDS, std::mem::size_of::<Params>());
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::models::common::testing::{conductor, dielectric, dir, f, hemisphere, lambert, stack};
    use crate::stack::Layer;

    fn model(layers: Vec<Layer>, reciprocal: bool) -> Prepared {
        prepare(&stack(layers), &Options { g2: G2Form::Separable, roughening: true, reciprocal }).unwrap()
    }

    #[test]
    fn view_scaling_over_a_white_base_is_a_white_furnace_for_every_view() {
        // S = 1 − E(μo): what the coat's lobe does not reflect towards wo the white base returns, so
        // ∫ f cos θi dωi = E_lobe(μo) + 1 − E_table(μo) = 1 up to the FGD table's error and the quadrature's
        // (measured −3.4e-4 at most).
        let m = model(vec![dielectric(1.5, 0.3, 0.0, 0.0, 0.0), lambert(1.0)], false);
        for theta in [0.0, 30.0, 60.0, 80.0] {
            let wo = dir(theta, 0.0);
            let albedo = hemisphere(192, 384, |wi| f(&m, wi, wo, 1)[0]);
            assert!((albedo - 1.0).abs() < 1e-3, "θo = {theta}°: {albedo}");
        }
    }

    #[test]
    fn reciprocal_scaling_is_reciprocal() {
        let layers = vec![dielectric(1.5, 0.2, 0.5, 0.3, 0.0), conductor(0.27, 3.4, (0.3, 0.3))];
        let m = model(layers, true);
        for (a, b) in [(dir(10.0, 30.0), dir(70.0, 200.0)), (dir(85.0, 0.0), dir(5.0, 90.0))] {
            let (x, y) = (f(&m, a, b, 1)[0], f(&m, b, a, 1)[0]);
            assert!((x - y).abs() <= 1e-13 * x, "{x} vs {y}");
        }
    }

    #[test]
    fn openpbr_roughening_in_alpha_is_the_standards_fourth_power_law_in_r() {
        // OpenPBR writes r′ = min(1, r⁴ + 2 r_c⁴)^{1/4} with α = r²; lamina applies it to α.
        for (alpha, coat) in [(0.1, 0.3), (0.5, 0.5), (0.9, 0.8)] {
            let (r, rc) = (f64::sqrt(alpha), f64::sqrt(coat));
            let r_new = (r.powi(4) + 2.0 * rc.powi(4)).min(1.0).powf(0.25);
            assert!((roughened(alpha, coat) - r_new * r_new).abs() < 1e-15);
        }
    }
}
