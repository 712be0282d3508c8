//! The adding-doubling tabulated over the viewing direction, and the block evaluator that interpolates it.

use super::adding::{self, DiffuseBase, Step};
use super::cov::Cov;
use super::{add_diffuse, add_lobe, symmetric_cosine, Options, Prepared};
use crate::bsdf;
use crate::dual::Real;
use crate::models::common::block::{eval_rows, BLOCK};
use crate::optics::distribution::{Distribution, G2Form, Microfacet};
use crate::tables;
use glam::DVec3;
use rayon::prelude::*;
use std::f64::consts::FRAC_1_PI;

/// Everything the adding-doubling produces, tabulated over the cosine it is run for, at nodes uniform in √cos θ
/// (denser at grazing angles, where a smooth top's Fresnel term rises steeply): evaluation interpolates linearly
/// instead of re-running the loop. The interpolation error is measured and asserted in tests/test_belcour.py.
/// Anisotropic stacks add the viewing azimuth φ as a second axis (the statistics have period π in φ): 128 cosine
/// nodes x 32 azimuths uniform in `pseudo_angle` (nearly uniform in φ), bilinear.
pub(super) const TABLE_NODES: usize = 512;
pub(super) const ANISO_NODES: usize = 128;
pub(super) const ANISO_AZIMUTHS: usize = 32;

pub(super) struct LobeTable<T = f64> {
    pub(super) lobes: usize,
    pub(super) nodes: usize,
    pub(super) azimuths: usize,
    /// Values per lobe: the GGX roughness (isotropic stacks) or the roughness matrix (`Cov::alpha_matrix`, xx, xy,
    /// yy; anisotropic stacks), then the energy per channel. No h⁻¹ is evaluated per evaluation.
    pub(super) width: usize,
    /// [node][azimuth][lobe][width]: each run's record is contiguous, so that interpolation reads whole records.
    pub(super) record: Vec<T>,
    /// [node][azimuth][channel]: energy transmitted down to the base (T0i) and up from it (Ti0).
    pub(super) t_down: Vec<T>,
    pub(super) t_up: Vec<T>,
}

/// A lobe as sampling and the gradient see it: GGX (αx, αy, tangent angle) and energy per channel.
pub(super) type GgxLobe<T = f64> = ((T, T, T), Vec<T>);

/// The table corners of one direction: run index and bilinear weight of each of the four.
pub(super) type Corner = [(i32, f64); 4];

/// Table corners of up to BLOCK rows: run index and bilinear weight of each of the four corners, per row.
pub(super) struct Corners {
    pub(super) index: [[i32; BLOCK]; 4],
    pub(super) weight: [[f64; BLOCK]; 4],
}

impl<T: Real> LobeTable<T> {
    /// The adding-doubling of `steps` run at every node, in f64 (`eval`'s table) or in Duals (the gradient of the
    /// model that table interpolates).
    pub(super) fn new(steps: &[Step<T>], opts: &Options, channels: usize, anisotropic: bool) -> Self {
        let c = channels;
        let (nodes, azimuths) = if anisotropic { (ANISO_NODES, ANISO_AZIMUTHS) } else { (TABLE_NODES, 1) };
        let runs: Vec<_> = (0..nodes * azimuths)
            .into_par_iter()
            .map(|k| {
                let mu = ((k / azimuths) as f64 / (nodes - 1) as f64).powi(2);
                let p = std::f64::consts::PI * (k % azimuths) as f64 / azimuths as f64;
                let (cos, sin) = direction_of_pseudo_angle(p);
                adding::adding(steps, opts, c, T::from(mu), cos, sin)
            })
            .collect();
        let lobes = runs.iter().map(|(l, _)| l.len()).max().unwrap_or(0);
        let width = if anisotropic { 3 } else { 1 } + c;
        let mut t = LobeTable {
            lobes,
            nodes,
            azimuths,
            width,
            record: vec![T::from(0.0); runs.len() * lobes * width],
            t_down: Vec::with_capacity(runs.len() * c),
            t_up: Vec::with_capacity(runs.len() * c),
        };
        for (k, (l, state)) in runs.iter().enumerate() {
            for (j, lobe) in l.iter().enumerate() {
                let v = &mut t.record[(k * lobes + j) * width..][..width];
                let m = lobe.cov.alpha_matrix();
                let alpha: &[T] = if anisotropic { &[m.xx, m.xy, m.yy] } else { &[lobe.roughness().0] };
                v[..alpha.len()].copy_from_slice(alpha);
                v[alpha.len()..].copy_from_slice(&lobe.energy);
            }
            t.t_down.extend_from_slice(&state.t0i);
            t.t_up.extend_from_slice(&state.ti0);
        }
        t
    }

