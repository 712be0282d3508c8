//! The float32 evaluation engine: a model's kernel written once against the lane type (`lanes.rs`: sixteen float32
//! lanes) is run here over NumPy's float32 rows, from load to store in float32, in parallel with rayon.
//!
//! What a model writes: a type that implements `Kernel` (f for LANES pairs of unit directions) with `#[inline(always)]`
//! on its `eval`, and a `Model::eval_f32` that calls `engine::eval` with it and the correction it is given (a
//! `Correction` of f applied in the same pass, lane group by lane group: transport_fit's). Everything else is here: the (n, 3) rows
//! are read straight from NumPy's memory (or one broadcast row is splat), de-interleaved, checked and normalised in
//! lanes, evaluated, and written straight into the output. No allocation per block and no zeroing pass. The row
//! loop is compiled twice, for AVX2 + FMA (the kernel's lane operations become 256-bit instructions) and portably,
//! and the choice is made once per call; both give the same bits (lanes.rs).
//!
//! Importance sampling takes the same path: a kernel that also proposes its sampling mixture in lanes
//! (models/common/mixture_lanes.rs, `Proposals`) gets `Stack.sample` in float32 from `mixture_lanes::sample`, called
//! by its `Model::sample_f32`, with no sampling code of its own.
//!
//! A row that float32 cannot take as it is (NaN, Inf, a zero-length direction, or one whose squared length leaves
//! float32's normal range or reaches 2¹²⁶) stops the engine: the call then runs on the careful float64 path, which raises the same
//! errors as before and computes such rows exactly.

pub mod lanes;

pub use lanes::{per_lane, Floats, Mask, LANES, V3};
use rayon::prelude::*;
use std::sync::atomic::{AtomicBool, Ordering};

/// A model's float32 kernel.
pub trait Kernel: Sync {
    /// f(wi, wo) of LANES pairs of unit directions (either side of the surface), channel c into out[c].
    fn eval(&self, wi: V3, wo: V3, out: &mut [Floats]);
}

/// A correction of a kernel's f in lanes, applied in the kernel's pass before the lanes are stored (transport_fit's
/// s f + a after a model's own f).
pub trait Correction: Sync {
    fn apply(&self, wi: V3, wo: V3, f: &mut [Floats]);
}

/// No correction (`None::<&()>`).
impl Correction for () {
    #[inline(always)]
    fn apply(&self, _: V3, _: V3, _: &mut [Floats]) {}
}

/// An (n, 3) float32 input: n rows in C order, or one row broadcast to every element.
#[derive(Clone, Copy, Debug)]
pub enum Rows<'a> {
    Packed(&'a [f32]),
    Splat([f32; 3]),
}

impl<'a> Rows<'a> {
    /// Rows start..start + len.
    pub fn rows(self, start: usize, len: usize) -> Rows<'a> {
        match self {
            Rows::Packed(s) => Rows::Packed(&s[3 * start..3 * (start + len)]),
            splat => splat,
        }
    }
}

/// Rows per parallel task.
const TASK_ROWS: usize = 2048;

/// f of every pair (wi[r], wo[r]) into out (rows of `channels` values) by `kernel`, then `correction` if any; false,
/// with `out` partly written, where a row needs the careful path (module comment).
pub fn eval<K: Kernel, C: Correction>(
    kernel: &K,
    correction: Option<&C>,
    channels: usize,
    wi: Rows,
    wo: Rows,
    out: &mut [f32],
) -> bool {
    // Two loops, so that the one without a correction is compiled without its code (which costs registers: 10% more
    // instructions per evaluation for the rough conductor, measured with callgrind).
    match correction {
        Some(correction) => run(&Corrected { kernel, correction }, channels, wi, wo, out),
        None => run(kernel, channels, wi, wo, out),
    }
}

/// A model's float32 importance sampling.
pub trait Sampler: Sync {
    /// For LANES unit viewing directions wo and uniform numbers u in [0, 1]: wi (out[0..3]), the weight f cos θi / pdf
    /// per channel and the pdf (the last).
    fn sample(&self, wo: V3, u: V3, out: &mut [Floats]);
}

/// `Stack.sample`'s rows (wi, weight per channel, pdf: `width` values) of every (wo[r], u[r]) by `sampler`; false,
/// with `out` partly written, where a row needs the careful path (a direction as in `eval`, or a u outside [0, 1]).
pub fn sample<S: Sampler>(sampler: &S, width: usize, wo: Rows, u: Rows, out: &mut [f32]) -> bool {
    run(&Sampling(sampler), width, wo, u, out)
}

/// What the row loop computes from a group of LANES rows of its two inputs: false where a lane's input is one it does
/// not take.
trait Pass: Sync {
    fn lanes(&self, a: V3, b: V3, out: &mut [Floats]) -> bool;
}

