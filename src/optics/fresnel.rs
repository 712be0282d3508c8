//! Fresnel reflectance: exact dielectric and conductor, Schlick, Lazányi–Szirmay-Kalos, and the
//! hemispherical (diffuse) Fresnel reflectance.

use crate::dual::Real;
use std::ops::{Add, Mul, Sub};

/// The cosines of a refraction by Snell's law: (|cos_i| clamped to 1, the relative IOR seen from the incident side,
/// cos_t), the IOR inverted for incidence from inside (cos_i < 0); None under total internal reflection. The cosine
/// and the IOR are f64 or Duals (their gradients).
#[inline(always)]
fn refraction_cosines<T: Real>(cos_i: T, eta: T) -> Option<(T, T, T)> {
    let (cos_i, eta) = if cos_i.value() < 0.0 { (-cos_i, T::from(1.0) / eta) } else { (cos_i, eta) };
    let cos_i = if cos_i.value() > 1.0 { T::from(1.0) } else { cos_i };
    let sin2_t = (T::from(1.0) - cos_i * cos_i) / (eta * eta);
    (sin2_t.value() < 1.0).then(|| (cos_i, eta, (T::from(1.0) - sin2_t).sqrt()))
}

/// Exact unpolarized dielectric Fresnel reflectance (Born & Wolf §1.5). `cos_i` is the cosine of the incident
/// direction with the normal on the side of the incidence; a negative `cos_i` means incidence from inside, where
/// the relative IOR becomes 1/`eta`. `eta` = η_inside / η_outside. Returns 1 under total internal reflection.
#[inline(always)]
pub fn dielectric<C: Real, T: Real + From<C>>(cos_i: C, eta: T) -> T {
    let Some((cos_i, eta, cos_t)) = refraction_cosines(T::from(cos_i), eta) else { return T::from(1.0) };
    let r_s = (cos_i - eta * cos_t) / (eta * cos_t + cos_i);
    let r_p = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    (r_s * r_s + r_p * r_p) * 0.5
}

/// Transmittance 1 − F of `dielectric`, in a form without cancellation near grazing incidence (where F → 1):
/// 1 − r² = (1 − r)(1 + r) for each polarization, T_s = 4η cos_i cos_t / (cos_i + η cos_t)²,
/// T_p = 4η cos_i cos_t / (η cos_i + cos_t)². 0 under total internal reflection.
#[inline(always)]
pub fn dielectric_transmittance<C: Real, T: Real + From<C>>(cos_i: C, eta: T) -> T {
    let Some((cos_i, eta, cos_t)) = refraction_cosines(T::from(cos_i), eta) else { return T::from(0.0) };
    let (s, p) = (eta * cos_t + cos_i, eta * cos_i + cos_t);
    eta * 2.0 * cos_i * cos_t * (T::from(1.0) / (s * s) + T::from(1.0) / (p * p))
}

/// Exact unpolarized conductor Fresnel reflectance for the relative complex IOR `eta` + i`k`
/// (closed form of the Fresnel equations, e.g. Lagarde 2013 / Born & Wolf §14.2). `cos_i` in [0, 1]. The cosine
/// and the IOR are each f64 or Dual: a microfacet's cosine carries no derivative, Belcour's mean cosine does.
#[inline(always)]
pub fn conductor<C: Real, T: Real + Add<C, Output = T> + Sub<C, Output = T> + Mul<C, Output = T>>(
    cos_i: C,
    eta: T,
    k: T,
) -> T {
    let cos_i = cos_i.clamp_c(0.0, 1.0);
    let cos2 = cos_i * cos_i;
    let sin2 = C::from(1.0) - cos2;
    let t0 = eta * eta - k * k - sin2;
    let a2b2 = (t0 * t0 + T::from(4.0) * eta * eta * k * k).sqrt();
    // a² = (a2b2 + t0)/2, written as 2η²κ²/(a2b2 − t0) for t0 < 0 (total internal reflection when κ → 0), where the
    // sum cancels: in float32 it loses F − 1 entirely for κ ≈ 1e-5.
    let a = if t0.value() >= 0.0 { (a2b2 + t0) * 0.5 } else { T::from(2.0) * eta * eta * k * k / (a2b2 - t0) }.sqrt();
    // Both ratios are ((a ∓ cos)² + b²)-like, ≥ 0: clamped so that rounding (e.g. η = 1, κ = 0, where F = 0) cannot
    // make them negative; a vanishing denominator (grazing incidence on η = 1, κ = 0) is the grazing limit 1.
    let den_s = a2b2 + a * 2.0 * cos_i + cos2;
    let r_s = if den_s.value() > 0.0 { ((a2b2 - a * 2.0 * cos_i + cos2) / den_s).max_c(0.0) } else { T::from(1.0) };
    let num = a2b2 * cos2 - a * 2.0 * cos_i * sin2 + sin2 * sin2;
    let den = a2b2 * cos2 + a * 2.0 * cos_i * sin2 + sin2 * sin2;
    let r_p = if den.value() > 0.0 { (r_s * num / den).max_c(0.0) } else { r_s };
    (r_s + r_p) * 0.5
}

