//! `model="microfacet"`: exact evaluation of the stacks that have a closed form — a single opaque interface
//! (rough conductor, Lambert, Oren–Nayar) and a smooth dielectric coat over a Lambertian base.
//!
//! | Parameter      | Type   | Default             | Description                                                    |
//! |----------------|--------|---------------------|----------------------------------------------------------------|
//! | `distribution` | string | `ggx`               | microfacet distribution, `ggx` or `beckmann`                   |
//! | `g2`           | string | `height_correlated` | masking-shadowing: `height_correlated`, `separable`, `v_cavity` |
//! | `fresnel`      | string | `exact`             | conductor Fresnel: `exact`, `schlick`, `lazanyi`                |
//!
//! Sampling: the conductor's visible normals (Heitz 2018); the diffuse forms by the cosine. A smooth conductor or
//! the smooth coat's reflection are Dirac lobes (`specular`).

use super::common::block::{eval_rows, row, simd_columns, BLOCK};
use super::common::options::{DISTRIBUTION, FRESNEL, G2};
use super::{
    per_pair, Args, Differentiable, Field, Gradient, InputSpec, Model, ModelInfo, OptionSpec, Properties, Proposal,
    Seed,
};
use crate::bsdf;
use crate::dual::{Dual, Real};
use crate::engine::{self, with_avx2, Floats, Rows, V3};
use crate::error::{value_error, Result};
use crate::models::FitLanes;
use crate::optics::diffuse;
use crate::optics::distribution::{Distribution, G2Form, Microfacet};
use crate::optics::fresnel::{self, FresnelForm};
use crate::optics::lanes::{self, ConductorIor, Lobe, Visible};
use crate::stack::{Layer, Stack};
use glam::DVec3;
use std::f64::consts::FRAC_1_PI;

pub enum Prepared {
    /// Rough conductor with relative IOR eta + ik per channel.
    Conductor { mf: Microfacet, g2: G2Form, fresnel: FresnelForm, eta: Vec<f64>, k: Vec<f64> },
    /// Lambert (sigma = 0) or Oren–Nayar.
    Diffuse { albedo: Vec<f64>, sigma: f64 },
    /// Smooth coat over Lambert: relative IOR and F̄_int per channel.
    CoatLambert { albedo: Vec<f64>, eta: Vec<f64>, f_int: Vec<f64> },
}

pub const INFO: ModelInfo = ModelInfo {
    name: "microfacet",
    summary: "exact single interfaces (rough conductor, Lambert, Oren–Nayar) and a smooth coat over Lambert",
    options: &[DISTRIBUTION, G2, FRESNEL] as &[OptionSpec],
    inputs: &[] as &[InputSpec],
    properties: Properties { reciprocal: true, energy_conserving: true, anisotropic: true, spectral: true },
    gradients: &["ior", "k", "roughness_x", "roughness_y", "angle", "albedo", "diffuse_roughness"],
    prepare: |stack, args| Ok(Box::new(prepare(stack, &Options::parse(args)?)?)),
    prepare_gradient: None,
    #[cfg(feature = "gpu")]
    gpu: Some(&gpu::HALF),
};

/// The exact models' options (the table above).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Options {
    pub distribution: Distribution,
    pub g2: G2Form,
    pub fresnel: FresnelForm,
}

impl Options {
    pub fn parse(args: &Args) -> Result<Options> {
        Ok(Options {
            distribution: args.choice("distribution")?,
            g2: args.choice("g2")?,
            fresnel: args.choice("fresnel")?,
        })
    }
}

