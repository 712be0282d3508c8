//! The structure shared by the single-pass layered models, Steinberg's multi-layered GGX model and Weidlich–Wilkie
//! 2007 as adapted by Elek 2010: walk the stack once from the top; at each interface add its specular lobe at the
//! current directions, weighted by the attenuation accumulated above; then refract the light and view directions
//! into the slab below, attenuate both by Beer–Lambert over the path d (1/cos θi′ + 1/cos θo′), and add the slab's
//! scattered light as a diffuse term t_i t_o (1 − k) ⊙ c / π. The walk ends at the opaque base (conductor lobe or
//! diffuse). The models differ in how a dielectric interface transmits (`Passage`) and in their specular term.
//!
//! lamina's slabs map onto these models as: extinction σ = σa + σs for the Beer–Lambert factor k, and colour c =
//! σs / σ (the single-scattering albedo) for the diffuse term of scattering slabs; the HG asymmetry g is not used.
//! As in both publications, no inter-reflections between layers are modelled by default; lamina's options
//! `interreflection` and `conductor_interreflection` add those between the base and the coat above it
//! (corrections/interreflection.rs: a gain per channel of a diffuse base, a tabulated diffuse term of a conductor
//! base, which the walk evaluates). The radiance compression 1/η² across each interface, which both publications
//! omit, is lamina's option `eta2` (on by default: measured in docs/validation.md).
//!
//! Parameter gradients (`gradient`): the same walk in Reals (`Walk::eval_real`, the layers from `layers_with` in
//! Duals), with each model's passage in Reals (`RealTransport`): the refracted directions carry the derivatives of
//! the IORs and roughnesses above them.

use super::block::{row, BLOCK};
use super::options::Args;
use crate::bsdf;
use crate::dual::{dir, Dir, Dual, Real};
use crate::error::{value_error, Result};
use crate::models::{per_pair, seeded, store, Gradient, Proposal, Seed};
use crate::optics::distribution::{Distribution, G2Form, Microfacet};
use crate::optics::fresnel::{self, FresnelForm};
use crate::optics::{diffuse, sin_theta};
use crate::sampling::orthonormal_basis;
use crate::stack::{Field, Layer, Stack};
use crate::tables::elek::FresnelTable;
use glam::DVec3;
use std::f64::consts::FRAC_1_PI;

/// A rough (or smooth) interface with its relative IOR per channel (below / above) and κ for conductors; `table`
/// holds Elek's precomputed Fresnel table per channel with the option `precomputed`. Its numbers are f64, or Duals
/// for parameter gradients (`layers_with`).
pub struct SpInterface<T = f64> {
    pub mf: Microfacet<T>,
    pub eta: Vec<T>,
    pub kappa: Vec<T>,
    pub conductor: bool,
    pub table: Vec<FresnelTable>,
}

impl SpInterface {
    /// Fresnel reflectance of channel `c` at cosine `cos_i` in `form`, or from the precomputed table if any.
    #[inline(always)]
    pub fn fresnel(&self, form: FresnelForm, cos_i: f64, c: usize) -> f64 {
        match self.table.get(c) {
            Some(t) => t.lookup(cos_i),
            None if self.conductor => form.conductor(cos_i, self.eta[c], self.kappa[c]),
            None => form.dielectric(cos_i, self.eta[c]),
        }
    }

    /// Transmittance 1 − F of channel `c` into the layer below, without cancellation at grazing incidence (a
    /// dielectric's), or from the precomputed table if any.
    #[inline(always)]
    pub fn transmittance(&self, form: FresnelForm, cos_i: f64, c: usize) -> f64 {
        match self.table.get(c) {
            Some(t) => t.transmittance(cos_i),
            None if self.conductor => 1.0 - form.conductor(cos_i, self.eta[c], self.kappa[c]),
            None => form.dielectric_transmittance(cos_i, self.eta[c]),
        }
    }

    /// Fills `table` with 128-sample Fresnel tables (Elek 2010), with the transmittance beside F.
    pub fn precompute(&mut self, form: FresnelForm) {
        self.table = (0..self.eta.len())
            .map(|c| FresnelTable::new(|cos| (self.fresnel(form, cos, c), self.transmittance(form, cos, c))))
            .collect();
    }
}