/// Reflectance at normal incidence of a relative complex IOR `eta` + i`k`.
#[inline(always)]
pub fn f0(eta: f64, k: f64) -> f64 {
    ((eta - 1.0).powi(2) + k * k) / ((eta + 1.0).powi(2) + k * k)
}

/// Schlick 1994 approximation F0 + (1 − F0)(1 − cos θ)^5.
#[inline(always)]
pub fn schlick(cos_i: f64, f0: f64) -> f64 {
    f0 + (1.0 - f0) * (1.0 - cos_i.clamp(0.0, 1.0)).powi(5)
}

/// Lazányi & Szirmay-Kalos 2005, "Fresnel term approximations for metals" (the rescaled Schlick form used by
/// Elek 2010): [(η−1)² + 4η(1−cos θ)^5 + κ²] / [(η+1)² + κ²], at most 1 (it is 1 at grazing incidence, where
/// rounding could otherwise exceed it and make 1 − F negative).
#[inline(always)]
pub fn lazanyi(cos_i: f64, eta: f64, k: f64) -> f64 {
    let m = (1.0 - cos_i.clamp(0.0, 1.0)).powi(5);
    (((eta - 1.0).powi(2) + 4.0 * eta * m + k * k) / ((eta + 1.0).powi(2) + k * k)).min(1.0)
}

/// 1 − (1 − cos θ)^5 without cancellation near grazing incidence: with x = 1 − cos θ, cos θ (1 + x + x² + x³ + x⁴).
#[inline(always)]
fn one_minus_pow5(cos_i: f64) -> f64 {
    let c = cos_i.clamp(0.0, 1.0);
    let x = 1.0 - c;
    c * (1.0 + x * (1.0 + x * (1.0 + x * (1.0 + x))))
}

/// Transmittance 1 − F of `schlick`: (1 − F0)(1 − (1 − cos θ)^5), without cancellation at grazing incidence.
#[inline(always)]
pub fn schlick_transmittance(cos_i: f64, f0: f64) -> f64 {
    (1.0 - f0) * one_minus_pow5(cos_i)
}

/// Transmittance 1 − F of `lazanyi`: 4η(1 − (1 − cos θ)^5) / [(η+1)² + κ²], at least 0, without cancellation at
/// grazing incidence.
#[inline(always)]
pub fn lazanyi_transmittance(cos_i: f64, eta: f64, k: f64) -> f64 {
    (4.0 * eta * one_minus_pow5(cos_i) / ((eta + 1.0).powi(2) + k * k)).max(0.0)
}

/// Hemispherical (cosine-weighted) average of the dielectric Fresnel reflectance for light incident from the
/// side with relative IOR `eta`: F̄ = 2 ∫₀¹ F(μ, eta) μ dμ. For eta > 1 the integrand is smooth (Gauss–Legendre,
/// ~1e-12); for eta < 1 energy balance across the interface (Snell: η_i² μ dμ = η_t² μ_t dμ_t) gives exactly
/// F̄(eta) = 1 − eta² (1 − F̄(1/eta)), which avoids the √-kink at the critical angle.
pub fn diffuse_reflectance<T: Real>(eta: T) -> T {
    let one = T::from(1.0);
    if eta.value() < 1.0 {
        return one - eta * eta * (one - diffuse_reflectance(one / eta));
    }
    crate::quadrature::integrate(|mu: T| mu * 2.0 * dielectric(mu.value(), eta), T::from(0.0), one, 8)
}

/// Which Fresnel term a model uses for conductors.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FresnelForm {
    Exact,
    Schlick,
    Lazanyi,
}

impl std::str::FromStr for FresnelForm {
    type Err = crate::error::Error;
    fn from_str(s: &str) -> crate::error::Result<Self> {
        crate::error::parse_choice("fresnel", s, &Self::NAMES, &Self::ALL)
    }
}

