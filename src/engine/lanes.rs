//! The lane type of the float32 engine: LANES = 16 float32 lanes (`Floats`), their masks, and 3-vectors of lanes
//! (`V3`). Sixteen lanes are two 256-bit registers on AVX2 (one on AVX-512): two independent chains of square roots
//! and divisions in flight per operation, measured 10% faster than eight lanes for the rough conductor (105 → 115
//! million evaluations/s on one core of the 2-core CI machine; examples/engine_scaling.rs).
//!
//! Every operation is written lane by lane on plain arrays, and each is one correctly rounded IEEE operation per lane
//! (fma included: `mul_add` is fused on every target), so the lanes are independent and every backend computes the
//! same bits. engine/mod.rs compiles the kernels once for AVX2 + FMA, where LLVM turns each operation into 256-bit instructions,
//! and once portably. `min`/`max` follow the x86 `minps`/`maxps` rule (the second operand when either
//! is NaN), so that a clamp of a NaN gives the bound on every backend.

use std::ops::{Add, BitAnd, BitOr, Div, Mul, Neg, Not, Sub};

/// Lanes per `Floats`.
pub const LANES: usize = 16;

/// LANES float32 lanes.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C, align(32))]
pub struct Floats(pub [f32; LANES]);

/// A mask of LANES lanes: all bits set (true) or clear (false) per lane.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C, align(32))]
pub struct Mask(pub [u32; LANES]);

/// A 3-vector of lanes (structure of arrays).
#[derive(Clone, Copy, Debug)]
pub struct V3 {
    pub x: Floats,
    pub y: Floats,
    pub z: Floats,
}

/// [f(0), …, f(LANES − 1)]: `std::array::from_fn` as a plain loop, which LLVM inlines into a row loop however large
/// it is. The selects and integer lane work use it: in the mixture sampler's row loop from_fn's closures were left
/// out of line, compiled without AVX2 (10% of its time, perf; 1.3x the samples/s with this). The arithmetic keeps
/// from_fn: with every operation a loop the crate took 4x longer to build (9 minutes) for no measured gain.
#[inline(always)]
pub fn per_lane<T: Copy + Default>(f: impl Fn(usize) -> T) -> [T; LANES] {
    let mut out = [T::default(); LANES];
    for (i, o) in out.iter_mut().enumerate() {
        *o = f(i);
    }
    out
}

#[inline(always)]
fn map(f: impl Fn(usize) -> f32) -> Floats {
    Floats(std::array::from_fn(f))
}

#[inline(always)]
fn mask(f: impl Fn(usize) -> bool) -> Mask {
    Mask(std::array::from_fn(|i| if f(i) { u32::MAX } else { 0 }))
}

macro_rules! binary {
    ($trait:ident, $method:ident, $op:tt) => {
        impl $trait for Floats {
            type Output = Floats;
            #[inline(always)]
            fn $method(self, b: Floats) -> Floats {
                map(|i| self.0[i] $op b.0[i])
            }
        }
        impl $trait<f32> for Floats {
            type Output = Floats;
            #[inline(always)]
            fn $method(self, b: f32) -> Floats {
                map(|i| self.0[i] $op b)
            }
        }
        impl $trait<Floats> for f32 {
            type Output = Floats;
            #[inline(always)]
            fn $method(self, b: Floats) -> Floats {
                map(|i| self $op b.0[i])
            }
        }
    };
}
binary!(Add, add, +);
binary!(Sub, sub, -);
binary!(Mul, mul, *);
binary!(Div, div, /);

impl Neg for Floats {
    type Output = Floats;
    #[inline(always)]
    fn neg(self) -> Floats {
        map(|i| -self.0[i])
    }
}

impl Floats {
    #[inline(always)]
    pub fn splat(x: f32) -> Floats {
        Floats([x; LANES])
    }

    /// self · a + b, rounded once.
    #[inline(always)]
    pub fn mul_add(self, a: Floats, b: Floats) -> Floats {
        map(|i| self.0[i].mul_add(a.0[i], b.0[i]))
    }

    #[inline(always)]
    pub fn sqrt(self) -> Floats {
        map(|i| self.0[i].sqrt())
    }

    /// The smaller of self and b; b where either is NaN (x86 `minps`).
    #[inline(always)]
    pub fn abs(self) -> Floats {
        map(|i| self.0[i].abs())
    }