    /// The lobes at the corners `c` (`corner_of` the viewing direction, at cos θo or |wo·h| with `symmetric`),
    /// interpolated as the block evaluator does: per lobe its GGX roughness (αx, αy, tangent angle) and energies.
    pub(super) fn lobes_at(&self, c: &Corner) -> Vec<GgxLobe<T>> {
        (0..self.lobes)
            .map(|j| {
                (self.roughness_at(c, j), (0..self.width - self.first()).map(|ch| self.energy_of(c, j, ch)).collect())
            })
            .collect()
    }

    /// Where a lobe's energies start in its record: after its roughness matrix (xx, xy, yy) or its one roughness.
    fn first(&self) -> usize {
        if self.azimuths > 1 {
            3
        } else {
            1
        }
    }

    /// Value i of lobe j's record at the corners `c`.
    #[inline(always)]
    fn value_at(&self, c: &Corner, j: usize, i: usize) -> T {
        interpolate(c, &self.record, self.lobes * self.width, j * self.width + i)
    }

    /// Lobe j's GGX roughness (αx, αy, tangent angle) at the corners `c`: its interpolated roughness matrix
    /// eigen-decomposed (Yamaguchi et al. 2019), or its one roughness.
    #[inline(always)]
    pub(super) fn roughness_at(&self, c: &Corner, j: usize) -> (T, T, T) {
        if self.azimuths > 1 {
            let value = |i: usize| self.value_at(c, j, i);
            let (ax, ay, cos, sin) = Cov { xx: value(0), xy: value(1), yy: value(2) }.eigen_frame();
            (ax, ay, sin.atan2(cos))
        } else {
            let alpha = self.value_at(c, j, 0);
            (alpha, alpha, T::from(0.0))
        }
    }

    /// Lobe j's energy in channel ch at the corners `c`.
    #[inline(always)]
    pub(super) fn energy_of(&self, c: &Corner, j: usize, ch: usize) -> T {
        self.value_at(c, j, self.first() + ch)
    }

    /// The energy transmitted down to the base (`t_down`) or up from it (`t_up`) in channel ch at the corners `c`.
    #[inline(always)]
    pub(super) fn energy_at(&self, values: &[T], c: &Corner, ch: usize) -> T {
        interpolate(c, values, values.len() / (self.nodes * self.azimuths), ch)
    }

    /// The corners of the direction w looked up at the cosine `cos_theta` (see `corners`).
    #[inline(always)]
    pub(super) fn corner_of(&self, cos_theta: f64, w: DVec3) -> Corner {
        let v = if self.azimuths > 1 { pseudo_angle(w.x, w.y) * (FRAC_1_PI * self.azimuths as f64) } else { 0.0 };
        self.corner(cos_theta, v)
    }

    /// The corners of one direction: its cosine θ to look up, and its `pseudo_angle` in units of the azimuths'
    /// spacing `v`.
    #[inline(always)]
    fn corner(&self, cos_theta: f64, v: f64) -> Corner {
        let azimuths = self.azimuths as i32;
        let (k, fk) = tables::node(cos_theta.clamp(0.0, 1.0).sqrt(), self.nodes);
        let k = k as i32;
        let a = (v as i32).min(azimuths - 1);
        let fa = v - a as f64;
        let b = if a + 1 == azimuths { 0 } else { a + 1 };
        [
            (k * azimuths + a, (1.0 - fk) * (1.0 - fa)),
            ((k + 1) * azimuths + a, fk * (1.0 - fa)),
            (k * azimuths + b, (1.0 - fk) * fa),
            ((k + 1) * azimuths + b, fk * fa),
        ]
    }

