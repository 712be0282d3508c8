//! `model="microfacet"`: exact evaluation of the stacks that have a closed form — a single opaque interface
//! (rough conductor, Lambert, Oren–Nayar) and a smooth dielectric coat over a Lambertian base.

use super::Options;
use crate::bsdf;
use crate::optics::diffuse;
use crate::optics::fresnel::{self, FresnelForm};
use crate::optics::microfacet::{G2Form, Microfacet};
use crate::stack::{value_error, Layer, Result, Stack};
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

pub fn prepare(stack: &Stack, opts: &Options) -> Result<Prepared> {
    let rel = |v: &[f64]| v.iter().map(|x| x / stack.ext_ior).collect::<Vec<f64>>();
    match stack.layers.as_slice() {
        [layer @ Layer::Conductor { ior, k, .. }] => Ok(Prepared::Conductor {
            mf: layer.microfacet(opts.distribution).expect("conductors have an interface"),
            g2: opts.g2,
            fresnel: opts.fresnel,
            eta: rel(ior),
            k: rel(k),
        }),
        [Layer::Diffuse { albedo, roughness }] => Ok(Prepared::Diffuse { albedo: albedo.clone(), sigma: *roughness }),
        [Layer::Dielectric { ior, alpha: (ax, ay), thickness, sigma_a, sigma_s, .. }, Layer::Diffuse { albedo, roughness }]
            if *ax == 0.0
                && *ay == 0.0
                && *roughness == 0.0
                && (*thickness == 0.0 || sigma_a.iter().chain(sigma_s).all(|&s| s == 0.0)) =>
        {
            let eta = rel(ior);
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
    pub fn eval(&self, wi: DVec3, wo: DVec3, out: &mut [f64]) {
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

/// Smooth dielectric coat over a Lambertian base, off the specular direction (the sum of all internal bounces;
/// Mitsuba's `plastic` with nonlinear = true, Weidlich–Wilkie 2007 §3):
/// f = ρ (1 − F(θi)) (1 − F(θo)) / (π η² (1 − ρ F̄_int)), F̄_int the hemispherical Fresnel reflectance from inside.
pub fn smooth_coat_lambert(albedo: f64, eta: f64, f_int: f64, cos_i: f64, cos_o: f64) -> f64 {
    let t = (1.0 - fresnel::dielectric(cos_i, eta)) * (1.0 - fresnel::dielectric(cos_o, eta));
    albedo * t * FRAC_1_PI / (eta * eta * (1.0 - albedo * f_int))
}
