//! Anisotropic microfacet distributions (GGX / Trowbridge–Reitz and Beckmann) with Smith masking, the V-cavity
//! masking of Torrance–Sparrow, and visible-normal sampling. Directions are in the local frame (z = normal); each
//! distribution carries the rotation `angle` of its tangent frame, along whose x axis `alpha_x` applies.

use crate::dual::{dot, normalize, value, Dir, Real, With};
use glam::DVec3;
use std::f64::consts::PI;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Distribution {
    Ggx,
    Beckmann,
}

impl Distribution {
    /// The names `from_str` reads, in the order of `ALL`.
    pub const NAMES: [&'static str; 2] = ["ggx", "beckmann"];
    pub const ALL: [Distribution; 2] = [Distribution::Ggx, Distribution::Beckmann];
}

impl std::str::FromStr for Distribution {
    type Err = crate::error::Error;
    fn from_str(s: &str) -> crate::error::Result<Self> {
        crate::error::parse_choice("distribution", s, &Self::NAMES, &Self::ALL)
    }
}

/// A microfacet distribution: its roughnesses and tangent frame are f64, or Duals where a gradient is taken with
/// respect to them (src/dual.rs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Microfacet<T = f64> {
    pub dist: Distribution,
    pub alpha_x: T,
    pub alpha_y: T,
    smooth: bool,
    cos_phi: T,
    sin_phi: T,
}

/// Smallest roughness evaluated as a microfacet lobe (as in Mitsuba 3); (0, 0) is a smooth Dirac interface.
pub const MIN_ALPHA: f64 = 1e-4;

impl Microfacet {
    pub fn new(dist: Distribution, alpha_x: f64, alpha_y: f64, angle: f64) -> Self {
        Microfacet::<f64>::with_parameters(dist, alpha_x, alpha_y, angle)
    }
}

impl<T: Real> Microfacet<T> {
    /// The distribution of roughnesses αx, αy (each at least MIN_ALPHA; both zero: smooth) along the tangent frame
    /// rotated by `angle` (radians), in f64 or in Duals.
    pub fn with_parameters(dist: Distribution, alpha_x: T, alpha_y: T, angle: T) -> Self {
        // The frame of a constant angle 0 without the sine and cosine (exactly (0, 1) either way).
        let (sin_phi, cos_phi) = if angle.same(T::from(0.0)) { (T::from(0.0), T::from(1.0)) } else { angle.sin_cos() };
        Self {
            dist,
            alpha_x: alpha_x.max_c(MIN_ALPHA),
            alpha_y: alpha_y.max_c(MIN_ALPHA),
            smooth: alpha_x.value() == 0.0 && alpha_y.value() == 0.0,
            cos_phi,
            sin_phi,
        }
    }

    /// Its numbers: the roughnesses and the frame's cosine and sine.
    pub fn numbers(&self) -> [T; 4] {
        [self.alpha_x, self.alpha_y, self.cos_phi, self.sin_phi]
    }

    /// The same microfacets with each number as `x` maps it (to another kind of Real).
    pub fn map<R: Real>(&self, x: impl Fn(T) -> R) -> Microfacet<R> {
        let (alpha_x, alpha_y, cos_phi, sin_phi) = (x(self.alpha_x), x(self.alpha_y), x(self.cos_phi), x(self.sin_phi));
        Microfacet { dist: self.dist, alpha_x, alpha_y, smooth: self.smooth, cos_phi, sin_phi }
    }

    /// True when both roughnesses are zero: the interface is a perfectly smooth (Dirac) one, whose reflection and
    /// refraction are delta lobes that a BSDF evaluation does not return.
    pub fn is_smooth(&self) -> bool {
        self.smooth
    }

    /// w in the tangent frame: (x, y) along αx and αy, and z.
    #[inline(always)]
    fn tangent_t<C: Real>(&self, w: Dir<C>) -> (T, T, C)
    where
        T: With<C>,
    {
        (self.cos_phi * w[0] + self.sin_phi * w[1], self.cos_phi * w[1] - self.sin_phi * w[0], w[2])
    }

