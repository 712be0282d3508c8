//! The interpolated adding-doubling (table.rs) in float32 lanes: the table's records as float32, read per lane at the
//! two (isotropic) or four (anisotropic: bilinear in the azimuth) corners of the viewing direction, then each lobe's
//! GGX shape and energies, then the diffuse base; the same arithmetic as `Prepared::eval_columns`. The record's
//! width and the channels are compile-time constants (1 or 3 channels; other counts take the float64 path): with
//! them the records stay in registers, 1.3x the evaluations/s of a run-time width, which spilled them (perf).

use super::table::LobeTable;
use super::Prepared;
use crate::engine::{self, Floats, Mask, Rows, LANES, V3};
use crate::models::common::mixture_lanes::{self, mean, LaneMixture, Proposals, MAX_TERMS};
use crate::models::FitLanes;
use crate::optics::distribution::{G2Form, MIN_ALPHA};
use crate::optics::lanes::{ggx_reflection, Ggx, Visible};
use crate::tables::node_lanes;
use std::f32::consts::{FRAC_PI_2, FRAC_PI_4, PI};

/// A table in float32 and what the kernel needs besides: built once per stack at `prepare`.
pub(super) struct TableF32 {
    lobes: usize,
    nodes: usize,
    azimuths: usize,
    width: usize,
    record: Vec<f32>,
    t_down: Vec<f32>,
    t_up: Vec<f32>,
    /// ρ / (π (1 − ρ R̄↑) η²) per channel: the diffuse base's factor on T↓ T↑; empty without a base.
    diffuse: Vec<f32>,
    /// ρ / (1 − ρ R̄↑) per channel: the base's factor on T↑² in the sampling mixture's cosine weight.
    diffuse_proposal: Vec<f32>,
}

impl TableF32 {
    /// The lane form of table `t`.
    pub(super) fn new(p: &Prepared, t: &LobeTable) -> TableF32 {
        let f32s = |v: &[f64]| v.iter().map(|&x| x as f32).collect();
        let diffuse = p.diffuse.as_ref().map_or(vec![], |d| {
            let scale = |(rho, r_up): (&f64, &f64)| rho / (std::f64::consts::PI * (1.0 - rho * r_up) * d.eta * d.eta);
            d.albedo.iter().zip(&d.r_up).map(scale).map(|x| x as f32).collect()
        });
        let diffuse_proposal = p.diffuse.as_ref().map_or(vec![], |d| {
            d.albedo.iter().zip(&d.r_up).map(|(rho, r_up)| (rho / (1.0 - rho * r_up)) as f32).collect()
        });
        TableF32 {
            lobes: t.lobes,
            nodes: t.nodes,
            azimuths: t.azimuths,
            width: t.width,
            record: f32s(&t.record),
            t_down: f32s(&t.t_down),
            t_up: f32s(&t.t_up),
            diffuse,
            diffuse_proposal,
        }
    }
}

/// The corners of one direction per lane: run indices and bilinear weights (two corners in an isotropic table).
struct Corners {
    index: [[u32; LANES]; 4],
    weight: [Floats; 4],
    count: usize,
}

/// Table corners of cosines `cos` at azimuths (x, y) per lane: linear in √cos θ and in the azimuth's `pseudo_angle`,
/// as `Prepared::corners`.
#[inline(always)]
fn corners(t: &TableF32, cos: Floats, x: Floats, y: Floats) -> Corners {
    let (k, fk) = node_lanes(cos.max(Floats::splat(0.0)).sqrt(), t.nodes);
    let one = Floats::splat(1.0);
    if t.azimuths == 1 {
        let (i0, i1) = (k, k.map(|k| k + 1));
        return Corners { index: [i0, i1, i0, i1], weight: [one - fk, fk, fk, fk], count: 2 };
    }
    let n = t.azimuths as u32;
    let v = pseudo_angle(x, y) * (n as f32 / PI);
    let (a, below) = v.max(Floats::splat(0.0)).min(Floats::splat((n - 1) as f32)).floor_index();
    let fa = v - below;
    let b = a.map(|a| if a + 1 == n { 0 } else { a + 1 });
    Corners {
        index: [run(&k, 0, n, &a), run(&k, 1, n, &a), run(&k, 0, n, &b), run(&k, 1, n, &b)],
        weight: [(one - fk) * (one - fa), fk * (one - fa), (one - fk) * fa, fk * fa],
        count: 4,
    }
}