    #[inline(always)]
    pub fn min(self, b: Floats) -> Floats {
        map(|i| if self.0[i] < b.0[i] { self.0[i] } else { b.0[i] })
    }

    /// The larger of self and b; b where either is NaN (x86 `maxps`).
    #[inline(always)]
    pub fn max(self, b: Floats) -> Floats {
        map(|i| if self.0[i] > b.0[i] { self.0[i] } else { b.0[i] })
    }

    #[inline(always)]
    pub fn lt(self, b: Floats) -> Mask {
        mask(|i| self.0[i] < b.0[i])
    }

    #[inline(always)]
    pub fn le(self, b: Floats) -> Mask {
        mask(|i| self.0[i] <= b.0[i])
    }

    #[inline(always)]
    pub fn gt(self, b: Floats) -> Mask {
        mask(|i| self.0[i] > b.0[i])
    }

    #[inline(always)]
    pub fn ge(self, b: Floats) -> Mask {
        mask(|i| self.0[i] >= b.0[i])
    }

    /// Lane i: a[i] where m[i] is set, else b[i].
    #[inline(always)]
    pub fn select(m: Mask, a: Floats, b: Floats) -> Floats {
        Floats(per_lane(|i| f32::from_bits((m.0[i] & a.0[i].to_bits()) | (!m.0[i] & b.0[i].to_bits()))))
    }

    /// a where m is set, else 0.
    #[inline(always)]
    pub fn and(m: Mask, a: Floats) -> Floats {
        Floats(per_lane(|i| f32::from_bits(m.0[i] & a.0[i].to_bits())))
    }

    /// Polynomial c[0] + c[1] x + … in Horner's form with fused multiply-adds.
    #[inline(always)]
    pub fn poly(self, c: &[f32]) -> Floats {
        let mut p = Floats::splat(c[c.len() - 1]);
        for &ci in c[..c.len() - 1].iter().rev() {
            p = p.mul_add(self, Floats::splat(ci));
        }
        p
    }

    /// ⌊x⌋ per lane.
    #[inline(always)]
    pub fn floor(self) -> Floats {
        map(|i| self.0[i].floor())
    }

    /// ⌈x⌉ per lane.
    #[inline(always)]
    pub fn ceil(self) -> Floats {
        map(|i| self.0[i].ceil())
    }

    /// (⌊x⌋ as integers, ⌊x⌋) per lane for x in [0, 2²³) (a table's node; the callers clamp x): the integer is the
    /// mantissa of ⌊x⌋ + 2²³, whose ulp is 1. Rust's `as` casts saturate and map NaN to 0, which LLVM compiled to a
    /// scalar conversion per lane inside the row loops (perf: a quarter of Beckmann's sampler).
    #[inline(always)]
    pub fn floor_index(self) -> ([u32; LANES], Floats) {
        let floor = self.floor();
        let bits = (floor + Floats::splat(8_388_608.0)).bits();
        (per_lane(|i| bits[i] & 0x007f_ffff), floor)
    }

    /// The bit patterns of the lanes.
    #[inline(always)]
    pub fn bits(self) -> [u32; LANES] {
        per_lane(|i| self.0[i].to_bits())
    }

    /// e^x, at most 2 ulp from the correctly rounded value for x in [-87.3, 88.7] (measured: tests below); 0 below,
    /// +Inf above, NaN for NaN. Cody–Waite reduction x = n ln 2 + r, |r| ≤ ln2 / 2, and a degree-7 Taylor polynomial
    /// of e^r (its truncation error, r⁸/8! < 3e-9, is below half an ulp), scaled by 2ⁿ in two steps so that
    /// n = 128 does not overflow the exponent.
    #[inline(always)]
    pub fn exp(self) -> Floats {
        const LN2_HI: f32 = 0.693_145_75; // ln 2 split so that n · LN2_HI is exact for |n| < 2^9
        const LN2_LO: f32 = 1.428_606_8e-6;
        const TAYLOR: [f32; 8] = [1.0, 1.0, 0.5, 1.0 / 6.0, 1.0 / 24.0, 1.0 / 120.0, 1.0 / 720.0, 1.0 / 5040.0];
        let x = self.max(Floats::splat(-104.0)).min(Floats::splat(89.0));
        let n = map(|i| (x.0[i] * std::f32::consts::LOG2_E).round_ties_even());
        let r = (-n).mul_add(Floats::splat(LN2_LO), (-n).mul_add(Floats::splat(LN2_HI), x));
        let p = r.poly(&TAYLOR);
        // 2^n as 2^(n/2 rounded down) · 2^(the rest): each factor a normal float32 for n in [-150, 128].
        let half = (0.5 * n).floor();
        let y = p * pow2(half) * pow2(n - half);
        let y = Floats::select(self.lt(Floats::splat(-104.0)), Floats::splat(0.0), y);
        Floats::select(self.gt(Floats::splat(89.0)), Floats::splat(f32::INFINITY), y)
            + map(|i| if self.0[i].is_nan() { f32::NAN } else { 0.0 })
    }