pub enum SpLayer<T = f64> {
    Dielectric {
        iface: SpInterface<T>,
        thickness: T,
        sigma_t: Vec<T>,
        albedo: Vec<T>,
    },
    /// `diffuse`: empty, or with the `conductor_interreflection` correction per channel the Lambertian albedo of the
    /// light that the coat above returns to the base, at INTERREFLECTION_NODES cosines of the light's arrival
    /// (`add_conductor_interreflection`, `interreflected`).
    Conductor {
        iface: SpInterface<T>,
        diffuse: Vec<f64>,
    },
    /// `gain` per channel: 1, or with the `interreflection` correction the geometric series 1/(1 − ρ r).
    Diffuse {
        albedo: Vec<T>,
        sigma: T,
        gain: Vec<f64>,
    },
}

impl<T> SpLayer<T> {
    /// The layer's interface (none for a diffuse base).
    pub fn interface(&self) -> Option<&SpInterface<T>> {
        match self {
            SpLayer::Dielectric { iface, .. } | SpLayer::Conductor { iface, .. } => Some(iface),
            SpLayer::Diffuse { .. } => None,
        }
    }
}

/// The stack as single-pass layers. With `clamp_roughness` each layer is at least as rough as the one above
/// (Elek 2010's m₂ ≥ m₁: a rough coat blurs what lies beneath, which a single pass cannot otherwise express).
pub fn layers(stack: &Stack, dist: Distribution, clamp_roughness: bool) -> Vec<SpLayer> {
    layers_with(stack, dist, clamp_roughness, |_, _, _, v| v)
}

/// `layers` with each number through `value(layer, field, channel, number)`: the identity, or a Dual seeded for
/// parameter gradients (models::seeded).
pub fn layers_with<T: Real>(
    stack: &Stack,
    dist: Distribution,
    clamp_roughness: bool,
    value: impl Fn(usize, Field, usize, f64) -> T,
) -> Vec<SpLayer<T>> {
    let channels = |i: usize, field: Field, v: &[f64]| -> Vec<T> {
        v.iter().enumerate().map(|(c, &x)| value(i, field, c, x)).collect()
    };
    let larger = |a: T, b: T| if b.value() > a.value() { b } else { a };
    let mut rough_above = (T::from(0.0), T::from(0.0));
    let mut out = Vec::with_capacity(stack.layers.len());
    for (i, (layer, rel)) in stack.layers.iter().zip(stack.interfaces()).enumerate() {
        let iface = |alpha: (T, T), angle: f64, conductor: bool| {
            let alpha =
                if clamp_roughness { (larger(alpha.0, rough_above.0), larger(alpha.1, rough_above.1)) } else { alpha };
            SpInterface {
                mf: Microfacet::with_parameters(dist, alpha.0, alpha.1, value(i, Field::Angle, 0, angle)),
                eta: channels(i, Field::Ior, &rel.eta),
                kappa: channels(i, Field::K, &rel.kappa),
                conductor,
                table: Vec::new(),
            }
        };
        let roughness =
            |alpha: (f64, f64)| (value(i, Field::RoughnessX, 0, alpha.0), value(i, Field::RoughnessY, 0, alpha.1));
        match layer {
            Layer::Dielectric { alpha, angle, thickness, sigma_a, sigma_s, .. } => {
                let (sigma_a, sigma_s) = (channels(i, Field::SigmaA, sigma_a), channels(i, Field::SigmaS, sigma_s));
                let sigma_t: Vec<T> = sigma_a.iter().zip(&sigma_s).map(|(&a, &s)| a + s).collect();
                let albedo: Vec<T> = sigma_s
                    .iter()
                    .zip(&sigma_t)
                    .map(|(&s, &t)| if t.value() > 0.0 { s / t } else { T::from(0.0) })
                    .collect();
                let alpha = roughness(*alpha);
                out.push(SpLayer::Dielectric {
                    iface: iface(alpha, *angle, false),
                    thickness: value(i, Field::Thickness, 0, *thickness),
                    sigma_t,
                    albedo,
                });
                rough_above = (larger(rough_above.0, alpha.0), larger(rough_above.1, alpha.1));
            }
            Layer::Conductor { alpha, angle, .. } => {
                out.push(SpLayer::Conductor { iface: iface(roughness(*alpha), *angle, true), diffuse: Vec::new() })
            }
            Layer::Diffuse { albedo, roughness } => out.push(SpLayer::Diffuse {
                albedo: channels(i, Field::Albedo, albedo),
                sigma: value(i, Field::DiffuseRoughness, 0, *roughness),
                gain: vec![1.0; albedo.len()],
            }),
        }
    }
    out
}