/// The runs (node k + dk, azimuth) of an anisotropic table of n azimuths, per lane.
#[inline(always)]
fn run(k: &[u32; LANES], dk: u32, n: u32, azimuth: &[u32; LANES]) -> [u32; LANES] {
    let mut r = [0; LANES];
    for ((r, &k), &a) in r.iter_mut().zip(k).zip(azimuth) {
        *r = (k + dk) * n + a;
    }
    r
}

/// Σ_q weight_q values[index_q · stride + offset + i] for i < N per lane: one record's interpolation, a value at a
/// time across the lanes (gathers).
#[inline(always)]
fn interpolate<const N: usize>(c: &Corners, values: &[f32], stride: usize, offset: usize) -> [Floats; N] {
    let mut v = [Floats::splat(0.0); N];
    for q in 0..c.count {
        let mut base = [0usize; LANES];
        for (b, &k) in base.iter_mut().zip(&c.index[q]) {
            *b = k as usize * stride + offset;
        }
        debug_assert!(base.iter().all(|&b| b + N <= values.len()));
        for (i, v) in v.iter_mut().enumerate() {
            let mut at = Floats::splat(0.0);
            for (a, &b) in at.0.iter_mut().zip(&base) {
                // SAFETY: `corners` clamps its nodes below `nodes − 1` and its azimuths below `azimuths`, so every
                // record index · stride + offset + i (i < N ≤ the record's width) lies inside `values`.
                *a = unsafe { *values.get_unchecked(b + i) };
            }
            *v = c.weight[q].mul_add(at, *v);
        }
    }
    v
}

/// The kernel: the stack's float32 table and options, for records of W values (the roughness, or the anisotropic
/// tables' roughness matrix, then C energies).
pub(super) struct Lanes<'a, const W: usize, const C: usize> {
    t: &'a TableF32,
    symmetric: bool,
    height_correlated: bool,
}

impl<'a, const W: usize, const C: usize> Lanes<'a, W, C> {
    fn new(p: &'a Prepared, t: &'a TableF32) -> Self {
        debug_assert!(t.width == W && p.channels == C);
        let height_correlated = p.opts.g2 == G2Form::HeightCorrelated;
        Lanes { t, symmetric: p.opts.symmetric, height_correlated }
    }
}

/// `$run` with `$k` the kernel of `p`'s record shape (isotropic or anisotropic, 1 or 3 channels); false where the
/// lanes do not cover the stack (no float32 table, the V-cavity, other channel counts).
macro_rules! with_kernel {
    ($p:expr, |$k:ident| $run:expr) => {{
        let p: &Prepared = $p;
        match (p.table_f32.as_ref(), p.opts.g2 != G2Form::VCavity) {
            (Some(t), true) => match (t.azimuths > 1, p.channels) {
                (false, 1) => {
                    let $k = Lanes::<2, 1>::new(p, t);
                    $run
                }
                (false, 3) => {
                    let $k = Lanes::<4, 3>::new(p, t);
                    $run
                }
                (true, 1) => {
                    let $k = Lanes::<4, 1>::new(p, t);
                    $run
                }
                (true, 3) => {
                    let $k = Lanes::<6, 3>::new(p, t);
                    $run
                }
                _ => false,
            },
            _ => false,
        }
    }};
}

/// f of float32 rows by the lanes, where they cover the stack (`with_kernel`).
pub(super) fn eval(p: &Prepared, wi: Rows, wo: Rows, fit: Option<&FitLanes>, out: &mut [f32]) -> bool {
    with_kernel!(p, |k| engine::eval(&k, fit, p.channels, wi, wo, out))
}

/// `Stack.sample`'s rows of float32 (wo, u) by the lanes' mixture (`Prepared::proposals` in lanes).
pub(super) fn sample(p: &Prepared, wo: Rows, u: Rows, out: &mut [f32]) -> bool {
    with_kernel!(p, |k| k.t.lobes < MAX_TERMS && mixture_lanes::sample(&k, p.channels, wo, u, out))
}

