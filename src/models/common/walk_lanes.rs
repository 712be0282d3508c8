//! The single-pass walk (single_pass.rs) in float32 lanes, as structure-of-arrays passes with masks instead of
//! `continue`: each interface's lobe at the current directions weighted by the attenuation above, then the model's
//! passage into the slab below (`LanePassage`), Beer–Lambert and the slab's scattering per channel, down to the opaque
//! base. Every term is masked after its product, so that what a lane outside the walk computes never reaches f.
//! The same arithmetic as `Walk::eval_group`, for the stacks the lanes cover (`LaneWalk::new`); the others stay
//! on the float64 path.

use super::mixture_lanes::{mean, LaneMixture, MAX_TERMS};
use super::single_pass::{shared_eta, SpLayer, Walk};
use crate::engine::{Floats, Mask, V3};
use crate::optics::fresnel::FresnelForm;
use crate::optics::lanes::{conductor, dielectric, sin_theta, ConductorIor, Lobe, Visible};

/// Channels the lanes carry at the most: more (spectral stacks) run on the float64 path.
pub const MAX_CHANNELS: usize = 8;

/// What a dielectric interface passes to the slab below, per lane (single_pass::Passage); `through` is clear where
/// nothing gets through.
pub struct LanePassage {
    pub t_light: Floats,
    pub t_view: Floats,
    pub t_view_slab: Floats,
    pub wi: V3,
    pub wo: V3,
    pub through: Mask,
}

/// A single-pass model's passage in lanes (single_pass::Transport::passage): layer `layer` of the walk, whose
/// channels share one IOR.
pub trait LaneTransport: Sync {
    fn passage(&self, layer: usize, wi: V3, wo: V3) -> LanePassage;
}

/// A layer of the walk as the lanes take it.
enum LaneLayer {
    /// The lobe (None: smooth), the relative IOR, the compression 1/η² (or 1), and per channel σt·d and the colour
    /// of the slab's scattering c/π.
    Dielectric {
        lobe: Option<Lobe>,
        eta: f64,
        compression: f32,
        depth: Vec<f32>,
        colour: Vec<f32>,
    },
    Conductor {
        lobe: Option<Lobe>,
        ior: Vec<ConductorIor>,
    },
    /// ρ · gain / π per channel (a Lambertian base).
    Diffuse {
        rho: Vec<f32>,
    },
}

/// The walk's layers in lanes.
pub struct LaneWalk {
    layers: Vec<LaneLayer>,
    channels: usize,
    /// Per layer the lobe its interface proposes to the sampling mixture (None: smooth, or no interface), where the
    /// lanes sample the walk (`proposals`): None with more terms than MAX_TERMS.
    sampled: Option<Vec<Option<Visible>>>,
}

impl LaneWalk {
    /// The lanes' form of `walk` over `channels`; None where they do not cover it: Beckmann with a Smith G2 (`Lobe`),
    /// a dielectric Fresnel other than the exact one, dispersion, Elek's precomputed Fresnel tables,
    /// a conductor base's inter-reflection term, an Oren–Nayar base, more than MAX_CHANNELS channels.
    pub fn new(walk: &Walk, channels: usize) -> Option<LaneWalk> {
        if channels > MAX_CHANNELS || !shared_eta(&walk.layers) {
            return None;
        }
        let f32s = |v: &[f64], s: f64| v.iter().map(|&x| (x * s) as f32).collect::<Vec<_>>();
        // Some(None): a smooth interface, whose reflection is a Dirac delta outside f.
        let lobe = |layer: &SpLayer| {
            let iface = layer.interface().expect("an interface");
            let lobe = Lobe::new(&iface.mf, walk.g2);
            (iface.table.is_empty() && (lobe.is_some() || iface.mf.is_smooth())).then_some(lobe)
        };
        let lane_layer = |layer: &SpLayer| -> Option<LaneLayer> {
            Some(match layer {
                SpLayer::Dielectric { iface, thickness, sigma_t, albedo } => {
                    if walk.fresnel != FresnelForm::Exact {
                        return None;
                    }
                    let eta = iface.eta[0];
                    LaneLayer::Dielectric {
                        lobe: lobe(layer)?,
                        eta,
                        compression: if walk.eta2 { (1.0 / (eta * eta)) as f32 } else { 1.0 },
                        depth: f32s(sigma_t, *thickness),
                        colour: f32s(albedo, std::f64::consts::FRAC_1_PI),
                    }
                }
                SpLayer::Conductor { iface, diffuse } if diffuse.is_empty() => LaneLayer::Conductor {
                    lobe: lobe(layer)?,
                    ior: iface
                        .eta
                        .iter()
                        .zip(&iface.kappa)
                        .map(|(&e, &k)| ConductorIor::new(walk.fresnel, e, k))
                        .collect(),
                },
                SpLayer::Diffuse { albedo, sigma, gain } if *sigma == 0.0 => {
                    let rho: Vec<f64> = albedo.iter().zip(gain).map(|(a, g)| a * g).collect();
                    LaneLayer::Diffuse { rho: f32s(&rho, std::f64::consts::FRAC_1_PI) }
                }
                _ => return None,
            })
        };
        let layers = walk.layers.iter().map(lane_layer).collect::<Option<Vec<_>>>()?;
        let sampled = |layer: &SpLayer| layer.interface().and_then(|iface| Visible::new(&iface.mf));
        let terms = |layer: &LaneLayer| match layer {
            LaneLayer::Dielectric { lobe, .. } => 1 + lobe.is_some() as usize,
            LaneLayer::Conductor { lobe, .. } => lobe.is_some() as usize,
            LaneLayer::Diffuse { .. } => 1,
        };
        let sampled = walk.layers.iter().map(sampled).collect();
        let sampled = (layers.iter().map(terms).sum::<usize>() < MAX_TERMS).then_some(sampled);
        Some(LaneWalk { layers, channels, sampled })
    }