/// The gradient (`Differentiable::gradient`) of model `name`'s walk with respect to N parameters: the stack's layers in
/// Duals seeded by `seeds` (`layers_with`), walked by `Walk::eval_real` with the model's passages in Duals. Exact for
/// every field (the HG asymmetry g, which a single pass does not use, has gradient 0); Fresnel forms other than the
/// exact one and lamina's inter-reflection corrections are refused.
pub fn gradient<'a, const N: usize, M: RealTransport + Sync>(
    name: &str,
    model: &'a M,
    walk: &'a Walk,
    stack: &Stack,
    dist: Distribution,
    opts: &WalkOptions,
    seeds: &[Seed],
) -> Result<Gradient<'a>> {
    if opts.fresnel != FresnelForm::Exact {
        return value_error(format!("gradients of model '{name}' take fresnel='exact'"));
    }
    if opts.interreflection || opts.conductor_interreflection {
        return value_error(format!(
            "gradients of model '{name}' take interreflection=False and conductor_interreflection=False"
        ));
    }
    let value = |layer: usize, field: Field, channel: usize, v: f64| seeded::<N>(seeds, layer, field, channel, v);
    let layers = layers_with(stack, dist, opts.clamp_roughness, value);
    let channels = stack.channels;
    Ok(per_pair(move |wi, wo, out| {
        let mut f = vec![Dual::<N>::from(0.0); channels];
        walk.eval_real(model, &layers, wi, wo, &mut f);
        f.into_iter().enumerate().for_each(|(c, x)| store(out, c, x));
    }))
}

/// Cosines at which a conductor base's inter-reflection term is tabulated: uniform in [0, 1].
pub const INTERREFLECTION_NODES: usize = 8;

/// A row of values at INTERREFLECTION_NODES cosines uniform in [0, 1], linear between them at `mu`.
#[inline(always)]
pub fn node_lerp(row: &[f64], mu: f64) -> f64 {
    let x = mu.clamp(0.0, 1.0) * (INTERREFLECTION_NODES - 1) as f64;
    let j = (x as usize).min(INTERREFLECTION_NODES - 2);
    row[j] + (x - j as f64) * (row[j + 1] - row[j])
}

/// A conductor base's inter-reflection albedo g(μi) g(μo) for channel c between cosines `mu_i` and `mu_o` at the
/// base (add_conductor_interreflection's table `diffuse`).
#[inline(always)]
pub fn interreflected(diffuse: &[f64], c: usize, mu_i: f64, mu_o: f64) -> f64 {
    let row = &diffuse[c * INTERREFLECTION_NODES..][..INTERREFLECTION_NODES];
    node_lerp(row, mu_i) * node_lerp(row, mu_o)
}

/// What a dielectric interface passes to the slab below for one channel: the light's transmission into the slab,
/// the factor on the view side that multiplies everything below, the view-side transmission that multiplies the
/// slab's scattering, and the refracted directions (pointing up, away from the slab's bottom). In f64, or in Reals
/// with directions `Dir<T>` for parameter gradients (`RealTransport`).
pub struct Passage<T = f64, W = DVec3> {
    pub t_light: T,
    pub t_view: T,
    pub t_view_slab: T,
    pub wi: W,
    pub wo: W,
}

impl From<Passage<f64, Dir<f64>>> for Passage {
    fn from(p: Passage<f64, Dir<f64>>) -> Passage {
        let (wi, wo) = (p.wi.into(), p.wo.into());
        Passage { t_light: p.t_light, t_view: p.t_view, t_view_slab: p.t_view_slab, wi, wo }
    }
}

/// Direction `w` refracted into a slab and flipped to point up: same azimuth, sine `sin_t`; in f64 or in Duals.
#[inline(always)]
pub fn refracted_up<T: Real>(w: Dir<T>, sin_t: T) -> Dir<T> {
    let r = sin_theta(w);
    let cos_t = (T::from(1.0) - sin_t * sin_t).max_c(0.0).sqrt();
    if r.value() == 0.0 {
        return [T::from(0.0), T::from(0.0), cos_t];
    }
    [w[0] / r * sin_t, w[1] / r * sin_t, cos_t]
}

/// Beer–Lambert transmittance exp(−σ d (1/cos θi + 1/cos θo)) along both refracted directions, of their cosines.
#[inline(always)]
pub fn beer_lambert<T: Real>(sigma_t: T, thickness: T, cos_i: T, cos_o: T) -> T {
    // σ d = 0 with its derivatives (`same`): nothing to attenuate, nor to differentiate.
    if (sigma_t * thickness).same(T::from(0.0)) {
        return T::from(1.0);
    }
    (-sigma_t * thickness * (T::from(1.0) / cos_i.max_c(1e-9) + T::from(1.0) / cos_o.max_c(1e-9))).exp()
}