    /// (sin 2πu, cos 2πu) of u in turns, u in [0, 1] (a sampler's azimuth), within 1.5e-7 of the exact values
    /// (measured: tests below). u = q/4 + r with q the nearest quarter turn (r exact, |r| ≤ 1/8), the Cephes minimax
    /// polynomials of sin and cos on x = 2πr in [−π/4, π/4], then the quarter turns: (sin, cos)(x + qπ/2).
    #[inline(always)]
    pub fn sincos_2pi(self) -> (Floats, Floats) {
        const SIN: [f32; 3] = [-1.666_665_5e-1, 8.332_161e-3, -1.951_529_6e-4];
        const COS: [f32; 3] = [4.166_664_6e-2, -1.388_731_6e-3, 2.443_315_7e-5];
        let q = map(|i| (self.0[i] * 4.0).round_ties_even());
        let x = (q.mul_add(Floats::splat(-0.25), self)) * std::f32::consts::TAU;
        let x2 = x * x;
        let sin = (x * x2).mul_add(x2.poly(&SIN), x);
        let cos = (x2 * x2).mul_add(x2.poly(&COS), x2.mul_add(Floats::splat(-0.5), Floats::splat(1.0)));
        // sin(x + kπ/2) = s, c, −s, −c and cos(x + kπ/2) = c, −s, −c, s for k = q mod 4 = 0, 1, 2, 3.
        // As selects (a table lookup per lane stays scalar): swap where k is odd, negate the sine where k ≥ 2 and
        // the cosine where k is 1 or 2.
        let k = (q + Floats::splat(12_582_912.0)).bits(); // q mod 4 in the low bits of q + 1.5 · 2²³ (its ulp is 1)
        let bit = |b: u32| Mask(per_lane(|i| if k[i] & b != 0 { u32::MAX } else { 0 }));
        let (odd, high) = (bit(1), bit(2));
        let (s, c) = (Floats::select(odd, cos, sin), Floats::select(odd, sin, cos));
        let flip_cos = Mask(per_lane(|i| odd.0[i] ^ high.0[i]));
        (Floats::select(high, -s, s), Floats::select(flip_cos, -c, c))
    }

    /// ln x for positive normal x, within 3 ulp of the correctly rounded value (measured: tests below). x = 2ᵉ m with
    /// m in [√½, √2), then ln m = 2 atanh s = 2 (s + s³/3 + s⁵/5 + …), s = (m − 1)/(m + 1), |s| ≤ 0.172 (the series
    /// to s¹³, its truncation below 1e-9), and e ln 2 in two parts.
    #[inline(always)]
    pub fn ln(self) -> Floats {
        const LN2_HI: f32 = 0.693_145_75;
        const LN2_LO: f32 = 1.428_606_8e-6;
        const ATANH: [f32; 7] = [2.0, 2.0 / 3.0, 2.0 / 5.0, 2.0 / 7.0, 2.0 / 9.0, 2.0 / 11.0, 2.0 / 13.0];
        let bits = self.bits();
        // The mantissa in [1, 2), halved where it is above √2 (and the exponent raised).
        let m = Floats(per_lane(|i| f32::from_bits((bits[i] & 0x007f_ffff) | 0x3f80_0000)));
        let high = m.gt(Floats::splat(std::f32::consts::SQRT_2));
        let m = Floats::select(high, 0.5 * m, m);
        let e = Floats(per_lane(|i| ((bits[i] >> 23) as i32 - 127 + (high.0[i] & 1) as i32) as f32));
        let s = (m - 1.0) / (m + 1.0);
        let log_m = s * (s * s).poly(&ATANH);
        e.mul_add(Floats::splat(LN2_HI), e.mul_add(Floats::splat(LN2_LO), log_m))
    }