impl FresnelForm {
    /// The names `from_str` reads, in the order of `ALL`.
    pub const NAMES: [&'static str; 3] = ["exact", "schlick", "lazanyi"];
    pub const ALL: [FresnelForm; 3] = [FresnelForm::Exact, FresnelForm::Schlick, FresnelForm::Lazanyi];

    /// Conductor reflectance of η + iκ in the chosen form.
    pub fn conductor(self, cos_i: f64, eta: f64, k: f64) -> f64 {
        match self {
            FresnelForm::Exact => conductor(cos_i, eta, k),
            FresnelForm::Schlick => schlick(cos_i, f0(eta, k)),
            FresnelForm::Lazanyi => lazanyi(cos_i, eta, k),
        }
    }

    /// Dielectric reflectance of relative IOR η in the chosen form; the approximations (κ = 0) apply for η ≥ 1
    /// only, the exact form (with total internal reflection) is used for η < 1.
    pub fn dielectric(self, cos_i: f64, eta: f64) -> f64 {
        match self {
            FresnelForm::Exact => dielectric(cos_i, eta),
            _ if eta < 1.0 => dielectric(cos_i, eta),
            form => form.conductor(cos_i, eta, 0.0),
        }
    }

    /// Transmittance 1 − `dielectric` in the chosen form, without cancellation at grazing incidence.
    pub fn dielectric_transmittance(self, cos_i: f64, eta: f64) -> f64 {
        match self {
            FresnelForm::Exact => dielectric_transmittance(cos_i, eta),
            _ if eta < 1.0 => dielectric_transmittance(cos_i, eta),
            FresnelForm::Schlick => schlick_transmittance(cos_i, f0(eta, 0.0)),
            FresnelForm::Lazanyi => lazanyi_transmittance(cos_i, eta, 0.0),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn transmittance_is_one_minus_reflectance() {
        for eta in [0.5, 1.0 / 1.5, 1.0, 1.33, 1.5, 2.4] {
            for k in 0..=200 {
                let cos_i = -1.0 + 2.0 * k as f64 / 200.0;
                let (t, r) = (dielectric_transmittance(cos_i, eta), dielectric(cos_i, eta));
                assert!((t - (1.0 - r)).abs() < 1e-14, "eta {eta} cos {cos_i}: {t} vs 1 - {r}");
            }
        }
        // Every form's transmittance is 1 − F, and at grazing incidence it is 5 (1 − F0) cos θ to first order (Schlick;
        // Lazányi 20η cos θ / (η+1)²), which 1 − F in float32 would lose entirely.
        for form in [FresnelForm::Exact, FresnelForm::Schlick, FresnelForm::Lazanyi] {
            for eta in [0.5, 1.33, 1.5, 2.4] {
                for k in 0..=100 {
                    let cos_i = k as f64 / 100.0;
                    let (t, r) = (form.dielectric_transmittance(cos_i, eta), form.dielectric(cos_i, eta));
                    assert!((t - (1.0 - r)).abs() < 1e-14, "{form:?} eta {eta} cos {cos_i}: {t} vs 1 - {r}");
                }
            }
        }
        let c = 1e-9;
        assert!((schlick_transmittance(c, 0.04) / (5.0 * 0.96 * c) - 1.0).abs() < 1e-8);
        assert!((lazanyi_transmittance(c, 1.5, 0.0) / (20.0 * 1.5 * c / 6.25) - 1.0).abs() < 1e-8);
    }

    #[test]
    fn dielectric_limits() {
        assert!((dielectric(1.0, 1.5) - 0.04).abs() < 1e-12);
        assert!((dielectric(0.0, 1.5) - 1.0).abs() < 1e-12);
        assert_eq!(dielectric(0.3, 1.0 / 1.5), 1.0, "beyond the critical angle");
        assert_eq!(dielectric(-0.3, 1.5), 1.0, "negative cosine means incidence from inside");
        assert!((dielectric(0.7, 1.5) - dielectric(-0.7, 1.0 / 1.5)).abs() < 1e-15);
    }

    #[test]
    fn conductor_reduces_to_dielectric_without_absorption() {
        for i in 0..=20 {
            let mu = i as f64 / 20.0;
            assert!((conductor(mu, 1.7, 0.0) - dielectric(mu, 1.7)).abs() < 1e-12, "mu = {mu}");
        }
        assert!((conductor(1.0, 0.2, 3.0) - f0(0.2, 3.0)).abs() < 1e-12);
        assert!((conductor(0.0, 0.2, 3.0) - 1.0).abs() < 1e-12);
    }

    #[test]
    fn approximations_are_exact_at_normal_incidence() {
        assert!((lazanyi(1.0, 0.35, 2.7) - f0(0.35, 2.7)).abs() < 1e-15);
        assert!((schlick(0.0, 0.04) - 1.0).abs() < 1e-15);
    }

    #[test]
    fn diffuse_reflectance_known_values() {
        // Brute-force midpoint sums (2e6 points) on both sides of a glass interface.
        for eta in [1.5, 1.0 / 1.5, 1.1, 0.4] {
            let n = 2_000_000;
            let brute: f64 =
                (0..n).map(|i| (i as f64 + 0.5) / n as f64).map(|mu| 2.0 * mu * dielectric(mu, eta)).sum::<f64>()
                    / n as f64;
            assert!(
                (diffuse_reflectance(eta) - brute).abs() < 1e-8,
                "eta {eta}: {} vs {brute}",
                diffuse_reflectance(eta)
            );
        }
    }
}