/// What distinguishes one single-pass model from another: its lobe geometry and how a dielectric interface transmits.
pub trait Transport {
    /// D G2 / (4 cos θi cos θo) of the interface at (wi, wo) and the cosine wi·h its Fresnel term takes.
    fn lobe(&self, iface: &SpInterface, wi: DVec3, wo: DVec3) -> Option<(f64, f64)>;
    /// The passage of channel `c` (and of every channel sharing its IOR) into the slab below.
    fn passage(&self, iface: &SpInterface, wi: DVec3, wo: DVec3, c: usize) -> Option<Passage>;
}

/// `Transport::passage` in Reals (f64 or Duals), with the exact Fresnel form: what a single-pass model gives
/// `Walk::eval_real` for parameter gradients.
pub trait RealTransport {
    /// The passage of channel `c` (and of every channel sharing its IOR) into the slab below.
    fn passage_real<T: Real>(
        &self,
        iface: &SpInterface<T>,
        wi: Dir<T>,
        wo: Dir<T>,
        c: usize,
    ) -> Option<Passage<T, Dir<T>>>;
}

/// Most channels evaluated together (a group shares one pass through the stack).
const GROUP: usize = 16;

/// Whether every dielectric interface has one IOR for all channels: then the refracted directions, transmissions and
/// lobe shapes of a pass are the same for every channel.
pub fn shared_eta(layers: &[SpLayer]) -> bool {
    layers.iter().all(|l| match l {
        SpLayer::Dielectric { iface, .. } => iface.eta.iter().all(|e| *e == iface.eta[0]),
        _ => true,
    })
}

/// Groups of channels that share the geometry of a pass: groups of up to 16 channels where the IOR is shared
/// (`shared_eta`), else (dispersion) each channel makes its own pass.
fn channel_groups(layers: &[SpLayer], channels: usize) -> Vec<std::ops::Range<usize>> {
    let step = if shared_eta(layers) { GROUP } else { 1 };
    (0..channels).step_by(step).map(|c| c..(c + step).min(channels)).collect()
}

/// The options of the walk that the single-pass models share (their tables list them): the masking and Fresnel forms,
/// Elek's roughness clamp, the radiance compression 1/η², and the inter-reflection corrections
/// (corrections/interreflection.rs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WalkOptions {
    pub g2: G2Form,
    pub fresnel: FresnelForm,
    pub clamp_roughness: bool,
    pub eta2: bool,
    pub interreflection: bool,
    pub conductor_interreflection: bool,
}

impl WalkOptions {
    pub fn parse(args: &Args) -> Result<WalkOptions> {
        Ok(WalkOptions {
            g2: args.choice("g2")?,
            fresnel: args.choice("fresnel")?,
            clamp_roughness: args.flag("clamp_roughness")?,
            eta2: args.flag("eta2")?,
            interreflection: args.flag("interreflection")?,
            conductor_interreflection: args.flag("conductor_interreflection")?,
        })
    }
}

/// What every single-pass model prepares from a stack: its layers, the channel groups of a pass, and the options the
/// walk itself uses (masking form, Fresnel form, the radiance compression 1/η²).
pub struct Walk {
    pub layers: Vec<SpLayer>,
    groups: Vec<std::ops::Range<usize>>,
    pub g2: G2Form,
    pub fresnel: FresnelForm,
    pub eta2: bool,
}

impl Walk {
    /// The walk of `stack` with microfacets of `dist`, without corrections (corrections/interreflection.rs adds them to
    /// its layers).
    pub fn new(stack: &Stack, dist: Distribution, opts: &WalkOptions) -> Walk {
        let layers = layers(stack, dist, opts.clamp_roughness);
        let groups = channel_groups(&layers, stack.channels);
        Walk { layers, groups, g2: opts.g2, fresnel: opts.fresnel, eta2: opts.eta2 }
    }

    /// f(wi, wo) of `layers` (this walk's, or per-element layers of the same channel structure) for
    /// every channel into `out`; zero below the horizon. `normal` tilts the base, `tint` scales it per channel (or one
    /// for all). A block of one row (`eval_block`).
    #[allow(clippy::too_many_arguments)]
    pub fn eval(
        &self,
        model: &impl Transport,
        layers: &[SpLayer],
        wi: DVec3,
        wo: DVec3,
        normal: Option<DVec3>,
        tint: &[f64],
        out: &mut [f64],
    ) {
        let normal = normal.map(|n| [n]);
        let (wi, wo) = ([&[wi.x][..], &[wi.y], &[wi.z]], [&[wo.x][..], &[wo.y], &[wo.z]]);
        self.eval_block(model, layers, wi, wo, normal.as_ref().map(|n| &n[..]), tint, out)
    }

