//! `model="weidlich_wilkie"`: Weidlich & Wilkie 2007, "Arbitrarily layered micro-facet surfaces", in the recursive
//! form of Elek 2010 — f⁽ⁱ⁾(L, V) = f_i(L, V) + T₁₂ · f⁽ⁱ⁺¹⁾(L′, V′) · a_i · t_i, with L′, V′ refracted by Snell's law
//! at the macro-surface, a_i = exp(−σ d (1/cos θL′ + 1/cos θV′)), t_i = (1 − G_i) + T₂₁ G_i, T₁₂ = 1 − F(cos θL) and
//! T₂₁ = 1 − F(cos θV). Each f_i is a Torrance–Sparrow lobe (by default Beckmann D and the V-cavity G); the base is
//! a conductor lobe or Lambert / Oren–Nayar. Unrolled by models/common/single_pass.rs.
//!
//! Options: the Fresnel form (exact or Lazányi–Szirmay-Kalos), Elek's m₂ ≥ m₁ roughness clamp, and Elek's
//! precomputed form (tables/elek.rs: 128-sample Fresnel tables and the 512 × 512 Beckmann table).
//! Car paint: a per-sample base normal normalize(flake + max(distance, 1) ẑ) (Elek's distance-based smoothing).
//! Copper patina: `eval_patina`.

//!
//! | Parameter         | Type   | Default    | Description                                                          |
//! |-------------------|--------|------------|----------------------------------------------------------------------|
//! | `distribution`    | string | `beckmann` | microfacet distribution, `beckmann` or `ggx`                         |
//! | `g2`              | string | `v_cavity` | masking-shadowing (Torrance–Sparrow's V-cavity by default)           |
//! | `fresnel`         | string | `exact`    | `exact`, `schlick` or Elek's `lazanyi`                               |
//! | `precomputed`     | bool   | `false`    | Elek's precomputed Fresnel and Beckmann tables                       |
//! | `clamp_roughness` | bool   | `true`     | Elek's m₂ ≥ m₁; `false` for the published form                       |
//! | `eta2`            | bool   | `true`     | radiance compression 1/η²; `false` for the published form            |
//! | `interreflection` | bool   | `false`    | lamina's correction: diffuse-base inter-reflections 1/(1 − ρ r)       |
//! | `conductor_interreflection` | bool | `false` | lamina's correction: conductor-base inter-reflections      |
//! | `extent`          | float  | 0.5        | patina: smoothstep centre over the `mask` values                     |
//! | `transition`      | float  | 0.1        | patina: smoothstep half-width                                        |
//! | `tint`            | floats | 1          | patina: tarnish of the base under the patina, per channel            |
//! | `transport_fit`   | bool   | `false`    | lamina's correction: f ← s f + a fitted to the stack's adding-doubling |
//! | `variant`         | string | `published`| `improved`: with `transport_fit` (corrections/transport_fit.rs)      |
//!
//! Per-element inputs: `flake_normal` (..., 3) and `distance` (...) tilt the base normal to
//! normalize(flake + max(distance, 1) ẑ) (car paint; a base tilted below the horizon reflects nothing); `mask`
//! (...) in [0, 1] covers the surface with the stack's top layer, the patina (`Patina`). Sampling: the shared
//! single-pass mixture (models/common/single_pass.rs).
//! Gradients (`Stack.eval_grad`): the walk in Duals (single_pass::gradient), with the exact Fresnel form, without
//! Elek's precomputed tables or the inter-reflection corrections.

use super::common::block::{eval_rows, simd_columns, BLOCK};
use super::common::mixture_lanes::{self, LaneMixture, Proposals};
use super::common::options::{
    distribution, flag, g2, number, variant, OptionKind, CLAMP_ROUGHNESS, CONDUCTOR_INTERREFLECTION, ETA2, FRESNEL,
    INTERREFLECTION, TRANSPORT_FIT,
};
use super::common::single_pass::{
    self, refracted_up, Passage, RealTransport, SpInterface, SpLayer, Transport, Walk, WalkOptions,
};
use super::common::walk_lanes::{self, LanePassage, LaneTransport, LaneWalk};
use super::corrections::{interreflection, transport_fit};
use super::{
    Args, Differentiable, Field, Gradient, InputSpec, Inputs, Model, ModelInfo, OptionSpec, Properties, Proposal, Seed,
};
use crate::bsdf;
use crate::dual::{normalize, plus, Dir, Real};
use crate::engine::{self, Floats, Rows, V3};
use crate::error::{value_error, Result};
use crate::models::FitLanes;
use crate::optics::distribution::{Distribution, G2Form};
use crate::optics::lanes::{self, dielectric_transmittance};
use crate::optics::{fresnel, sin_theta};
use crate::stack::{Layer, Stack};
use crate::tables::elek::beckmann_table;
use glam::DVec3;