    /// Normal distribution D(m) (Walter et al. 2007 eq. 33 for GGX, eq. 25 for Beckmann; anisotropic form of
    /// Heitz 2014 eq. 85/86). Zero for m below the horizon. m is f64 (a DVec3), or Duals where a parameter moves it.
    /// (This and the masking functions below compute first and select last, without early returns, so that loops
    /// over them vectorize.)
    #[inline(always)]
    pub fn d<C: Real>(&self, m: impl Into<Dir<C>>) -> T
    where
        T: With<C>,
    {
        let (mx, my, mz) = self.tangent_t(m.into());
        let (x, y) = (mx / self.alpha_x, my / self.alpha_y);
        let z2 = mz * mz;
        let d = match self.dist {
            Distribution::Ggx => {
                let s = x * x + y * y + z2;
                T::from(1.0) / (T::from(PI) * self.alpha_x * self.alpha_y * s * s)
            }
            Distribution::Beckmann => {
                (-(x * x + y * y) / z2).exp() / (T::from(PI) * self.alpha_x * self.alpha_y * z2 * z2)
            }
        };
        if mz.value() > 0.0 {
            d
        } else {
            T::from(0.0)
        }
    }

    /// Smith Λ(w) of the distribution (Heitz 2014 eq. 72 for GGX, eq. 69 for Beckmann), using the projected
    /// roughness α(φ) along the azimuth of w. Both forms give 0 for α tan θ = 0 and ∞ for α tan θ = ∞ (grazing).
    #[inline(always)]
    pub fn lambda<C: Real>(&self, w: impl Into<Dir<C>>) -> T
    where
        T: With<C>,
    {
        let (wx, wy, wz) = self.tangent_t(w.into());
        let (ax, ay) = (wx * self.alpha_x, wy * self.alpha_y);
        let alpha_tan2 = (ax * ax + ay * ay) / (wz * wz);
        match self.dist {
            Distribution::Ggx => ((alpha_tan2 + 1.0).sqrt() - 1.0) * 0.5,
            Distribution::Beckmann => {
                let a = T::from(1.0) / alpha_tan2.sqrt();
                (a.erf() - 1.0) * 0.5 + (-a * a).exp() / (a * (2.0 * PI.sqrt()))
            }
        }
    }

    /// Smith masking G1(w, m) = χ⁺((w·m)/(w·n)) / (1 + Λ(w)) (Heitz 2014 eq. 43); m enters only through χ⁺.
    #[inline(always)]
    pub fn g1<C: Real>(&self, w: impl Into<Dir<C>>, m: DVec3) -> T
    where
        T: With<C>,
    {
        let w = w.into();
        let g = T::from(1.0) / (self.lambda(w) + 1.0);
        let w = value(w);
        if w.dot(m) * w.z > 0.0 {
            g
        } else {
            T::from(0.0)
        }
    }

    /// Separable Smith masking-shadowing G1(wi) G1(wo) (Heitz 2014 eq. 98; what Mitsuba 3 uses).
    #[inline(always)]
    pub fn g2_separable<A: Real, B: Real>(&self, wi: impl Into<Dir<A>>, wo: impl Into<Dir<B>>, m: DVec3) -> T
    where
        T: With<A> + With<B>,
    {
        self.g1(wi, m) * self.g1(wo, m)
    }

    /// Height-correlated Smith masking-shadowing 1 / (1 + Λ(wi) + Λ(wo)) (Heitz 2014 eq. 99; pbrt-v4).
    #[inline(always)]
    pub fn g2_height_correlated<A: Real, B: Real>(&self, wi: impl Into<Dir<A>>, wo: impl Into<Dir<B>>, m: DVec3) -> T
    where
        T: With<A> + With<B>,
    {
        let (wi, wo) = (wi.into(), wo.into());
        let g = T::from(1.0) / (T::from(1.0) + self.lambda(wi) + self.lambda(wo));
        let (wi, wo) = (value(wi), value(wo));
        if wi.dot(m) * wi.z > 0.0 && wo.dot(m) * wo.z > 0.0 {
            g
        } else {
            T::from(0.0)
        }
    }

