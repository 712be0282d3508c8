//! Forward-mode automatic differentiation (Griewank and Walther 2008, ch. 3): a `Dual<N>` is a value with its
//! derivatives with respect to N parameters. The optics primitives that take layer parameters are generic over
//! `Real` (f64, or a Dual), so that one function serves the evaluation and its parameter gradients; directions stay
//! f64 (no parameter moves them). Branches read the value.

use glam::DVec3;
use std::ops::{Add, Div, Mul, Neg, Sub};

/// A real number as the generic primitives compute with it: f64, or a Dual carrying derivatives.
pub trait Real:
    Copy
    + PartialEq
    + Send
    + Sync
    + std::iter::Sum
    + From<f64>
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
    + Add<f64, Output = Self>
    + Sub<f64, Output = Self>
    + Mul<f64, Output = Self>
    + Div<f64, Output = Self>
{
    fn value(self) -> f64;
    fn sqrt(self) -> Self;
    fn exp(self) -> Self;
    fn erf(self) -> Self;
    fn sin_cos(self) -> (Self, Self);
    /// max(self, floor), floor a constant.
    fn max_c(self, floor: f64) -> Self;
    /// min(self, ceiling), ceiling a constant (NaN gives the ceiling, as f64::min).
    fn min_c(self, ceiling: f64) -> Self;
    /// self clamped to the constants [lo, hi].
    fn clamp_c(self, lo: f64, hi: f64) -> Self;
    fn abs(self) -> Self;
    fn ln(self) -> Self;
    /// self^p for a constant p (self ≥ 0).
    fn powf(self, p: f64) -> Self;
    /// atan2(self, x): the angle of (x, self).
    fn atan2(self, x: Self) -> Self;
    /// Whether two numbers are the same, derivatives included.
    fn same(self, o: Self) -> bool;
    /// How many derivatives the number carries: 0 for f64.
    const DERIVATIVES: usize;
    /// g(x₁, …, x_K) from its value and partials ∂g/∂x_k (a Dual<K> computed in f64), with the derivatives of the
    /// x's own carried through by the chain rule; for f64, the value.
    fn compose<const K: usize>(g: Dual<K>, x: [Self; K]) -> Self;
}

impl Real for f64 {
    #[inline(always)]
    fn value(self) -> f64 {
        self
    }
    #[inline(always)]
    fn sqrt(self) -> f64 {
        f64::sqrt(self)
    }
    #[inline(always)]
    fn exp(self) -> f64 {
        f64::exp(self)
    }
    #[inline(always)]
    fn erf(self) -> f64 {
        libm::erf(self)
    }
    #[inline(always)]
    fn sin_cos(self) -> (f64, f64) {
        f64::sin_cos(self)
    }
    #[inline(always)]
    fn max_c(self, floor: f64) -> f64 {
        self.max(floor)
    }
    #[inline(always)]
    fn min_c(self, ceiling: f64) -> f64 {
        self.min(ceiling)
    }
    #[inline(always)]
    fn clamp_c(self, lo: f64, hi: f64) -> f64 {
        self.clamp(lo, hi)
    }
    #[inline(always)]
    fn abs(self) -> f64 {
        f64::abs(self)
    }
    #[inline(always)]
    fn ln(self) -> f64 {
        f64::ln(self)
    }
    #[inline(always)]
    fn powf(self, p: f64) -> f64 {
        f64::powf(self, p)
    }
    #[inline(always)]
    fn atan2(self, x: f64) -> f64 {
        f64::atan2(self, x)
    }
    #[inline(always)]
    fn same(self, o: f64) -> bool {
        self == o
    }
    const DERIVATIVES: usize = 0;
    #[inline(always)]
    fn compose<const K: usize>(g: Dual<K>, _: [f64; K]) -> f64 {
        g.v
    }
}

/// A Real's arithmetic with a `C` on its right: an f64, or the same kind of Real. The primitives take a cosine or a
/// direction that no parameter moves as f64, and one that a parameter moves (a half vector through the IOR, a sampled
/// normal through the roughness) as Duals.
pub trait With<C>:
    Real + Add<C, Output = Self> + Sub<C, Output = Self> + Mul<C, Output = Self> + Div<C, Output = Self>
{
}

impl<C, T> With<C> for T where
    T: Real + Add<C, Output = T> + Sub<C, Output = T> + Mul<C, Output = T> + Div<C, Output = T>
{
}