pub const INFO: ModelInfo = ModelInfo {
    name: "weidlich_wilkie",
    summary: "Weidlich–Wilkie 2007 as adapted by Elek 2010: one recursive pass, car-paint flakes, copper patina",
    options: &[
        distribution("beckmann"),
        g2("v_cavity", "masking-shadowing (Torrance–Sparrow's V-cavity by default)"),
        FRESNEL,
        flag("precomputed", false, "Elek's precomputed Fresnel (128 samples) and Beckmann (512 x 512) tables"),
        CLAMP_ROUGHNESS,
        ETA2,
        INTERREFLECTION,
        CONDUCTOR_INTERREFLECTION,
        number(
            "extent",
            0.0,
            1.0,
            0.5,
            "patina (with mask): coverage 1 − smoothstep(extent − transition, extent + transition, mask)",
        ),
        number("transition", 0.0, 1.0, 0.1, "patina (with mask): half-width of the smoothstep"),
        OptionSpec {
            name: "tint",
            kind: OptionKind::Channels { lo: 0.0, hi: 1.0, default: 1.0 },
            doc: "patina (with mask): tarnish of the base under the patina, per channel, lerp(1, tint, coverage)",
        },
        TRANSPORT_FIT,
        variant(
            &["transport_fit"],
            "published: Weidlich–Wilkie / Elek (lamina's defaults); improved: with transport_fit",
        ),
    ] as &[OptionSpec],
    inputs: &[
        InputSpec {
            name: "flake_normal",
            width: 3,
            range: (-10.0, 10.0),
            doc: "car-paint flake vector; the base normal is normalize(flake + max(distance, 1) ẑ)",
        },
        InputSpec { name: "distance", width: 1, range: (0.0, f64::MAX), doc: "viewing distance smoothing the flakes" },
        InputSpec { name: "mask", width: 1, range: (0.0, 1.0), doc: "patina map: where the top layer covers the base" },
    ],
    properties: Properties { reciprocal: false, energy_conserving: false, anisotropic: true, spectral: true },
    gradients: &Field::NAMES,
    prepare: |stack, args| {
        let opts = Options::parse(args, stack.channels)?;
        transport_fit::apply(opts.transport_fit, Box::new(prepare(stack, &opts)?), stack)
    },
    prepare_gradient: None,
    #[cfg(feature = "gpu")]
    gpu: Some(&gpu::HALF),
};

/// Weidlich–Wilkie's options (the table above).
#[derive(Clone, Debug, PartialEq)]
pub struct Options {
    pub walk: WalkOptions,
    pub distribution: Distribution,
    /// Elek's precomputed Fresnel and Beckmann tables.
    pub precomputed: bool,
    /// Elek's patina (with the per-element input `mask`): smoothstep centre and half-width, and the tarnish of the
    /// base under the patina per channel (or one for all).
    pub extent: f64,
    pub transition: f64,
    pub tint: Vec<f64>,
    pub transport_fit: bool,
}

impl Options {
    /// The options for a stack of `channels` channels (`tint` has one value or one per channel).
    pub fn parse(args: &Args, channels: usize) -> Result<Options> {
        let tint = args.channels("tint")?;
        if tint.len() != 1 && tint.len() != channels {
            return value_error(format!("tint has {} values but the stack has {channels} channels", tint.len()));
        }
        Ok(Options {
            walk: WalkOptions::parse(args)?,
            distribution: args.choice("distribution")?,
            precomputed: args.flag("precomputed")?,
            extent: args.number("extent")?,
            transition: args.number("transition")?,
            tint,
            transport_fit: args.flag("transport_fit")?,
        })
    }

    /// The walk of `stack` with these options' microfacets and corrections (`clamp`: Elek's roughness clamp).
    fn walk_of(&self, stack: &Stack, clamp: bool) -> Walk {
        let opts = WalkOptions { clamp_roughness: clamp, ..self.walk };
        let mut walk = Walk::new(stack, self.distribution, &opts);
        interreflection::correct(&mut walk.layers, &opts);
        walk
    }
}

