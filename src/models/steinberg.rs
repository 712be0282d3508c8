//! `model="steinberg"`: Steinberg 2016, "Light Transport in a Multi-Layered Microfacet Model" — one pass through
//! the stack (models/common/single_pass.rs) with a Cook–Torrance GGX lobe per interface; a dielectric interface transmits
//! t(wo) t(wi), the mean Fresnel transmissions over the visible microfacets, and bends both directions to the mean
//! refracted directions, both from lamina's tables (tables/steinberg.rs, tabulated or fitted form).
//!
//! Anisotropic layers (lamina's analytic approximation; the article names a 3D LUT or an analytic form): each
//! direction looks the tables up with the projected roughness α(φ) of its azimuth in the layer's tangent frame —
//! the roughness that the Smith masking of that direction sees — and stays in its plane of incidence. The lobes
//! themselves use the full anisotropic D and G2.
//!
//! | Parameter         | Type   | Default             | Description                                                 |
//! |-------------------|--------|---------------------|-------------------------------------------------------------|
//! | `g2`              | string | `height_correlated` | masking-shadowing of the lobes                              |
//! | `fresnel`         | string | `exact`             | Fresnel form of the lobes                                   |
//! | `lut`             | string | `tabulated`         | `tabulated` integrals or the article's `fitted` closed forms |
//! | `clamp_roughness` | bool   | `true`              | Elek's m₂ ≥ m₁; `false` for the published form              |
//! | `eta2`            | bool   | `true`              | radiance compression 1/η²; `false` for the published form   |
//! | `interreflection` | bool   | `false`             | lamina's correction: diffuse-base inter-reflections 1/(1 − ρ r) |
//! | `conductor_interreflection` | bool | `false`   | lamina's correction: conductor-base inter-reflections       |
//! | `microfacet_transmission` | bool | `false`     | lamina's correction: T (masking included) instead of t      |
//! | `transport_fit`   | bool   | `false`             | lamina's correction: f ← s f + a fitted to the stack's adding-doubling |
//! | `variant`         | string | `published`         | `improved`: with `transport_fit` (corrections/transport_fit.rs) |
//!
//! The distribution is GGX (the tables are GGX). Sampling: the shared single-pass mixture (models/common/single_pass.rs).
//! Gradients (`Stack.eval_grad`): the walk in Duals (single_pass::gradient), through the tables' interpolants or the
//! fitted closed forms, with the exact Fresnel form and without the inter-reflection corrections.

use super::common::block::simd_columns;
use super::common::mixture_lanes::{self, LaneMixture, Proposals};
use super::common::options::{
    choice, variant, CLAMP_ROUGHNESS, CONDUCTOR_INTERREFLECTION, ETA2, FRESNEL, G2, INTERREFLECTION,
    MICROFACET_TRANSMISSION, TRANSPORT_FIT,
};
use super::common::single_pass::{
    self, refracted_up, Passage, RealTransport, SpInterface, SpLayer, Transport, Walk, WalkOptions,
};
use super::common::walk_lanes::{self, LanePassage, LaneTransport, LaneWalk};
use super::corrections::{interreflection, transport_fit};
use super::{
    Args, Differentiable, Field, Gradient, InputSpec, Model, ModelInfo, OptionSpec, Properties, Proposal, Seed,
};
use crate::bsdf;
use crate::dual::{Dir, Real};
use crate::engine::{self, Floats, Mask, Rows, V3};
use crate::error::{value_error, Result};
use crate::models::FitLanes;
use crate::optics::distribution::Distribution;
use crate::stack::Stack;
use crate::tables::steinberg::{self as lut, steinberg};
use crate::tables::{bilerp_lanes, lerp_lanes, node_lanes};
use glam::DVec3;

/// The values of the option `lut`: lamina's tabulated integrals or the article's fitted closed forms.
pub const LUTS: [&str; 2] = ["tabulated", "fitted"];

/// Steinberg's options (the table above).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Options {
    pub walk: WalkOptions,
    /// The article's fitted closed forms instead of lamina's tabulated integrals.
    pub fitted: bool,
    /// lamina's correction: the passages transmit T (tables::steinberg) instead of t.
    pub microfacet_transmission: bool,
    pub transport_fit: bool,
}

