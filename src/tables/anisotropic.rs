//! The BRDF of an anisotropic stack (Yamaguchi et al. 2019's case: layers of anisotropic roughness, each with its own
//! tangent angle) by adding-doubling on a grid of directions that keeps both azimuths: the isotropic solver's
//! transport (tables/adding_doubling.rs, the reference walk's boundaries and slabs) on zenith cells × azimuth bins.
//!
//! Discretization. NZ zenith cells (the isotropic solver's x = √(1 − cos θ), every other edge of its grid) times NA
//! bins of the travel direction's azimuth over [0, 2π), centred on φ_p = p Δφ. An operator maps the radiance in
//! incident cell (j, p) to the radiance in outgoing cell (o, q):
//!   S[(o, q), (j, p)] = f̄ w_j Δφ,   w_j = Δu_j / 2,
//! f̄ the BSDF averaged over both cells (Gauss points in u and two azimuths across the outgoing bin, the incident
//! cell's centre). Every boundary is symmetric under a half turn of both azimuths (microfacet distributions are
//! centrally symmetric), so the radiance splits into two classes, even and odd under φ → φ + π, which no operator
//! mixes: each is solved on its own with NZ · NA/2 unknowns (two dense 1536 × 1536 systems instead of one of 3072).
//! The mirror symmetries of an aligned stack would split them again; layers with their own tangent angles have none.
//!
//! Anisotropic boundaries are projected on this grid, each column rescaled to the energy that importance sampling of
//! their microfacets gives (as the isotropic solver does). Isotropic boundaries and slabs come from the isotropic
//! solver (64 cells, 64 Fourier orders): coarsened to these cells and expanded in azimuth, a Dirac in azimuth (a
//! smooth boundary, an unscattered beam) exactly as the identity. The layers combine by the adding equations, class
//! by class, and the table stores f less the top's reflection at the cells' edges in zenith and the bins' centres in
//! azimuth.

use super::adding_doubling::{self as iso, Cells, Paths, Shared, N_THETA, ORDERS};
use crate::error::Result;
use crate::stack::Stack;
use crate::transport::{Base, ChannelStack, Interface, Microsurface};
use glam::DVec3;
use rayon::prelude::*;
use std::f64::consts::PI;

/// Zenith cells over [0, π/2], of equal Δx in x = √(1 − cos θ).
pub const NZ: usize = 32;
/// Azimuth bins over [0, 2π).
pub const NA: usize = 96;
/// Bins per symmetry class: those of φ ∈ [0, π).
const HALF: usize = NA / 2;
/// Unknowns per class.
const D: usize = NZ * HALF;
/// Zenith nodes of the table: the cells' edges.
pub const NODES: usize = NZ + 1;
/// The table's azimuths of wi: φi = a Δφ for a = 0 … NA/2 (a half turn: f is unchanged when both azimuths turn by π).
pub const AZIMUTHS_I: usize = HALF + 1;
/// Width of an azimuth bin.
pub const DPHI: f64 = 2.0 * PI / NA as f64;
/// Values per channel of a table: (θi node, φi node, θo node, φo node).
pub const LEN: usize = NODES * AZIMUTHS_I * NODES * NA;

/// A D × D matrix of one class, row-major: m[(o * HALF + q) * D + j * HALF + p].
type Mat = Vec<f64>;
/// An operator: its even and odd classes.
type Op = [Mat; 2];

/// A layer's four operators, as in the isotropic solver.
struct Operators {
    r_top: Op,
    r_bottom: Op,
    t_down: Op,
    t_up: Op,
}

/// True when `b` is a rough boundary of anisotropic roughness.
fn anisotropic(s: &ChannelStack, b: usize) -> bool {
    let mf = match (s.interfaces.get(b), &s.base) {
        (Some(it), _) => &it.mf,
        (None, Base::Conductor { mf, .. }) => mf,
        (None, Base::Diffuse { .. }) => return false,
    };
    !mf.is_smooth() && mf.alpha_x != mf.alpha_y
}

/// True when any layer of `stack` has anisotropic roughness (these stacks are tabulated here).
pub fn is_anisotropic(stack: &Stack, surface: Microsurface) -> bool {
    let s = ChannelStack::new(stack, 0, surface);
    (0..=s.interfaces.len()).any(|b| anisotropic(&s, b))
}

/// a · b (matrixmultiply's dgemm).
fn mul(a: &[f64], b: &[f64]) -> Mat {
    assert!(a.len() == D * D && b.len() == D * D);
    let mut c = vec![0.0; D * D];
    let n = D as isize;
    // SAFETY: a, b and c hold D × D values, row-major with row stride D.
    unsafe {
        matrixmultiply::dgemm(D, D, D, 1.0, a.as_ptr(), n, 1, b.as_ptr(), n, 1, 0.0, c.as_mut_ptr(), n, 1);
    }
    c
}