    /// Bilinear interpolation corners of directions (columns x, y, and the cosine θ to look up) in the table: linear
    /// in √cos θ and in the azimuth's `pseudo_angle` (period π); isotropic tables use the first two corners only.
    #[inline(always)]
    fn corners(&self, cos_theta: &[f64], x: &[f64], y: &[f64]) -> Corners {
        let mut c = Corners { index: [[0; BLOCK]; 4], weight: [[0.0; BLOCK]; 4] };
        let (n, azimuths) = (cos_theta.len(), self.azimuths);
        // Each pass a loop of its own, so that it vectorizes (positions as i32: AVX2 converts f64 to i32 only).
        let mut v = [0.0; BLOCK];
        if azimuths > 1 {
            for r in 0..n {
                v[r] = pseudo_angle(x[r], y[r]) * (FRAC_1_PI * azimuths as f64);
            }
        }
        for r in 0..n {
            for (q, (index, weight)) in self.corner(cos_theta[r], v[r]).into_iter().enumerate() {
                (c.index[q][r], c.weight[q][r]) = (index, weight);
            }
        }
        c
    }
}

/// Value `i` of `values` (records of `width`) interpolated at the corners `c`.
#[inline(always)]
fn interpolate<T: Real>(c: &Corner, values: &[T], width: usize, i: usize) -> T {
    // Corners of weight 0 (an isotropic table's last two) add nothing.
    c.iter().filter(|&&(_, w)| w != 0.0).fold(T::from(0.0), |sum, &(k, w)| sum + values[k as usize * width + i] * w)
}

/// f at (wi, wo) from the table `t`, as `eval_columns` interpolates it, row by row: in Duals, the gradient of the
/// interpolated model.
pub(super) fn eval_table<T: Real>(
    t: &LobeTable<T>,
    diffuse: Option<&DiffuseBase<T>>,
    opts: &Options,
    wi: DVec3,
    wo: DVec3,
    out: &mut [T],
) {
    out.fill(T::from(0.0));
    if wi.z <= 0.0 || wo.z <= 0.0 {
        return;
    }
    let cos_theta = if opts.symmetric { symmetric_cosine(wi, wo) } else { wo.z };
    let view = t.corner_of(cos_theta, wo);
    for j in 0..t.lobes {
        add_lobe(opts.g2, t.roughness_at(&view, j), |ch| t.energy_of(&view, j, ch), wi, wo, out);
    }
    if diffuse.is_some() {
        let (down, up) = (t.corner_of(wi.z, wi), t.corner_of(wo.z, wo));
        add_diffuse(diffuse, |ch| t.energy_at(&t.t_down, &down, ch), |ch| t.energy_at(&t.t_up, &up, ch), out);
    }
}

