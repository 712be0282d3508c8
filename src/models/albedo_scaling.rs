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
//! | `scaling` | string | `reciprocal`        | S = T (1 − E(μi))(1 − E(μo)) (Adobe's openpbr-bsdf: reciprocal) |
//! |           |        |                     | or `view`: S = T (1 − E(μo)) (the OpenPBR text, Standard        |
//! |           |        |                     | Surface, MaterialX: energy-conserving for a view, not reciprocal) |
//! | `roughening` | bool | `true`               | OpenPBR's roughening of each layer under a rough one:           |
//! |           |        |                     | r′ = min(1, r⁴ + 2 r_c⁴)^{1/4} with r = √α: α′ = √min(1, α² + 2α_c²) |
//!
//! What the standards add and lamina leaves out: OpenPBR's coat darkening Δ = (1 − K)/(1 − E_b K) (the light the
//! coat reflects back onto the base), coat colour as the square of the normal-incidence transmittance, and the
//! weights that blend a coat in and out. The roughening is applied down the stack, each layer against the already
//! roughened one above it. E is the FGD table's (separable Smith, like the lobes by default), at the
//! geometric-mean roughness √(αx αy) for anisotropic interfaces. Sampling: each rough lobe by its visible normals,
//! weighted by its share of the energy, and the diffuse base by the cosine.

use super::options::{choice, flag, G2_FORMS};
use super::{eval_rows, InputSpec, Inputs, Model, ModelInfo, OptionSpec, Options, Properties, Proposal};
use crate::bsdf;
use crate::error::Result;
use crate::optics::distribution::{Distribution, G2Form, Microfacet};
use crate::optics::{diffuse, fresnel, sin_theta};
use crate::stack::{Layer, Stack};
use crate::tables;
use glam::DVec3;

