//! `model="microfacet"`: exact evaluation of the stacks that have a closed form — a single opaque interface
//! (rough conductor, Lambert, Oren–Nayar) and a smooth dielectric coat over a Lambertian base.

use super::Options;
use crate::bsdf;
use crate::optics::diffuse;
use crate::optics::fresnel;
use crate::stack::{value_error, Layer, Result, Stack};
use glam::DVec3;
use std::f64::consts::FRAC_1_PI;

pub fn check(stack: &Stack) -> Result<()> {
    match stack.layers.as_slice() {
        [_] => Ok(()),
        [Layer::Dielectric { alpha: (ax, ay), thickness, sigma_a, sigma_s, .. }, Layer::Diffuse { roughness, .. }]
            if *ax == 0.0 && *ay == 0.0 && *roughness == 0.0
                && (*thickness == 0.0 || sigma_a.iter().chain(sigma_s).all(|&s| s == 0.0)) => Ok(()),
        _ => value_error(
            "model 'microfacet' evaluates a single opaque interface or a smooth non-absorbing coat over a \
             Lambertian base exactly; this stack needs a layered model",
        ),
    }
}

pub fn eval(stack: &Stack, opts: &Options, wi: DVec3, wo: DVec3, out: &mut [f64]) {
    out.fill(0.0);
    if wi.z <= 0.0 || wo.z <= 0.0 {
        return;
    }
    match stack.layers.as_slice() {
        [layer @ Layer::Conductor { ior, k, .. }] => {
            let mf = layer.microfacet(opts.distribution).unwrap();
            if let Some((geo, cos_h)) = bsdf::reflection_geometry(&mf, opts.g2, wi, wo) {
                for (c, o) in out.iter_mut().enumerate() {
                    let (eta, kappa) = (ior[c] / stack.ext_ior, k[c] / stack.ext_ior);
                    *o = geo * opts.fresnel.conductor(cos_h, eta, kappa);
                }
            }
        }
        [Layer::Diffuse { albedo, roughness }] => {
            for (o, &rho) in out.iter_mut().zip(albedo) {
                *o = diffuse::oren_nayar(rho, *roughness, wi, wo);
            }
        }
        [Layer::Dielectric { ior, .. }, Layer::Diffuse { albedo, .. }] => {
            for c in 0..out.len() {
                out[c] = smooth_coat_lambert(albedo[c], ior[c] / stack.ext_ior, wi.z, wo.z);
            }
        }
        _ => unreachable!("checked by check()"),
    }
}

/// Smooth dielectric coat over a Lambertian base, off the specular direction (the sum of all internal bounces;
/// Mitsuba's `plastic` with nonlinear = true, Weidlich–Wilkie 2007 §3):
/// f = ρ (1 − F(θi)) (1 − F(θo)) / (π η² (1 − ρ F̄_int)), F̄_int the hemispherical Fresnel reflectance from inside.
pub fn smooth_coat_lambert(albedo: f64, eta: f64, cos_i: f64, cos_o: f64) -> f64 {
    let f_int = fresnel::diffuse_reflectance(1.0 / eta);
    let t = (1.0 - fresnel::dielectric(cos_i, eta)) * (1.0 - fresnel::dielectric(cos_o, eta));
    albedo * t * FRAC_1_PI / (eta * eta * (1.0 - albedo * f_int))
}