    /// f of LANES pairs into out[..channels] (single_pass::Walk::eval_group, one group of every channel).
    #[inline(always)]
    pub fn eval(&self, model: &impl LaneTransport, wi: V3, wo: V3, out: &mut [Floats]) {
        let (zero, one) = (Floats::splat(0.0), Floats::splat(1.0));
        let out = &mut out[..self.channels];
        out.fill(zero);
        let mut alive = wi.z.gt(zero) & wo.z.gt(zero);
        let mut weight = [one; MAX_CHANNELS];
        let weight = &mut weight[..self.channels];
        let (mut wi, mut wo) = (wi, wo);
        for (j, layer) in self.layers.iter().enumerate() {
            match layer {
                LaneLayer::Dielectric { lobe, eta, compression, depth, colour } => {
                    if let Some(lobe) = lobe {
                        add_dielectric_lobe(out, weight, alive, lobe, *eta, wi, wo);
                    }
                    let p = model.passage(j, wi, wo);
                    alive = alive & p.through;
                    let through = p.t_light * *compression;
                    let path = 1.0 / p.wi.z.max(Floats::splat(1e-9)) + 1.0 / p.wo.z.max(Floats::splat(1e-9));
                    for ((o, w), (&d, &c)) in out.iter_mut().zip(weight.iter_mut()).zip(depth.iter().zip(colour)) {
                        let a = if d == 0.0 { one } else { (-(path * d)).exp() };
                        if c != 0.0 {
                            *o = *o + Floats::and(alive, *w * through * p.t_view_slab * (1.0 - a) * c);
                        }
                        *w = *w * through * p.t_view * a;
                    }
                    (wi, wo) = (p.wi, p.wo);
                }
                LaneLayer::Conductor { lobe, ior } => {
                    if let Some(lobe) = lobe {
                        add_conductor_lobe(out, weight, alive, lobe, ior, wi, wo);
                    }
                }
                LaneLayer::Diffuse { rho } => {
                    let above = alive & wi.z.gt(zero) & wo.z.gt(zero);
                    for ((o, w), &rho) in out.iter_mut().zip(weight.iter()).zip(rho) {
                        *o = *o + Floats::and(above, *w * rho);
                    }
                }
            }
        }
    }

    /// Whether the lanes sample the walk (`proposals`).
    pub fn samples(&self) -> bool {
        self.sampled.is_some()
    }