    /// f for a block of n ≤ BLOCK rows given as columns into `out` (n rows of one value per channel); `normal` tilts
    /// the base per row (car-paint flakes), `tint` scales the base per channel (or one for all). The walk runs in
    /// passes over the block, layer by layer: the lobes' geometry per row, their Fresnel terms per channel over the
    /// whole block, then the passages into the slab below.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    pub fn eval_block(
        &self,
        model: &impl Transport,
        layers: &[SpLayer],
        wi: [&[f64]; 3],
        wo: [&[f64]; 3],
        normal: Option<&[DVec3]>,
        tint: &[f64],
        out: &mut [f64],
    ) {
        out.fill(0.0);
        for g in &self.groups {
            self.eval_group(model, layers, wi, wo, g.clone(), normal, tint, out);
        }
    }

    /// f for the channels of `group`: each interface's lobe at the current directions, then the passage into the
    /// slab below (None: nothing gets through), down to the opaque base. With `eta2` every passage through a
    /// dielectric interface also carries the radiance compression 1/η² of the exact smooth-coat result
    /// (f = T(θi) T(θo) f_below(θi′, θo′) / η², e.g. Mitsuba's `plastic`), which neither publication has.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn eval_group(
        &self,
        model: &impl Transport,
        layers: &[SpLayer],
        wi: [&[f64]; 3],
        wo: [&[f64]; 3],
        group: std::ops::Range<usize>,
        normal: Option<&[DVec3]>,
        tint: &[f64],
        out: &mut [f64],
    ) {
        let n = wi[0].len();
        let k = out.len() / n;
        let c0 = group.start;
        let mut state = [(DVec3::ZERO, DVec3::ZERO, false); BLOCK];
        let state = &mut state[..n];
        for (r, s) in state.iter_mut().enumerate() {
            let (i, o) = (row(wi, r), row(wo, r));
            *s = (i, o, i.z > 0.0 && o.z > 0.0);
        }
        let mut weight = [[1.0f64; GROUP]; BLOCK];
        let weight = &mut weight[..n];
        let channels = || group.clone().zip(0..);
        for layer in layers {
            match layer {
                SpLayer::Dielectric { iface, thickness, sigma_t, albedo } => {
                    self.add_lobes(model, iface, state, weight, group.clone(), &|_| 1.0, out);
                    let compression = if self.eta2 { 1.0 / (iface.eta[c0] * iface.eta[c0]) } else { 1.0 };
                    for (r, (wi, wo, alive)) in state.iter_mut().enumerate().filter(|(_, s)| s.2) {
                        let Some(p) = model.passage(iface, *wi, *wo, c0) else {
                            *alive = false;
                            continue;
                        };
                        let through = p.t_light * compression;
                        let o = &mut out[r * k..][..k];
                        for (c, g) in channels() {
                            let a = beer_lambert(sigma_t[c], *thickness, p.wi.z, p.wo.z);
                            o[c] += weight[r][g] * through * p.t_view_slab * (1.0 - a) * albedo[c] * FRAC_1_PI;
                            weight[r][g] *= through * p.t_view * a;
                        }
                        (*wi, *wo) = (p.wi, p.wo);
                        *alive = weight[r][..group.len()].iter().any(|w| *w != 0.0);
                    }
                }
                opaque => {
                    let tint = |c: usize| tint[c.min(tint.len() - 1)];
                    if let Some(normals) = normal {
                        for (s, &n) in state.iter_mut().zip(normals) {
                            let (t, b) = orthonormal_basis(n);
                            let local = |w: DVec3| DVec3::new(w.dot(t), w.dot(b), w.dot(n));
                            let (wi, wo) = (local(s.0), local(s.1));
                            // Below a tilted base normal's horizon the base returns nothing.
                            *s = (wi, wo, s.2 && wi.z > 0.0 && wo.z > 0.0);
                        }
                    }
                    match opaque {
                        SpLayer::Conductor { iface, diffuse } => {
                            self.add_lobes(model, iface, state, weight, group.clone(), &tint, out);
                            if !diffuse.is_empty() {
                                for (r, (wi, wo, _)) in state.iter().enumerate().filter(|(_, s)| s.2) {
                                    for (c, g) in channels() {
                                        let d = interreflected(diffuse, c, wi.z, wo.z);
                                        out[r * k + c] += weight[r][g] * tint(c) * d * FRAC_1_PI;
                                    }
                                }
                            }
                        }
                        SpLayer::Diffuse { albedo, sigma, gain } => {
                            for (r, (wi, wo, _)) in state.iter().enumerate().filter(|(_, s)| s.2) {
                                let shape = diffuse::oren_nayar_shape(*sigma, *wi, *wo);
                                for (c, g) in channels() {
                                    out[r * k + c] += weight[r][g] * tint(c) * albedo[c] * gain[c] * shape;
                                }
                            }
                        }
                        SpLayer::Dielectric { .. } => unreachable!(),
                    }
                }
            }
        }
    }

    /// Adds an interface's lobe at every live row's directions, weighted by the attenuation above and `tint`: its
    /// geometry per row, then its Fresnel term per channel over the whole block.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn add_lobes(
        &self,
        model: &impl Transport,
        iface: &SpInterface,
        state: &[(DVec3, DVec3, bool)],
        weight: &[[f64; GROUP]],
        group: std::ops::Range<usize>,
        tint: &dyn Fn(usize) -> f64,
        out: &mut [f64],
    ) {
        let n = state.len();
        let k = out.len() / n;
        let (mut geo, mut cos_h) = ([0.0; BLOCK], [0.0; BLOCK]);
        for (r, &(wi, wo, alive)) in state.iter().enumerate() {
            let (g, c) = model.lobe(iface, wi, wo).unwrap_or((0.0, 0.0));
            (geo[r], cos_h[r]) = if alive { (g, c) } else { (0.0, 0.0) };
        }
        for (c, g) in group.zip(0..) {
            let t = tint(c);
            for r in 0..n {
                out[r * k + c] += weight[r][g] * t * geo[r] * iface.fresnel(self.fresnel, cos_h[r], c);
            }
        }
    }
}