fn add(a: &[f64], b: &[f64]) -> Mat {
    a.iter().zip(b).map(|(a, b)| a + b).collect()
}

/// Per class: f(even), f(odd), in parallel.
fn classes(f: impl Fn(usize) -> Mat + Sync) -> Op {
    let (even, odd) = rayon::join(|| f(0), || f(1));
    [even, odd]
}

/// The radiance's outgoing cells: coarse cell O is the fine cells `O * R .. (O + 1) * R` of the isotropic grid.
const R: usize = N_THETA / NZ;

/// An isotropic solver's operator (N_THETA cells, ORDERS cosine orders of the azimuth between the travel directions)
/// on this grid: a coarse cell's radiance is the w-weighted mean of its fine cells', its incident radiance the same in
/// each, S[O][J] = Σ_{o ∈ O} (w_o / w_O) Σ_{j ∈ J} S[o][j]; in azimuth the kernel Σ_m S_m cos(m Δ) / (π (1 + δ_m0))
/// averaged over both bins (× sinc²(m Δφ / 2)), the even orders in the even class and the odd ones in the odd class.
/// An operator equal in every order (a Dirac in azimuth) is the identity in azimuth.
fn from_isotropic(fine: &Cells, coarse: &Cells, op: &iso::Op) -> Op {
    let dirac = op.iter().all(|m| *m == op[0]);
    let orders = if dirac { 1 } else { ORDERS };
    let zenith: Vec<Vec<f64>> = op[..orders]
        .iter()
        .map(|m| {
            let mut c = vec![0.0; NZ * NZ];
            for o in 0..N_THETA {
                for j in 0..N_THETA {
                    c[o / R * NZ + j / R] += fine.w[o] / coarse.w[o / R] * m[o * N_THETA + j];
                }
            }
            c
        })
        .collect();
    if dirac {
        let c = &zenith[0];
        let m: Mat = (0..D * D)
            .map(|k| {
                let ((o, q), (j, p)) = (((k / D) / HALF, (k / D) % HALF), ((k % D) / HALF, (k % D) % HALF));
                if q == p {
                    c[o * NZ + j]
                } else {
                    0.0
                }
            })
            .collect();
        return [m.clone(), m];
    }
    // 2 c_m(Δ) for Δ = q − p over a half turn, m of the class's parity.
    let kernel = |class: usize, m: usize, delta: usize| {
        let x = m as f64 * DPHI / 2.0;
        let sinc = if m == 0 { 1.0 } else { x.sin() / x };
        let norm = PI * if m == 0 { 2.0 } else { 1.0 };
        debug_assert_eq!(m % 2, class);
        2.0 * DPHI * (m as f64 * delta as f64 * DPHI).cos() * sinc * sinc / norm
    };
    classes(|class| {
        let orders: Vec<usize> = (class..ORDERS).step_by(2).collect();
        let c: Vec<Vec<f64>> = (0..HALF).map(|d| orders.iter().map(|&m| kernel(class, m, d)).collect()).collect();
        let mut out = vec![0.0; D * D];
        out.par_chunks_mut(HALF * D).enumerate().for_each(|(o, rows)| {
            for q in 0..HALF {
                for j in 0..NZ {
                    for p in 0..HALF {
                        let c = &c[(q + HALF - p) % HALF];
                        // Δ and Δ + half turn: the same value for the class (cos(m (Δ + π)) = (−1)^m cos(m Δ)).
                        let sign = if q < p && class == 1 { -1.0 } else { 1.0 };
                        let v: f64 = orders.iter().zip(c).map(|(&m, c)| zenith[m][o * NZ + j] * c).sum();
                        rows[q * D + j * HALF + p] = sign * v;
                    }
                }
            }
        });
        out
    })
}

fn operators_from_isotropic(fine: &Cells, coarse: &Cells, ops: &iso::Operators) -> Operators {
    let f = |op| from_isotropic(fine, coarse, op);
    Operators { r_top: f(&ops.r_top), r_bottom: f(&ops.r_bottom), t_down: f(&ops.t_down), t_up: f(&ops.t_up) }
}

/// Visible normals per Gauss point of the energy that a column is rescaled to (a quarter of the isotropic solver's:
/// there are 48 times as many columns).
const ENERGY_NORMALS: usize = 1024;

/// Outgoing sample points across a bin: two azimuths at ±Δφ/4.
const BIN_POINTS: [f64; 2] = [-0.25, 0.25];

