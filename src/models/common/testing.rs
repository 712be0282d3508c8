//! What the models' unit tests share: layers, directions, one evaluation, and a hemispherical quadrature.

use crate::models::{eval_one, Args, Model, ModelInfo, Value};
use crate::quadrature::gauss_legendre;
use crate::stack::{Layer, Stack};
use glam::DVec3;
use std::f64::consts::TAU;

/// A one-channel dielectric layer.
pub fn dielectric(ior: f64, alpha: f64, thickness: f64, sigma_a: f64, sigma_s: f64) -> Layer {
    Layer::Dielectric {
        ior: vec![ior],
        alpha: (alpha, alpha),
        angle: 0.0,
        thickness,
        sigma_a: vec![sigma_a],
        sigma_s: vec![sigma_s],
        g: 0.3,
    }
}

/// A one-channel conductor of roughness (αx, αy).
pub fn conductor(ior: f64, k: f64, alpha: (f64, f64)) -> Layer {
    Layer::Conductor { ior: vec![ior], k: vec![k], alpha, angle: 0.0 }
}

/// A one-channel Lambertian base.
pub fn lambert(albedo: f64) -> Layer {
    Layer::Diffuse { albedo: vec![albedo], roughness: 0.0 }
}

/// A stack in air.
pub fn stack(layers: Vec<Layer>) -> Stack {
    Stack::new(layers, 1.0).unwrap()
}

/// The direction at zenith θ and azimuth φ (degrees).
pub fn dir(theta: f64, phi: f64) -> DVec3 {
    let (t, p) = (theta.to_radians(), phi.to_radians());
    DVec3::new(t.sin() * p.cos(), t.sin() * p.sin(), t.cos())
}

/// f(wi, wo) of every channel.
pub fn f(model: &dyn Model, wi: DVec3, wo: DVec3, channels: usize) -> Vec<f64> {
    let mut out = vec![0.0; channels];
    eval_one(model, wi, wo, &[], &mut out);
    out
}

/// ∫ g(w) cos θ dω over the upper hemisphere: Gauss–Legendre in cos θ (`n` nodes) by `n_phi` midpoints in φ.
pub fn hemisphere(n: usize, n_phi: usize, g: impl Fn(DVec3) -> f64) -> f64 {
    let mut sum = 0.0;
    for (x, w) in gauss_legendre(n) {
        let mu: f64 = 0.5 * (x + 1.0);
        let s = (1.0 - mu * mu).sqrt();
        for p in 0..n_phi {
            let phi = (p as f64 + 0.5) * TAU / n_phi as f64;
            sum += 0.5 * w * mu * g(DVec3::new(s * phi.cos(), s * phi.sin(), mu)) * TAU / n_phi as f64;
        }
    }
    sum
}

/// A model's options from its table, with the values given by name.
pub fn args(info: &ModelInfo, given: &[(&str, Value)]) -> Args {
    let given: Vec<(String, Value)> = given.iter().map(|(k, v)| (k.to_string(), v.clone())).collect();
    Args::parse(info, &given).unwrap()
}

/// The one-channel stack of channel `c` of `stack`'s optical constants (its geometry is every channel's).
pub fn channel(stack: &Stack, c: usize) -> Stack {
    let one = |v: &[f64]| vec![v[c]];
    let layers = stack
        .layers
        .iter()
        .map(|layer| match layer {
            Layer::Dielectric { ior, alpha, angle, thickness, sigma_a, sigma_s, g } => Layer::Dielectric {
                ior: one(ior),
                alpha: *alpha,
                angle: *angle,
                thickness: *thickness,
                sigma_a: one(sigma_a),
                sigma_s: one(sigma_s),
                g: *g,
            },
            Layer::Conductor { ior, k, alpha, angle } => {
                Layer::Conductor { ior: one(ior), k: one(k), alpha: *alpha, angle: *angle }
            }
            Layer::Diffuse { albedo, roughness } => Layer::Diffuse { albedo: one(albedo), roughness: *roughness },
        })
        .collect();
    Stack::new(layers, stack.ext_ior).unwrap()
}