impl Prepared {
    /// `eval` for a block of columns (see Model::eval_block). A tabulated stack runs in passes over the
    /// block: table corners per row; the records of all lobes interpolated per row (contiguous reads); then per lobe
    /// its roughness (eigen-decomposed for anisotropic stacks), its GGX shape (a branch-free loop that vectorizes)
    /// and its energies per channel; then the diffuse base. Without a table, row by row.
    #[inline(always)]
    pub(super) fn eval_columns(&self, wi: [&[f64]; 3], wo: [&[f64]; 3], out: &mut [f64]) {
        let n = wi[0].len();
        let c = self.channels;
        let Some(t) = &self.table else {
            return eval_rows(wi, wo, out, |_, wi, wo, o| self.eval(wi, wo, o));
        };
        let ([ix, iy, iz], [ox, oy, oz]) = (wi.map(|col| &col[..n]), wo.map(|col| &col[..n]));
        let mut above = [false; BLOCK];
        let mut cos_theta = [0.0; BLOCK];
        for r in 0..n {
            above[r] = iz[r] > 0.0 && oz[r] > 0.0;
            cos_theta[r] = if self.opts.symmetric && above[r] {
                symmetric_cosine(DVec3::new(ix[r], iy[r], iz[r]), DVec3::new(ox[r], oy[r], oz[r]))
            } else {
                oz[r]
            };
        }
        let (above, anisotropic) = (&above[..n], t.azimuths > 1);
        let corners = t.corners(&cos_theta[..n], ox, oy);
        let ([mut ax, mut ay, mut cos, mut sin], mut shape) = ([[0.0; BLOCK]; 4], [0.0; BLOCK]);
        if anisotropic {
            // Per row, the records of all lobes interpolated at once (contiguous reads of the four corners).
            let w = t.lobes * t.width;
            let mut values = vec![0.0; n * w];
            for (r, v) in values.chunks_exact_mut(w).enumerate() {
                let [r0, r1, r2, r3] = std::array::from_fn(|q| &t.record[corners.index[q][r] as usize * w..][..w]);
                let [w0, w1, w2, w3] = std::array::from_fn(|q| corners.weight[q][r]);
                for i in 0..w {
                    v[i] = w0 * r0[i] + w1 * r1[i] + w2 * r2[i] + w3 * r3[i];
                }
            }
            for j in 0..t.lobes {
                let lobe = |r: usize| &values[r * w + j * t.width..][..t.width];
                // The roughness matrices as columns (xx, xy, yy in ax, ay, cos), then eigen-decomposed in place.
                for r in 0..n {
                    (ax[r], ay[r], cos[r]) = (lobe(r)[0], lobe(r)[1], lobe(r)[2]);
                }
                for r in 0..n {
                    (ax[r], ay[r], cos[r], sin[r]) = Cov { xx: ax[r], xy: ay[r], yy: cos[r] }.eigen_frame();
                }
                let frame = Some([&cos[..n], &sin[..n]]);
                ggx_shapes(self.opts.g2, [&ax[..n], &ay[..n]], frame, above, wi, wo, &mut shape);
                for (r, o) in out.chunks_exact_mut(c).enumerate() {
                    for (o, e) in o.iter_mut().zip(&lobe(r)[3..]) {
                        *o += e * shape[r];
                    }
                }
            }
        } else {
            // Two corners along cos θ: each value gathered from its two records.
            let (k, weight) = ([&corners.index[0][..n], &corners.index[1][..n]], &corners.weight);
            for j in 0..t.lobes {
                let at = |q: usize, r: usize| (k[q][r] as usize * t.lobes + j) * t.width;
                for r in 0..n {
                    ax[r] = weight[0][r] * t.record[at(0, r)] + weight[1][r] * t.record[at(1, r)];
                }
                ggx_shapes(self.opts.g2, [&ax[..n], &ax[..n]], None, above, wi, wo, &mut shape);
                for (r, o) in out.chunks_exact_mut(c).enumerate() {
                    let (a, b) = (at(0, r) + 1, at(1, r) + 1);
                    for (ch, o) in o.iter_mut().enumerate() {
                        *o += (weight[0][r] * t.record[a + ch] + weight[1][r] * t.record[b + ch]) * shape[r];
                    }
                }
            }
        }
        if self.diffuse.is_some() {
            // T↓ at θi and T↑ at θo: the lobes' corners serve for wo unless they were found at |wo·h|.
            let down_at = t.corners(iz, ix, iy);
            let up_symmetric = self.opts.symmetric.then(|| t.corners(oz, ox, oy));
            let up_at = up_symmetric.as_ref().unwrap_or(&corners);
            for (r, o) in out.chunks_exact_mut(c).enumerate().filter(|&(r, _)| above[r]) {
                let at = |corners: &Corners, table: &[f64], ch: usize| {
                    (0..4).map(|q| corners.weight[q][r] * table[corners.index[q][r] as usize * c + ch]).sum::<f64>()
                };
                super::add_diffuse(
                    self.diffuse.as_ref(),
                    |ch| at(&down_at, &t.t_down, ch),
                    |ch| at(up_at, &t.t_up, ch),
                    o,
                );
            }
        }
    }
}

