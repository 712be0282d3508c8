//! Optics primitives shared by every model: Fresnel terms, microfacet distributions, diffuse lobes.
//! Conventions (docs/conventions.md): local frame with z = normal, directions point away from the surface.

pub mod diffuse;
pub mod distribution;
pub mod fresnel;
pub mod jacobian;
pub mod lanes;

use glam::DVec3;

/// cos θ of a unit direction in the local frame.
#[inline]
pub fn cos_theta(w: DVec3) -> f64 {
    w.z
}

/// sin θ of a unit direction in the local frame, from its tangent components (√(x² + y²): a unit direction cannot
/// overflow, so no `hypot`, which is slow).
#[inline(always)]
pub fn sin_theta(w: DVec3) -> f64 {
    (w.x * w.x + w.y * w.y).sqrt()
}

/// Mirror reflection of `w` about the normal `n` (both unit, pointing away from the surface).
#[inline]
pub fn reflect(w: DVec3, n: DVec3) -> DVec3 {
    2.0 * w.dot(n) * n - w
}

/// Refraction of `w` through a surface with normal `n` and relative IOR `eta` = η_transmitted / η_incident
/// (Snell's law); `None` under total internal reflection. `w` and `n` lie on the same side.
#[inline]
pub fn refract(w: DVec3, n: DVec3, eta: f64) -> Option<DVec3> {
    let cos_i = w.dot(n);
    let sin2_t = (1.0 - cos_i * cos_i).max(0.0) / (eta * eta);
    if sin2_t >= 1.0 {
        return None;
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    Some(-w / eta + (cos_i / eta - cos_t) * n)
}

/// Rotates a local direction about the normal by -`angle` given (cos angle, sin angle): world tangent frame to
/// a layer's tangent frame rotated by `angle`.
#[inline]
pub fn to_tangent_frame(w: DVec3, cos_phi: f64, sin_phi: f64) -> DVec3 {
    DVec3::new(cos_phi * w.x + sin_phi * w.y, -sin_phi * w.x + cos_phi * w.y, w.z)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn refraction_obeys_snell() {
        let w = DVec3::new(0.6, 0.0, 0.8);
        let t = refract(w, DVec3::Z, 1.5).unwrap();
        assert!((t.length() - 1.0).abs() < 1e-12);
        assert!((0.6 - 1.5 * (-t.x)).abs() < 1e-12, "sin θi = η sin θt");
        assert!(t.z < 0.0);
        assert!(refract(DVec3::new(0.9, 0.0, (1.0f64 - 0.81).sqrt()), DVec3::Z, 1.0 / 1.5).is_none());
    }
}
