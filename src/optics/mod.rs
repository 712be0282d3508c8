//! Optics primitives shared by every model: Fresnel terms, microfacet distributions, diffuse lobes.
//! Conventions (docs/conventions.md): local frame with z = normal, directions point away from the surface.

pub mod diffuse;
pub mod distribution;
pub mod fresnel;
pub mod jacobian;
pub mod lanes;

use crate::dual::{dir, dot, value, Dir, Real};
use glam::DVec3;

/// cos θ of a unit direction in the local frame.
#[inline]
pub fn cos_theta(w: DVec3) -> f64 {
    w.z
}

/// sin θ of a unit direction in the local frame, from its tangent components (√(x² + y²): a unit direction cannot
/// overflow, so no `hypot`, which is slow); in f64 or in Duals.
#[inline(always)]
pub fn sin_theta<T: Real>(w: impl Into<Dir<T>>) -> T {
    let [x, y, _] = w.into();
    (x * x + y * y).sqrt()
}

/// Mirror reflection of `w` about the normal `n` (both unit, pointing away from the surface).
#[inline]
pub fn reflect(w: DVec3, n: DVec3) -> DVec3 {
    value(reflect_about(w, dir::<f64>(n)))
}

/// `reflect` about a normal in Reals (one that a parameter moves).
#[inline(always)]
pub fn reflect_about<T: Real>(w: DVec3, n: Dir<T>) -> Dir<T> {
    let d = dot(dir(w), n) * 2.0;
    [d * n[0] - w.x, d * n[1] - w.y, d * n[2] - w.z]
}

/// Refraction of `w` through a surface with normal `n` and relative IOR `eta` = η_transmitted / η_incident
/// (Snell's law); `None` under total internal reflection. `w` and `n` lie on the same side.
#[inline]
pub fn refract(w: DVec3, n: DVec3, eta: f64) -> Option<DVec3> {
    refract_about(w, dir::<f64>(n), eta).map(value)
}

/// `refract` through a normal and an IOR in Reals (that parameters move).
#[inline(always)]
pub fn refract_about<T: Real>(w: DVec3, n: Dir<T>, eta: T) -> Option<Dir<T>> {
    let cos_i = dot(dir(w), n);
    let sin2_t = (T::from(1.0) - cos_i * cos_i).max_c(0.0) / (eta * eta);
    if sin2_t.value() >= 1.0 {
        return None;
    }
    let cos_t = (T::from(1.0) - sin2_t).sqrt();
    let k = cos_i / eta - cos_t;
    Some([T::from(-w.x) / eta + k * n[0], T::from(-w.y) / eta + k * n[1], T::from(-w.z) / eta + k * n[2]])
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