    /// Masking-shadowing of the chosen form; the V-cavity's carries no derivative by directions that parameters move
    /// (`g2_at`'s does).
    #[inline(always)]
    pub fn g2<A: Real, B: Real>(&self, form: G2Form, wi: impl Into<Dir<A>>, wo: impl Into<Dir<B>>, m: DVec3) -> T
    where
        T: With<A> + With<B>,
    {
        match form {
            G2Form::Separable => self.g2_separable(wi, wo, m),
            G2Form::HeightCorrelated => self.g2_height_correlated(wi, wo, m),
            G2Form::VCavity => T::from(v_cavity(value(wi.into()), value(wo.into()), m)),
        }
    }

    /// Masking-shadowing of the chosen form at the half vector h, carrying the derivatives by directions that
    /// parameters move, the V-cavity's included (which takes h itself).
    #[inline(always)]
    pub fn g2_at<C: Real>(&self, form: G2Form, wi: Dir<C>, wo: Dir<C>, h: Dir<C>) -> T
    where
        T: With<C> + From<C>,
    {
        match form {
            G2Form::VCavity => T::from(v_cavity(wi, wo, h)),
            _ => self.g2(form, wi, wo, value(h)),
        }
    }

    /// Projected roughness α(φ) = √(αx² cos²φ + αy² sin²φ) along the azimuth φ of `w` in the tangent frame (Heitz
    /// 2014 eq. 80); αx for a direction along the normal.
    #[inline(always)]
    pub fn projected_alpha<C: Real>(&self, w: impl Into<Dir<C>>) -> T
    where
        T: With<C>,
    {
        let (x, y, _) = self.tangent_t(w.into());
        let r2 = x * x + y * y;
        if r2.value() == 0.0 {
            return self.alpha_x;
        }
        (((x * self.alpha_x) * (x * self.alpha_x) + (y * self.alpha_y) * (y * self.alpha_y)) / r2).sqrt()
    }

    /// The same distribution and tangent frame with other roughnesses.
    #[inline(always)]
    pub fn with_alpha(&self, alpha_x: T, alpha_y: T) -> Self {
        Self {
            alpha_x: alpha_x.max_c(MIN_ALPHA),
            alpha_y: alpha_y.max_c(MIN_ALPHA),
            smooth: alpha_x.value() == 0.0 && alpha_y.value() == 0.0,
            ..*self
        }
    }
}

impl Microfacet {
    /// The same distribution with other roughnesses along the tangent frame rotated by the angle of cosine `cos_phi`
    /// and sine `sin_phi`.
    #[inline(always)]
    pub fn with_frame(&self, alpha_x: f64, alpha_y: f64, cos_phi: f64, sin_phi: f64) -> Self {
        Self { cos_phi, sin_phi, ..self.with_alpha(alpha_x, alpha_y) }
    }

    /// (cos, sin) of the rotation of the tangent frame.
    pub fn frame(&self) -> (f64, f64) {
        (self.cos_phi, self.sin_phi)
    }

    /// Distribution of visible normals D_wi(m) = G1(wi, m) max(0, wi·m) D(m) / cos θi (Heitz 2018 eq. 1),
    /// the pdf of `sample_visible` with respect to solid angle of m.
    pub fn pdf_visible(&self, wi: DVec3, m: DVec3) -> f64 {
        if wi.z <= 0.0 {
            return 0.0;
        }
        self.g1(wi, m) * wi.dot(m).max(0.0) * self.d(m) / wi.z
    }

    /// Samples a visible normal for wi (wi.z > 0) from two uniform numbers. GGX: Heitz 2018, "Sampling the GGX
    /// distribution of visible normals" (JCGT 7(4)), listing 1. Beckmann: Heitz & d'Eon 2014 §4 (stretch,
    /// sample the slope distribution of the standard Beckmann configuration, unstretch).
    pub fn sample_visible(&self, wi: DVec3, u1: f64, u2: f64) -> DVec3 {
        value(self.visible_normal(wi, u1, u2))
    }
}