impl Walk {
    /// f at one pair (wi, wo) in Reals (f64 or Duals, for parameter gradients): `eval_group`'s walk, the same
    /// arithmetic, over `layers` from `layers_with` and the model's passages in Reals, with the exact Fresnel form
    /// and without corrections (`gradient` refuses them).
    pub fn eval_real<T: Real>(
        &self,
        model: &impl RealTransport,
        layers: &[SpLayer<T>],
        wi: DVec3,
        wo: DVec3,
        out: &mut [T],
    ) {
        out.fill(T::from(0.0));
        if wi.z <= 0.0 || wo.z <= 0.0 {
            return;
        }
        for group in &self.groups {
            let c0 = group.start;
            let channels = || group.clone().zip(0..);
            let (mut wi, mut wo) = (dir::<T>(wi), dir::<T>(wo));
            let mut weight = [T::from(1.0); GROUP];
            for layer in layers {
                if let Some(i) = layer.interface() {
                    if let Some((geo, cos_h)) = bsdf::reflection_geometry::<T, T>(&i.mf, self.g2, wi, wo) {
                        for (c, g) in channels() {
                            let f = match i.conductor {
                                true => fresnel::conductor(cos_h, i.eta[c], i.kappa[c]),
                                false => fresnel::dielectric(cos_h, i.eta[c]),
                            };
                            out[c] = out[c] + weight[g] * geo * f;
                        }
                    }
                }
                match layer {
                    SpLayer::Dielectric { iface, thickness, sigma_t, albedo } => {
                        let Some(p) = model.passage_real(iface, wi, wo, c0) else { break };
                        let compression = match self.eta2 {
                            true => T::from(1.0) / (iface.eta[c0] * iface.eta[c0]),
                            false => T::from(1.0),
                        };
                        let through = p.t_light * compression;
                        for (c, g) in channels() {
                            let a = beer_lambert(sigma_t[c], *thickness, p.wi[2], p.wo[2]);
                            out[c] = out[c]
                                + weight[g] * through * p.t_view_slab * (T::from(1.0) - a) * albedo[c] * FRAC_1_PI;
                            weight[g] = weight[g] * through * p.t_view * a;
                        }
                        (wi, wo) = (p.wi, p.wo);
                    }
                    SpLayer::Conductor { .. } => {}
                    SpLayer::Diffuse { albedo, sigma, .. } => {
                        let shape = diffuse::oren_nayar_shape(*sigma, wi, wo);
                        for (c, g) in channels() {
                            out[c] = out[c] + weight[g] * albedo[c] * shape;
                        }
                    }
                }
            }
        }
    }