pub const INFO: ModelInfo = ModelInfo {
    name: "albedo_scaling",
    summary: "the production coat model (OpenPBR, Standard Surface): lobes stacked with 1 − E(μ) albedo scaling",
    options: &[
        choice("g2", G2_FORMS, "separable", "masking-shadowing of the lobes; separable, as in the FGD table behind E"),
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
    prepare: |stack, opts| Ok(Box::new(prepare(stack, opts)?)),
};

/// One interface: its lobe, relative IOR and κ per channel, and the slab beneath it (thickness, σt per channel).
struct Interface {
    mf: Microfacet,
    eta: Vec<f64>,
    kappa: Vec<f64>,
    conductor: bool,
    thickness: f64,
    sigma_t: Vec<f64>,
}

pub struct Prepared {
    interfaces: Vec<Interface>,
    /// A diffuse base: albedo per channel and Oren–Nayar σ.
    diffuse: Option<(Vec<f64>, f64)>,
    g2: G2Form,
    reciprocal: bool,
    channels: usize,
}

/// OpenPBR's roughening of what lies under a rough coat, r′ = min(1, r⁴ + 2 r_c⁴)^{1/4} in its roughness r = √α,
/// i.e. α′ = √min(1, α² + 2 α_c²), per tangent axis.
pub fn roughened(alpha: f64, coat: f64) -> f64 {
    (alpha * alpha + 2.0 * coat * coat).min(1.0).sqrt()
}

pub fn prepare(stack: &Stack, opts: &Options) -> Result<Prepared> {
    let mut interfaces: Vec<Interface> = Vec::new();
    let mut diffuse = None;
    for (layer, rel) in stack.layers.iter().zip(stack.interfaces()) {
        let mf = layer.microfacet(Distribution::Ggx).map(|mf| match interfaces.last() {
            Some(above) if opts.roughening && !above.mf.is_smooth() => {
                let (ax, ay) = if mf.is_smooth() { (0.0, 0.0) } else { (mf.alpha_x, mf.alpha_y) };
                mf.with_alpha(roughened(ax, above.mf.alpha_x), roughened(ay, above.mf.alpha_y))
            }
            _ => mf,
        });
        match layer {
            Layer::Dielectric { thickness, sigma_a, sigma_s, .. } => interfaces.push(Interface {
                mf: mf.expect("dielectrics have an interface"),
                eta: rel.eta,
                kappa: rel.kappa,
                conductor: false,
                thickness: *thickness,
                sigma_t: sigma_a.iter().zip(sigma_s).map(|(a, s)| a + s).collect(),
            }),
            Layer::Conductor { .. } => interfaces.push(Interface {
                mf: mf.expect("conductors have an interface"),
                eta: rel.eta,
                kappa: rel.kappa,
                conductor: true,
                thickness: 0.0,
                sigma_t: vec![0.0; stack.channels],
            }),
            Layer::Diffuse { albedo, roughness } => diffuse = Some((albedo.clone(), *roughness)),
        }
    }
    tables::fgd(); // generate or load the table outside the parallel evaluation
    Ok(Prepared { interfaces, diffuse, g2: opts.g2, reciprocal: opts.scaling_reciprocal, channels: stack.channels })
}

impl Interface {
    /// Fresnel reflectance of channel c at cosine `cos` (exact dielectric or conductor).
    fn fresnel(&self, cos: f64, c: usize) -> f64 {
        if self.conductor {
            fresnel::conductor(cos, self.eta[c], self.kappa[c])
        } else {
            fresnel::dielectric(cos, self.eta[c])
        }
    }

    /// E(μ): the directional albedo of the interface's lobe (FGD table; the Fresnel reflectance itself when smooth).
    fn albedo(&self, mu: f64, c: usize) -> f64 {
        if self.mf.is_smooth() {
            return self.fresnel(mu, c);
        }
        let alpha = (self.mf.alpha_x * self.mf.alpha_y).sqrt();
        tables::fgd().lookup(mu, alpha, self.eta[c], self.kappa[c])
    }

    /// Beer–Lambert transmittance of the slab beneath, along both refracted directions (Snell at channel c's IOR).
    fn transmittance(&self, wi: DVec3, wo: DVec3, c: usize) -> f64 {
        if self.sigma_t[c] * self.thickness == 0.0 {
            return 1.0;
        }
        let refracted = |w: DVec3| (1.0 - (sin_theta(w) / self.eta[c]).powi(2)).max(1e-18).sqrt();
        (-self.sigma_t[c] * self.thickness * (1.0 / refracted(wi) + 1.0 / refracted(wo))).exp()
    }
}

impl Prepared {
    /// The scale S of what lies beneath interface `i` for channel c.
    fn scale(&self, i: &Interface, wi: DVec3, wo: DVec3, c: usize) -> f64 {
        let view = 1.0 - i.albedo(wo.z, c);
        let light = if self.reciprocal { 1.0 - i.albedo(wi.z, c) } else { 1.0 };
        (light * view).max(0.0) * i.transmittance(wi, wo, c)
    }

    /// f(wi, wo) per channel into `out`; zero below the horizon.
    fn eval(&self, wi: DVec3, wo: DVec3, out: &mut [f64]) {
        out.fill(0.0);
        if wi.z <= 0.0 || wo.z <= 0.0 {
            return;
        }
        let mut weight = vec![1.0; self.channels];
        for i in &self.interfaces {
            if let Some((geo, cos_h)) = bsdf::reflection_geometry(&i.mf, self.g2, wi, wo) {
                for (c, o) in out.iter_mut().enumerate() {
                    *o += weight[c] * geo * i.fresnel(cos_h, c);
                }
            }
            if i.conductor {
                return;
            }
            for (c, w) in weight.iter_mut().enumerate() {
                *w *= self.scale(i, wi, wo, c);
            }
        }
        if let Some((albedo, sigma)) = &self.diffuse {
            let shape = diffuse::oren_nayar_shape(*sigma, wi, wo);
            for (c, o) in out.iter_mut().enumerate() {
                *o += weight[c] * albedo[c] * shape;
            }
        }
    }

    /// Each term's energy at wo (its albedo times the scales above, mean over channels) with its lobe, and the
    /// Dirac reflection of smooth interfaces reached through smooth ones (`mirror`, per channel).
    fn terms(&self, wo: DVec3, mirror: &mut [f64]) -> Vec<(f64, Proposal)> {
        mirror.fill(0.0);
        let mean = |f: &dyn Fn(usize) -> f64| (0..self.channels).map(f).sum::<f64>() / self.channels as f64;
        let mut weight = vec![1.0; self.channels];
        let mut smooth_above = true;
        let mut out = Vec::new();
        for i in &self.interfaces {
            if i.mf.is_smooth() {
                if smooth_above {
                    (0..self.channels).for_each(|c| mirror[c] += weight[c] * i.fresnel(wo.z, c));
                }
            } else {
                out.push((mean(&|c| weight[c] * i.albedo(wo.z, c)), Proposal::Reflection(i.mf)));
                smooth_above = false;
            }
            if i.conductor {
                return out;
            }
            for (c, w) in weight.iter_mut().enumerate() {
                *w *= self.scale(i, wo, wo, c);
            }
        }
        if let Some((albedo, _)) = &self.diffuse {
            out.push((mean(&|c| weight[c] * albedo[c]), Proposal::Cosine));
        }
        out
    }
}

impl Model for Prepared {
    fn eval_block(&self, wi: [&[f64]; 3], wo: [&[f64]; 3], _: &Inputs, out: &mut [f64]) {
        eval_rows(wi, wo, out, |_, wi, wo, o| self.eval(wi, wo, o))
    }

    fn proposals(&self, wo: DVec3) -> Vec<(f64, Proposal)> {
        let mut mirror = vec![0.0; self.channels];
        let mut lobes: Vec<_> = self.terms(wo, &mut mirror).into_iter().filter(|(w, _)| *w > 0.0).collect();
        let total: f64 = lobes.iter().map(|(w, _)| w).sum();
        if total > 0.0 {
            // The lower lobes are evaluated at the outside directions, so the lobes cover f; a small cosine share
            // keeps the pdf positive wherever a grazing lobe's visible normals thin out.
            lobes.push((0.02 * total, Proposal::Cosine));
        }
        lobes
    }

    fn specular(&self, wo: DVec3, out: &mut [f64]) {
        if wo.z > 0.0 {
            self.terms(wo, out);
        } else {
            out.fill(0.0);
        }
    }
}
