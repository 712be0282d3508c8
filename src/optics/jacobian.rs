//! Jacobians of the projected-direction maps of Belcour 2018 / Yamaguchi et al. 2019: how the projected outgoing
//! direction (x, y) moves with the projected microfacet normal (xh, yh), for light incident from wi = (sin θi, 0,
//! cos θi). Derived by the chain rule from ωo = 2(ωi·h)h − ωi (reflection) and ωt = −ωi/η + ((ωi·h)/η − cos θt)h
//! (refraction), with h = (xh, yh, √(1 − xh² − yh²)).

use crate::dual::Real;
use glam::DVec3;

fn incident(theta_i: f64) -> DVec3 {
    DVec3::new(theta_i.sin(), 0.0, theta_i.cos())
}

/// h and the derivatives of d = ωi·h with respect to (xh, yh).
fn half_vector(wi: DVec3, xh: f64, yh: f64) -> (DVec3, f64, [f64; 2]) {
    let zh = (1.0 - xh * xh - yh * yh).max(0.0).sqrt();
    let h = DVec3::new(xh, yh, zh);
    (h, wi.dot(h), [wi.x - wi.z * xh / zh, wi.y - wi.z * yh / zh])
}

/// Exact J_r = ∂(xo, yo)/∂(xh, yh) of mirror reflection about h (rows: xo, yo; columns: xh, yh).
pub fn reflect(theta_i: f64, xh: f64, yh: f64) -> [[f64; 2]; 2] {
    let (h, d, dd) = half_vector(incident(theta_i), xh, yh);
    [[2.0 * (dd[0] * h.x + d), 2.0 * dd[1] * h.x], [2.0 * dd[0] * h.y, 2.0 * (dd[1] * h.y + d)]]
}

/// Exact J_t = ∂(xt, yt)/∂(xh, yh) of refraction through h with relative IOR η; None under total internal reflection.
pub fn refract(theta_i: f64, eta: f64, xh: f64, yh: f64) -> Option<[[f64; 2]; 2]> {
    let (h, d, dd) = half_vector(incident(theta_i), xh, yh);
    let sin2_t = (1.0 - d * d) / (eta * eta);
    if sin2_t >= 1.0 {
        return None;
    }
    let ct = (1.0 - sin2_t).sqrt();
    let a = d / eta - ct; // the coefficient of h in ωt
    let da = 1.0 / eta - d / (eta * eta * ct); // ∂a/∂d
    Some([[da * dd[0] * h.x + a, da * dd[1] * h.x], [da * dd[0] * h.y, da * dd[1] * h.y + a]])
}

/// The scale of J_r at h = n (Belcour 2018, first order): J_r = 2 cos θi I.
pub fn reflection_scale<T: Real>(cos_i: T) -> T {
    cos_i * 2.0
}

/// The scale of J_t at h = n (Belcour 2018, first order): J_t = ((cos θi − η cos θt)/η) I, cos θt from Snell's law;
/// None under total internal reflection.
pub fn refraction_scale<T: Real>(cos_i: T, eta: T) -> Option<T> {
    let one = T::from(1.0);
    let sin2_t = (one - cos_i * cos_i) / (eta * eta);
    (sin2_t.value() < 1.0).then(|| (cos_i - eta * (one - sin2_t).sqrt()) / eta)
}

/// First-order form at h = n (Belcour 2018): J_r ≈ 2 cos θi I.
pub fn reflect_first_order(theta_i: f64) -> [[f64; 2]; 2] {
    let c = reflection_scale(theta_i.cos());
    [[c, 0.0], [0.0, c]]
}

/// First-order form at h = n (Belcour 2018): J_t ≈ ((cos θi − η cos θt)/η) I; None under total internal reflection.
pub fn refract_first_order(theta_i: f64, eta: f64) -> Option<[[f64; 2]; 2]> {
    refraction_scale(theta_i.cos(), eta).map(|c| [[c, 0.0], [0.0, c]])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exact_jacobians_equal_first_order_forms_at_the_normal() {
        for t in [0.0, 0.4, 1.2] {
            assert_eq!(reflect(t, 0.0, 0.0), reflect_first_order(t));
            let (a, b) = (refract(t, 1.5, 0.0, 0.0).unwrap(), refract_first_order(t, 1.5).unwrap());
            for r in 0..2 {
                for c in 0..2 {
                    assert!((a[r][c] - b[r][c]).abs() < 1e-14);
                }
            }
        }
        assert!(refract(1.2, 0.6, 0.0, 0.0).is_none(), "sin θi / η > 1: total internal reflection");
    }

    #[test]
    fn jacobian_ratio_at_the_mean_is_belcours_transmission_scale() {
        // Belcour 2018's s with real cosines: |η cos θt − cos θi| / (2η cos θt) down, |cos θi/η − cos θt| /
        // (2 cos θi/η) up.
        for (t, eta) in [(0.0, 1.5), (0.7, 1.5), (1.4, 1.33), (1.2, 2.4)] {
            let (ci, ct) = (f64::cos(t), (1.0 - f64::sin(t).powi(2) / (eta * eta)).sqrt());
            let down = refraction_scale(ci, eta).unwrap().abs() / reflection_scale(ct);
            let up = refraction_scale(ct, 1.0 / eta).unwrap().abs() / reflection_scale(ci);
            assert!((down - 0.5 * (eta * ct - ci).abs() / (eta * ct)).abs() < 1e-14, "{t} {eta}");
            assert!((up - 0.5 * (ci / eta - ct).abs() / (ci / eta)).abs() < 1e-14, "{t} {eta}");
        }
    }
}