impl<T: Real> Microfacet<T> {
    /// `sample_visible` in f64, or in Duals by the roughnesses and the frame angle: the normal that the same uniform
    /// numbers give, as the parameters move it (for GGX; Beckmann's slopes, found by Newton's method, carry none).
    pub fn visible_normal(&self, wi: DVec3, u1: f64, u2: f64) -> Dir<T> {
        let (vx, vy, vz) = self.tangent_t([wi.x, wi.y, wi.z]);
        let vh = normalize([self.alpha_x * vx, self.alpha_y * vy, T::from(vz)]);
        let m = match self.dist {
            Distribution::Ggx => {
                let len2 = vh[0] * vh[0] + vh[1] * vh[1];
                let (zero, one) = (T::from(0.0), T::from(1.0));
                let t1 = if len2.value() > 0.0 {
                    let len = len2.sqrt();
                    [-vh[1] / len, vh[0] / len, zero / len]
                } else {
                    [one, zero, zero]
                };
                // vh × t1, as glam crosses.
                let t2 = [vh[1] * t1[2] - t1[1] * vh[2], vh[2] * t1[0] - t1[2] * vh[0], vh[0] * t1[1] - t1[0] * vh[1]];
                let r = u1.sqrt();
                let phi = 2.0 * PI * u2;
                let p1 = r * phi.cos();
                let s = (vh[2] + 1.0) * 0.5;
                let p2 = (one - s) * (1.0 - p1 * p1).max(0.0).sqrt() + s * r * phi.sin();
                let p3 = (T::from(1.0 - p1 * p1) - p2 * p2).max_c(0.0).sqrt();
                let nh: Dir<T> = std::array::from_fn(|i| t1[i] * p1 + t2[i] * p2 + vh[i] * p3);
                [self.alpha_x * nh[0], self.alpha_y * nh[1], nh[2].max_c(0.0)]
            }
            Distribution::Beckmann => {
                let (sx, sy) = beckmann_sample_slopes(value(vh), u1, u2);
                [self.alpha_x * -sx, self.alpha_y * -sy, T::from(1.0)]
            }
        };
        // Back from the tangent frame (the rotation by −angle).
        let [x, y, z] = normalize(m);
        [self.cos_phi * x - self.sin_phi * y, self.sin_phi * x + self.cos_phi * y, z]
    }
}

/// Which masking-shadowing term a microfacet BSDF uses.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum G2Form {
    Separable,
    HeightCorrelated,
    VCavity,
}