    /// Walk::proposals in lanes (where `samples`): each rough interface's lobe and each diffuse term weighted by the
    /// same estimates (Fresnel at the macro-surface cosine, Snell, Beer–Lambert both ways), then the defensive share.
    #[inline(always)]
    pub fn proposals(&self, wo: V3) -> LaneMixture {
        let (zero, one) = (Floats::splat(0.0), Floats::splat(1.0));
        let c = self.channels;
        let mut mix = LaneMixture::new();
        let Some(sampled) = &self.sampled else { return mix };
        let mut weight = [one; MAX_CHANNELS];
        let mut term = [zero; MAX_CHANNELS];
        let (mut cos, mut alive) = (wo.z, Mask::ALL);
        for (layer, lobe) in self.layers.iter().zip(sampled) {
            match layer {
                LaneLayer::Dielectric { eta, depth, colour, .. } => {
                    let f = dielectric(cos, *eta);
                    if lobe.is_some() {
                        mix.push(Floats::and(alive, mean(&weight[..c]) * f), *lobe);
                    }
                    let sin_t = (1.0 - cos * cos).max(zero).sqrt() * (1.0 / *eta as f32);
                    alive = alive & sin_t.lt(one);
                    cos = (1.0 - sin_t * sin_t).max(zero).sqrt();
                    let path = -2.0 / cos.max(Floats::splat(1e-9));
                    let kept = (1.0 - f) * (1.0 - f);
                    for ch in 0..c {
                        let k = if depth[ch] == 0.0 { one } else { (path * depth[ch]).exp() };
                        let t = weight[ch] * kept;
                        term[ch] = t * (1.0 - k) * (colour[ch] * std::f32::consts::PI);
                        weight[ch] = t * k;
                    }
                    mix.push(Floats::and(alive, mean(&term[..c])), None);
                }
                LaneLayer::Conductor { ior, .. } => {
                    if lobe.is_some() {
                        for ch in 0..c {
                            term[ch] = weight[ch] * conductor(cos, &ior[ch]);
                        }
                        mix.push(Floats::and(alive, mean(&term[..c])), *lobe);
                    }
                }
                LaneLayer::Diffuse { rho } => {
                    for ch in 0..c {
                        term[ch] = weight[ch] * (rho[ch] * std::f32::consts::PI);
                    }
                    mix.push(Floats::and(alive, mean(&term[..c])), None);
                }
            }
        }
        mix.add_defensive_share();
        mix
    }
}

/// out[c] += weight[c] · a dielectric interface's lobe at relative IOR η (its reflection times the Fresnel term), in
/// the lanes `alive`: the term every layered model in lanes adds for a rough dielectric interface.
#[inline(always)]
pub fn add_dielectric_lobe(out: &mut [Floats], weight: &[Floats], alive: Mask, lobe: &Lobe, eta: f64, wi: V3, wo: V3) {
    let (geo, cos_h) = lobe.reflection(wi, wo);
    let lobe = geo * dielectric(cos_h, eta);
    for (o, w) in out.iter_mut().zip(weight) {
        *o = *o + Floats::and(alive, *w * lobe);
    }
}

/// out[c] += weight[c] · a conductor's lobe with channel c's IOR, in the lanes `alive`.
#[inline(always)]
pub fn add_conductor_lobe(
    out: &mut [Floats],
    weight: &[Floats],
    alive: Mask,
    lobe: &Lobe,
    ior: &[ConductorIor],
    wi: V3,
    wo: V3,
) {
    let (geo, cos_h) = lobe.reflection(wi, wo);
    for ((o, w), ior) in out.iter_mut().zip(weight).zip(ior) {
        *o = *o + Floats::and(alive, *w * geo * conductor(cos_h, ior));
    }
}

/// Direction `w` (unit, per lane) refracted into a slab and flipped to point up: the same azimuth and sin θt =
/// min(k sin θ, 1) (single_pass::refracted_up), k given as d = 1 − k. cos θt as √(k² cos²θ + d (2 − d)): this does
/// not cancel at grazing incidence as 1 − sin²θt would in float32, and d keeps the digits that k loses near 1 (an
/// interface nearly index-matched, where cos θt ≈ cos θ is small). Total internal reflection where that radicand is
/// not positive (k sin θ ≥ 1), decided from it rather than from k sin θ, which float32 rounds to 1 at grazing
/// incidence when k rounds to 1.
#[inline(always)]
pub fn refracted_up(w: V3, d: Floats) -> V3 {
    let zero = Floats::splat(0.0);
    let k = 1.0 - d;
    let kz = k * w.z;
    let cos2_t = kz.mul_add(kz, d * (2.0 - d));
    let clamped = cos2_t.le(zero);
    let scale = Floats::select(clamped, 1.0 / sin_theta(w), k);
    V3 { x: w.x * scale, y: w.y * scale, z: Floats::and(!clamped, cos2_t.max(zero).sqrt()) }
}