/// The operators, in both classes and not yet rescaled, of K boundaries (or channels) whose kernels `f(w_light, w_view,
/// out)` write f for each into out[..K]: light arriving on the side `z_light`, travelling at azimuth φ_p, leaving on
/// the side `z_view`. f̄ by the incident cell's Gauss points at the bin's centre and the outgoing cell's Gauss points
/// at `BIN_POINTS`.
fn project<const K: usize>(
    cells: &Cells,
    z_light: f64,
    z_view: f64,
    f: &(dyn Fn(DVec3, DVec3, &mut [f64; K]) + Sync),
) -> [Op; K] {
    // Column (j, p) of the full operator for p < HALF, all NZ × NA outgoing cells; the other half of the columns
    // follows by the half-turn symmetry.
    // The outgoing sample directions of cell (o, q), with their weights: the same for every column.
    let views: Vec<Vec<(DVec3, f64)>> = (0..NZ * NA)
        .map(|k| {
            let (o, q) = (k / NA, k % NA);
            let azimuths = BIN_POINTS.iter().map(|b| ((q as f64 + b) * DPHI).sin_cos());
            let azimuths: Vec<(f64, f64)> = azimuths.map(|(sin, cos)| (cos, sin)).collect();
            let scale = DPHI / (BIN_POINTS.len() as f64 * cells.w[o]);
            let points = cells.points(o).iter();
            points
                .flat_map(|&(u, v)| azimuths.iter().map(move |&a| (iso::direction(u, a, z_view), v * scale)))
                .collect()
        })
        .collect();
    let columns: Vec<Vec<[f64; K]>> = (0..D)
        .into_par_iter()
        .map(|col| {
            let (j, p) = (col / HALF, col % HALF);
            let phi = p as f64 * DPHI;
            let mut column = vec![[0.0; K]; NZ * NA];
            let mut v = [0.0; K];
            for &(us, vs) in cells.points(j) {
                let w_light = iso::direction(us, (-phi.cos(), -phi.sin()), z_light);
                for (c, view) in column.iter_mut().zip(&views) {
                    for &(w_view, weight) in view {
                        f(w_light, w_view, &mut v);
                        (0..K).for_each(|k| c[k] += v[k] * weight * vs);
                    }
                }
            }
            column
        })
        .collect();
    std::array::from_fn(|k| {
        classes(|class| {
            let sign = if class == 0 { 1.0 } else { -1.0 };
            let mut out = vec![0.0; D * D];
            for (col, column) in columns.iter().enumerate() {
                for o in 0..NZ {
                    for q in 0..HALF {
                        out[(o * HALF + q) * D + col] = column[o * NA + q][k] + sign * column[o * NA + q + HALF][k];
                    }
                }
            }
            out
        })
    })
}

/// The energies `energy(w)` (K of them) of each incident column (j, p)'s direction w (on the +z side, averaged over
/// the cell's Gauss points), which `rescale` makes the columns carry.
fn energies<const K: usize>(cells: &Cells, energy: &(dyn Fn(DVec3) -> [f64; K] + Sync)) -> Vec<[f64; K]> {
    (0..D)
        .into_par_iter()
        .map(|col| {
            let (j, p) = (col / HALF, col % HALF);
            let phi = p as f64 * DPHI;
            let mut e = [0.0; K];
            for &(u, v) in cells.points(j) {
                let x = energy(iso::direction(u, (-phi.cos(), -phi.sin()), 1.0));
                (0..K).for_each(|k| e[k] += x[k] * v / cells.w[j]);
            }
            e
        })
        .collect()
}

/// Rescales each incident column (j, p) of `op` (and so (j, p + NA/2)) to carry the energy `target(col)`: the
/// quadrature misses narrow lobes, importance sampling of the microfacets does not. A column's energy
/// Σ_{o, q} S w_o / w_j is its even class's column sum.
fn rescale(cells: &Cells, op: &mut Op, target: impl Fn(usize) -> f64 + Sync) {
    let factors: Vec<f64> = (0..D)
        .into_par_iter()
        .map(|col| {
            let e: f64 =
                (0..D).map(|row| op[0][row * D + col] * cells.w[row / HALF]).sum::<f64>() / cells.w[col / HALF];
            if e > 0.0 {
                target(col) / e
            } else {
                1.0
            }
        })
        .collect();
    for m in op.iter_mut() {
        m.par_chunks_mut(D).for_each(|row| row.iter_mut().zip(&factors).for_each(|(v, k)| *v *= k));
    }
}

/// The operators of anisotropic interface b of `s`. Transmission upward by generalized reciprocity from transmission
/// downward (Walter et al. 2007 §5.2: f(w_below, w_above) = f(w_above, w_below) / η², so that with the half turn
/// S_up[(o, q), (j, p)] = S_down[(j, p), (o, q)] w_j / (w_o η²)), each rescaled to its own energies.
fn interface(cells: &Cells, s: &ChannelStack, b: usize) -> Operators {
    let it = &s.interfaces[b];
    let f = |w_light: DVec3, w_view: DVec3, out: &mut [f64; 1]| out[0] = s.boundary_f(b, w_light, w_view);
    // Seen from below, the microfacets are those seen from above (D is even in m's z): the energy at w with 1/η.
    let energy = |eta: f64| energies(cells, &|w| iso::interface_energy(&it.mf, s.g2, eta, w, ENERGY_NORMALS).into());
    let (above, below) = rayon::join(|| energy(it.eta), || energy(1.0 / it.eta));
    let ([mut r_top], [mut r_bottom], [mut t_down]) =
        (project(cells, 1.0, 1.0, &f), project(cells, -1.0, -1.0, &f), project(cells, 1.0, -1.0, &f));
    let scale = |row: usize, col: usize| cells.w[col / HALF] / (cells.w[row / HALF] * it.eta * it.eta);
    let mut t_up: Op = classes(|c| {
        let m = &t_down[c];
        (0..D * D).map(|k| m[(k % D) * D + k / D] * scale(k / D, k % D)).collect()
    });
    rescale(cells, &mut r_top, |col| above[col][0]);
    rescale(cells, &mut t_down, |col| above[col][1]);
    rescale(cells, &mut r_bottom, |col| below[col][0]);
    rescale(cells, &mut t_up, |col| below[col][1]);
    Operators { r_top, r_bottom, t_down, t_up }
}