    /// The complementary error function erfc x, within 1 ulp of the correctly rounded value where it is a normal
    /// float32 (measured: tests below). Computed in float64 and rounded once, as libm's float erfc: the form of
    /// Numerical Recipes (Press et al. 2007 §6.2.2), erfc z = t exp(−z² + P(t)) with t = 1 / (1 + z/2), z = |x|, but
    /// with our own degree-10 least-squares P on the t of z in [0, 12] (ln error 1.2e-8), and erfc x = 2 − erfc z
    /// for x < 0. z² of a float32 is exact in float64. Beyond 12 erfc underflows float32; NaN gives 0.
    #[inline(always)]
    pub fn erfc(self) -> Floats {
        const P: [f64; 11] = [
            -1.265556898987554,
            1.0013224543858597,
            0.3581843268754615,
            0.20459390921891152,
            -0.63495787866519,
            1.482645075235199,
            -3.2559623002145046,
            3.925019755563436,
            -2.5785703608769763,
            0.8917278731279215,
            -0.1284459504269643,
        ];
        let z = self.abs().min(Floats::splat(12.0));
        let t = per_lane(|i| 1.0 / (z.0[i] as f64).mul_add(0.5, 1.0));
        let y = per_lane(|i| {
            let p = P.iter().rev().fold(0.0, |acc: f64, &c| acc.mul_add(t[i], c));
            p - (z.0[i] as f64) * (z.0[i] as f64)
        });
        let e = exp_f64(y);
        let negative = self.lt(Floats::splat(0.0));
        Floats(per_lane(|i| {
            let e = t[i] * e[i];
            (if negative.0[i] != 0 { 2.0 - e } else { e }) as f32
        }))
    }

    /// erf⁻¹(2u − 1) of u in [0, 1] (a sampler's normal deviate), within 4e-7 relative of the exact value (measured:
    /// tests below): Giles 2010's single-precision fit in w = −ln(1 − y²), with 1 − y² = 4u(1 − u) formed from u,
    /// without the cancellation 1 − y² has near y = ±1. Beyond the fit's range (s = min(u, 1 − u) < 2⁻²⁴, rare) three
    /// Newton steps on ln erfc(−x) = ln 2s refine it. u = 0 and 1 give ∓5.86, as erf_inv's clamp of y to 2⁻⁵³ from ±1
    /// (optics/distribution.rs).
    #[inline(always)]
    pub fn erf_inv_uniform(self) -> Floats {
        const CENTRAL: [f32; 9] = [
            1.501_409_4,
            0.246_640_73,
            -0.004_177_681_6,
            -0.001_253_725,
            0.000_218_580_87,
            -4.391_506_5e-6,
            -3.523_387_7e-6,
            3.432_739_4e-7,
            2.810_226_4e-8,
        ];
        const TAIL: [f32; 9] = [
            2.832_976_8,
            1.001_674,
            0.009_438_870_5,
            -0.007_622_461_3,
            0.005_739_507_7,
            -0.003_673_428_4,
            0.001_349_343_2,
            0.000_100_950_56,
            -0.000_200_214_26,
        ];
        let y = 2.0 * self - 1.0;
        let w = -((4.0 * self * (1.0 - self)).max(Floats::splat(4e-16)).ln());
        let central = (w - 2.5).poly(&CENTRAL);
        let tail = (w.sqrt() - 3.0).poly(&TAIL);
        let x = Floats::select(w.lt(Floats::splat(5.0)), central, tail) * y;
        // 1 − u is exact for u ≥ ½, so s is.
        let s = self.min(1.0 - self);
        let beyond = s.lt(Floats::splat(1.0 / 16_777_216.0));
        if !beyond.any() {
            return x;
        }
        let ln_2s = (2.0 * s.max(Floats::splat(1.0 / 18_014_398_509_481_984.0))).ln();
        let mut xs = -x.abs();
        for _ in 0..3 {
            let f = (-xs).erfc();
            xs = xs - (f.ln() - ln_2s) * f / (std::f32::consts::FRAC_2_SQRT_PI * (-(xs * xs)).exp());
        }
        Floats::select(beyond, Floats::select(self.gt(Floats::splat(0.5)), -xs, xs), x)
    }
}