impl Options {
    pub fn parse(args: &Args) -> Result<Options> {
        Ok(Options {
            walk: WalkOptions::parse(args)?,
            fitted: args.is("lut", "fitted")?,
            microfacet_transmission: args.flag("microfacet_transmission")?,
            transport_fit: args.flag("transport_fit")?,
        })
    }
}

pub struct Prepared {
    pub walk: Walk,
    pub opts: Options,
    pub channels: usize,
    /// The stack, whose layers the gradient takes in Duals.
    stack: Stack,
    /// The float32 kernel, where the lanes cover the stack (`Lanes::new`).
    lanes: Option<Lanes>,
}

pub const INFO: ModelInfo = ModelInfo {
    name: "steinberg",
    summary: "Steinberg's multi-layered GGX: one pass, mean transmissions and refractions from tables",
    options: &[
        G2,
        FRESNEL,
        choice(
            "lut",
            &LUTS,
            "tabulated",
            "transmission and refraction: lamina's tabulated integrals or the article's fitted closed forms",
        ),
        CLAMP_ROUGHNESS,
        ETA2,
        INTERREFLECTION,
        CONDUCTOR_INTERREFLECTION,
        MICROFACET_TRANSMISSION,
        TRANSPORT_FIT,
        variant(&["transport_fit"], "published: Steinberg's model (lamina's defaults); improved: with transport_fit"),
    ] as &[OptionSpec],
    inputs: &[] as &[InputSpec],
    properties: Properties { reciprocal: false, energy_conserving: false, anisotropic: true, spectral: true },
    gradients: &Field::NAMES,
    prepare: |stack, args| {
        let opts = Options::parse(args)?;
        transport_fit::apply(opts.transport_fit, Box::new(prepare(stack, &opts)?), stack)
    },
    prepare_gradient: None,
    #[cfg(feature = "gpu")]
    gpu: Some(&gpu::HALF),
};

pub fn prepare(stack: &Stack, opts: &Options) -> Result<Prepared> {
    let mut walk = Walk::new(stack, Distribution::Ggx, &opts.walk);
    interreflection::correct(&mut walk.layers, &opts.walk);
    for (i, layer) in walk.layers.iter().enumerate() {
        if let SpLayer::Dielectric { iface, .. } = layer {
            if let Some(eta) = iface.eta.iter().find(|e| !(lut::ETA_MIN..=lut::ETA_MAX).contains(*e)) {
                return value_error(format!(
                    "layer {i}: model 'steinberg' tabulates relative IORs (this layer's over the one above) in \
                     [{}, {}], got {eta}",
                    lut::ETA_MIN,
                    lut::ETA_MAX
                ));
            }
        }
    }
    steinberg(); // generate or load the tables outside the parallel evaluation
    let lanes = Lanes::new(&walk, opts, stack.channels);
    Ok(Prepared { walk, opts: *opts, channels: stack.channels, stack: stack.clone(), lanes })
}

/// Steinberg's walk in float32 lanes (models/common/walk_lanes.rs): each dielectric interface's table sliced at its
/// fixed α and η to [t, 1 − s / sin θ, T] in μ (`Steinberg::slice`), read at two nodes per direction; an anisotropic
/// interface's at its η over (μ, α) (`Steinberg::slice_alpha`), read at each direction's projected roughness.
struct Lanes {
    walk: LaneWalk,
    /// Per layer: the slice of a dielectric interface (empty for the base).
    slices: Vec<Slice>,
    microfacet_transmission: bool,
}

/// A dielectric interface's table slice.
enum Slice {
    /// In μ at the interface's α.
    Fixed(Vec<f32>),
    /// In (μ, α), with αx², αy² and the tangent frame's (cos, sin) for the projected roughness.
    Projected { records: Vec<f32>, ax2: f32, ay2: f32, frame: (f32, f32) },
}

impl Lanes {
    /// The lanes' form of the walk; None for what they do not cover (LaneWalk::new, the fitted LUT).
    fn new(walk: &Walk, opts: &Options, channels: usize) -> Option<Lanes> {
        if opts.fitted {
            return None;
        }
        let lane_walk = LaneWalk::new(walk, channels)?;
        let slice = |layer: &SpLayer| match layer {
            SpLayer::Dielectric { iface, .. } => {
                let (mf, eta) = (&iface.mf, iface.eta[0]);
                if mf.alpha_x == mf.alpha_y || mf.is_smooth() {
                    Slice::Fixed(steinberg().slice(if mf.is_smooth() { 0.0 } else { mf.alpha_x }, eta))
                } else {
                    let (c, s) = mf.frame();
                    let (ax2, ay2) = ((mf.alpha_x * mf.alpha_x) as f32, (mf.alpha_y * mf.alpha_y) as f32);
                    Slice::Projected { records: steinberg().slice_alpha(eta), ax2, ay2, frame: (c as f32, s as f32) }
                }
            }
            _ => Slice::Fixed(vec![]),
        };
        let slices = walk.layers.iter().map(slice).collect();
        Some(Lanes { walk: lane_walk, slices, microfacet_transmission: opts.microfacet_transmission })
    }
}