/// The reflection of the anisotropic conductor base of every channel stack in `channels`: the microfacets' geometry
/// projected once, times each channel's Fresnel factor, each rescaled to its own energies.
fn conductor_base(cells: &Cells, channels: &[&ChannelStack]) -> Vec<Op> {
    let bases: Vec<(&crate::optics::distribution::Microfacet, f64, f64)> = channels
        .iter()
        .map(|s| match &s.base {
            Base::Conductor { mf, eta, k } => (mf, *eta, *k),
            Base::Diffuse { .. } => unreachable!("an anisotropic base is a conductor"),
        })
        .collect();
    let (mf, g2) = (bases[0].0, channels[0].g2);
    let mut ops: Vec<Op> = match bases.len() {
        1 => Vec::from(project::<1>(cells, 1.0, 1.0, &|wl, wv, out| {
            out[0] = crate::bsdf::rough_conductor(mf, g2, bases[0].1, bases[0].2, wl, wv)
        })),
        3 => Vec::from(project::<3>(cells, 1.0, 1.0, &|wl, wv, out| {
            let (geo, cos_h) = crate::bsdf::reflection_geometry(mf, g2, wl, wv).unwrap_or((0.0, 0.0));
            (0..3).for_each(|c| out[c] = geo * crate::optics::fresnel::conductor(cos_h, bases[c].1, bases[c].2));
        })),
        _ => return channels.iter().flat_map(|s| conductor_base(cells, &[s])).collect(),
    };
    for (op, &(mf, eta, k)) in ops.iter_mut().zip(&bases) {
        let e = energies(cells, &|w| [iso::conductor_energy(mf, g2, eta, k, w, ENERGY_NORMALS)]);
        rescale(cells, op, |col| e[col][0]);
    }
    ops
}

/// c ← c − a · b for row-major blocks of a matrix of row stride D (a: m × k at `a`, b: k × n at `b`, c: m × n at `c`).
///
/// # Safety
/// The blocks lie inside their matrices; c overlaps neither a nor b.
unsafe fn subtract_product(m: usize, k: usize, n: usize, a: *const f64, b: *const f64, c: *mut f64) {
    let s = D as isize;
    matrixmultiply::dgemm(m, k, n, -1.0, a, s, 1, b, s, 1, 1.0, c, s, 1);
}