/// e^y per lane in float64, within 3e-10 relative for y in [−708, 709] (erfc's exponent is in [−146, 0]):
/// y = n ln 2 + r, |r| ≤ ln 2 / 2, and the degree-8 Taylor polynomial of e^r (truncation r⁹/9! < 2.1e-10), scaled
/// by 2ⁿ through the exponent bits of n + 1023 + 2⁵² (whose ulp is 1).
#[inline(always)]
fn exp_f64(y: [f64; LANES]) -> [f64; LANES] {
    const LN2_HI: f64 = 0.693_147_180_369_123_8; // ln 2 with 21 trailing zero bits: n · LN2_HI is exact for |n| < 2²¹
    const LN2_LO: f64 = 1.908_214_929_270_587_7e-10;
    const TAYLOR: [f64; 9] =
        [1.0, 1.0, 0.5, 1.0 / 6.0, 1.0 / 24.0, 1.0 / 120.0, 1.0 / 720.0, 1.0 / 5040.0, 1.0 / 40_320.0];
    per_lane(|i| {
        let n = (y[i] * std::f64::consts::LOG2_E).round_ties_even();
        let r = (-n).mul_add(LN2_LO, (-n).mul_add(LN2_HI, y[i]));
        let p = TAYLOR.iter().rev().fold(0.0, |acc: f64, &c| acc.mul_add(r, c));
        p * f64::from_bits((n + 4_503_599_627_371_519.0).to_bits() << 52)
    })
}

/// 2^k per lane for integral k (exp's scaling; 0 for k ≤ −127, 2¹²⁸ = +Inf above), through the exponent bits: k + 127
/// is the mantissa of k + 127 + 2²³ (whose ulp is 1), shifted into the exponent field.
#[inline(always)]
fn pow2(k: Floats) -> Floats {
    let t = k.max(Floats::splat(-127.0)).min(Floats::splat(128.0)) + Floats::splat(8_388_735.0);
    Floats(per_lane(|i| f32::from_bits(t.0[i].to_bits() << 23)))
}

impl BitAnd for Mask {
    type Output = Mask;
    #[inline(always)]
    fn bitand(self, b: Mask) -> Mask {
        Mask(per_lane(|i| self.0[i] & b.0[i]))
    }
}

impl BitOr for Mask {
    type Output = Mask;
    #[inline(always)]
    fn bitor(self, b: Mask) -> Mask {
        Mask(per_lane(|i| self.0[i] | b.0[i]))
    }
}

impl Not for Mask {
    type Output = Mask;
    #[inline(always)]
    fn not(self) -> Mask {
        Mask(per_lane(|i| !self.0[i]))
    }
}

impl Mask {
    /// Every lane set.
    pub const ALL: Mask = Mask([u32::MAX; LANES]);
    /// No lane set.
    pub const NONE: Mask = Mask([0; LANES]);

    /// Whether any lane is set.
    #[inline(always)]
    pub fn any(self) -> bool {
        self.0.iter().fold(0, |a, &m| a | m) != 0
    }

    /// Whether every lane is set.
    #[inline(always)]
    pub fn all(self) -> bool {
        self.0.iter().fold(u32::MAX, |a, &m| a & m) == u32::MAX
    }
}

impl V3 {
    #[inline(always)]
    pub fn splat(v: [f32; 3]) -> V3 {
        V3 { x: Floats::splat(v[0]), y: Floats::splat(v[1]), z: Floats::splat(v[2]) }
    }

    #[inline(always)]
    pub fn dot(self, b: V3) -> Floats {
        self.x.mul_add(b.x, self.y.mul_add(b.y, self.z * b.z))
    }

    #[inline(always)]
    pub fn scale(self, s: Floats) -> V3 {
        V3 { x: self.x * s, y: self.y * s, z: self.z * s }
    }

    #[inline(always)]
    pub fn plus(self, b: V3) -> V3 {
        V3 { x: self.x + b.x, y: self.y + b.y, z: self.z + b.z }
    }