pub fn prepare(stack: &Stack, opts: &Options) -> Result<Prepared> {
    let top = stack.interfaces().swap_remove(0);
    match stack.layers.as_slice() {
        [layer @ Layer::Conductor { .. }] => Ok(Prepared::Conductor {
            mf: layer.microfacet(opts.distribution).expect("conductors have an interface"),
            g2: opts.g2,
            fresnel: opts.fresnel,
            eta: top.eta,
            k: top.kappa,
        }),
        [Layer::Diffuse { albedo, roughness }] => Ok(Prepared::Diffuse { albedo: albedo.clone(), sigma: *roughness }),
        [Layer::Dielectric { alpha: (ax, ay), thickness, sigma_a, sigma_s, .. }, Layer::Diffuse { albedo, roughness }]
            if *ax == 0.0
                && *ay == 0.0
                && *roughness == 0.0
                && (*thickness == 0.0 || sigma_a.iter().chain(sigma_s).all(|&s| s == 0.0)) =>
        {
            let eta = top.eta;
            let f_int = eta.iter().map(|e| fresnel::diffuse_reflectance(1.0 / e)).collect();
            Ok(Prepared::CoatLambert { albedo: albedo.clone(), eta, f_int })
        }
        _ => value_error(
            "model 'microfacet' evaluates a single opaque interface or a smooth non-absorbing coat over a \
             Lambertian base exactly; this stack needs a layered model",
        ),
    }
}

impl Prepared {
    fn eval(&self, wi: DVec3, wo: DVec3, out: &mut [f64]) {
        out.fill(0.0);
        if wi.z <= 0.0 || wo.z <= 0.0 {
            return;
        }
        match self {
            Prepared::Conductor { mf, g2, fresnel, eta, k } => {
                if let Some((geo, cos_h)) = bsdf::reflection_geometry(mf, *g2, wi, wo) {
                    for (c, o) in out.iter_mut().enumerate() {
                        *o = geo * fresnel.conductor(cos_h, eta[c], k[c]);
                    }
                }
            }
            Prepared::Diffuse { albedo, sigma } => {
                let shape = diffuse::oren_nayar_shape(*sigma, wi, wo);
                for (o, &rho) in out.iter_mut().zip(albedo) {
                    *o = rho * shape;
                }
            }
            Prepared::CoatLambert { albedo, eta, f_int } => {
                for (c, o) in out.iter_mut().enumerate() {
                    *o = smooth_coat_lambert(albedo[c], eta[c], f_int[c], wi.z, wo.z);
                }
            }
        }
    }
}

