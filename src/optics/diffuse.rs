//! Diffuse lobes: Lambert and the qualitative Oren–Nayar model.

use crate::dual::{Dir, Real, With};
use glam::DVec3;
use std::f64::consts::FRAC_1_PI;

/// Lambertian BRDF ρ/π for directions above the horizon.
pub fn lambert(albedo: f64, wi: DVec3, wo: DVec3) -> f64 {
    if wi.z <= 0.0 || wo.z <= 0.0 {
        return 0.0;
    }
    albedo * FRAC_1_PI
}

/// Qualitative Oren–Nayar 1994 BRDF (eq. 30, the form pbrt and Elek 2010 use):
/// ρ/π [A + B max(0, cos(φi − φo)) sin α tan β], α = max(θi, θo), β = min(θi, θo),
/// A = 1 − 0.5σ²/(σ² + 0.33), B = 0.45σ²/(σ² + 0.09); σ is the facet-slope standard deviation in radians.
pub fn oren_nayar(albedo: f64, sigma: f64, wi: DVec3, wo: DVec3) -> f64 {
    albedo * oren_nayar_shape(sigma, wi, wo)
}

/// The Oren–Nayar BRDF per unit albedo, f/ρ (shared by all colour channels). σ is f64 or a Dual; the directions
/// too, where a parameter moves them (below a coat).
pub fn oren_nayar_shape<T, C>(sigma: T, wi: impl Into<Dir<C>>, wo: impl Into<Dir<C>>) -> T
where
    C: Real,
    T: With<C>,
{
    let (wi, wo) = (wi.into(), wo.into());
    if wi[2].value() <= 0.0 || wo[2].value() <= 0.0 {
        return T::from(0.0);
    }
    if sigma.value() == 0.0 {
        return T::from(FRAC_1_PI);
    }
    let s2 = sigma * sigma;
    let a = T::from(1.0) - s2 * 0.5 / (s2 + 0.33);
    let b = s2 * 0.45 / (s2 + 0.09);
    let sin_i = (C::from(1.0) - wi[2] * wi[2]).max_c(0.0).sqrt();
    let sin_o = (C::from(1.0) - wo[2] * wo[2]).max_c(0.0).sqrt();
    let cos_dphi = if sin_i.value() > 1e-12 && sin_o.value() > 1e-12 {
        ((wi[0] * wo[0] + wi[1] * wo[1]) / (sin_i * sin_o)).clamp_c(-1.0, 1.0)
    } else {
        C::from(0.0)
    };
    // sin α tan β with α the larger zenith angle, β the smaller one; tan β grows without bound as both directions
    // graze, so its cosine is kept ≥ 1e-12 (f stays finite; unchanged above 1e-12).
    let larger = if wo[2].value() > wi[2].value() { wo[2] } else { wi[2] };
    let sin_alpha_tan_beta = sin_i * sin_o / larger.max_c(1e-12);
    (a + b * cos_dphi.max_c(0.0) * sin_alpha_tan_beta) * FRAC_1_PI
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn oren_nayar_reduces_to_lambert_and_is_reciprocal() {
        let wi = DVec3::new(0.5, 0.2, 0.8426149773176359);
        let wo = DVec3::new(0.3, -0.6, 0.7416198487095663);
        assert!((oren_nayar(0.7, 0.0, wi, wo) - lambert(0.7, wi, wo)).abs() < 1e-15);
        assert!((oren_nayar(0.7, 0.5, wi, wo) - oren_nayar(0.7, 0.5, wo, wi)).abs() < 1e-15);
    }
}