/// (I − a)⁻¹ b by blocked LU with partial pivoting (the trailing updates and both substitutions in matrix products;
/// the isotropic solver's elimination, blocked). Cells that a maps onto themselves with weight 1 and nothing else into
/// or out of (light trapped between two total internal reflections, which no light reaches) are left out, as there.
fn solve_one_minus(a: &[f64], b: &[f64]) -> Mat {
    const NB: usize = 64;
    let n = D;
    let mut m: Mat = (0..n * n).map(|k| if k / n == k % n { 1.0 } else { 0.0 } - a[k]).collect();
    let mut x = b.to_vec();
    let trapped: Vec<usize> = (0..n)
        .filter(|&j| {
            let leak: f64 = (0..n).filter(|&k| k != j).map(|k| a[j * n + k].abs() + a[k * n + j].abs()).sum();
            m[j * n + j].abs() < 1e-12 && leak < 1e-12
        })
        .collect();
    for &j in &trapped {
        for k in 0..n {
            (m[j * n + k], m[k * n + j]) = (0.0, 0.0);
        }
        m[j * n + j] = 1.0;
        x[j * n..(j + 1) * n].fill(0.0);
    }
    for k0 in (0..n).step_by(NB) {
        let k1 = (k0 + NB).min(n);
        // The panel: columns k0..k1 factored, rows swapped whole (in m and x).
        for col in k0..k1 {
            iso::pivot(&mut m, &mut x, n, col);
            let d = m[col * n + col];
            for i in col + 1..n {
                let l = m[i * n + col] / d;
                m[i * n + col] = l;
                if l != 0.0 {
                    for k in col + 1..k1 {
                        m[i * n + k] -= l * m[col * n + k];
                    }
                }
            }
        }
        // U12 = L11⁻¹ M12 (rows k0..k1, columns k1..n), then the trailing M22 −= L21 U12.
        for r in k0..k1 {
            for i in k0..r {
                let l = m[r * n + i];
                for k in k1..n {
                    m[r * n + k] -= l * m[i * n + k];
                }
            }
        }
        if k1 < n {
            let p = m.as_mut_ptr();
            // SAFETY: L21 (rows k1.., columns k0..k1), U12 (rows k0..k1, columns k1..) and M22 (rows k1.., columns k1..)
            // are disjoint blocks of m.
            unsafe {
                subtract_product(n - k1, k1 - k0, n - k1, p.add(k1 * n + k0), p.add(k0 * n + k1), p.add(k1 * n + k1))
            };
        }
    }
    // L y = x (unit lower), block by block.
    for k0 in (0..n).step_by(NB) {
        let k1 = (k0 + NB).min(n);
        for r in k0..k1 {
            for i in k0..r {
                let l = m[r * n + i];
                if l != 0.0 {
                    for k in 0..n {
                        x[r * n + k] -= l * x[i * n + k];
                    }
                }
            }
        }
        if k1 < n {
            // SAFETY: L21 is in m; x's rows k0..k1 and k1.. are disjoint.
            let px = x.as_mut_ptr();
            unsafe {
                subtract_product(n - k1, k1 - k0, n, m.as_ptr().add(k1 * n + k0), px.add(k0 * n), px.add(k1 * n))
            };
        }
    }
    // U x = y, block by block from the last.
    for k0 in (0..n).step_by(NB).rev() {
        let k1 = (k0 + NB).min(n);
        for r in (k0..k1).rev() {
            for i in r + 1..k1 {
                let u = m[r * n + i];
                if u != 0.0 {
                    for k in 0..n {
                        x[r * n + k] -= u * x[i * n + k];
                    }
                }
            }
            let d = 1.0 / m[r * n + r];
            x[r * n..(r + 1) * n].iter_mut().for_each(|v| *v *= d);
        }
        if k0 > 0 {
            // SAFETY: U01 is in m; x's rows 0..k0 and k0..k1 are disjoint.
            let px = x.as_mut_ptr();
            unsafe { subtract_product(k0, k1 - k0, n, m.as_ptr().add(k0), px.add(k0 * n), px) };
        }
    }
    x
}

/// Layer `a` over a stack of reflection `r`: a.R_top + a.T_up (I − R a.R_bottom)⁻¹ R a.T_down, without a.R_top when
/// `with_top` is false.
fn over(a: &Operators, r: &Op, with_top: bool) -> Op {
    classes(|c| {
        let rt = mul(&r[c], &a.t_down[c]);
        let x = if a.r_bottom[c].iter().all(|&v| v == 0.0) {
            rt
        } else {
            solve_one_minus(&mul(&r[c], &a.r_bottom[c]), &rt)
        };
        let below = mul(&a.t_up[c], &x);
        if with_top {
            add(&a.r_top[c], &below)
        } else {
            below
        }
    })
}

/// The reflection of channel stack `s` less its top boundary's own reflection and (below a smooth top) less the Dirac
/// paths that the model adds exactly, both classes; `anisotropic_ops` memoizes the anisotropic interfaces' operators
/// across channels (a coat of equal IOR in every channel is projected once).
fn reflection_below_top(
    fine: &Cells,
    coarse: &Cells,
    s: &ChannelStack,
    base: Option<Op>,
    shared: &Shared<f64>,
    anisotropic_ops: &mut Vec<(Interface, std::rc::Rc<Operators>)>,
) -> Result<Op> {
    let n = s.interfaces.len();
    let mut r = if let Some(r) = base { r } else { from_isotropic(fine, coarse, &iso::base(fine, s, n, Paths::All)) };
    for i in (0..n).rev() {
        crate::interrupt::check()?;
        if let Some(sl) = iso::slab(fine, s, i, Paths::All)? {
            r = over(&operators_from_isotropic(fine, coarse, &sl), &r, true);
        }
        let ops = if anisotropic(s, i) {
            let it = s.interfaces[i];
            match anisotropic_ops.iter().find(|(x, _)| *x == it) {
                Some((_, ops)) => ops.clone(),
                None => {
                    let ops = std::rc::Rc::new(interface(coarse, s, i));
                    anisotropic_ops.push((it, ops.clone()));
                    ops
                }
            }
        } else {
            std::rc::Rc::new(operators_from_isotropic(fine, coarse, &shared.interface(fine, s, i, Paths::All)))
        };
        r = over(&ops, &r, i > 0);
    }
    if n > 0 && s.is_delta(0) {
        // The Dirac paths (smooth boundaries and unscattered beams only: isotropic, identity in azimuth).
        let dirac = iso::reflection_below_top(fine, s, Paths::Dirac, shared)?;
        let d = from_isotropic(fine, coarse, &dirac);
        for (r, d) in r.iter_mut().zip(&d) {
            r.iter_mut().zip(d).for_each(|(r, d)| *r -= d);
        }
    }
    Ok(r)
}