/// The gradient of `Prepared::eval` with respect to N parameters (`Differentiable::gradient`), f and ∂f/∂p per channel
/// in Duals: a rough conductor's η, κ (exact Fresnel), αx, αy and frame angle; a diffuse base's albedo and Oren–Nayar
/// σ; a smooth coat's η (F̄_int's quadrature included) and the albedo beneath it.
fn gradient<const N: usize>(p: &Prepared, seeds: &[Seed]) -> Result<Gradient<'static>> {
    let dual_at =
        |layer: usize, field: Field, channel: usize, v: f64| super::seeded::<N>(seeds, layer, field, channel, v);
    let dual = |field: Field, channel: usize, v: f64| dual_at(0, field, channel, v);
    let takes = |fields: &[Field], what: &str| match seeds.iter().find(|s| !fields.contains(&s.field)) {
        Some(s) => {
            value_error(format!("model 'microfacet' has no gradient by {} of this stack ({what})", s.field.name()))
        }
        None => Ok(()),
    };
    match p {
        Prepared::Conductor { mf, g2, fresnel, eta, k } => {
            let fields = [Field::Ior, Field::K, Field::RoughnessX, Field::RoughnessY, Field::Angle];
            takes(&fields, "a conductor: ior, k, roughness_x, roughness_y and angle")?;
            if *fresnel != FresnelForm::Exact {
                return value_error("gradients of model 'microfacet' take fresnel='exact'");
            }
            let (cos, sin) = mf.frame();
            let mfd = Microfacet::<Dual<N>>::with_parameters(
                mf.dist,
                dual(Field::RoughnessX, 0, mf.alpha_x),
                dual(Field::RoughnessY, 0, mf.alpha_y),
                dual(Field::Angle, 0, sin.atan2(cos)),
            );
            let (smooth, g2) = (mf.is_smooth(), *g2);
            let eta: Vec<Dual<N>> = eta.iter().enumerate().map(|(c, &e)| dual(Field::Ior, c, e)).collect();
            let k: Vec<Dual<N>> = k.iter().enumerate().map(|(c, &x)| dual(Field::K, c, x)).collect();
            Ok(Box::new(move |wi, wo, out| {
                // A smooth conductor's reflection is a Dirac lobe, not part of f (`mfd` holds the clamped roughness).
                if smooth {
                    return out.fill(0.0);
                }
                let (mf, ior) = (&mfd, [&eta[..], &k[..]]);
                with_avx2!(
                    [const N: usize] (
                        mf: &Microfacet<Dual<N>>,
                        g2: G2Form,
                        ior: [&[Dual<N>]; 2],
                        wi: [&[f64]; 3],
                        wo: [&[f64]; 3],
                        out: &mut [f64]
                    ) => conductor_gradient(mf, g2, ior, wi, wo, out)
                )
            }))
        }
        Prepared::Diffuse { albedo, sigma } => {
            takes(&[Field::Albedo, Field::DiffuseRoughness], "a diffuse base: albedo and diffuse_roughness")?;
            let sigma = dual(Field::DiffuseRoughness, 0, *sigma);
            let albedo: Vec<Dual<N>> = albedo.iter().enumerate().map(|(c, &a)| dual(Field::Albedo, c, a)).collect();
            Ok(per_pair(move |wi, wo, out| {
                let shape = diffuse::oren_nayar_shape(sigma, wi, wo);
                for (c, &a) in albedo.iter().enumerate() {
                    super::store(out, c, a * shape);
                }
            }))
        }
        Prepared::CoatLambert { albedo, eta, .. } => {
            // The coat's IOR (layer 0) and the base's albedo (layer 1); the base's own IOR seed (its medium against
            // the outside) is the coat's again, not a second parameter.
            let fields = [Field::Ior, Field::Albedo];
            takes(&fields, "a smooth coat over Lambert: the coat's ior and the base's albedo")?;
            let eta: Vec<Dual<N>> = eta.iter().enumerate().map(|(c, &e)| dual(Field::Ior, c, e)).collect();
            let albedo: Vec<Dual<N>> =
                albedo.iter().enumerate().map(|(c, &a)| dual_at(1, Field::Albedo, c, a)).collect();
            let f_int: Vec<Dual<N>> = eta.iter().map(|&e| fresnel::diffuse_reflectance(Dual::from(1.0) / e)).collect();
            Ok(per_pair(move |wi, wo, out| {
                out.fill(0.0);
                if wi.z <= 0.0 || wo.z <= 0.0 {
                    return;
                }
                for c in 0..eta.len() {
                    super::store(out, c, smooth_coat_lambert(albedo[c], eta[c], f_int[c], wi.z, wo.z));
                }
            }))
        }
    }
}