impl Lanes {
    /// t (or T) at w's cosine (and projected roughness) from a layer's slice, and w refracted along the mean
    /// direction.
    #[inline(always)]
    fn lookup(&self, slice: &Slice, w: V3) -> (Floats, V3) {
        let at = node_lanes(w.z, lut::N_MU);
        let t_column = if self.microfacet_transmission { 2 } else { 0 };
        let (t, d) = match slice {
            Slice::Fixed(records) => (lerp_lanes(records, 3, &at, t_column), lerp_lanes(records, 3, &at, 1)),
            Slice::Projected { records, ax2, ay2, frame } => {
                let alpha = node_lanes(projected_alpha(w, *ax2, *ay2, *frame), lut::N_ALPHA);
                let n = lut::N_ALPHA;
                (bilerp_lanes(records, 3, n, &at, &alpha, t_column), bilerp_lanes(records, 3, n, &at, &alpha, 1))
            }
        };
        let t = if self.microfacet_transmission { t.max(Floats::splat(0.0)).min(Floats::splat(1.0)) } else { t };
        (t, walk_lanes::refracted_up(w, d))
    }
}

/// Microfacet::projected_alpha in lanes: √((x² αx² + y² αy²) / (x² + y²)) in the tangent frame, αx along the normal.
#[inline(always)]
fn projected_alpha(w: V3, ax2: f32, ay2: f32, (c, s): (f32, f32)) -> Floats {
    let w = w.rotate(Floats::splat(c), Floats::splat(s));
    let (x2, y2) = (w.x * w.x, w.y * w.y);
    let r2 = x2 + y2;
    let alpha2 = x2.mul_add(Floats::splat(ax2), y2 * ay2) / r2;
    Floats::select(r2.gt(Floats::splat(0.0)), alpha2.sqrt(), Floats::splat(ax2.sqrt()))
}

impl LaneTransport for Lanes {
    /// `Transport::passage` in lanes, from the layer's slice.
    #[inline(always)]
    fn passage(&self, layer: usize, wi: V3, wo: V3) -> LanePassage {
        let slice = &self.slices[layer];
        let ((t_i, wi), (t_o, wo)) = (self.lookup(slice, wi), self.lookup(slice, wo));
        LanePassage { t_light: t_i, t_view: t_o, t_view_slab: t_o, wi, wo, through: Mask::ALL }
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
    /// Cook–Torrance GGX lobe (Cook & Torrance 1982 with the GGX D and Smith G2 of Walter et al. 2007).
    #[inline(always)]
    fn lobe(&self, iface: &SpInterface, wi: DVec3, wo: DVec3) -> Option<(f64, f64)> {
        bsdf::reflection_geometry(&iface.mf, self.walk.g2, wi, wo)
    }

    /// `passage_real` in f64.
    #[inline(always)]
    fn passage(&self, iface: &SpInterface, wi: DVec3, wo: DVec3, c: usize) -> Option<Passage> {
        self.passage_real(iface, wi.into(), wo.into(), c).map(Passage::from)
    }
}

impl RealTransport for Prepared {
    /// t(wo) t(wi) (or T(wo) T(wi) with `microfacet_transmission`) and the mean refracted directions from the
    /// tables (their interpolants, or the fitted closed forms), at each direction's projected roughness.
    #[inline(always)]
    fn passage_real<T: Real>(
        &self,
        iface: &SpInterface<T>,
        wi: Dir<T>,
        wo: Dir<T>,
        c: usize,
    ) -> Option<Passage<T, Dir<T>>> {
        let (table, eta) = (steinberg(), iface.eta[c]);
        let lookup = |w: Dir<T>| {
            let alpha = if iface.mf.is_smooth() { T::from(0.0) } else { iface.mf.projected_alpha(w) };
            let (t, s) = match self.opts.fitted {
                true => table.fitted(w[2], alpha, eta),
                false => table.tabulated(w[2], alpha, eta),
            };
            (if self.opts.microfacet_transmission { table.transmitted(w[2], alpha, eta) } else { t }, s)
        };
        let ((t_i, s_i), (t_o, s_o)) = (lookup(wi), lookup(wo));
        Some(Passage {
            t_light: t_i,
            t_view: t_o,
            t_view_slab: t_o,
            wi: refracted_up(wi, s_i),
            wo: refracted_up(wo, s_o),
        })
    }
}

impl Prepared {
    #[inline(always)]
    fn eval_columns(&self, wi: [&[f64]; 3], wo: [&[f64]; 3], out: &mut [f64]) {
        self.walk.eval_block(self, &self.walk.layers, wi, wo, None, &[1.0], out)
    }
}

/// The gradient of the walk with respect to N parameters (single_pass::gradient), through the tables' interpolants
/// (or the fitted closed forms).
fn gradient<'a, const N: usize>(p: &'a Prepared, seeds: &[Seed]) -> Result<Gradient<'a>> {
    single_pass::gradient::<N, _>("steinberg", p, &p.walk, &p.stack, Distribution::Ggx, &p.opts.walk, seeds)
}