pub struct Prepared {
    pub walk: Walk,
    pub precomputed: bool,
    pub channels: usize,
    /// The stack and the walk's options, which the gradient takes in Duals.
    stack: Stack,
    opts: WalkOptions,
    distribution: Distribution,
    /// The patina form of the stack (its top layer over the rest), when the top layer is a dielectric.
    patina: Option<Patina>,
    /// The float32 kernel, where the lanes cover the stack (`Lanes::new`).
    lanes: Option<Lanes>,
}

pub fn prepare(stack: &Stack, opts: &Options) -> Result<Prepared> {
    let mut walk = opts.walk_of(stack, opts.walk.clamp_roughness);
    let precomputed = opts.precomputed;
    if precomputed {
        for layer in &mut walk.layers {
            if let SpLayer::Dielectric { iface, .. } | SpLayer::Conductor { iface, .. } = layer {
                iface.precompute(opts.walk.fresnel);
            }
        }
        beckmann_table();
    }
    let patina = match &stack.layers[..] {
        [Layer::Dielectric { .. }, base] if !precomputed => Some(Patina::new(base, stack, opts)?),
        _ => None,
    };
    let lanes = if precomputed { None } else { Lanes::new(&walk, stack.channels) };
    let (stack, distribution) = (stack.clone(), opts.distribution);
    Ok(Prepared { walk, precomputed, channels: stack.channels, stack, opts: opts.walk, distribution, patina, lanes })
}

/// Weidlich–Wilkie's walk in float32 lanes (models/common/walk_lanes.rs), with V-cavity lobes (the published form)
/// of either distribution: the passages' Snell refraction, T₁₂ and (1 − G) + T₂₁ G in lanes.
struct Lanes {
    walk: LaneWalk,
    /// Per layer: a dielectric interface's IOR η, 1 − 1/η (walk_lanes::refracted_up) and whether it is rough.
    interfaces: Vec<(f64, f32, bool)>,
}

impl Lanes {
    /// The lanes' form of the walk; None for what they do not cover (LaneWalk::new; a rough dielectric interface with
    /// a Smith G2, whose G the passage would need in lanes; Elek's precomputed tables).
    fn new(walk: &Walk, channels: usize) -> Option<Lanes> {
        let lane_walk = LaneWalk::new(walk, channels)?;
        let interface = |layer: &SpLayer| match layer {
            SpLayer::Dielectric { iface, .. } if iface.mf.is_smooth() || walk.g2 == G2Form::VCavity => {
                let eta = iface.eta[0];
                Some((eta, (1.0 - 1.0 / eta) as f32, !iface.mf.is_smooth()))
            }
            SpLayer::Dielectric { .. } => None,
            _ => Some((1.0, 0.0, false)),
        };
        let interfaces = walk.layers.iter().map(interface).collect::<Option<Vec<_>>>()?;
        Some(Lanes { walk: lane_walk, interfaces })
    }
}

impl LaneTransport for Lanes {
    /// `Transport::passage` in lanes.
    #[inline(always)]
    fn passage(&self, layer: usize, wi: V3, wo: V3) -> LanePassage {
        let &(eta, d, rough) = &self.interfaces[layer];
        let limit = Floats::splat(eta as f32);
        let through = lanes::sin_theta(wi).lt(limit) & lanes::sin_theta(wo).lt(limit);
        let (t12, t21) = (dielectric_transmittance(wi.z, eta), dielectric_transmittance(wo.z, eta));
        let g = if rough { lanes::v_cavity(wi, wo) } else { Floats::splat(1.0) };
        let d = Floats::splat(d);
        LanePassage {
            t_light: t12,
            t_view: (1.0 - g) + t21 * g,
            t_view_slab: t21,
            wi: walk_lanes::refracted_up(wi, d),
            wo: walk_lanes::refracted_up(wo, d),
            through,
        }
    }
}

impl engine::Kernel for Lanes {
    #[inline(always)]
    fn eval(&self, wi: V3, wo: V3, out: &mut [Floats]) {
        self.walk.eval(self, wi, wo, out)
    }
}

impl Proposals for Lanes {
    #[inline(always)]
    fn proposals(&self, wo: V3) -> LaneMixture {
        self.walk.proposals(wo)
    }
}

