//! Covariances in the projected disc (Yamaguchi et al. 2019) and Belcour 2018's roughness and scattering maps.

use crate::dual::Real;

/// Belcour 2018 roughness-to-variance map h(α) = α^1.1 / (1 − α^1.1) (the reference code's fit).
pub fn variance_from_alpha<T: Real>(alpha: T) -> T {
    let a = alpha.clamp_c(0.0, 0.9999).powf(1.1);
    a / (T::from(1.0) - a)
}

/// Inverse of `variance_from_alpha`: α = (v / (1 + v))^(1/1.1).
pub fn alpha_from_variance<T: Real>(v: T) -> T {
    let v = v.max_c(0.0);
    (v / (v + 1.0)).powf(1.0 / 1.1)
}

/// Variance of Henyey–Greenstein forward scattering in the projected disc, ((1 − g)/g)^0.8 / (1 + g) (Belcour 2018
/// reference code), with g clamped to [0.01, 0.99].
pub fn hg_variance<T: Real>(g: T) -> T {
    let g = g.clamp_c(0.01, 0.99);
    ((T::from(1.0) - g) / g).powf(0.8) / (g + 1.0)
}

/// A symmetric 2x2 covariance of directions projected on the tangent plane (Yamaguchi et al. 2019 §4), in the local
/// tangent frame; in f64, or in Duals for parameter gradients.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Cov<T = f64> {
    pub xx: T,
    pub xy: T,
    pub yy: T,
}

impl Cov {
    pub const ZERO: Cov = Cov { xx: 0.0, xy: 0.0, yy: 0.0 };
}

impl<T: Real> Cov<T> {
    pub fn zero() -> Cov<T> {
        Cov::iso(T::from(0.0))
    }

    pub fn iso(v: T) -> Cov<T> {
        Cov { xx: v, xy: T::from(0.0), yy: v }
    }

    /// R diag(vx, vy) Rᵀ with R the rotation by `angle` (Yamaguchi et al. 2019 eq. 7).
    pub fn oriented(vx: T, vy: T, angle: T) -> Cov<T> {
        if vx.same(vy) {
            return Cov::iso(vx);
        }
        let (s, c) = angle.sin_cos();
        Cov { xx: c * c * vx + s * s * vy, xy: c * s * (vx - vy), yy: s * s * vx + c * c * vy }
    }

    /// The variance along the unit tangent direction (cos φ, sin φ).
    pub fn along(self, cos_phi: f64, sin_phi: f64) -> T {
        self.xx * (cos_phi * cos_phi) + self.xy * (2.0 * cos_phi * sin_phi) + self.yy * (sin_phi * sin_phi)
    }

    /// Eigen-decomposition: (λ₁, λ₂, angle of λ₁'s eigenvector); (v, v, 0) for an isotropic Σ = vI.
    pub fn eigen(self) -> (T, T, T) {
        let (l1, l2, cos, sin) = self.eigen_frame();
        (l1, l2, sin.atan2(cos))
    }

    /// Eigen-decomposition with the eigenvector of λ₁ ≥ λ₂ as (cos, sin) of its angle in (−π/2, π/2]: the unit
    /// vector along (Σ_xx − λ₂, Σ_xy), or along (Σ_xy, λ₁ − Σ_xx) when Σ_xx < Σ_yy (no trigonometric call, no branch:
    /// loops over it vectorize); (v, v, 1, 0) for Σ = vI.
    #[inline(always)]
    pub fn eigen_frame(self) -> (T, T, T, T) {
        let mean = (self.xx + self.yy) * 0.5;
        let half = (self.xx - self.yy) * 0.5;
        let r = (half * half + self.xy * self.xy).sqrt();
        let (x, y) = if half.value() >= 0.0 { (half + r, self.xy) } else { (self.xy, r - half) };
        let (x, y) = if x.value() < 0.0 { (-x, -y) } else { (x, y) };
        let len = (x * x + y * y).sqrt();
        if r.value() > 0.0 {
            (mean + r, mean - r, x / len, y / len)
        } else {
            (mean, mean, T::from(1.0), T::from(0.0))
        }
    }

    /// The roughness matrix R diag(αx, αy) Rᵀ of this covariance's GGX lobe: h⁻¹ applied to its eigenvalues.
    pub fn alpha_matrix(self) -> Cov<T> {
        let (ax, ay, angle) = self.ggx();
        Cov::oriented(ax, ay, angle)
    }

    /// The anisotropic GGX lobe (αx, αy, tangent angle) of this covariance: h⁻¹ of the eigenvalues.
    pub fn ggx(self) -> (T, T, T) {
        let (l1, l2, angle) = self.eigen();
        (alpha_from_variance(l1), alpha_from_variance(l2), angle)
    }
}

impl<T: Real> std::ops::Add for Cov<T> {
    type Output = Cov<T>;
    fn add(self, o: Cov<T>) -> Cov<T> {
        Cov { xx: self.xx + o.xx, xy: self.xy + o.xy, yy: self.yy + o.yy }
    }
}

impl std::ops::Mul<Cov> for f64 {
    type Output = Cov;
    fn mul(self, c: Cov) -> Cov {
        c * self
    }
}

impl<T: Real> std::ops::Mul<T> for Cov<T> {
    type Output = Cov<T>;
    fn mul(self, d: T) -> Cov<T> {
        Cov { xx: self.xx * d, xy: self.xy * d, yy: self.yy * d }
    }
}

impl<T: Real> std::ops::Div<T> for Cov<T> {
    type Output = Cov<T>;
    fn div(self, d: T) -> Cov<T> {
        Cov { xx: self.xx / d, xy: self.xy / d, yy: self.yy / d }
    }
}

/// One output lobe: energy per channel and its anisotropic GGX roughness and tangent angle.
#[derive(Clone, Debug, PartialEq)]
pub struct Lobe<T = f64> {
    pub energy: Vec<T>,
    pub cov: Cov<T>,
}

impl<T: Real> Lobe<T> {
    /// (αx, αy, angle) of the lobe's GGX distribution.
    pub fn roughness(&self) -> (T, T, T) {
        self.cov.ggx()
    }
}
