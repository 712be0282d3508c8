//! Covariances in the projected disc (Yamaguchi et al. 2019) and Belcour 2018's roughness and scattering maps.

/// Belcour 2018 roughness-to-variance map h(α) = α^1.1 / (1 − α^1.1) (the reference code's fit).
pub fn variance_from_alpha(alpha: f64) -> f64 {
    let a = alpha.clamp(0.0, 0.9999).powf(1.1);
    a / (1.0 - a)
}

/// Inverse of `variance_from_alpha`: α = (v / (1 + v))^(1/1.1).
pub fn alpha_from_variance(v: f64) -> f64 {
    let v = v.max(0.0);
    (v / (1.0 + v)).powf(1.0 / 1.1)
}

/// Variance of Henyey–Greenstein forward scattering in the projected disc, ((1 − g)/g)^0.8 / (1 + g) (Belcour 2018
/// reference code), with g clamped to [0.01, 0.99].
pub fn hg_variance(g: f64) -> f64 {
    let g = g.clamp(0.01, 0.99);
    ((1.0 - g) / g).powf(0.8) / (1.0 + g)
}

/// A symmetric 2x2 covariance of directions projected on the tangent plane (Yamaguchi et al. 2019 §4), in the local
/// tangent frame.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Cov {
    pub xx: f64,
    pub xy: f64,
    pub yy: f64,
}

impl Cov {
    pub const ZERO: Cov = Cov { xx: 0.0, xy: 0.0, yy: 0.0 };

    pub fn iso(v: f64) -> Cov {
        Cov { xx: v, xy: 0.0, yy: v }
    }

    /// R diag(vx, vy) Rᵀ with R the rotation by `angle` (Yamaguchi et al. 2019 eq. 7).
    pub fn oriented(vx: f64, vy: f64, angle: f64) -> Cov {
        if vx == vy {
            return Cov::iso(vx);
        }
        let (s, c) = angle.sin_cos();
        Cov { xx: c * c * vx + s * s * vy, xy: c * s * (vx - vy), yy: s * s * vx + c * c * vy }
    }

    /// The variance along the unit tangent direction (cos φ, sin φ).
    pub fn along(self, cos_phi: f64, sin_phi: f64) -> f64 {
        cos_phi * cos_phi * self.xx + 2.0 * cos_phi * sin_phi * self.xy + sin_phi * sin_phi * self.yy
    }

    /// Eigen-decomposition: (λ₁, λ₂, angle of λ₁'s eigenvector); (v, v, 0) for an isotropic Σ = vI.
    pub fn eigen(self) -> (f64, f64, f64) {
        let (l1, l2, cos, sin) = self.eigen_frame();
        (l1, l2, sin.atan2(cos))
    }

    /// Eigen-decomposition with the eigenvector of λ₁ ≥ λ₂ as (cos, sin) of its angle in (−π/2, π/2]: the unit
    /// vector along (Σ_xx − λ₂, Σ_xy), or along (Σ_xy, λ₁ − Σ_xx) when Σ_xx < Σ_yy (no trigonometric call, no branch:
    /// loops over it vectorize); (v, v, 1, 0) for Σ = vI.
    #[inline(always)]
    pub fn eigen_frame(self) -> (f64, f64, f64, f64) {
        let mean = 0.5 * (self.xx + self.yy);
        let half = 0.5 * (self.xx - self.yy);
        let r = (half * half + self.xy * self.xy).sqrt();
        let (x, y) = if half >= 0.0 { (half + r, self.xy) } else { (self.xy, r - half) };
        let (x, y) = if x < 0.0 { (-x, -y) } else { (x, y) };
        let len = (x * x + y * y).sqrt();
        if r > 0.0 {
            (mean + r, mean - r, x / len, y / len)
        } else {
            (mean, mean, 1.0, 0.0)
        }
    }

    /// The roughness matrix R diag(αx, αy) Rᵀ of this covariance's GGX lobe: h⁻¹ applied to its eigenvalues.
    pub fn alpha_matrix(self) -> Cov {
        let (ax, ay, angle) = self.ggx();
        Cov::oriented(ax, ay, angle)
    }

    /// The anisotropic GGX lobe (αx, αy, tangent angle) of this covariance: h⁻¹ of the eigenvalues.
    pub fn ggx(self) -> (f64, f64, f64) {
        let (l1, l2, angle) = self.eigen();
        (alpha_from_variance(l1), alpha_from_variance(l2), angle)
    }
}

impl std::ops::Add for Cov {
    type Output = Cov;
    fn add(self, o: Cov) -> Cov {
        Cov { xx: self.xx + o.xx, xy: self.xy + o.xy, yy: self.yy + o.yy }
    }
}

impl std::ops::Mul<Cov> for f64 {
    type Output = Cov;
    fn mul(self, c: Cov) -> Cov {
        Cov { xx: self * c.xx, xy: self * c.xy, yy: self * c.yy }
    }
}

impl std::ops::Mul<f64> for Cov {
    type Output = Cov;
    fn mul(self, d: f64) -> Cov {
        Cov { xx: self.xx * d, xy: self.xy * d, yy: self.yy * d }
    }
}

impl std::ops::Div<f64> for Cov {
    type Output = Cov;
    fn div(self, d: f64) -> Cov {
        Cov { xx: self.xx / d, xy: self.xy / d, yy: self.yy / d }
    }
}

/// One output lobe: energy per channel and its anisotropic GGX roughness and tangent angle.
#[derive(Clone, Debug, PartialEq)]
pub struct Lobe {
    pub energy: Vec<f64>,
    pub cov: Cov,
}

impl Lobe {
    /// (αx, αy, angle) of the lobe's GGX distribution.
    pub fn roughness(&self) -> (f64, f64, f64) {
        self.cov.ggx()
    }
}