/// A direction's components as Reals.
pub type Dir<T> = [T; 3];

/// `w` as a Dir.
#[inline(always)]
pub fn dir<T: Real>(w: DVec3) -> Dir<T> {
    [T::from(w.x), T::from(w.y), T::from(w.z)]
}

/// The value of a Dir, as glam's vector.
#[inline(always)]
pub fn value<C: Real>(w: Dir<C>) -> DVec3 {
    DVec3::new(w[0].value(), w[1].value(), w[2].value())
}

/// a · b, summed as glam sums it.
#[inline(always)]
pub fn dot<T: Real>(a: Dir<T>, b: Dir<T>) -> T {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// a + b.
#[inline(always)]
pub fn plus<T: Real>(a: Dir<T>, b: Dir<T>) -> Dir<T> {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

/// a / |a|, as glam normalizes (times the reciprocal of the length).
#[inline(always)]
pub fn normalize<T: Real>(a: Dir<T>) -> Dir<T> {
    let r = T::from(1.0) / dot(a, a).sqrt();
    a.map(|x| x * r)
}

/// A value and its derivatives with respect to N parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Dual<const N: usize> {
    pub v: f64,
    pub d: [f64; N],
}

impl<const N: usize> Dual<N> {
    /// `v` with derivative `dv` with respect to parameter `i` (0 for the others).
    pub fn seeded(v: f64, i: usize, dv: f64) -> Self {
        let mut d = [0.0; N];
        d[i] = dv;
        Dual { v, d }
    }

    /// The chain rule: g(self) given g(v) and g'(v).
    #[inline(always)]
    fn chain(self, g: f64, dg: f64) -> Self {
        Dual { v: g, d: self.d.map(|x| x * dg) }
    }
}

impl<const N: usize> From<f64> for Dual<N> {
    fn from(v: f64) -> Self {
        Dual { v, d: [0.0; N] }
    }
}

impl<const N: usize> Add for Dual<N> {
    type Output = Self;
    #[inline(always)]
    fn add(self, o: Self) -> Self {
        Dual { v: self.v + o.v, d: std::array::from_fn(|i| self.d[i] + o.d[i]) }
    }
}

impl<const N: usize> Sub for Dual<N> {
    type Output = Self;
    #[inline(always)]
    fn sub(self, o: Self) -> Self {
        Dual { v: self.v - o.v, d: std::array::from_fn(|i| self.d[i] - o.d[i]) }
    }
}

impl<const N: usize> Mul for Dual<N> {
    type Output = Self;
    #[inline(always)]
    #[allow(clippy::suspicious_arithmetic_impl)] // the product rule
    fn mul(self, o: Self) -> Self {
        Dual { v: self.v * o.v, d: std::array::from_fn(|i| self.d[i] * o.v + self.v * o.d[i]) }
    }
}

impl<const N: usize> Div for Dual<N> {
    type Output = Self;
    #[inline(always)]
    #[allow(clippy::suspicious_arithmetic_impl)] // the quotient rule
    fn div(self, o: Self) -> Self {
        let r = 1.0 / o.v;
        let v = self.v * r;
        Dual { v, d: std::array::from_fn(|i| (self.d[i] - v * o.d[i]) * r) }
    }
}

impl<const N: usize> Neg for Dual<N> {
    type Output = Self;
    #[inline(always)]
    fn neg(self) -> Self {
        Dual { v: -self.v, d: self.d.map(|x| -x) }
    }
}

impl<const N: usize> Add<f64> for Dual<N> {
    type Output = Self;
    #[inline(always)]
    fn add(self, c: f64) -> Self {
        Dual { v: self.v + c, d: self.d }
    }
}

impl<const N: usize> Sub<f64> for Dual<N> {
    type Output = Self;
    #[inline(always)]
    fn sub(self, c: f64) -> Self {
        Dual { v: self.v - c, d: self.d }
    }
}

impl<const N: usize> Mul<f64> for Dual<N> {
    type Output = Self;
    #[inline(always)]
    fn mul(self, c: f64) -> Self {
        Dual { v: self.v * c, d: self.d.map(|x| x * c) }
    }
}

impl<const N: usize> Div<f64> for Dual<N> {
    type Output = Self;
    #[inline(always)]
    fn div(self, c: f64) -> Self {
        self * (1.0 / c)
    }
}

/// Sums from −0.0, as f64's `Sum` does.
impl<const N: usize> std::iter::Sum for Dual<N> {
    fn sum<I: Iterator<Item = Self>>(it: I) -> Self {
        it.fold(Dual::from(-0.0), |a, b| a + b)
    }
}

impl<const N: usize> Real for Dual<N> {
    fn value(self) -> f64 {
        self.v
    }
    fn sqrt(self) -> Self {
        let s = self.v.sqrt();
        // d√x = dx / (2√x); at 0 the derivative is unbounded, taken as 0 (√ of a clamped square, e.g. a grazing sine).
        self.chain(s, if s > 0.0 { 0.5 / s } else { 0.0 })
    }
    fn exp(self) -> Self {
        let e = self.v.exp();
        self.chain(e, e)
    }
    fn erf(self) -> Self {
        // d erf(x)/dx = 2/√π e^{−x²}.
        self.chain(libm::erf(self.v), std::f64::consts::FRAC_2_SQRT_PI * (-self.v * self.v).exp())
    }
    fn sin_cos(self) -> (Self, Self) {
        let (s, c) = self.v.sin_cos();
        (self.chain(s, c), self.chain(c, -s))
    }
    fn max_c(self, floor: f64) -> Self {
        if self.v >= floor {
            self
        } else {
            Dual::from(floor)
        }
    }
    fn min_c(self, ceiling: f64) -> Self {
        if self.v <= ceiling {
            self
        } else {
            Dual::from(ceiling)
        }
    }
    fn clamp_c(self, lo: f64, hi: f64) -> Self {
        if self.v < lo {
            Dual::from(lo)
        } else if self.v > hi {
            Dual::from(hi)
        } else {
            self
        }
    }
    fn abs(self) -> Self {
        if self.v < 0.0 {
            -self
        } else {
            self
        }
    }
    fn ln(self) -> Self {
        self.chain(self.v.ln(), 1.0 / self.v)
    }
    fn powf(self, p: f64) -> Self {
        // d x^p = p x^(p−1) dx; at 0 (a clamped roughness or variance) taken as 0.
        let y = self.v.powf(p);
        self.chain(y, if self.v > 0.0 { p * y / self.v } else { 0.0 })
    }
    fn atan2(self, x: Self) -> Self {
        // d atan2(y, x) = (x dy − y dx) / (x² + y²).
        let r2 = x.v * x.v + self.v * self.v;
        let k = if r2 > 0.0 { 1.0 / r2 } else { 0.0 };
        Dual { v: self.v.atan2(x.v), d: std::array::from_fn(|i| (x.v * self.d[i] - self.v * x.d[i]) * k) }
    }
    fn same(self, o: Self) -> bool {
        self == o
    }
    const DERIVATIVES: usize = N;
    #[inline(always)]
    fn compose<const K: usize>(g: Dual<K>, x: [Self; K]) -> Self {
        Dual { v: g.v, d: std::array::from_fn(|i| (0..K).map(|k| g.d[k] * x[k].d[i]).sum()) }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A function of three parameters, written once and evaluated in f64 and in Dual<3>.
    fn g<T: Real>(x: T, y: T, z: T) -> T {
        let (s, c) = (x * y).sin_cos();
        let more = (x * x + 0.5).ln() + (z * z + 0.1).powf(1.1) + y.atan2(x - 2.0) - (y * 3.0).abs();
        (x * x + 1.0).sqrt() * (-y).exp() / (z + 2.0) + (z * 0.7).erf() * s - c * 3.0 + more
    }

    #[test]
    fn dual_derivatives_are_central_differences() {
        let p = [0.3, -0.8, 1.1];
        let seed = |i: usize| Dual::<3>::seeded(p[i], i, 1.0);
        let d = g(seed(0), seed(1), seed(2));
        assert_eq!(d.v, g(p[0], p[1], p[2]));
        for i in 0..3 {
            let h = 1e-6;
            let (mut a, mut b) = (p, p);
            a[i] += h;
            b[i] -= h;
            let fd = (g(a[0], a[1], a[2]) - g(b[0], b[1], b[2])) / (2.0 * h);
            assert!((d.d[i] - fd).abs() < 1e-8 * (1.0 + fd.abs()), "{i}: {} vs {fd}", d.d[i]);
        }
    }
}