/// A rough conductor's f and gradient over a block (`Gradient`): the geometry D G2 / (4 cos θi cos θo) per row in
/// Duals (αx, αy, angle), then per channel the exact Fresnel F(cos θh; η, κ) with its partials ∂F/∂η and ∂F/∂κ in a
/// Dual<2>, a loop over the rows that vectorizes, composed into the N parameters' derivatives (`Real::compose`).
#[inline(always)]
fn conductor_gradient<const N: usize>(
    mf: &Microfacet<Dual<N>>,
    g2: G2Form,
    [eta, k]: [&[Dual<N>]; 2],
    wi: [&[f64]; 3],
    wo: [&[f64]; 3],
    out: &mut [f64],
) {
    let n = wi[0].len();
    let (mut geo, mut cos_h) = ([Dual::<N>::from(0.0); BLOCK], [0.0; BLOCK]);
    for r in 0..n {
        let above = wi[2][r] > 0.0 && wo[2][r] > 0.0;
        let (g, c) = bsdf::reflection_geometry(mf, g2, row(wi, r), row(wo, r)).unwrap_or((Dual::from(0.0), 1.0));
        (geo[r], cos_h[r]) = (if above { g } else { Dual::from(0.0) }, c);
    }
    let width = out.len() / n;
    let mut f = [Dual::<2>::from(0.0); BLOCK];
    for c in 0..eta.len() {
        let (e, x) = (Dual::seeded(eta[c].v, 0, 1.0), Dual::seeded(k[c].v, 1, 1.0));
        for r in 0..n {
            f[r] = fresnel::conductor(cos_h[r], e, x);
        }
        for (r, o) in out.chunks_exact_mut(width).enumerate() {
            super::store(o, c, geo[r] * Dual::compose(f[r], [eta[c], k[c]]));
        }
    }
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
        self.lanes().is_some_and(|k| engine::eval(&k, fit, k.ior.len(), wi, wo, out))
    }

    fn sample_f32(&self, wo: Rows, u: Rows, out: &mut [f32]) -> bool {
        self.lanes().is_some_and(|k| engine::sample(&k, 3 + k.ior.len() + 1, wo, u, out))
    }

    fn proposals(&self, _wo: DVec3) -> Vec<(f64, Proposal)> {
        match self {
            Prepared::Conductor { mf, .. } if mf.is_smooth() => vec![],
            Prepared::Conductor { mf, .. } => vec![(1.0, Proposal::Reflection(*mf))],
            _ => vec![(1.0, Proposal::Cosine)],
        }
    }

    fn specular(&self, wo: DVec3, out: &mut [f64]) {
        out.fill(0.0);
        if wo.z <= 0.0 {
            return;
        }
        match self {
            Prepared::Conductor { mf, fresnel, eta, k, .. } if mf.is_smooth() => {
                for (c, o) in out.iter_mut().enumerate() {
                    *o = fresnel.conductor(wo.z, eta[c], k[c]);
                }
            }
            Prepared::CoatLambert { eta, .. } => {
                for (o, e) in out.iter_mut().zip(eta) {
                    *o = fresnel::dielectric(wo.z, *e);
                }
            }
            _ => {}
        }
    }
}

impl Prepared {
    /// The rough conductor in lanes (GGX or Beckmann, any G2).
    fn lanes(&self) -> Option<ConductorLanes> {
        let Prepared::Conductor { mf, g2, fresnel, eta, k } = self else { return None };
        let ior = eta.iter().zip(k).map(|(&e, &k)| ConductorIor::new(*fresnel, e, k)).collect();
        Some(ConductorLanes { lobe: Lobe::new(mf, *g2)?, visible: Visible::new(mf)?, ior })
    }

    /// f for a block of columns. The rough conductor runs in two passes, the geometry per row and then the Fresnel
    /// term per channel over the whole block, a branch-free loop that vectorizes.
    #[inline(always)]
    fn eval_columns(&self, wi: [&[f64]; 3], wo: [&[f64]; 3], out: &mut [f64]) {
        let n = wi[0].len();
        let k = out.len() / n;
        let Prepared::Conductor { mf, g2, fresnel, eta, k: kappa } = self else {
            return eval_rows(wi, wo, out, |_, wi, wo, o| self.eval(wi, wo, o));
        };
        let (mut geo, mut cos_h) = ([0.0; BLOCK], [0.0; BLOCK]);
        let (geo, cos_h) = (&mut geo[..n], &mut cos_h[..n]);
        geometry(mf, *g2, wi, wo, geo, cos_h);
        let mut f = [0.0; BLOCK];
        let f = &mut f[..n];
        for c in 0..k {
            let (eta, kappa) = (eta[c], kappa[c]);
            match fresnel {
                FresnelForm::Exact => {
                    for r in 0..n {
                        f[r] = geo[r] * fresnel::conductor(cos_h[r], eta, kappa);
                    }
                }
                form => {
                    for r in 0..n {
                        f[r] = geo[r] * form.conductor(cos_h[r], eta, kappa);
                    }
                }
            }
            for (o, &x) in out.chunks_exact_mut(k).zip(f.iter()) {
                o[c] = x;
            }
        }
    }
}