impl Transport for Prepared {
    /// Torrance–Sparrow lobe D G / (4 cos θi cos θo); the precomputed form takes D from Elek's table (isotropic
    /// Beckmann interfaces; others keep the analytic D).
    #[inline(always)]
    fn lobe(&self, iface: &SpInterface, wi: DVec3, wo: DVec3) -> Option<(f64, f64)> {
        let (geo, cos_h) = bsdf::reflection_geometry(&iface.mf, self.walk.g2, wi, wo)?;
        let mf = &iface.mf;
        if !self.precomputed || geo == 0.0 || mf.dist != Distribution::Beckmann || mf.alpha_x != mf.alpha_y {
            return Some((geo, cos_h));
        }
        let h = (wi + wo).normalize();
        Some((geo * beckmann_table().lookup(h.z, mf.alpha_x) / mf.d(h), cos_h))
    }

    /// `snell` with the option's Fresnel form (or Elek's tables).
    #[inline(always)]
    fn passage(&self, iface: &SpInterface, wi: DVec3, wo: DVec3, c: usize) -> Option<Passage> {
        let transmittance = |cos: f64| iface.transmittance(self.walk.fresnel, cos, c);
        self.snell(iface, wi.into(), wo.into(), c, transmittance).map(Passage::from)
    }
}

impl RealTransport for Prepared {
    /// `snell` with the exact Fresnel form (the gradient's).
    #[inline(always)]
    fn passage_real<T: Real>(
        &self,
        iface: &SpInterface<T>,
        wi: Dir<T>,
        wo: Dir<T>,
        c: usize,
    ) -> Option<Passage<T, Dir<T>>> {
        self.snell(iface, wi, wo, c, |cos| fresnel::dielectric_transmittance(cos, iface.eta[c]))
    }
}

impl Prepared {
    /// Snell's law at the macro-surface; T₁₂ = 1 − F(cos θL) into the layer, t = (1 − G) + T₂₁ G out of it, with
    /// 1 − F of a cosine from `transmittance`. In f64, or in Duals for gradients.
    #[inline(always)]
    fn snell<T: Real>(
        &self,
        iface: &SpInterface<T>,
        wi: Dir<T>,
        wo: Dir<T>,
        c: usize,
        transmittance: impl Fn(T) -> T,
    ) -> Option<Passage<T, Dir<T>>> {
        let eta = iface.eta[c];
        let (sin_i, sin_o) = (sin_theta(wi) / eta, sin_theta(wo) / eta);
        if sin_i.value() >= 1.0 || sin_o.value() >= 1.0 {
            return None; // total internal reflection at the macro-surface
        }
        let (t12, t21) = (transmittance(wi[2]), transmittance(wo[2]));
        let g = match iface.mf.is_smooth() {
            true => T::from(1.0),
            false => iface.mf.g2_at::<T>(self.walk.g2, wi, wo, normalize(plus(wi, wo))),
        };
        Some(Passage {
            t_light: t12,
            t_view: (T::from(1.0) - g) + t21 * g,
            t_view_slab: t21,
            wi: refracted_up(wi, sin_i),
            wo: refracted_up(wo, sin_o),
        })
    }

    #[inline(always)]
    fn eval_columns(&self, wi: [&[f64]; 3], wo: [&[f64]; 3], out: &mut [f64]) {
        self.walk.eval_block(self, &self.walk.layers, wi, wo, None, &[1.0], out)
    }
}

/// The gradient of the walk with respect to N parameters (single_pass::gradient); Elek's precomputed tables have
/// none.
fn gradient<'a, const N: usize>(p: &'a Prepared, seeds: &[Seed]) -> Result<Gradient<'a>> {
    if p.precomputed {
        return value_error("gradients of model 'weidlich_wilkie' take precomputed=False");
    }
    single_pass::gradient::<N, _>("weidlich_wilkie", p, &p.walk, &p.stack, p.distribution, &p.opts, seeds)
}

impl Differentiable for Prepared {
    fn gradient(&self, seeds: &[Seed], n_params: usize) -> Result<Gradient<'_>> {
        super::dual_width!(n_params, gradient(self, seeds))
    }
}