    /// a where m is set, else b, per lane.
    #[inline(always)]
    pub fn select(m: Mask, a: V3, b: V3) -> V3 {
        V3 { x: Floats::select(m, a.x, b.x), y: Floats::select(m, a.y, b.y), z: Floats::select(m, a.z, b.z) }
    }

    /// The vector in the tangent frame rotated by the angle of cosine c and sine s about z (Microfacet's tangent frame, optics/distribution.rs).
    #[inline(always)]
    pub fn rotate(self, c: Floats, s: Floats) -> V3 {
        V3 { x: self.x.mul_add(c, self.y * s), y: self.y.mul_add(c, -(self.x * s)), z: self.z }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Distance in units in the last place between two finite float32 of one sign.
    fn ulps(a: f32, b: f32) -> u32 {
        (a.to_bits() as i64 - b.to_bits() as i64).unsigned_abs() as u32
    }

    #[test]
    fn exp_is_within_two_ulp_of_the_correctly_rounded_value() {
        // 5e6 points evenly spaced in [-87.3, 88.7], against e^x in float64 rounded once to float32 (within half an
        // ulp of the correctly rounded value). Measured: 1 ulp at most.
        let n = 5_000_000;
        let worst = (0..=n)
            .map(|i| (-87.3 + 176.0 * i as f64 / n as f64) as f32)
            .map(|x| ulps(Floats::splat(x).exp().0[0], (x as f64).exp() as f32))
            .max()
            .unwrap();
        assert!(worst <= 2, "worst {worst} ulp");
    }

    #[test]
    fn sincos_2pi_is_within_1_5e7_of_the_exact_values() {
        // 2^22 + 1 points over [0, 1] turns (every quadrant and its ends) against float64's sin and cos of the same
        // float32 u; measured 1.05e-7 at most.
        let n = 1 << 22;
        let mut worst = 0.0f64;
        for chunk in (0..=n).collect::<Vec<u32>>().chunks(LANES) {
            let u: [f32; LANES] = std::array::from_fn(|l| chunk.get(l).map_or(0.5, |&k| k as f32 / n as f32));
            let (s, c) = Floats(u).sincos_2pi();
            for ((&u, s), c) in u.iter().zip(s.0).zip(c.0) {
                let phi = std::f64::consts::TAU * u as f64;
                worst = worst.max((s as f64 - phi.sin()).abs()).max((c as f64 - phi.cos()).abs());
            }
        }
        assert!(worst <= 1.5e-7, "{worst}");
    }

    /// The worst of `measure(x)` over every float32 in `xs`, a lane group at a time.
    fn worst(xs: impl Iterator<Item = f32>, f: impl Fn(Floats) -> Floats, measure: impl Fn(f32, f32) -> f64) -> f64 {
        let xs: Vec<f32> = xs.collect();
        let mut worst = 0.0f64;
        for chunk in xs.chunks(LANES) {
            let x: [f32; LANES] = std::array::from_fn(|l| chunk[l % chunk.len()]);
            worst = f(Floats(x)).0.iter().zip(x).fold(worst, |w, (&y, x)| w.max(measure(x, y)));
        }
        worst
    }

    #[test]
    fn ln_is_within_three_ulp_of_the_correctly_rounded_value() {
        // 4e6 points log-spaced over [1e-37, 1e38] and 1e6 evenly spaced in [0.5, 2] (around 1, where ln is smallest),
        // against ln in float64 rounded to float32. Measured: 3 ulp at most.
        let spread = (0..4_000_000).map(|i| 10f64.powf(-37.0 + 75.0 * i as f64 / 4e6) as f32);
        let near_one = (0..1_000_000).map(|i| (0.5 + 1.5 * i as f64 / 1e6) as f32);
        let ulp = |x: f32, y: f32| ulps(y, (x as f64).ln() as f32) as f64;
        let w = worst(spread.chain(near_one).filter(|&x| x != 1.0), Floats::ln, |x, y| {
            // ulps between values of one sign; ln 1 = 0 is exact.
            if y.signum() == ((x as f64).ln() as f32).signum() {
                ulp(x, y)
            } else {
                f64::INFINITY
            }
        });
        assert!(w <= 3.0, "worst {w} ulp");
        assert_eq!(Floats::splat(1.0).ln().0[0], 0.0);
    }

    #[test]
    fn erfc_is_within_one_ulp_of_the_correctly_rounded_value() {
        // 4e6 points evenly spaced in [-4, 9] (erfc 9 = 4e-37, the last normal float32 decade) and 1e6 around the
        // threshold 0.5 where erfc crosses 1/2 and 1/4 binades, against libm's erfc in float64 rounded to float32.
        // Measured: 1 ulp at most.
        let xs = (0..=4_000_000).map(|i| (-4.0 + 13.0 * i as f64 / 4e6) as f32);
        let near = (0..=1_000_000).map(|i| (0.4 + 0.4 * i as f64 / 1e6) as f32);
        let w = worst(xs.chain(near), Floats::erfc, |x, y| ulps(y, libm::erfc(x as f64) as f32) as f64);
        assert!(w <= 1.0, "worst {w} ulp");
        let e = Floats(std::array::from_fn(|i| [12.5, f32::INFINITY, f32::NEG_INFINITY][i % 3])).erfc().0;
        assert_eq!(&e[..3], &[0.0, 0.0, 2.0]);
    }

    #[test]
    fn erf_inv_uniform_is_within_4e7_of_the_exact_value() {
        // Every 64th float32 in (0, 1) from 4.7e-10 (4e6 points, dense near 0 where the tail is steepest), their
        // mirror images 1 − u, and the ends, against float64's erf_inv(2u − 1) (2u − 1 exact in float64). Measured:
        // 3.0e-7 relative.
        let us = (1..(1u32 << 30) / 64).map(|k| f32::from_bits(k * 64 + 0x3000_0000)).filter(|&u| u < 1.0);
        let us = us.flat_map(|u| [u, 1.0 - u]).chain([0.0, 1.0]).filter(|&u| u != 0.5);
        let w = worst(us, Floats::erf_inv_uniform, |u, y| {
            let exact = crate::optics::distribution::erf_inv(2.0 * u as f64 - 1.0);
            (y as f64 - exact).abs() / exact.abs()
        });
        assert!(w <= 4e-7, "worst {w}");
    }

    #[test]
    fn exp_limits() {
        let x = [-200.0, -104.5, 0.0, 89.5, f32::INFINITY, f32::NEG_INFINITY, f32::NAN, 1.0];
        let e = Floats(std::array::from_fn(|i| x[i % 8])).exp().0;
        assert_eq!(&e[..6], &[0.0, 0.0, 1.0, f32::INFINITY, f32::INFINITY, 0.0]);
        assert!(e[6].is_nan());
        assert_eq!(e[7], std::f32::consts::E);
    }

    #[test]
    fn floor_index_and_pow2_are_the_integer_casts() {
        // floor_index against Rust's cast over [0, 2²³): every 16th float32 of [0, 1] and of [1, 2²³), a value just
        // below each integer up to 2¹⁶, and 2²³ − ½; pow2 against powi over its whole range of normal results.
        let below: Vec<f32> = (1..1u32 << 16).map(|k| f32::from_bits((k as f32).to_bits() - 1)).collect();
        let spread = (0..0x3f80_0000u32).step_by(16).chain((0x3f80_0000..0x4b00_0000).step_by(16)).map(f32::from_bits);
        let xs: Vec<f32> = spread.chain(below).chain([8_388_607.5]).collect();
        for chunk in xs.chunks(LANES) {
            let x = Floats(std::array::from_fn(|l| chunk[l % chunk.len()]));
            let (index, floor) = x.floor_index();
            for ((&i, &f), &x) in index.iter().zip(&floor.0).zip(&x.0) {
                assert_eq!((i, f), (x as u32, x.floor()), "x = {x}");
            }
        }
        for k in -126..=127 {
            assert_eq!(pow2(Floats::splat(k as f32)).0[0], 2f32.powi(k), "k = {k}");
        }
        assert_eq!(pow2(Floats::splat(-127.0)).0[0], 0.0);
        assert_eq!(pow2(Floats::splat(128.0)).0[0], f32::INFINITY);
    }

    #[test]
    fn clamps_of_nan_give_the_bound() {
        let nan = Floats::splat(f32::NAN);
        assert_eq!(nan.max(Floats::splat(0.0)).0[0], 0.0);
        assert_eq!(nan.min(Floats::splat(1.0)).0[0], 1.0);
    }
}