/// Where the value of channel c at θi node i, φi node a, θo node o, φo node b lies in a table.
#[inline(always)]
pub fn index(i: usize, a: usize, o: usize, b: usize, channels: usize, c: usize) -> usize {
    (((i * AZIMUTHS_I + a) * NODES + o) * NA + b) * channels + c
}

/// The table of an anisotropic stack: f less the top boundary's reflection at θi, θo on the cells' edges x = k / NZ
/// and the directions' azimuths φi = a Δφ (a = 0 … NA/2), φo = b Δφ (b = 0 … NA − 1), `index`'s layout; reciprocal
/// (the mean of (wi, wo) and (wo, wi)); at θ = 0 the mean over that direction's azimuth; the ringing of the coarse
/// grid below zero clipped. Interrupted when asked to stop (interrupt.rs).
pub fn tabulate(stack: &Stack, surface: Microsurface) -> Result<Vec<f32>> {
    let (fine, coarse) = (Cells::new(), Cells::with(NZ));
    let ch = stack.channels;
    let mut table = vec![0.0f32; LEN * ch];
    let channels: Vec<ChannelStack> = (0..ch).map(|c| ChannelStack::new(stack, c, surface)).collect();
    let shared = Shared::new(&channels.iter().flat_map(|s| s.interfaces.clone()).collect::<Vec<_>>());
    let mut anisotropic_ops = Vec::new();
    // Channels with equal optical constants share one solution; an anisotropic conductor base is projected once for
    // all the others.
    let keys: Vec<Vec<f64>> = (0..ch).map(|c| iso::channel_key(stack, c)).collect();
    let solved: Vec<usize> = (0..ch).filter(|&c| !keys[..c].contains(&keys[c])).collect();
    let n = channels[0].interfaces.len();
    let mut bases: Vec<Option<Op>> = match anisotropic(&channels[0], n) {
        true => conductor_base(&coarse, &solved.iter().map(|&c| &channels[c]).collect::<Vec<_>>())
            .into_iter()
            .map(Some)
            .collect(),
        false => solved.iter().map(|_| None).collect(),
    };
    for c in 0..ch {
        if let Some(c0) = (0..c).find(|&c0| keys[c0] == keys[c]) {
            for k in 0..LEN {
                table[k * ch + c] = table[k * ch + c0];
            }
            continue;
        }
        let s = &channels[c];
        let base = bases[solved.iter().position(|&x| x == c).unwrap_or(0)].take();
        let r = reflection_below_top(&fine, &coarse, s, base, &shared, &mut anisotropic_ops)?;
        // f̄ of outgoing cell (o, q), incident travel cell (j, p), from the classes: (E ± O) / 2.
        let f = |o: usize, q: usize, j: usize, p: usize| {
            let (q, p) = (q % NA, p % NA);
            let sign = if (q / HALF + p / HALF).is_multiple_of(2) { 1.0 } else { -1.0 };
            let k = (o * HALF + q % HALF) * D + j * HALF + p % HALF;
            0.5 * (r[0][k] + sign * r[1][k]) / (coarse.w[j] * DPHI)
        };
        // wi at azimuth a Δφ travels at (a + HALF) Δφ; light from wo's side travels at (b + HALF) Δφ.
        let value = |i: usize, a: usize, o: usize, b: usize| {
            let mut v = 0.0;
            for (ci, wi) in iso::node_cells(i, NZ) {
                for (co, wo) in iso::node_cells(o, NZ) {
                    v += wi * wo * 0.5 * (f(co, b, ci, a + HALF) + f(ci, a, co, b + HALF));
                }
            }
            v
        };
        // At the normal, f does not depend on that direction's azimuth: the mean over it (wi's azimuths a Δφ over a
        // full turn: those past a half turn are (a − NA/2, b − NA/2)).
        let normal_i: Vec<f64> = (0..NODES * NA)
            .into_par_iter()
            .map(|k| {
                let (o, b) = (k / NA, k % NA);
                match o {
                    0 => 0.0,
                    _ => {
                        (0..HALF).map(|a| value(0, a, o, b) + value(0, a, o, (b + HALF) % NA)).sum::<f64>() / NA as f64
                    }
                }
            })
            .collect();
        let normal_o: Vec<f64> = (0..NODES * AZIMUTHS_I)
            .into_par_iter()
            .map(|k| (0..NA).map(|b| value(k / AZIMUTHS_I, k % AZIMUTHS_I, 0, b)).sum::<f64>() / NA as f64)
            .collect();
        let both_normal = (0..HALF).map(|a| normal_o[a]).sum::<f64>() / HALF as f64;
        let values: Vec<f64> = (0..LEN)
            .into_par_iter()
            .map(|k| {
                let (b, o) = (k % NA, (k / NA) % NODES);
                let (a, i) = ((k / (NA * NODES)) % AZIMUTHS_I, k / (NA * NODES * AZIMUTHS_I));
                match (i, o) {
                    (0, 0) => both_normal,
                    (0, _) => normal_i[o * NA + b],
                    (_, 0) => normal_o[i * AZIMUTHS_I + a],
                    _ => value(i, a, o, b),
                }
            })
            .collect();
        for (k, v) in values.into_iter().enumerate() {
            table[k * ch + c] = v.max(0.0) as f32;
        }
    }
    Ok(table)
}