/// f by a kernel, from two directions that the pass normalises: false where one is not a direction float32 takes.
#[inline(always)]
fn evaluate<K: Kernel>(kernel: &K, wi: V3, wo: V3, f: &mut [Floats]) -> Option<(V3, V3)> {
    let (wi, wo, ok) = units(wi, wo);
    if (!ok).any() {
        return None;
    }
    kernel.eval(wi, wo, f);
    Some((wi, wo))
}

impl<K: Kernel> Pass for K {
    #[inline(always)]
    fn lanes(&self, wi: V3, wo: V3, f: &mut [Floats]) -> bool {
        evaluate(self, wi, wo, f).is_some()
    }
}

/// f by a kernel, then its correction.
struct Corrected<'a, K, C> {
    kernel: &'a K,
    correction: &'a C,
}

impl<K: Kernel, C: Correction> Pass for Corrected<'_, K, C> {
    #[inline(always)]
    fn lanes(&self, wi: V3, wo: V3, f: &mut [Floats]) -> bool {
        let Some((wi, wo)) = evaluate(self.kernel, wi, wo, f) else { return false };
        self.correction.apply(wi, wo, f);
        true
    }
}

/// Samples by a sampler, from a direction that the pass normalises and three numbers in [0, 1].
struct Sampling<'a, S>(&'a S);

impl<S: Sampler> Pass for Sampling<'_, S> {
    #[inline(always)]
    fn lanes(&self, wo: V3, u: V3, out: &mut [Floats]) -> bool {
        let (wo, ok) = unit(wo);
        let (zero, one) = (Floats::splat(0.0), Floats::splat(1.0));
        // In [0, 1] (false for NaN).
        let inside = u.x.ge(zero) & u.x.le(one) & u.y.ge(zero) & u.y.le(one) & u.z.ge(zero) & u.z.le(one);
        if (!(ok & inside)).any() {
            return false;
        }
        self.0.sample(wo, u, out);
        true
    }
}

/// `pass` over every row of a and b into out (rows of `width` values), in parallel.
fn run<P: Pass>(pass: &P, width: usize, a: Rows, b: Rows, out: &mut [f32]) -> bool {
    let rows: RowLoop<P> = rows_for_cpu::<P>();
    let failed = AtomicBool::new(false);
    out.par_chunks_mut(TASK_ROWS * width).enumerate().for_each_init(
        || vec![Floats::splat(0.0); width],
        |scratch, (t, o)| {
            if !failed.load(Ordering::Relaxed) && !rows(pass, a, b, t * TASK_ROWS, o, scratch) {
                failed.store(true, Ordering::Relaxed);
            }
        },
    );
    !failed.into_inner()
}

/// A row loop: `rows` for pass P, compiled for one instruction set.
type RowLoop<P> = fn(&P, Rows, Rows, usize, &mut [f32], &mut [Floats]) -> bool;

/// The row loop compiled for this CPU: AVX2 + FMA when it has them, else portable.
fn rows_for_cpu<P: Pass>() -> RowLoop<P> {
    #[cfg(target_arch = "x86_64")]
    if has_avx2() {
        return |p, a, b, first, out, scratch| {
            // SAFETY: the CPU supports every feature the function is compiled for.
            unsafe { rows_avx2(p, a, b, first, out, scratch) }
        };
    }
    rows::<P>
}

/// Whether the CPU has AVX2 and FMA (checked once, then cached by std).
#[cfg(target_arch = "x86_64")]
#[inline]
pub fn has_avx2() -> bool {
    std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma")
}

/// `$body`, a function of the named arguments, compiled for AVX2 + FMA when the CPU has them (the loops that
/// vectorize run in 4 f64 lanes, of f64 or of Duals), else as is: `with_avx2!([generics] (arg: Type, …) -> Out =>
/// body)` returns from the enclosing function on the AVX2 path and otherwise evaluates to `body`. Rust never
/// contracts a * b + c into an FMA by itself, so both paths give identical bits.
macro_rules! with_avx2 {
    ([$($g:tt)*] ($($arg:ident: $ty:ty),*) $(-> $out:ty)? => $body:expr) => {{
        #[cfg(target_arch = "x86_64")]
        if $crate::engine::has_avx2() {
            #[target_feature(enable = "avx2,fma")]
            unsafe fn avx2<$($g)*>($($arg: $ty),*) $(-> $out)? {
                $body
            }
            // SAFETY: the CPU supports every feature the function is compiled for.
            return unsafe { avx2($($arg),*) };
        }
        $body
    }};
}
pub(crate) use with_avx2;

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn rows_avx2<P: Pass>(p: &P, a: Rows, b: Rows, first: usize, out: &mut [f32], f: &mut [Floats]) -> bool {
    rows(p, a, b, first, out, f)
}