impl<const W: usize, const C: usize> engine::Kernel for Lanes<'_, W, C> {
    #[inline(always)]
    fn eval(&self, wi: V3, wo: V3, out: &mut [Floats]) {
        let (t, zero) = (self.t, Floats::splat(0.0));
        let cos_theta = if self.symmetric { symmetric_cosine(wi, wo) } else { wo.z };
        let at = corners(t, cos_theta, wo.x, wo.y);
        let mut f = [zero; C];
        for k in 0..t.lobes {
            let (ggx, smooth, energy) = self.lobe(&at, k);
            // A lobe of roughness 0 is a Dirac delta, not part of f.
            let shape = Floats::select(smooth, zero, ggx_reflection(&ggx, wi, wo).0);
            for (f, e) in f.iter_mut().zip(energy) {
                *f = e.mul_add(shape, *f);
            }
        }
        if !t.diffuse.is_empty() {
            // T↓ at θi and T↑ at θo: the lobes' corners serve for wo unless they were found at |wo·h|.
            let down: [Floats; C] = interpolate(&corners(t, wi.z, wi.x, wi.y), &t.t_down, C, 0);
            let up_at = if self.symmetric { corners(t, wo.z, wo.x, wo.y) } else { at };
            let up: [Floats; C] = interpolate(&up_at, &t.t_up, C, 0);
            let above = wi.z.gt(zero) & wo.z.gt(zero);
            for (c, f) in f.iter_mut().enumerate() {
                *f = *f + Floats::and(above, Floats::splat(t.diffuse[c]) * down[c] * up[c]);
            }
        }
        out[..C].copy_from_slice(&f);
    }
}

impl<const W: usize, const C: usize> Lanes<'_, W, C> {
    /// Lobe k's record interpolated at the corners `at`: its GGX (the anisotropic tables' roughness matrix
    /// eigen-decomposed per lane), where its roughness is 0 (a Dirac delta), and its energies per channel.
    #[inline(always)]
    fn lobe(&self, at: &Corners, k: usize) -> (Ggx, Mask, [Floats; C]) {
        let record: [Floats; W] = interpolate(at, &self.t.record, self.t.lobes * W, k * W);
        let (ax, ay, frame) = if W - C == 3 {
            let (ax, ay, cos, sin) = eigen_frame(record[0], record[1], record[2]);
            (ax, ay, Some((cos, sin)))
        } else {
            (record[0], record[0], None)
        };
        let energy = std::array::from_fn(|c| record[W - C + c]);
        let zero = Floats::splat(0.0);
        let min = Floats::splat(MIN_ALPHA as f32);
        (Ggx::lanes(ax.max(min), ay.max(min), frame, self.height_correlated), ax.le(zero) & ay.le(zero), energy)
    }
}

/// `Prepared::proposals` in lanes: each rough lobe at the viewing direction weighted by its mean energy, then the
/// diffuse base by its mean ρ T↑² / (1 − ρ R̄↑).
impl<const W: usize, const C: usize> Proposals for Lanes<'_, W, C> {
    #[inline(always)]
    fn proposals(&self, wo: V3) -> LaneMixture {
        let (t, zero) = (self.t, Floats::splat(0.0));
        let mut mix = LaneMixture::new();
        let at = corners(t, wo.z, wo.x, wo.y);
        for k in 0..t.lobes {
            let (ggx, smooth, energy) = self.lobe(&at, k);
            mix.push(Floats::select(smooth, zero, mean(&energy)), Some(Visible::Ggx(ggx)));
        }
        if !t.diffuse.is_empty() {
            let up: [Floats; C] = interpolate(&at, &t.t_up, C, 0);
            let mut weight = [zero; C];
            for ((w, &u), &d) in weight.iter_mut().zip(&up).zip(&t.diffuse_proposal) {
                *w = u * u * d;
            }
            mix.push(mean(&weight), None);
        }
        mix
    }
}

/// |wo·h| with h the half vector (Belcour 2018 §6; super::symmetric_cosine), as |wi + wo| / 2 for unit directions
/// (without wo·(wi + wo)'s cancellation); wo·n where wi + wo is zero.
#[inline(always)]
fn symmetric_cosine(wi: V3, wo: V3) -> Floats {
    let h = wi.plus(wo);
    let h2 = h.dot(h);
    Floats::select(h2.gt(Floats::splat(0.0)), 0.5 * h2.sqrt(), wo.z)
}