/// What the table `table` (`channels` channels) reflects per θi node, ∫ f cos θo dωo averaged over φi and the
/// channels: by trapezoids over the θo nodes in u = sin²θ and midpoints in φo (the sampling's weights).
pub fn albedo(table: &[f32], channels: usize) -> Vec<f64> {
    let cells = Cells::with(NZ);
    let v = |i: usize, a: usize, o: usize, b: usize| {
        let k = index(i, a, o, b, channels, 0);
        table[k..k + channels].iter().map(|&v| v as f64).sum::<f64>() / channels as f64
    };
    (0..NODES)
        .map(|i| {
            let per_azimuth = |a: usize| {
                (0..NZ)
                    .map(|o| cells.w[o] * (0..NA).map(|b| 0.5 * (v(i, a, o, b) + v(i, a, o + 1, b))).sum::<f64>())
                    .sum::<f64>()
                    * DPHI
            };
            (0..HALF).map(per_azimuth).sum::<f64>() / HALF as f64
        })
        .collect()
}

/// A pair's place in the table: the lower nodes (θi, φi, θo, φo) and the weights of the upper ones (`coordinates`).
#[derive(Clone, Copy, Default)]
pub struct At {
    node: [usize; 4],
    w: [f32; 4],
}

/// atan(t)/t as a polynomial in t², t ∈ [0, 1]: lamina's least-squares fit on Chebyshev nodes, |atan error| ≤ 1.1e-9.
const ATAN: [f64; 10] = [
    0.9999999778952146,
    -0.33333164390683345,
    0.1999615551539637,
    -0.14244972680446283,
    0.10868261299180201,
    -0.08188949889297344,
    0.054646418484433884,
    -0.028141838630028948,
    0.009392884309649449,
    -0.001472577957333021,
];

/// The azimuth of (x, y) in [0, 2π), within 1.1e-9 (ATAN by octant; 0 at the origin): libm's atan2 was a sixth of
/// an evaluation.
#[inline(always)]
fn azimuth(x: f64, y: f64) -> f64 {
    let (ax, ay) = (x.abs(), y.abs());
    let t = ax.min(ay) / ax.max(ay).max(1e-300);
    let u = t * t;
    let mut phi = t * ATAN.iter().rev().fold(0.0f64, |p, &c| p.mul_add(u, c));
    if ay > ax {
        phi = 0.5 * PI - phi;
    }
    if x < 0.0 {
        phi = PI - phi;
    }
    if y < 0.0 && phi > 0.0 {
        phi = 2.0 * PI - phi;
    }
    phi
}

/// The table's coordinates of (wi, wo), both above the horizon (None otherwise): zenith nodes in x = √(1 − cos θ),
/// azimuths turned by half a turn when φi ≥ π (f is unchanged), φo periodic.
#[inline(always)]
pub fn coordinates(wi: DVec3, wo: DVec3) -> Option<At> {
    if wi.z <= 0.0 || wo.z <= 0.0 {
        return None;
    }
    let (mut phi_i, mut phi_o) = (azimuth(wi.x, wi.y), azimuth(wo.x, wo.y));
    if phi_i >= PI {
        phi_i -= PI;
        phi_o = if phi_o >= PI { phi_o - PI } else { phi_o + PI };
    }
    let (s, t) = (phi_i / DPHI, phi_o / DPHI);
    let (a, b) = ((s as usize).min(HALF - 1), (t as usize).min(NA - 1));
    // x = √(1 − cos θ), as the isotropic table, in the form without cancellation near the normal: 1 − cos θ =
    // sin² θ / (1 + cos θ) (float32 directions, rounded there, then give float64's coordinates).
    let zenith = |w: DVec3| (w.x.mul_add(w.x, w.y * w.y) / (1.0 + w.z)).sqrt();
    let (i, fi) = super::node(zenith(wi), NODES);
    let (o, fo) = super::node(zenith(wo), NODES);
    let (fa, fb) = ((s - a as f64).clamp(0.0, 1.0), (t - b as f64).clamp(0.0, 1.0));
    Some(At { node: [i, a, o, b], w: [fi as f32, fa as f32, fo as f32, fb as f32] })
}