/// Rows first.. of the output slice `out`, LANES at a time; false at the first group with a row the pass does not
/// take.
#[inline(always)]
fn rows<P: Pass>(p: &P, a: Rows, b: Rows, first: usize, out: &mut [f32], f: &mut [Floats]) -> bool {
    let channels = f.len();
    for (g, o) in out.chunks_mut(LANES * channels).enumerate() {
        let (r, m) = (first + g * LANES, o.len() / channels);
        if !p.lanes(load(a, r, m), load(b, r, m), f) {
            return false;
        }
        // Clamped to the largest finite float32 as they are stored, as the float64 path's float32 output is: a
        // grazing mirror pair with a denormal zenith can reach 1e41. (Clamped in place in `f`, LLVM made the clamp a
        // masked store, microcoded on AMD: 9% of belcour's time, perf.)
        if m == LANES && channels == 3 {
            // RGB: `load`'s transposition backwards, three permutations and the blends into three vectors.
            let t: [Floats; 3] = std::array::from_fn(|c| Floats(per_lane(|l| f[c].0[ROW[c][l]])).min(largest()));
            for (k, v) in o.chunks_exact_mut(LANES).enumerate() {
                v.copy_from_slice(&per_lane(|l| t[(LANES * k + l) % 3].0[l]));
            }
        } else {
            for (i, row) in o.chunks_exact_mut(channels).enumerate() {
                for (c, v) in row.iter_mut().enumerate() {
                    let x = f[c].0[i];
                    *v = if x < f32::MAX { x } else { f32::MAX }; // Floats::min's rule: NaN gives the bound
                }
            }
        }
    }
    true
}

/// The largest finite float32 in every lane (the output's clamp).
#[inline(always)]
fn largest() -> Floats {
    Floats::splat(f32::MAX)
}

/// HOLDER[c][l]: which of three vectors of LANES rows' (x, y, z) holds a component c in lane l.
const HOLDER: [[usize; LANES]; 3] = holders();
/// ROW[c][l]: the row whose component c lies in lane l.
const ROW: [[usize; LANES]; 3] = rows_of_lanes();

const fn holders() -> [[usize; LANES]; 3] {
    let mut h = [[0; LANES]; 3];
    let (mut c, mut i) = (0, 0);
    while c < 3 {
        while i < LANES {
            h[c][(3 * i + c) % LANES] = (3 * i + c) / LANES;
            i += 1;
        }
        (c, i) = (c + 1, 0);
    }
    h
}

const fn rows_of_lanes() -> [[usize; LANES]; 3] {
    let mut r = [[0; LANES]; 3];
    let (mut c, mut i) = (0, 0);
    while c < 3 {
        while i < LANES {
            r[c][(3 * i + c) % LANES] = i;
            i += 1;
        }
        (c, i) = (c + 1, 0);
    }
    r
}

/// Rows r..r + m (m ≤ LANES) as lanes; lanes past m hold the normal (0, 0, 1).
#[inline(always)]
fn load(rows: Rows, r: usize, m: usize) -> V3 {
    match rows {
        Rows::Splat(v) => V3::splat(v),
        Rows::Packed(s) if m == LANES => {
            // LANES rows are three vectors of LANES floats; component c of row i is lane (3i + c) mod LANES of
            // vector (3i + c) / LANES (3 and LANES coprime). Per component: a blend of the three vectors (each lane from the vector that holds it
            // there), then a permutation of the lanes: two blends and a permute instruction on AVX2.
            let s = &s[3 * r..3 * r + 3 * LANES];
            let v: [Floats; 3] = std::array::from_fn(|k| Floats(per_lane(|l| s[LANES * k + l])));
            let lane = |c: usize| {
                let t = Floats(per_lane(|l| v[HOLDER[c][l]].0[l]));
                Floats(per_lane(|i| t.0[(3 * i + c) % LANES]))
            };
            V3 { x: lane(0), y: lane(1), z: lane(2) }
        }
        Rows::Packed(s) => {
            let s = &s[3 * r..3 * (r + m)];
            let lane = |c: usize, pad: f32| Floats(std::array::from_fn(|i| if i < m { s[3 * i + c] } else { pad }));
            V3 { x: lane(0, 0.0), y: lane(1, 0.0), z: lane(2, 1.0) }
        }
    }
}

/// w normalised, and the lanes it can be in float32: a squared length that is a normal float32 below 2¹²⁶ (not NaN,
/// Inf, zero, subnormal or near overflow). Always normalised, even when |w|² is within float32's rounding of 1: the
/// sum of a nearly opposite pair (a half vector) turns a length error of 4e-8 into a direction error 5× larger, which
/// moved a sharp GGX lobe's tail by 1.2e-5 when such directions were taken as unit (α = 0.01).
#[inline(always)]
pub fn unit(w: V3) -> (V3, Mask) {
    let len2 = w.dot(w);
    (w.scale(1.0 / len2.sqrt()), normal_length(len2))
}