    /// The energies of the walk's terms for the viewing direction wo, one estimate per term, and what smooth
    /// interfaces reached through smooth ones reflect as a Dirac lobe (`mirror`, per channel). Estimates, not the
    /// model: Fresnel at the macro-surface cosine, Snell at the mean IOR, Beer–Lambert along the refracted direction
    /// both ways; they weight the sampling mixture, whose samples the model's own f then weighs.
    fn terms(&self, wo: DVec3, mirror: &mut [f64]) -> Vec<(f64, Proposal)> {
        let channels = mirror.len();
        mirror.fill(0.0);
        let mean = |f: &dyn Fn(usize) -> f64| (0..channels).map(f).sum::<f64>() / channels as f64;
        let mut weight = vec![1.0; channels];
        let (mut cos, mut smooth_above) = (wo.z, true);
        let mut out = Vec::new();
        for layer in &self.layers {
            match layer {
                SpLayer::Dielectric { iface, thickness, sigma_t, albedo } => {
                    let f: Vec<f64> = (0..channels).map(|c| iface.fresnel(self.fresnel, cos, c)).collect();
                    if iface.mf.is_smooth() {
                        if smooth_above {
                            (0..channels).for_each(|c| mirror[c] += weight[c] * f[c]);
                        }
                    } else {
                        out.push((mean(&|c| weight[c] * f[c]), Proposal::Reflection(iface.mf)));
                        smooth_above = false;
                    }
                    let eta = mean(&|c| iface.eta[c]);
                    let sin_t = (1.0 - cos * cos).max(0.0).sqrt() / eta;
                    if sin_t >= 1.0 {
                        return out;
                    }
                    cos = (1.0 - sin_t * sin_t).sqrt();
                    let k: Vec<f64> =
                        (0..channels).map(|c| (-2.0 * sigma_t[c] * thickness / cos.max(1e-9)).exp()).collect();
                    let t: Vec<f64> = (0..channels).map(|c| weight[c] * (1.0 - f[c]) * (1.0 - f[c])).collect();
                    out.push((mean(&|c| t[c] * (1.0 - k[c]) * albedo[c]), Proposal::Cosine));
                    (0..channels).for_each(|c| weight[c] = t[c] * k[c]);
                }
                SpLayer::Conductor { iface, diffuse } => {
                    let f = |c: usize| weight[c] * iface.fresnel(self.fresnel, cos, c);
                    if !iface.mf.is_smooth() {
                        out.push((mean(&f), Proposal::Reflection(iface.mf)));
                    } else if smooth_above {
                        (0..channels).for_each(|c| mirror[c] += f(c));
                    }
                    if !diffuse.is_empty() {
                        out.push((mean(&|c| weight[c] * interreflected(diffuse, c, cos, cos)), Proposal::Cosine));
                    }
                }
                SpLayer::Diffuse { albedo, gain, .. } => {
                    out.push((mean(&|c| weight[c] * albedo[c] * gain[c]), Proposal::Cosine))
                }
            }
        }
        out
    }

    /// The sampling mixture for wo: each rough interface's reflection lobe and the diffuse terms, weighted by their
    /// estimated energies, plus the defensive cosine share.
    pub fn proposals(&self, wo: DVec3, channels: usize) -> Vec<(f64, Proposal)> {
        super::mixture::defensive_mixture(self.terms(wo, &mut vec![0.0; channels]))
    }

    /// The Dirac reflection at wo per channel (smooth interfaces seen through smooth ones).
    pub fn specular(&self, wo: DVec3, out: &mut [f64]) {
        if wo.z > 0.0 {
            self.terms(wo, out);
        } else {
            out.fill(0.0);
        }
    }
}