impl Model for Prepared {
    fn eval_block(&self, wi: [&[f64]; 3], wo: [&[f64]; 3], inputs: &Inputs, out: &mut [f64]) {
        let input = |j: usize| inputs.get(j).copied().flatten();
        let (flake, distance, mask) = (input(0), input(1), input(2));
        if flake.is_none() && mask.is_none() {
            return simd_columns!(Prepared, self, wi, wo, out);
        }
        let mut normals = [DVec3::Z; BLOCK];
        let normals = &mut normals[..wi[0].len()];
        if let Some(f) = flake {
            for (r, n) in normals.iter_mut().enumerate() {
                let d = distance.map_or(1.0, |d| d[0][r]).max(1.0);
                let m = (DVec3::new(f[0][r], f[1][r], f[2][r]) + d * DVec3::Z).normalize();
                *n = if m.z > 0.0 { m } else { -DVec3::Z }; // a base tilted below the horizon reflects nothing
            }
        }
        let normal = flake.map(|_| &normals[..]);
        match (mask, &self.patina) {
            (Some(m), Some(p)) => {
                eval_rows(wi, wo, out, |r, wi, wo, o| p.eval(self, wi, wo, m[0][r], normal.map(|n| n[r]), o))
            }
            _ => self.walk.eval_block(self, &self.walk.layers, wi, wo, normal, &[1.0], out),
        }
    }

    fn eval_f32(&self, wi: Rows, wo: Rows, fit: Option<&FitLanes>, out: &mut [f32]) -> bool {
        self.lanes.as_ref().is_some_and(|k| engine::eval(k, fit, self.channels, wi, wo, out))
    }

    fn sample_f32(&self, wo: Rows, u: Rows, out: &mut [f32]) -> bool {
        let lanes = self.lanes.as_ref().filter(|k| k.walk.samples());
        lanes.is_some_and(|k| mixture_lanes::sample(k, self.channels, wo, u, out))
    }

    fn check_inputs(&self, given: &[bool]) -> Result<()> {
        if given.get(2) == Some(&true) && self.patina.is_none() {
            return value_error(if self.precomputed {
                "mask: the patina's IOR changes per element, so it has no precomputed tables (precomputed=False)"
            } else {
                "mask: a patina stack is a Dielectric layer (the patina) over an opaque base"
            });
        }
        Ok(())
    }

    fn proposals(&self, wo: DVec3) -> Vec<(f64, Proposal)> {
        self.walk.proposals(wo, self.channels)
    }

    fn specular(&self, wo: DVec3, out: &mut [f64]) {
        self.walk.specular(wo, out)
    }
}

/// Elek 2010's copper patina: the stack's top dielectric layer (the patina) covers the rest (the bare surface)
/// where a grayscale mask says so.
pub struct Patina {
    /// The bare surface: the stack without its top layer.
    pub bare: Walk,
    /// The stack without the roughness clamp, which is applied per element against the interpolated patina.
    pub patina: Walk,
    /// Elek's m₂ ≥ m₁ against the interpolated patina roughness.
    pub clamp: bool,
    /// The bare top roughness: where the patina layer's roughness starts.
    pub bare_alpha: (f64, f64),
    /// Tarnish tone multiplying the base under the patina, per channel (or one for all).
    pub tint: Vec<f64>,
    pub extent: f64,
    pub transition: f64,
}

