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
        let half = map(|i| (n.0[i] * 0.5).floor());
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
        let k: [u32; LANES] = per_lane(|i| q.0[i] as i32 as u32);
        let bit = |b: u32| Mask(per_lane(|i| if k[i] & b != 0 { u32::MAX } else { 0 }));
        let (odd, high) = (bit(1), bit(2));
        let (s, c) = (Floats::select(odd, cos, sin), Floats::select(odd, sin, cos));
        let flip_cos = Mask(per_lane(|i| odd.0[i] ^ high.0[i]));
        (Floats::select(high, -s, s), Floats::select(flip_cos, -c, c))
    }
}

/// 2^k per lane for integral k (exp's scaling), through the exponent bits.
#[inline(always)]
fn pow2(k: Floats) -> Floats {
    map(|i| f32::from_bits((((k.0[i] as i32) + 127).clamp(0, 255) as u32) << 23))
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

    /// The vector in the tangent frame rotated by the angle of cosine c and sine s about z (optics::to_tangent_frame).
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

    #[test]
    fn exp_limits() {
        let x = [-200.0, -104.5, 0.0, 89.5, f32::INFINITY, f32::NEG_INFINITY, f32::NAN, 1.0];
        let e = Floats(std::array::from_fn(|i| x[i % 8])).exp().0;
        assert_eq!(&e[..6], &[0.0, 0.0, 1.0, f32::INFINITY, f32::INFINITY, 0.0]);
        assert!(e[6].is_nan());
        assert_eq!(e[7], std::f32::consts::E);
    }

    #[test]
    fn clamps_of_nan_give_the_bound() {
        let nan = Floats::splat(f32::NAN);
        assert_eq!(nan.max(Floats::splat(0.0)).0[0], 0.0);
        assert_eq!(nan.min(Floats::splat(1.0)).0[0], 1.0);
    }
}