/// The layers as layers.wgsl reads them, the nodes per Fresnel table (0: none) and the channels a pass of
/// single_pass.wgsl walks at once (4 where the IOR is shared, else 1): per layer 10 values (kind: 0 dielectric,
/// 1 conductor, 2 diffuse; the microfacet's distribution, smooth flag, αx, αy, cos φ, sin φ; thickness; Oren–Nayar σ;
/// the mean η over the channels), then per channel 5 (η, κ, σt, albedo, gain), a conductor base's inter-reflection albedo at
/// INTERREFLECTION_NODES cosines (zeros without) and Elek's Fresnel table, if any, as (F, 1 − F) per node.
#[cfg(feature = "gpu")]
pub fn gpu_layers(layers: &[SpLayer], channels: usize) -> (Vec<f32>, u32, u32) {
    use crate::tables::elek::FRESNEL_SAMPLES;
    let samples =
        if layers.iter().filter_map(SpLayer::interface).any(|i| !i.table.is_empty()) { FRESNEL_SAMPLES } else { 0 };
    let smooth = Microfacet::new(Distribution::Ggx, 0.0, 0.0, 0.0);
    let zeros = vec![0.0; channels];
    let mut out = Vec::new();
    for layer in layers {
        let (kind, mf, thickness, sigma, [eta, kappa, sigma_t, albedo, gain]) = match layer {
            SpLayer::Dielectric { iface, thickness, sigma_t, albedo } => {
                (0, &iface.mf, *thickness, 0.0, [&iface.eta, &iface.kappa, sigma_t, albedo, &zeros])
            }
            SpLayer::Conductor { iface, .. } => {
                (1, &iface.mf, 0.0, 0.0, [&iface.eta, &iface.kappa, &zeros, &zeros, &zeros])
            }
            SpLayer::Diffuse { albedo, sigma, gain } => {
                (2, &smooth, 0.0, *sigma, [&zeros, &zeros, &zeros, albedo, gain])
            }
        };
        let (cos_phi, sin_phi) = mf.frame();
        let dist = super::gpu::dist_code(mf.dist) as f64;
        let header = [kind as f64, dist, mf.is_smooth() as u8 as f64, mf.alpha_x, mf.alpha_y];
        let mean_eta = eta.iter().sum::<f64>() / channels as f64;
        out.extend(header.into_iter().chain([cos_phi, sin_phi, thickness, sigma, mean_eta]).map(|x| x as f32));
        let interreflected = match layer {
            SpLayer::Conductor { diffuse, .. } if !diffuse.is_empty() => &diffuse[..],
            _ => &[],
        };
        for c in 0..channels {
            out.extend([eta[c], kappa[c], sigma_t[c], albedo[c], gain[c]].map(|x| x as f32));
            let nodes = interreflected.get(c * INTERREFLECTION_NODES..(c + 1) * INTERREFLECTION_NODES);
            out.extend((0..INTERREFLECTION_NODES).map(|j| nodes.map_or(0.0, |n| n[j] as f32)));
            let table = layer.interface().and_then(|i| i.table.get(c)).map_or(&[][..], |t| t.samples());
            out.extend(table.iter().copied().chain(std::iter::repeat(0.0)).take(2 * samples));
        }
    }
    (out, samples as u32, if shared_eta(layers) { 4 } else { 1 })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::models::common::testing::{channel, dir};
    use crate::models::steinberg;

    #[test]
    fn refraction_keeps_the_azimuth_and_obeys_snell() {
        for (theta, phi) in [(0.0, 0.0), (30.0, 45.0), (80.0, 200.0)] {
            let w = dir(theta, phi);
            let sin_t = sin_theta(w) / 1.5;
            let r = DVec3::from(refracted_up(w.into(), sin_t));
            assert!((r.length() - 1.0).abs() < 1e-15 && (sin_theta(r) - sin_t).abs() < 1e-15);
            if theta > 0.0 {
                assert!((r.y.atan2(r.x) - w.y.atan2(w.x)).abs() < 1e-14, "{w} -> {r}");
            }
        }
    }

    #[test]
    fn channels_walked_together_equal_each_channel_walked_alone() {
        // The walk groups channels of one IOR into one pass (and walks dispersive ones one by one): each channel's
        // f is that of the one-channel stack of its own constants.
        let layer = |ior: [f64; 3], sigma_a: [f64; 3]| Layer::Dielectric {
            ior: ior.to_vec(),
            alpha: (0.2, 0.1),
            angle: 0.4,
            thickness: 0.7,
            sigma_a: sigma_a.to_vec(),
            sigma_s: vec![0.3, 0.0, 0.1],
            g: 0.0,
        };
        let base = Layer::Conductor { ior: vec![0.2, 0.9, 1.1], k: vec![3.6, 2.6, 2.3], alpha: (0.3, 0.3), angle: 0.0 };
        let opts = steinberg::Options::parse(&Args::defaults(steinberg::INFO.options)).unwrap();
        for ior in [[1.5; 3], [1.45, 1.5, 1.55]] {
            let rgb = Stack::new(vec![layer(ior, [0.1, 0.4, 0.9]), base.clone()], 1.0).unwrap();
            let m = steinberg::prepare(&rgb, &opts).unwrap();
            for (wi, wo) in [(dir(20.0, 0.0), dir(40.0, 150.0)), (dir(75.0, 60.0), dir(30.0, 300.0))] {
                let mut all = [0.0; 3];
                crate::models::eval_one(&m, wi, wo, &[], &mut all);
                for (c, f_all) in all.iter().enumerate() {
                    let mono = channel(&rgb, c);
                    let mut one = [0.0];
                    crate::models::eval_one(&steinberg::prepare(&mono, &opts).unwrap(), wi, wo, &[], &mut one);
                    assert_eq!(*f_all, one[0], "ior {ior:?}, channel {c}");
                }
            }
        }
    }
}