/// Two directions normalised as `unit` does, with one division for both: 1/|a| = |b| / (|a| |b|) (the lengths below
/// 2⁶³, so that their product is finite).
#[inline(always)]
pub fn units(a: V3, b: V3) -> (V3, V3, Mask) {
    let (la, lb) = (a.dot(a), b.dot(b));
    let (sa, sb) = (la.sqrt(), lb.sqrt());
    let r = 1.0 / (sa * sb);
    (a.scale(sb * r), b.scale(sa * r), normal_length(la) & normal_length(lb))
}

/// The lanes whose squared length float32 takes: normal and below 2¹²⁶.
#[inline(always)]
fn normal_length(len2: Floats) -> Mask {
    len2.ge(Floats::splat(f32::MIN_POSITIVE)) & len2.lt(Floats::splat(2f32.powi(126)))
}

#[cfg(test)]
pub mod tests {
    use super::*;

    /// The kernel run through `rows` (the portable loop) and through `eval` (the CPU's), on the same rows:
    /// (portable, dispatched) outputs.
    pub fn both_backends<K: Kernel>(k: &K, channels: usize, wi: &[f32], wo: &[f32]) -> (Vec<f32>, Vec<f32>) {
        let n = wi.len() / 3;
        let (mut a, mut b) = (vec![0.0; n * channels], vec![0.0; n * channels]);
        let mut f = vec![Floats::splat(0.0); channels];
        assert!(rows(k, Rows::Packed(wi), Rows::Packed(wo), 0, &mut a, &mut f));
        assert!(eval(k, None::<&()>, channels, Rows::Packed(wi), Rows::Packed(wo), &mut b));
        (a, b)
    }

    struct Dot;
    impl Kernel for Dot {
        #[inline(always)]
        fn eval(&self, wi: V3, wo: V3, out: &mut [Floats]) {
            out[0] = wi.dot(wo);
            out[1] = wi.z.exp();
        }
    }

    #[test]
    fn rows_are_read_normalised_and_written_in_order_with_a_ragged_tail() {
        let n = 2 * TASK_ROWS + 11;
        let wi: Vec<f32> = (0..n).flat_map(|r| [0.0, 0.0, 1.0 + r as f32]).collect();
        let wo: Vec<f32> = (0..n).flat_map(|r| [(r as f32).cos(), (r as f32).sin(), 0.0]).collect();
        let mut out = vec![0.0; 2 * n];
        assert!(eval(&Dot, None::<&()>, 2, Rows::Packed(&wi), Rows::Packed(&wo), &mut out));
        // wi's z normalised within 2 ulp of 1 (`units` rounds 1 / |wi| as |wo| / (|wi| |wo|)), so e^z within 3e-7.
        let e = std::f32::consts::E;
        for r in 0..n {
            assert_eq!(out[2 * r], 0.0, "row {r}");
            assert!((out[2 * r + 1] - e).abs() <= 3e-7 * e, "row {r}: {}", out[2 * r + 1]);
        }
        let mut splat = vec![0.0; 2 * n];
        assert!(eval(&Dot, None::<&()>, 2, Rows::Splat([0.0, 0.0, 2.0]), Rows::Packed(&wo), &mut splat));
        for (a, b) in splat.iter().zip(&out) {
            assert!((a - b).abs() <= 3e-7 * e);
        }
    }

    #[test]
    fn a_row_float32_cannot_take_sends_the_call_to_the_careful_path() {
        let wo = [0.0, 0.0, 1.0].repeat(100);
        for bad in [f32::NAN, f32::INFINITY, 0.0, 1e-30, 1e19] {
            let mut wi = wo.clone();
            wi[3 * 57..3 * 58].copy_from_slice(&[bad, 0.0, 0.0]);
            let mut out = vec![0.0; 200];
            assert!(!eval(&Dot, None::<&()>, 2, Rows::Packed(&wi), Rows::Packed(&wo), &mut out), "{bad}");
        }
    }

    #[test]
    fn the_portable_and_the_cpu_loops_give_the_same_bits() {
        let n = 1001;
        let wi: Vec<f32> = (0..3 * n).map(|i| ((i * 7919) % 1000) as f32 / 500.0 - 1.0 + 1e-3).collect();
        let wo: Vec<f32> = (0..3 * n).map(|i| ((i * 104_729) % 997) as f32 / 400.0 - 1.2 + 1e-3).collect();
        let (a, b) = both_backends(&Dot, 2, &wi, &wo);
        assert_eq!(
            a.iter().map(|x| x.to_bits()).collect::<Vec<_>>(),
            b.iter().map(|x| x.to_bits()).collect::<Vec<_>>()
        );
    }
}