/// GLSL smoothstep: 0 below `a`, 1 above `b`, 3t² − 2t³ between.
pub fn smoothstep(a: f64, b: f64, x: f64) -> f64 {
    if b <= a {
        return if x < a { 0.0 } else { 1.0 };
    }
    let t = ((x - a) / (b - a)).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

impl Patina {
    fn new(base: &Layer, stack: &Stack, opts: &Options) -> Result<Self> {
        let bare = Stack::new(vec![base.clone()], stack.ext_ior)?;
        let bare_alpha = match base {
            Layer::Dielectric { alpha, .. } | Layer::Conductor { alpha, .. } => *alpha,
            _ => (0.0, 0.0),
        };
        Ok(Patina {
            bare: opts.walk_of(&bare, opts.walk.clamp_roughness),
            patina: opts.walk_of(stack, false),
            clamp: opts.walk.clamp_roughness,
            bare_alpha,
            tint: opts.tint.clone(),
            extent: opts.extent,
            transition: opts.transition,
        })
    }

    /// extentFactor = 1 − smoothstep(extent − transition, extent + transition, mask): 1 where the patina covers.
    pub fn coverage(&self, mask: f64) -> f64 {
        1.0 - smoothstep(self.extent - self.transition, self.extent + self.transition, mask)
    }

    /// f = (1 − w) f_bare + w f_patina, where the patina layer's roughness and IOR go from the bare surface's (the
    /// outside medium's IOR: no layer) to the patina's with w, and the base is tinted by lerp(1, tint, w).
    /// (`normal`: the base's tilted normal, car paint.)
    fn eval(&self, model: &Prepared, wi: DVec3, wo: DVec3, mask: f64, normal: Option<DVec3>, out: &mut [f64]) {
        let w = self.coverage(mask);
        let mut bare = vec![0.0; out.len()];
        if w < 1.0 {
            self.bare.eval(model, &self.bare.layers, wi, wo, normal, &[1.0], &mut bare);
        }
        out.fill(0.0);
        if w > 0.0 {
            let [SpLayer::Dielectric { iface, thickness, sigma_t, albedo }, base] = &self.patina.layers[..] else {
                unreachable!("a patina is a dielectric over a base")
            };
            let lerp = |a: f64, b: f64| a + w * (b - a);
            // The patina's relative IOR over the outside goes from 1 (no layer) to its own; the base's relative
            // IOR follows the medium above it.
            let eta_top: Vec<f64> = iface.eta.iter().map(|e| lerp(1.0, *e)).collect();
            let rescale = |v: &[f64]| -> Vec<f64> {
                v.iter().zip(&iface.eta).zip(&eta_top).map(|((x, e), t)| x * e / t).collect()
            };
            let target = if iface.mf.is_smooth() { (0.0, 0.0) } else { (iface.mf.alpha_x, iface.mf.alpha_y) };
            let alpha = (lerp(self.bare_alpha.0, target.0), lerp(self.bare_alpha.1, target.1));
            let top = SpLayer::Dielectric {
                iface: SpInterface {
                    mf: iface.mf.with_alpha(alpha.0, alpha.1),
                    eta: eta_top.clone(),
                    kappa: iface.kappa.clone(),
                    conductor: false,
                    table: Vec::new(),
                },
                thickness: *thickness,
                sigma_t: sigma_t.clone(),
                albedo: albedo.clone(),
            };
            let base = match base {
                SpLayer::Conductor { iface: b, diffuse } => SpLayer::Conductor {
                    iface: SpInterface {
                        mf: if self.clamp && !b.mf.is_smooth() {
                            b.mf.with_alpha(b.mf.alpha_x.max(alpha.0), b.mf.alpha_y.max(alpha.1))
                        } else {
                            b.mf
                        },
                        eta: rescale(&b.eta),
                        kappa: rescale(&b.kappa),
                        conductor: true,
                        table: Vec::new(),
                    },
                    // The full patina's inter-reflections, scaled by its coverage.
                    diffuse: diffuse.iter().map(|d| w * d).collect(),
                },
                SpLayer::Diffuse { albedo, sigma, gain } => {
                    SpLayer::Diffuse { albedo: albedo.clone(), sigma: *sigma, gain: gain.clone() }
                }
                SpLayer::Dielectric { .. } => unreachable!("checked in Patina::new"),
            };
            let tint: Vec<f64> = self.tint.iter().map(|t| lerp(1.0, *t)).collect();
            self.patina.eval(model, &[top, base], wi, wo, normal, &tint, out);
        }
        for (o, b) in out.iter_mut().zip(&bare) {
            *o = (1.0 - w) * b + w * *o;
        }
    }
}

/// The GPU half (shaders/weidlich_wilkie.wgsl, after the single-pass layers and walk).
#[cfg(feature = "gpu")]
pub mod gpu {
    use super::{prepare, Options};
    use crate::error::Result;
    use crate::models::common::gpu::{
        fresnel_code, g2_code, params, word, words, GpuHalf, Kernel, LAYERS, SINGLE_PASS,
    };
    use crate::models::common::single_pass::gpu_layers;
    use crate::models::Args;
    use crate::stack::Stack;
    use crate::tables::elek::{beckmann_table, D_SIZE};
    use bytemuck::Zeroable;

    pub const HALF: GpuHalf = GpuHalf {
        shader: &[LAYERS, SINGLE_PASS, include_str!("../gpu/shaders/weidlich_wilkie.wgsl")],
        refusal: |_| None,
        kernel,
    };

    params! {
        /// weidlich_wilkie.wgsl's `Params`.
        n: u32,
        channels: u32,
        layers: u32,
        g2: u32,
        fresnel: u32,
        eta2: u32,
        fresnel_samples: u32,
        precomputed: u32,
        d_size: u32,
        layers_base: u32,
        group: u32,
        patina: u32,
        patina_at: u32,
        bare_at: u32,
        tint_at: u32,
        tints: u32,
        extent: f32,
        transition: f32,
        bare_alpha_x: f32,
        bare_alpha_y: f32,
        clamp: u32,
    }

    /// The kernel: the parameters, the layers (with Elek's Fresnel tables when precomputed; then the patina form's
    /// walks and tint, when the stack has one) and Elek's Beckmann table (one unused value when not precomputed).
    fn kernel(stack: &Stack, args: &Args) -> Result<Kernel> {
        let p = prepare(stack, &Options::parse(args, stack.channels)?)?;
        let (mut layers, fresnel_samples, group) = gpu_layers(&p.walk.layers, p.channels);
        let beckmann: &'static [f32] = if p.precomputed { beckmann_table().samples() } else { &[0.0] };
        let mut params = Params {
            n: 0,
            channels: p.channels as u32,
            layers: p.walk.layers.len() as u32,
            g2: g2_code(p.walk.g2),
            fresnel: fresnel_code(p.walk.fresnel),
            eta2: p.walk.eta2 as u32,
            fresnel_samples,
            precomputed: p.precomputed as u32,
            d_size: D_SIZE as u32,
            layers_base: 0,
            group,
            ..Params::zeroed()
        };
        if let Some(patina) = &p.patina {
            params.patina = 1;
            params.patina_at = layers.len() as u32;
            layers.extend(gpu_layers(&patina.patina.layers, p.channels).0);
            params.bare_at = layers.len() as u32;
            layers.extend(gpu_layers(&patina.bare.layers, p.channels).0);
            params.tint_at = layers.len() as u32;
            params.tints = patina.tint.len() as u32;
            layers.extend(patina.tint.iter().map(|&t| t as f32));
            params.extent = patina.extent as f32;
            params.transition = patina.transition as f32;
            params.bare_alpha_x = patina.bare_alpha.0 as f32;
            params.bare_alpha_y = patina.bare_alpha.1 as f32;
            params.clamp = patina.clamp as u32;
        }
        Ok(Kernel {
            shader: "weidlich_wilkie",
            words: words(&params),
            count_word: word!(Params, n),
            arrays: vec![(layers, word!(Params, layers_base))],
            tables: vec![beckmann],
            channels: p.channels,
            fit: None,
        })
    }

    #[cfg(test)]
    #[test]
    fn params_mirror_the_wgsl_struct() {
        crate::gpu::tests::assert_mirrors("weidlich_wilkie", Params::FIELDS, std::mem::size_of::<Params>());
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::models::common::testing::{args, conductor, dielectric, dir, f, lambert, stack};
    use crate::models::microfacet::smooth_coat_lambert;
    use crate::models::weidlich_wilkie;
    use crate::models::Value;
    use crate::optics::distribution::G2Form;
    use crate::optics::fresnel::diffuse_reflectance;

    fn options(interreflection: bool) -> Options {
        Options::parse(&args(&INFO, &[("interreflection", Value::Flag(interreflection))]), 1).unwrap()
    }

    fn model(layers: Vec<Layer>, interreflection: bool) -> Prepared {
        prepare(&stack(layers), &options(interreflection)).unwrap()
    }

    #[test]
    fn a_smooth_coat_over_lambert_is_the_closed_form() {
        // T₁₂ = 1 − F(θL), t = T₂₁ for a smooth coat, Snell's law and 1/η²: with the inter-reflections the exact
        // smooth-coat result; without them exactly the single pass, which lacks the factor 1/(1 − ρ F̄_int).
        let f_int = diffuse_reflectance(1.0 / 1.5);
        for (interreflection, gain) in [(true, 1.0), (false, 1.0 - 0.8 * f_int)] {
            let m = model(vec![dielectric(1.5, 0.0, 0.0, 0.0, 0.0), lambert(0.8)], interreflection);
            for (ti, to) in [(0.0, 0.0), (30.0, 60.0), (85.0, 45.0)] {
                let (wi, wo) = (dir(ti, 0.0), dir(to, 135.0));
                let exact = gain * smooth_coat_lambert(0.8, 1.5, f_int, wi.z, wo.z);
                assert!((f(&m, wi, wo, 1)[0] / exact - 1.0).abs() < 1e-13, "({ti}, {to})");
            }
        }
    }

    #[test]
    fn an_index_matched_coat_shows_its_base() {
        // A smooth coat of η = 1 reflects nothing, transmits everything and bends nothing: f is the base's
        // Torrance–Sparrow lobe (Beckmann, V-cavity), exactly.
        let base = conductor(0.27, 3.4, (0.25, 0.25));
        let m = model(vec![dielectric(1.0, 0.0, 0.0, 0.0, 0.0), base.clone()], false);
        let mf = base.microfacet(Distribution::Beckmann).unwrap();
        for (wi, wo) in [(dir(20.0, 0.0), dir(30.0, 170.0)), (dir(60.0, 40.0), dir(10.0, 250.0))] {
            let exact = bsdf::rough_conductor(&mf, G2Form::VCavity, 0.27, 3.4, wi, wo);
            assert!((f(&m, wi, wo, 1)[0] / exact - 1.0).abs() < 1e-13, "{wi} {wo}");
        }
    }

    #[test]
    fn an_absorbing_slab_attenuates_by_beer_lambert_along_the_refracted_directions() {
        // f(d) / f(0) = exp(−σ d (1/μi′ + 1/μo′)), μ′ the cosines refracted into the coat (Snell).
        let (sigma, d, eta) = (0.7, 0.5, 1.5);
        let clear = model(vec![dielectric(eta, 0.0, 0.0, 0.0, 0.0), lambert(0.8)], false);
        let tinted = model(vec![dielectric(eta, 0.0, d, sigma, 0.0), lambert(0.8)], false);
        let inside = |w: DVec3| (1.0 - (1.0 - w.z * w.z) / (eta * eta)).sqrt();
        for (wi, wo) in [(dir(0.0, 0.0), dir(40.0, 90.0)), (dir(70.0, 10.0), dir(80.0, 200.0))] {
            let ratio = f(&tinted, wi, wo, 1)[0] / f(&clear, wi, wo, 1)[0];
            let exact = (-sigma * d * (1.0 / inside(wi) + 1.0 / inside(wo))).exp();
            assert!((ratio / exact - 1.0).abs() < 1e-13, "{ratio} vs {exact}");
        }
    }

    #[test]
    fn the_patina_mask_goes_from_the_full_stack_to_the_bare_base() {
        // mask 0: coverage 1, the patina stack as it is; mask 1: coverage 0, the bare copper (Elek 2010's patina).
        let (patina, copper) = (dielectric(2.8, 0.35, 0.5, 1.5, 0.0), conductor(0.2, 4.0, (0.15, 0.15)));
        let full = model(vec![patina.clone(), copper.clone()], false);
        let bare = model(vec![copper], false);
        for (wi, wo) in [(dir(20.0, 0.0), dir(30.0, 170.0)), (dir(60.0, 40.0), dir(10.0, 250.0))] {
            for (mask, expected) in [(0.0, f(&full, wi, wo, 1)[0]), (1.0, f(&bare, wi, wo, 1)[0])] {
                let mut out = [0.0];
                crate::models::eval_one(&full, wi, wo, &[None, None, Some([mask, 0.0, 0.0])], &mut out);
                assert!((out[0] - expected).abs() <= 1e-13 * expected, "mask {mask}: {} vs {expected}", out[0]);
            }
        }
    }

    #[test]
    fn elek_s_precomputed_tables_stay_within_elek_s_bound() {
        // Elek 2010: the 128-sample Fresnel tables and the 512 x 512 Beckmann table err by under 6%; on a rough coat
        // over a rough conductor, measured 1.8e-4 at most.
        let layers = vec![dielectric(1.5, 0.3, 0.5, 0.2, 0.0), conductor(0.27, 3.4, (0.4, 0.4))];
        let exact = model(layers.clone(), false);
        let opts = weidlich_wilkie::Options::parse(&args(&INFO, &[("precomputed", Value::Flag(true))]), 1).unwrap();
        let tables = prepare(&stack(layers), &opts).unwrap();
        let mut worst: f64 = 0.0;
        for ti in [0.0, 30.0, 60.0, 80.0] {
            for to in [0.0, 30.0, 60.0, 80.0] {
                let (wi, wo) = (dir(ti, 0.0), dir(to, 180.0));
                worst = worst.max((f(&tables, wi, wo, 1)[0] / f(&exact, wi, wo, 1)[0] - 1.0).abs());
            }
        }
        assert!(worst < 0.06, "{worst}");
    }
}