impl Differentiable for Prepared {
    fn gradient(&self, seeds: &[Seed], n_params: usize) -> Result<Gradient<'_>> {
        super::dual_width!(n_params, gradient(self, seeds))
    }
}

impl Model for Prepared {
    fn eval_block(&self, wi: [&[f64]; 3], wo: [&[f64]; 3], _: &super::Inputs, out: &mut [f64]) {
        simd_columns!(Prepared, self, wi, wo, out)
    }

    fn eval_f32(&self, wi: Rows, wo: Rows, fit: Option<&FitLanes>, out: &mut [f32]) -> bool {
        self.lanes.as_ref().is_some_and(|k| engine::eval(k, fit, self.channels, wi, wo, out))
    }

    fn sample_f32(&self, wo: Rows, u: Rows, out: &mut [f32]) -> bool {
        let lanes = self.lanes.as_ref().filter(|k| k.walk.samples());
        lanes.is_some_and(|k| mixture_lanes::sample(k, self.channels, wo, u, out))
    }

    fn proposals(&self, wo: DVec3) -> Vec<(f64, Proposal)> {
        self.walk.proposals(wo, self.channels)
    }

    fn specular(&self, wo: DVec3, out: &mut [f64]) {
        self.walk.specular(wo, out)
    }
}

/// The GPU half (shaders/steinberg.wgsl, after the single-pass layers and walk).
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
    use crate::tables::steinberg::{steinberg, ETA_MAX, ETA_MIN, N_ALPHA, N_ETA, N_MU};

    pub const HALF: GpuHalf = GpuHalf {
        shader: &[LAYERS, SINGLE_PASS, include_str!("../gpu/shaders/steinberg.wgsl")],
        refusal: |_| None,
        kernel,
    };

    params! {
        /// steinberg.wgsl's `Params`.
        n: u32,
        channels: u32,
        layers: u32,
        g2: u32,
        fresnel: u32,
        eta2: u32,
        fitted: u32,
        n_mu: u32,
        n_alpha: u32,
        n_eta: u32,
        eta_min: f32,
        eta_max: f32,
        fresnel_samples: u32,
        layers_base: u32,
        microfacet_transmission: u32,
        group: u32,
    }

    /// The kernel: the parameters, the layers and Steinberg's tables.
    fn kernel(stack: &Stack, args: &Args) -> Result<Kernel> {
        let p = prepare(stack, &Options::parse(args)?)?;
        let walk = &p.walk;
        let (table, fits) = steinberg().gpu_data();
        let (layers, fresnel_samples, group) = gpu_layers(&walk.layers, p.channels);
        let params = Params {
            n: 0,
            channels: p.channels as u32,
            layers: walk.layers.len() as u32,
            g2: g2_code(walk.g2),
            fresnel: fresnel_code(walk.fresnel),
            eta2: walk.eta2 as u32,
            fitted: p.opts.fitted as u32,
            n_mu: N_MU as u32,
            n_alpha: N_ALPHA as u32,
            n_eta: N_ETA as u32,
            eta_min: ETA_MIN as f32,
            eta_max: ETA_MAX as f32,
            fresnel_samples,
            layers_base: 0,
            microfacet_transmission: p.opts.microfacet_transmission as u32,
            group,
        };
        Ok(Kernel {
            shader: "steinberg",
            words: words(&params),
            count_word: word!(Params, n),
            arrays: vec![(layers, word!(Params, layers_base))],
            tables: vec![table, fits],
            channels: p.channels,
            fit: None,
        })
    }

    #[cfg(test)]
    #[test]
    fn params_mirror_the_wgsl_struct() {
        crate::gpu::tests::assert_mirrors("steinberg", Params::FIELDS, std::mem::size_of::<Params>());
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::models::common::testing::{args, conductor, dielectric, dir, f, lambert, stack};
    use crate::models::microfacet::smooth_coat_lambert;
    use crate::models::Value;
    use crate::optics::distribution::G2Form;
    use crate::optics::fresnel::diffuse_reflectance;

    fn options(interreflection: bool) -> Options {
        Options::parse(&args(&INFO, &[("interreflection", Value::Flag(interreflection))])).unwrap()
    }

    #[test]
    fn a_single_rough_conductor_is_its_cook_torrance_lobe() {
        let layer = conductor(0.27, 3.4, (0.4, 0.15));
        let m = prepare(&stack(vec![layer.clone()]), &options(false)).unwrap();
        let mf = layer.microfacet(Distribution::Ggx).unwrap();
        for (wi, wo) in [(dir(20.0, 0.0), dir(50.0, 170.0)), (dir(70.0, 40.0), dir(10.0, 300.0))] {
            let exact = bsdf::rough_conductor(&mf, G2Form::HeightCorrelated, 0.27, 3.4, wi, wo);
            assert!((f(&m, wi, wo, 1)[0] - exact).abs() <= 1e-14 * exact, "{wi} {wo}");
        }
    }

    #[test]
    fn a_smooth_coat_over_lambert_is_the_closed_form() {
        // A smooth interface transmits t = 1 − F and refracts by Snell's law: with the inter-reflections (and the
        // η² compression) the walk is the exact smooth-coat result, up to the table's interpolation of t in μ
        // (measured 4.6e-4 at most, at 80°); without them it lacks exactly the factor 1/(1 − ρ F̄_int).
        let layers = vec![dielectric(1.5, 0.0, 0.0, 0.0, 0.0), lambert(0.8)];
        let f_int = diffuse_reflectance(1.0 / 1.5);
        for (interreflection, gain) in [(true, 1.0), (false, 1.0 - 0.8 * f_int)] {
            let m = prepare(&stack(layers.clone()), &options(interreflection)).unwrap();
            for (ti, to) in [(0.0, 0.0), (30.0, 60.0), (80.0, 45.0)] {
                let (wi, wo) = (dir(ti, 0.0), dir(to, 135.0));
                let exact = gain * smooth_coat_lambert(0.8, 1.5, f_int, wi.z, wo.z);
                let e = f(&m, wi, wo, 1)[0] / exact - 1.0;
                assert!(e.abs() < 1e-3, "interreflection {interreflection}, ({ti}, {to}): {e}");
            }
        }
    }

    #[test]
    fn a_rough_coat_transmits_no_more_with_its_masking() {
        // lamina's microfacet_transmission: T, the single-scattering transmission with the microsurface's masking,
        // is at most t, the mean Fresnel transmission over the visible normals, so what lies beneath gets no brighter.
        // Measured: f drops by 0.3%, 1.9% and 13% at these angles.
        let layers = vec![dielectric(1.5, 0.4, 0.0, 0.0, 0.0), lambert(0.8)];
        let plain = prepare(&stack(layers.clone()), &options(false)).unwrap();
        let opts = Options::parse(&args(&INFO, &[("microfacet_transmission", Value::Flag(true))])).unwrap();
        let masked = prepare(&stack(layers), &opts).unwrap();
        for (ti, to) in [(0.0, 0.0), (40.0, 20.0), (75.0, 70.0)] {
            let (wi, wo) = (dir(ti, 0.0), dir(to, 90.0));
            let (a, b) = (f(&plain, wi, wo, 1)[0], f(&masked, wi, wo, 1)[0]);
            assert!(b < a, "({ti}, {to}): {b} vs {a}");
        }
    }
}