/// The rough conductor in float32 lanes: the geometry once, the Fresnel term per channel; sampled through its
/// visible normals.
struct ConductorLanes {
    lobe: Lobe,
    visible: Visible,
    ior: Vec<ConductorIor>,
}

impl engine::Kernel for ConductorLanes {
    #[inline(always)]
    fn eval(&self, wi: V3, wo: V3, out: &mut [Floats]) {
        let (geo, cos_h) = self.lobe.reflection(wi, wo);
        for (o, ior) in out.iter_mut().zip(&self.ior) {
            *o = geo * lanes::conductor(cos_h, ior);
        }
    }
}

/// The rough conductor's importance sampling in lanes (`mixture::sample` of its one reflection lobe): wi through the
/// visible normals, the weight f cos θi / pdf from the kernel's own f, and the pdf; a wo below the horizon samples
/// the normal with pdf 0, and a wi below it has weight and pdf 0, as the float64 sampler's.
impl engine::Sampler for ConductorLanes {
    #[inline(always)]
    fn sample(&self, wo: V3, u: V3, out: &mut [Floats]) {
        use engine::Kernel;
        let (zero, one) = (Floats::splat(0.0), Floats::splat(1.0));
        let (wi, pdf) = self.visible.sample(wo, u.y, u.z);
        let above = wo.z.gt(zero);
        let kept = above & wi.z.gt(zero) & pdf.gt(zero);
        let (head, rest) = out.split_at_mut(3);
        let (weight, tail) = rest.split_at_mut(self.ior.len());
        self.eval(wi, wo, weight);
        let factor = Floats::and(kept, wi.z / pdf);
        weight.iter_mut().for_each(|w| *w = *w * factor);
        tail[0] = Floats::and(kept, pdf);
        head.copy_from_slice(&[Floats::and(above, wi.x), Floats::and(above, wi.y), Floats::select(above, wi.z, one)]);
    }
}

/// The Fresnel-free part of microfacet reflection and the cosine its Fresnel factor takes (bsdf::reflection_geometry)
/// for a block of columns; 0 below the horizon. GGX with a Smith G2 has no special-function calls: with the
/// distribution and the G2 form known constants in the loop, it vectorizes.
#[inline(always)]
pub fn geometry(mf: &Microfacet, g2: G2Form, wi: [&[f64]; 3], wo: [&[f64]; 3], geo: &mut [f64], cos_h: &mut [f64]) {
    let mut ggx = *mf;
    ggx.dist = Distribution::Ggx;
    match (mf.dist, g2) {
        (Distribution::Ggx, G2Form::Separable) => geometry_in(&ggx, G2Form::Separable, wi, wo, geo, cos_h),
        (Distribution::Ggx, G2Form::HeightCorrelated) => {
            geometry_in(&ggx, G2Form::HeightCorrelated, wi, wo, geo, cos_h)
        }
        _ => geometry_in(mf, g2, wi, wo, geo, cos_h),
    }
}

#[inline(always)]
fn geometry_in(mf: &Microfacet, form: G2Form, wi: [&[f64]; 3], wo: [&[f64]; 3], geo: &mut [f64], cos_h: &mut [f64]) {
    // Every column sliced to the same length: no bounds checks in the loop, which lets it vectorize.
    let n = geo.len();
    let cos_h = &mut cos_h[..n];
    let ([ix, iy, iz], [ox, oy, oz]) = (wi.map(|c| &c[..n]), wo.map(|c| &c[..n]));
    for r in 0..n {
        let (wi, wo) = (DVec3::new(ix[r], iy[r], iz[r]), DVec3::new(ox[r], oy[r], oz[r]));
        let (g, c) = bsdf::reflection_geometry(mf, form, wi, wo).unwrap_or((0.0, 0.0));
        let above = wi.z > 0.0 && wo.z > 0.0;
        (geo[r], cos_h[r]) = if above { (g, c) } else { (0.0, 0.0) };
    }
}