/// `table::pseudo_angle` in lanes: a monotonic stand-in for the azimuth modulo π (Rajan et al. 2006's octant
/// arctangent), 0 at the normal.
#[inline(always)]
fn pseudo_angle(x: Floats, y: Floats) -> Floats {
    let fold: Mask = y.lt(Floats::splat(0.0));
    let (x, y) = (Floats::select(fold, -x, x), Floats::select(fold, -y, y));
    let ax = x.max(-x);
    let t = ax.min(y) / ax.max(y);
    let a = t * (0.273 * (1.0 - t) + FRAC_PI_4);
    let a = Floats::select(y.gt(ax), FRAC_PI_2 - a, a);
    let p = Floats::select(x.lt(Floats::splat(0.0)), PI - a, a);
    // NaN (the normal: 0/0) and π fold to 0.
    Floats::select(p.lt(Floats::splat(PI)), p, Floats::splat(0.0))
}

/// `Cov::eigen_frame` in lanes: (λ₁, λ₂, cos, sin) of the symmetric matrix (xx, xy, yy), the eigenvector of λ₁ ≥ λ₂
/// in (−π/2, π/2], (v, v, 1, 0) for vI.
#[inline(always)]
fn eigen_frame(xx: Floats, xy: Floats, yy: Floats) -> (Floats, Floats, Floats, Floats) {
    let zero = Floats::splat(0.0);
    let (mean, half) = (0.5 * (xx + yy), 0.5 * (xx - yy));
    let r = half.mul_add(half, xy * xy).sqrt();
    let upper = half.ge(zero);
    let (x, y) = (Floats::select(upper, half + r, xy), Floats::select(upper, xy, r - half));
    let flip = x.lt(zero);
    let (x, y) = (Floats::select(flip, -x, x), Floats::select(flip, -y, y));
    let inv = 1.0 / x.mul_add(x, y * y).sqrt();
    let round = r.gt(zero);
    let (cos, sin) = (Floats::select(round, x * inv, Floats::splat(1.0)), Floats::and(round, y * inv));
    (mean + r, mean - r, cos, sin)
}

#[cfg(test)]
mod tests {
    use super::super::cov::Cov;
    use super::super::table::pseudo_angle as pseudo_angle_f64;
    use super::*;

    #[test]
    fn pseudo_angle_and_eigen_frame_are_their_float64_twins() {
        let (mut worst_p, mut worst_e) = (0.0f64, 0.0f64);
        for k in 0..LANES * 500 {
            let phi = 2.0 * std::f64::consts::PI * k as f64 / (LANES * 500) as f64;
            let (x, y) = ((phi.cos() as f32) as f64, (phi.sin() as f32) as f64);
            let p = pseudo_angle(Floats::splat(x as f32), Floats::splat(y as f32)).0[0] as f64;
            // Both fold at π: compare on the circle.
            let d = (p - pseudo_angle_f64(x, y)).abs();
            worst_p = worst_p.max(d.min(std::f64::consts::PI - d));
            let c = Cov::oriented(0.02 + 0.5 * (k % 7) as f64 / 7.0, 0.01 + 0.3 * (k % 5) as f64 / 5.0, phi);
            let (l1, l2, cos, sin) = c.eigen_frame();
            let s = |v: f64| Floats::splat(v as f32);
            let (m1, m2, mc, ms) = eigen_frame(s(c.xx), s(c.xy), s(c.yy));
            let e = [(m1.0[0], l1), (m2.0[0], l2), (mc.0[0], cos), (ms.0[0], sin)];
            worst_e = e.iter().fold(worst_e, |w, &(a, b)| w.max((a as f64 - b).abs()));
        }
        assert!(worst_p < 1e-6, "pseudo angle {worst_p}");
        assert!(worst_e < 1e-6, "eigen frame {worst_e}");
        let (l1, l2, c, s) = eigen_frame(Floats::splat(0.2), Floats::splat(0.0), Floats::splat(0.2));
        assert_eq!((l1.0[0], l2.0[0], c.0[0], s.0[0]), (0.2, 0.2, 1.0, 0.0));
        assert_eq!(pseudo_angle(Floats::splat(0.0), Floats::splat(0.0)).0[0], 0.0);
    }
}