impl G2Form {
    /// The names `from_str` reads, in the order of `ALL`.
    pub const NAMES: [&'static str; 3] = ["height_correlated", "separable", "v_cavity"];
    pub const ALL: [G2Form; 3] = [G2Form::HeightCorrelated, G2Form::Separable, G2Form::VCavity];
}

impl std::str::FromStr for G2Form {
    type Err = crate::error::Error;
    fn from_str(s: &str) -> crate::error::Result<Self> {
        crate::error::parse_choice("g2", s, &Self::NAMES, &Self::ALL)
    }
}

/// V-cavity masking-shadowing of Torrance–Sparrow 1967 / Cook–Torrance 1982:
/// min(1, 2(n·m)(n·wo)/(wo·m), 2(n·m)(n·wi)/(wi·m)).
#[inline(always)]
pub fn v_cavity<C: Real>(wi: impl Into<Dir<C>>, wo: impl Into<Dir<C>>, m: impl Into<Dir<C>>) -> C {
    let (wi, wo, m) = (wi.into(), wo.into(), m.into());
    let (im, om) = (dot(wi, m), dot(wo, m));
    if (im * wi[2]).value() <= 0.0 || (om * wo[2]).value() <= 0.0 {
        return C::from(0.0);
    }
    let (o, i) = ((m[2] * 2.0 * wo[2] / om).abs(), (m[2] * 2.0 * wi[2] / im).abs());
    // f64::min's rule: a NaN operand (m of two opposite directions, whose sum normalizes to 0/0) gives the other,
    // and G = 1 where both are.
    let g = if o.value().is_nan() || i.value() < o.value() { i } else { o };
    if g.value() > 1.0 || g.value().is_nan() {
        C::from(1.0)
    } else {
        g
    }
}

/// Samples the slopes (x̃, ỹ) of the visible standard Beckmann distribution (α = 1) seen from the stretched
/// direction `v` (Heitz & d'Eon 2014 §4). In a frame aligned with v the density is
/// ∝ max(0, cot θ − x̃) e^{−x̃²} e^{−ỹ²}: x̃ is found by inverting its CDF
/// c·(√π/2)(1 + erf x̃) + e^{−x̃²}/2 (safeguarded Newton), ỹ = erf⁻¹(2u₂ − 1).
fn beckmann_sample_slopes(v: DVec3, u1: f64, u2: f64) -> (f64, f64) {
    let sin_t = (1.0 - v.z * v.z).max(0.0).sqrt();
    let (cos_phi, sin_phi) = if sin_t > 1e-12 { (v.x / sin_t, v.y / sin_t) } else { (1.0, 0.0) };
    let c = if sin_t > 1e-12 { v.z / sin_t } else { f64::INFINITY };
    let x = if c > 1e6 {
        erf_inv(2.0 * u1 - 1.0)
    } else {
        let sqrt_pi = PI.sqrt();
        let cdf = |x: f64| 0.5 * c * sqrt_pi * (1.0 + libm::erf(x)) + 0.5 * (-x * x).exp();
        let target = u1 * cdf(c);
        let (mut lo, mut hi) = (-6.0f64, c.min(6.0));
        let mut x = 0.5 * (lo + hi);
        for _ in 0..64 {
            let f = cdf(x) - target;
            if f.abs() < 1e-14 {
                break;
            }
            if f > 0.0 {
                hi = x
            } else {
                lo = x
            }
            let newton = x - f / ((c - x) * (-x * x).exp());
            x = if newton > lo && newton < hi { newton } else { 0.5 * (lo + hi) };
            if hi - lo < 1e-13 {
                break;
            }
        }
        x
    };
    let y = erf_inv(2.0 * u2 - 1.0);
    (cos_phi * x - sin_phi * y, sin_phi * x + cos_phi * y)
}

/// Inverse error function: Giles 2010 single-precision starting point refined by Newton's method on libm's erf, in
/// the tails (|y| > ½) on ln erfc|x| = ln(1 − |y|), which erf's rounding to ±1 does not blur (1 − |y| is exact there).
pub fn erf_inv(y: f64) -> f64 {
    let y = y.clamp(-1.0 + 1e-16, 1.0 - 1e-16);
    let w = -((1.0 - y) * (1.0 + y)).ln();
    let mut x = if w < 5.0 {
        let w = w - 2.5;
        let p = [
            2.81022636e-08,
            3.43273939e-07,
            -3.5233877e-06,
            -4.39150654e-06,
            0.00021858087,
            -0.00125372503,
            -0.00417768164,
            0.246640727,
            1.50140941,
        ];
        p.iter().fold(0.0, |acc, &c| acc * w + c) * y
    } else {
        let w = w.sqrt() - 3.0;
        let p = [
            -0.000200214257,
            0.000100950558,
            0.00134934322,
            -0.00367342844,
            0.00573950773,
            -0.0076224613,
            0.00943887047,
            1.00167406,
            2.83297682,
        ];
        p.iter().fold(0.0, |acc, &c| acc * w + c) * y
    };
    let slope = |x: f64| std::f64::consts::FRAC_2_SQRT_PI * (-x * x).exp();
    if y.abs() <= 0.5 {
        for _ in 0..2 {
            x -= (libm::erf(x) - y) / slope(x);
        }
        return x;
    }
    // Giles' fit is made for float32's range; beyond it (1 − |y| < 1e-7) it starts a few percent away.
    let (target, mut a) = ((1.0 - y.abs()).ln(), x.abs());
    for _ in 0..8 {
        let f = libm::erfc(a);
        let step = (f.ln() - target) * f / slope(a);
        a += step;
        if step.abs() <= 1e-15 * a {
            break;
        }
    }
    a.copysign(y)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sphere_dir(theta: f64, phi: f64) -> DVec3 {
        DVec3::new(theta.sin() * phi.cos(), theta.sin() * phi.sin(), theta.cos())
    }

    /// Midpoint-rule integral of `f(m)` over the upper hemisphere in (θ, φ).
    fn hemisphere_integral<T: std::ops::Add<Output = T> + std::ops::Mul<f64, Output = T>>(
        (nt, np): (usize, usize),
        zero: T,
        f: impl Fn(DVec3) -> T,
    ) -> T {
        let da = (0.5 * PI / nt as f64) * (2.0 * PI / np as f64);
        let mut sum = zero;
        for i in 0..nt {
            let t = (i as f64 + 0.5) / nt as f64 * 0.5 * PI;
            for j in 0..np {
                let p = (j as f64 + 0.5) / np as f64 * 2.0 * PI;
                sum = sum + f(sphere_dir(t, p)) * (t.sin() * da);
            }
        }
        sum
    }

    /// ∫ D(m) max(0, m·w) dm (the projected area of the microsurface seen from w).
    fn projected_area(mf: &Microfacet, w: DVec3) -> f64 {
        hemisphere_integral((800, 400), 0.0, |m| mf.d(m) * m.dot(w).max(0.0))
    }

    #[test]
    fn ndf_normalisation_and_smith_consistency() {
        for dist in [Distribution::Ggx, Distribution::Beckmann] {
            let mf = Microfacet::new(dist, 0.4, 0.7, 0.3);
            let norm = projected_area(&mf, DVec3::Z);
            assert!((norm - 1.0).abs() < 2e-3, "{dist:?}: ∫D cos = {norm}");
            // Projected area seen from w equals cos θ (1 + Λ(w)) (Heitz 2014 eq. 14).
            let w = sphere_dir(1.0, 0.8);
            let area = projected_area(&mf, w);
            assert!((area - w.z * (1.0 + mf.lambda(w))).abs() < 3e-3, "{dist:?}: {area}");
        }
    }

    #[test]
    fn visible_normals_are_consistent_with_their_pdf() {
        for dist in [Distribution::Ggx, Distribution::Beckmann] {
            let mf = Microfacet::new(dist, 0.3, 0.6, 0.5);
            let wi = sphere_dir(1.1, 2.0);
            // The sampler's mean normal equals ∫ pdf(m) m dm (quadrature): checks the sampler against its pdf.
            let n = 200_000;
            let mut mean = DVec3::ZERO;
            for i in 0..n {
                let u1 = (i as f64 + 0.5) / n as f64;
                let u2 = ((i as f64 * 0.618_033_988_749_895) + 0.5).fract();
                mean += mf.sample_visible(wi, u1, u2);
            }
            mean /= n as f64;
            let norm = hemisphere_integral((600, 600), 0.0, |m| mf.pdf_visible(wi, m));
            let expect = hemisphere_integral((600, 600), DVec3::ZERO, |m| m * mf.pdf_visible(wi, m));
            assert!((norm - 1.0).abs() < 2e-3, "{dist:?}: ∫pdf = {norm}");
            let expect = expect / norm;
            assert!((mean - expect).length() < 3e-3, "{dist:?}: {mean} vs {expect}");
        }
    }

    #[test]
    fn erf_inv_inverts_erf() {
        for y in [-0.999999, -0.9, -0.3, 0.0, 0.2, 0.77, 0.99999] {
            assert!((libm::erf(erf_inv(y)) - y).abs() < 1e-13, "{y}");
        }
        // The tails, to the relative precision of 1 − |y| (exact there), which erf's rounding near ±1 would lose.
        for tail in [1e-3, 1e-7, 1e-11, 1e-15, 2f64.powi(-53)] {
            for y in [1.0 - tail, tail - 1.0] {
                assert!((libm::erfc(erf_inv(y).abs()) / (1.0 - y.abs()) - 1.0).abs() < 1e-12, "{y}");
            }
        }
    }

    #[test]
    fn v_cavity_is_at_most_one_and_symmetric() {
        let (wi, wo) = (sphere_dir(0.7, 0.1), sphere_dir(1.3, 2.9));
        let m = (wi + wo).normalize();
        let g = v_cavity(wi, wo, m);
        assert!(g > 0.0 && g <= 1.0);
        assert_eq!(g, v_cavity(wo, wi, m));
    }
}