/// D G2 / (4 cos θi cos θo) of GGX lobes of roughness `alpha` = [αx, αy] per row, along the tangent frame `frame`
/// = [cos, sin] per row (None: the local frame), for a block of columns; 0 where a row is not above the surface or
/// its lobe is a Dirac delta (α = 0).
#[inline(always)]
fn ggx_shapes(
    form: G2Form,
    alpha: [&[f64]; 2],
    frame: Option<[&[f64]; 2]>,
    above: &[bool],
    wi: [&[f64]; 3],
    wo: [&[f64]; 3],
    shape: &mut [f64],
) {
    // One loop per G2 form, the form a known constant in each, so that it vectorizes.
    #[inline(always)]
    fn shapes(
        form: G2Form,
        alpha: [&[f64]; 2],
        frame: Option<[&[f64]; 2]>,
        above: &[bool],
        wi: [&[f64]; 3],
        wo: [&[f64]; 3],
        shape: &mut [f64],
    ) {
        let n = above.len();
        let ([ax, ay], shape) = (alpha.map(|col| &col[..n]), &mut shape[..n]);
        let ([ix, iy, iz], [ox, oy, oz]) = (wi.map(|col| &col[..n]), wo.map(|col| &col[..n]));
        let frame = frame.map(|f| f.map(|col| &col[..n]));
        let ggx = Microfacet::new(Distribution::Ggx, 1.0, 1.0, 0.0);
        for r in 0..n {
            let (wi, wo) = (DVec3::new(ix[r], iy[r], iz[r]), DVec3::new(ox[r], oy[r], oz[r]));
            let mf = match frame {
                Some([cos, sin]) => ggx.with_frame(ax[r], ay[r], cos[r], sin[r]),
                None => ggx.with_alpha(ax[r], ay[r]),
            };
            let f = bsdf::reflection_geometry(&mf, form, wi, wo).map_or(0.0, |(g, _)| g);
            shape[r] = if above[r] { f } else { 0.0 };
        }
    }
    match form {
        G2Form::HeightCorrelated => shapes(G2Form::HeightCorrelated, alpha, frame, above, wi, wo, shape),
        G2Form::Separable => shapes(G2Form::Separable, alpha, frame, above, wi, wo, shape),
        G2Form::VCavity => shapes(G2Form::VCavity, alpha, frame, above, wi, wo, shape),
    }
}

/// A monotonic stand-in for the azimuth φ modulo π, without trigonometric calls: (x, y) folded into the upper
/// half-plane, then the octant's atan(t) by t (π/4 + 0.273 (1 − t)) (Rajan et al. 2006, within 0.004 rad of φ), so
/// that table nodes uniform in it are nearly uniform in φ. In [0, π): φ = π folds to 0, and so does the normal.
#[inline(always)]
pub(super) fn pseudo_angle(x: f64, y: f64) -> f64 {
    use std::f64::consts::{FRAC_PI_2, FRAC_PI_4, PI};
    let (x, y) = if y < 0.0 { (-x, -y) } else { (x, y) };
    let t = x.abs().min(y) / x.abs().max(y);
    let a = t * (FRAC_PI_4 + 0.273 * (1.0 - t));
    let a = if y > x.abs() { FRAC_PI_2 - a } else { a };
    let p = if x < 0.0 { PI - a } else { a };
    if p.is_finite() && p < PI {
        p
    } else {
        0.0
    }
}

/// (cos φ, sin φ) of the azimuth whose `pseudo_angle` is p ∈ [0, π) (by bisection: it is within 0.004 of φ).
pub(super) fn direction_of_pseudo_angle(p: f64) -> (f64, f64) {
    let (mut lo, mut hi) = ((p - 0.01).max(0.0), (p + 0.01).min(std::f64::consts::PI));
    for _ in 0..60 {
        let mid = 0.5 * (lo + hi);
        if pseudo_angle(mid.cos(), mid.sin()) < p {
            lo = mid
        } else {
            hi = mid
        }
    }
    let phi = 0.5 * (lo + hi);
    (phi.cos(), phi.sin())
}

/// (cos φ, sin φ) of a direction's azimuth; (1, 0) along the normal.
pub(super) fn azimuth(w: DVec3) -> (f64, f64) {
    let r = w.x.hypot(w.y);
    if r == 0.0 {
        (1.0, 0.0)
    } else {
        (w.x / r, w.y / r)
    }
}