/// The eight (θi, φi, θo) corners of `at`: where their rows start in a table of `channels` channels (`index` at
/// φo = 0), and their weights.
#[inline(always)]
fn rows(at: &At, channels: usize) -> [(usize, f32); 8] {
    let [i, a, o, _] = at.node;
    let [fi, fa, fo, _] = at.w;
    let w = |d: usize, f: f32| if d == 1 { f } else { 1.0 - f };
    std::array::from_fn(|c| {
        let (di, da, dj) = (c >> 2, (c >> 1) & 1, c & 1);
        (index(i + di, a + da, o + dj, 0, channels, 0), w(di, fi) * w(da, fa) * w(dj, fo))
    })
}

/// φo's two nodes of `at` (periodic) as offsets in a row of `channels` channels, and their weights.
#[inline(always)]
fn columns(at: &At, channels: usize) -> [(usize, f32); 2] {
    let b = at.node[3];
    let b1 = if b + 1 == NA { 0 } else { b + 1 };
    [(b * channels, 1.0 - at.w[3]), (b1 * channels, at.w[3])]
}

/// Requests the records of `at`'s eight (θi, φi, θo) corners (φo's two nodes side by side, mostly in one cache
/// line): a table of tens of MiB is read at random, and a block's misses then overlap.
#[inline(always)]
pub fn prefetch(table: &[f32], at: &At, channels: usize) {
    #[cfg(target_arch = "x86_64")]
    for (row, _) in rows(at, channels) {
        // SAFETY: a prefetch reads nothing; the address is inside the table.
        unsafe {
            std::arch::x86_64::_mm_prefetch::<{ std::arch::x86_64::_MM_HINT_T0 }>(
                table[row + columns(at, channels)[0].0..].as_ptr() as *const i8,
            )
        };
    }
}

/// The table's multilinear interpolation at `at` in float32, C channels (C = 0: any number, `channels`), channel by
/// channel into `add(c, f)`.
#[inline(always)]
pub fn interpolate_at<const C: usize>(table: &[f32], at: &At, channels: usize, mut add: impl FnMut(usize, f32)) {
    let ch = if C == 0 { channels } else { C };
    let [(b0, w0), (b1, w1)] = columns(at, ch);
    let mut f = [0.0f32; C];
    for (row, w) in rows(at, ch) {
        let (x, y) = (&table[row + b0..][..ch], &table[row + b1..][..ch]);
        let (w0, w1) = (w * w0, w * w1);
        if C == 0 {
            (0..ch).for_each(|c| add(c, x[c].mul_add(w0, y[c] * w1)));
        } else {
            (0..C).for_each(|c| f[c] = x[c].mul_add(w0, y[c].mul_add(w1, f[c])));
        }
    }
    f.iter().enumerate().for_each(|(c, &f)| add(c, f));
}

/// The table's multilinear interpolation at (wi, wo) (nothing below the horizon), channel by channel into `add(c, f)`.
#[inline(always)]
pub fn interpolate(table: &[f32], wi: DVec3, wo: DVec3, add: impl FnMut(usize, f32), channels: usize) {
    if let Some(at) = coordinates(wi, wo) {
        interpolate_at::<0>(table, &at, channels, add);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_azimuth_is_atan2_within_its_stated_error() {
        // Every octant, the axes and the diagonals: within 1.1e-9 of libm's atan2 (measured 1.03e-9), in [0, 2π).
        let mut worst: f64 = 0.0;
        for k in 0..100_000 {
            let phi = 2.0 * PI * k as f64 / 100_000.0;
            let (x, y) = (0.7 * phi.cos(), 0.7 * phi.sin());
            let exact = y.atan2(x).rem_euclid(2.0 * PI);
            let a = azimuth(x, y);
            assert!((0.0..2.0 * PI).contains(&a), "{phi}: {a}");
            let d = (a - exact).abs();
            worst = worst.max(d.min(2.0 * PI - d));
        }
        assert!(worst < 1.1e-9, "{worst}");
        assert_eq!(azimuth(0.0, 0.0), 0.0);
    }

    #[test]
    fn the_blocked_solve_is_the_elimination() {
        // (I − A)⁻¹ B for a pseudo-random A of row sums about 0.6 and a few diagonal entries of 0.999 (pivots that
        // must be swapped in), as the isotropic solver's unblocked elimination solves it.
        let a: Mat =
            (0..D * D)
                .map(|k| {
                    if k / D == k % D && k % 97 == 0 {
                        0.999
                    } else {
                        1.2 / D as f64 * ((k * 7919 % 101) as f64 / 100.0)
                    }
                })
                .collect();
        let b: Mat = (0..D * D).map(|k| ((k * 104_729 % 97) as f64 / 96.0) - 0.5).collect();
        let (x, y) = (solve_one_minus(&a, &b), iso::solve_one_minus(&a, &b));
        let scale = y.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        let worst = x.iter().zip(&y).map(|(x, y)| (x - y).abs()).fold(0.0, f64::max) / scale;
        assert!(worst < 1e-10, "{worst}");
    }
}