/// Smooth dielectric coat over a Lambertian base, off the specular direction (the sum of all internal bounces;
/// Mitsuba's `plastic` with nonlinear = true, Weidlich–Wilkie 2007 §3):
/// f = ρ (1 − F(θi)) (1 − F(θo)) / (π η² (1 − ρ F̄_int)), F̄_int the hemispherical Fresnel reflectance from inside.
pub fn smooth_coat_lambert<T: Real>(albedo: T, eta: T, f_int: T, cos_i: f64, cos_o: f64) -> T {
    let t = fresnel::dielectric_transmittance(cos_i, eta) * fresnel::dielectric_transmittance(cos_o, eta);
    albedo * t * FRAC_1_PI / (eta * eta * (T::from(1.0) - albedo * f_int))
}

/// The GPU half (shaders/microfacet.wgsl).
#[cfg(feature = "gpu")]
pub mod gpu {
    use super::{Options, Prepared};
    use crate::error::Result;
    use crate::models::common::gpu::{fresnel_code, g2_code, params, word, words, GpuHalf, GpuMicrofacet, Kernel};
    use crate::models::Args;
    use crate::optics::distribution::{Distribution, G2Form, Microfacet};
    use crate::optics::fresnel::FresnelForm;
    use crate::stack::Stack;

    pub const HALF: GpuHalf =
        GpuHalf { shader: &[include_str!("../gpu/shaders/microfacet.wgsl")], refusal: |_| None, kernel };

    params! {
        /// microfacet.wgsl's `Params`.
        kind: u32,
        g2: u32,
        fresnel: u32,
        channels: u32,
        n: u32,
        sigma: f32,
        pad0: u32,
        pad1: u32,
        mf: GpuMicrofacet,
        base: u32,
        pad2: u32,
    }

    /// The kernel: the parameters and per channel (eta, k, albedo, f_int).
    fn kernel(stack: &Stack, args: &Args) -> Result<Kernel> {
        let smooth = Microfacet::new(Distribution::Ggx, 0.0, 0.0, 0.0);
        let p = super::prepare(stack, &Options::parse(args)?)?;
        let (kind, mf, g2, fresnel, sigma, rows): (u32, &Microfacet, G2Form, FresnelForm, f64, Vec<[f64; 4]>) = match &p
        {
            Prepared::Conductor { mf, g2, fresnel, eta, k } => {
                (0, mf, *g2, *fresnel, 0.0, eta.iter().zip(k).map(|(e, k)| [*e, *k, 0.0, 0.0]).collect())
            }
            Prepared::Diffuse { albedo, sigma } => {
                let rows = albedo.iter().map(|a| [0.0, 0.0, *a, 0.0]).collect();
                (1, &smooth, G2Form::Separable, FresnelForm::Exact, *sigma, rows)
            }
            Prepared::CoatLambert { albedo, eta, f_int } => {
                let rows = (0..albedo.len()).map(|c| [eta[c], 0.0, albedo[c], f_int[c]]).collect();
                (2, &smooth, G2Form::Separable, FresnelForm::Exact, 0.0, rows)
            }
        };
        let params = Params {
            kind,
            g2: g2_code(g2),
            fresnel: fresnel_code(fresnel),
            channels: rows.len() as u32,
            n: 0,
            sigma: sigma as f32,
            pad0: 0,
            pad1: 0,
            mf: mf.into(),
            base: 0,
            pad2: 0,
        };
        Ok(Kernel {
            shader: "microfacet",
            words: words(&params),
            count_word: word!(Params, n),
            channels: rows.len(),
            arrays: vec![(rows.into_iter().flatten().map(|x| x as f32).collect(), word!(Params, base))],
            tables: vec![],
            fit: None,
        })
    }

    #[cfg(test)]
    #[test]
    fn params_mirror_the_wgsl_struct() {
        crate::gpu::tests::assert_mirrors("microfacet", Params::FIELDS, std::mem::size_of::<Params>());
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::models::common::testing::{conductor, dielectric, dir, f, hemisphere, lambert, stack};
    use crate::tables::visible_normals;

    fn model(layers: Vec<Layer>, distribution: Distribution, g2: G2Form) -> Prepared {
        prepare(&stack(layers), &Options { distribution, g2, fresnel: FresnelForm::Exact }).unwrap()
    }

    #[test]
    fn a_smooth_coat_over_white_lambert_with_its_mirror_reflects_everything() {
        // ρ = 1, no absorption: ∫ f cos θo dωo + F(θi) = 1 (the Stokes relation η²(1 − F̄_int) = 1 − F̄_ext). Measured:
        // 9e-16 at most.
        let m = model(vec![dielectric(1.5, 0.0, 0.0, 0.0, 0.0), lambert(1.0)], Distribution::Ggx, G2Form::Separable);
        for theta in [0.0, 40.0, 80.0, 89.0] {
            let wi = dir(theta, 0.0);
            let albedo = hemisphere(64, 4, |wo| f(&m, wi, wo, 1)[0]) + fresnel::dielectric(wi.z, 1.5);
            assert!((albedo - 1.0).abs() < 1e-12, "θi = {theta}°: {albedo}");
        }
    }

    #[test]
    fn a_rough_conductor_reflects_what_its_visible_normals_do() {
        // Two estimators of one integral: the quadrature of f cos θo, and the mean over the visible normals of
        // F G2/G1 (the reference walk's sampling weights). Measured: 4.2e-7 (GGX) and 1.5e-6 (Beckmann) apart at most,
        // the lattice of 65536 normals' error.
        for (dist, g2) in [(Distribution::Ggx, G2Form::HeightCorrelated), (Distribution::Beckmann, G2Form::VCavity)] {
            let m = model(vec![conductor(0.27, 3.4, (0.3, 0.3))], dist, g2);
            let mf = Microfacet::new(dist, 0.3, 0.3, 0.0);
            for theta in [0.0, 45.0, 75.0] {
                let wi = dir(theta, 0.0);
                let quadrature = hemisphere(256, 512, |wo| f(&m, wi, wo, 1)[0]);
                let normals = visible_normals(&mf, wi, 1 << 16);
                let weight = |h: DVec3| {
                    let wo = crate::optics::reflect(wi, h);
                    let g = if wo.z > 0.0 { mf.g2(g2, wi, wo, h) / mf.g1(wi, h) } else { 0.0 };
                    fresnel::conductor(wi.dot(h), 0.27, 3.4) * g
                };
                let sampled = normals.iter().map(|&h| weight(h)).sum::<f64>() / normals.len() as f64;
                assert!((quadrature - sampled).abs() < 1e-5, "{dist:?} θi = {theta}°: {quadrature} vs {sampled}");
            }
        }
    }

    #[test]
    fn every_exact_model_is_reciprocal() {
        let layers = [
            vec![conductor(0.27, 3.4, (0.3, 0.1))],
            vec![Layer::Diffuse { albedo: vec![0.5], roughness: 0.4 }],
            vec![dielectric(1.5, 0.0, 0.0, 0.0, 0.0), lambert(0.8)],
        ];
        for (layers, g2) in layers.into_iter().zip([G2Form::HeightCorrelated, G2Form::VCavity, G2Form::Separable]) {
            let m = model(layers, Distribution::Ggx, g2);
            for (a, b) in [(dir(10.0, 30.0), dir(70.0, 200.0)), (dir(85.0, 0.0), dir(5.0, 90.0))] {
                let (x, y) = (f(&m, a, b, 1)[0], f(&m, b, a, 1)[0]);
                assert!((x - y).abs() <= 1e-13 * x.abs().max(1e-300), "{x} vs {y}");
            }
        }
    }

    #[test]
    fn oren_nayar_of_zero_roughness_is_lambert() {
        let m = model(vec![Layer::Diffuse { albedo: vec![0.6], roughness: 0.0 }], Distribution::Ggx, G2Form::Separable);
        assert_eq!(f(&m, dir(30.0, 0.0), dir(60.0, 120.0), 1)[0], 0.6 * FRAC_1_PI);
    }
}
