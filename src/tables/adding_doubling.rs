//! The BRDF of an isotropic stack by Fourier-series adding-doubling (Stamnes and Conklin 1984; Jakob, d'Eon, Jakob
//! and Marschner 2014, "A Comprehensive Framework for Rendering Layered Materials"): the transport that the reference
//! walk samples (reference.rs: the same boundaries, BSDFs and slabs), solved on a grid of directions instead of by
//! paths. `model="tabulated"` interpolates the result.
//!
//! Discretization. Zenith angles fall in N_THETA cells of equal Δx, x = √(1 − cos θ) (nearly uniform in θ: Δθ from
//! 1.3° at the normal to 1.8° at the horizon, and one square root to find); a cell's radiance is its average over the
//! projected solid angle, which is uniform in u = sin²θ (cos θ dω = du dφ / 2). Azimuths are expanded in ORDERS
//! cosines of φ, the azimuth between the travel directions of the light before and after an event. A boundary's
//! operator maps order m of the radiance in incident cell j to order m of the radiance in outgoing cell o:
//!   S_m[o][j] = π (1 + δ_m0) ā_m(o, j) w_j,   w_j = Δu_j / 2,
//! ā_m being the Fourier coefficient of f averaged over both cells (SUB Gauss points in u, PHI_SAMPLES midpoints in
//! φ). Smooth boundaries are exact maps between cells (Snell's law on u, radiance × η², Fresnel), the same for every
//! order; slabs without scattering are Beer–Lambert diagonals; scattering slabs are doubled from a thin layer of
//! single Henyey–Greenstein scattering. Rough boundaries keep the energy that importance sampling of their
//! microfacets gives (each column rescaled to it: the quadrature misses narrow lobes). The layers combine by the
//! adding equations, order by order.

use crate::dual::{dir, dot, value};
use crate::dual::{Dual, Real};
use crate::engine::with_avx2;
use crate::error::Result;
use crate::optics::distribution::{G2Form, Microfacet};
use crate::optics::{fresnel, reflect_about, refract_about};
use crate::quadrature::gauss_legendre;
use crate::sampling::henyey_greenstein;
use crate::stack::Stack;
use crate::transport::{Base, ChannelStack, Interface, Microsurface};
use glam::DVec3;
use rayon::prelude::*;
use std::cell::RefCell;
use std::f64::consts::PI;
use std::rc::Rc;
use std::sync::atomic::{AtomicBool, Ordering};

/// Zenith cells over [0, π/2], of equal Δx in x = √(1 − cos θ).
pub const N_THETA: usize = 64;
/// Fourier orders of the azimuth.
pub const ORDERS: usize = 64;
/// Table nodes over the azimuth φ ∈ [0, π], uniform in y = sin(φ/2) (densest at φ = 0, where the lobes peak).
pub const N_PHI: usize = 33;
/// Zenith nodes of the table: the cells' edges, x = k / N_THETA, k = 0 … N_THETA.
pub const NODES: usize = N_THETA + 1;

/// Where the records of the zenith nodes (i, o) start in the table, in N_PHI × channels values: reciprocity
/// makes f symmetric in (i, o), so only i ≤ o is stored (the pairs ordered by max(i, o), then min(i, o)).
#[inline(always)]
pub fn pair(i: usize, o: usize) -> usize {
    let (lo, hi) = if i <= o { (i, o) } else { (o, i) };
    hi * (hi + 1) / 2 + lo
}

/// Zenith node pairs the table stores.
pub const PAIRS: usize = NODES * (NODES + 1) / 2;
/// Gauss points per cell (in u) of the cell averages.
const SUB: usize = 2;
/// Gauss points of `Cells::outside_integral` (a smooth interface's Fresnel terms over part of a cell).
const OUTSIDE_POINTS: usize = 4;
/// Midpoint samples over φ ∈ [0, π] of the Fourier projections.
const PHI_SAMPLES: usize = 2 * ORDERS;
/// Visible normals per Gauss point of the energy that a rough boundary's column is rescaled to.
const ENERGY_NORMALS: usize = 4096;
/// Optical thickness of the thin layer that doubling starts from (single scattering is exact to O(Δτ²/μ²)).
const THIN: f64 = 1e-5;

/// An n × n matrix, row-major: m[o * n + j] maps incident cell j to outgoing cell o; f64, or Duals carrying the
/// derivatives of a parameter gradient (the same solve differentiated in forward mode).
type Mat<T = f64> = Vec<T>;
/// One matrix per Fourier order.
pub(super) type Op<T = f64> = Vec<Mat<T>>;

/// The zenith cells: weights w_j = Δu/2 and Gauss points (u, weight), SUB per cell, weights summing to w_j; and the
/// Gauss rule of `outside_integral` on [−1, 1].
pub struct Cells {
    pub w: Vec<f64>,
    pub(super) edges: Vec<f64>,
    points: Vec<(f64, f64)>,
    outside: Vec<(f64, f64)>,
}

impl Cells {
    pub fn new() -> Cells {
        Cells::with(N_THETA)
    }

    /// `n` cells (a coarser grid: tables/anisotropic.rs).
    pub(super) fn with(n: usize) -> Cells {
        let edges: Vec<f64> = (0..=n).map(|k| 1.0 - (1.0 - (k as f64 / n as f64).powi(2)).powi(2)).collect();
        let gl = gauss_legendre(SUB);
        let points = (0..n)
            .flat_map(|j| {
                let (a, b) = (edges[j], edges[j + 1]);
                gl.iter().map(move |&(x, v)| (a + 0.5 * (b - a) * (x + 1.0), 0.25 * (b - a) * v))
            })
            .collect();
        let w = (0..n).map(|j| 0.5 * (edges[j + 1] - edges[j])).collect();
        Cells { w, edges, points, outside: gauss_legendre(OUTSIDE_POINTS) }
    }

    /// Gauss points of cell j: (u, weight).
    pub(super) fn points(&self, j: usize) -> &[(f64, f64)] {
        &self.points[j * SUB..(j + 1) * SUB]
    }

    /// ∫ v μ dμ over [0, 1] from v's values at the table's zenith nodes (`NODES`: the cells' edges), each cell
    /// taking the mean of its two edges; 2π times it is the hemisphere's ∫ v cos θ dω.
    pub fn node_integral(&self, v: impl Fn(usize) -> f64) -> f64 {
        (0..N_THETA).map(|j| self.w[j] * 0.5 * (v(j) + v(j + 1))).sum()
    }

    /// Average over cell j (projected solid angle) of g(μ).
    fn average<T: Real>(&self, j: usize, g: impl Fn(f64) -> T) -> T {
        self.points(j).iter().map(|&(u, v)| g((1.0 - u).sqrt()) * v).sum::<T>() / self.w[j]
    }

    /// Average over cell j of the Fresnel reflectance of a smooth interface of relative IOR `eta`, the cell split at
    /// the critical angle (u = η², for η < 1): beyond it exactly 1, before it by Gauss points in the cosine outside
    /// (`outside_integral`). A cell that straddles the critical angle thus transmits exactly the part that refraction
    /// maps into it from the other side.
    fn fresnel_average<T: Real>(&self, j: usize, eta: T) -> T {
        let (a, b) = (self.edges[j], self.edges[j + 1]);
        let c = if eta.value() < 1.0 { (eta * eta).clamp_c(a, b) } else { T::from(b) };
        let refracting =
            self.outside_integral(T::from(a), c, eta, |u| fresnel::dielectric((T::from(1.0) - u).sqrt(), eta));
        (refracting + (T::from(b) - c)) / (b - a)
    }

    /// ∫ g(u) du over [lo, hi], u = sin²θ on the side of a smooth interface of relative IOR `eta` (to the other
    /// side), by Gauss points in the cosine μ on the outside (the side of lower index: u = η² (1 − μ²) for η < 1,
    /// else 1 − μ²). A smooth interface's Fresnel terms are smooth in μ up to grazing incidence outside and up to the
    /// critical angle inside, where they have a square-root cusp in u: Gauss points in u (as before) made the solve's
    /// ∂f/∂η jump (from +0.32 to −0.09 within Δη = 2e-5 at grazing pairs, under a smooth coat) as the critical angle
    /// crossed a cell's edge, which stopped fits at those kinks short of their optimum.
    fn outside_integral<T: Real>(&self, lo: T, hi: T, eta: T, g: impl Fn(T) -> T) -> T {
        let e2 = if eta.value() < 1.0 { eta * eta } else { T::from(1.0) };
        let cosine = |u: T| (T::from(1.0) - u / e2).max_c(0.0).sqrt();
        let (mu_lo, mu_hi) = (cosine(hi), cosine(lo));
        // du = 2 η² μ dμ (η² read as 1 outside).
        self.outside
            .iter()
            .map(|&(x, v)| {
                let mu = mu_lo + (mu_hi - mu_lo) * (0.5 * (x + 1.0));
                g(e2 * (T::from(1.0) - mu * mu)) * e2 * mu * (mu_hi - mu_lo) * v
            })
            .sum()
    }
}

impl Default for Cells {
    fn default() -> Self {
        Cells::new()
    }
}

/// The direction of zenith u = sin²θ and azimuth (cos φ, sin φ), on the side `z` = ±1.
pub(super) fn direction(u: f64, (c, s): (f64, f64), z: f64) -> DVec3 {
    let sin = u.sqrt();
    DVec3::new(sin * c, sin * s, z * (1.0 - u).sqrt())
}

fn zeros<T: Real>() -> Mat<T> {
    vec![T::from(0.0); N_THETA * N_THETA]
}

fn diagonal<T: Real>(d: impl Fn(usize) -> T) -> Mat<T> {
    let mut m = zeros();
    (0..N_THETA).for_each(|j| m[j * N_THETA + j] = d(j));
    m
}

/// The same matrix for every order (a Dirac in azimuth: smooth boundaries, direct transmission).
fn every_order<T: Real>(m: Mat<T>) -> Op<T> {
    vec![m; ORDERS]
}

/// a · b.
fn mul<T: Real>(a: &[T], b: &[T]) -> Mat<T> {
    with_avx2!([T: Real] (a: &[T], b: &[T]) -> Mat<T> => mul_in(a, b))
}

#[inline(always)]
fn mul_in<T: Real>(a: &[T], b: &[T]) -> Mat<T> {
    let n = N_THETA;
    let mut c = zeros();
    for i in 0..n {
        let row = &mut c[i * n..(i + 1) * n];
        for k in 0..n {
            let x = a[i * n + k];
            if !x.same(T::from(0.0)) {
                row.iter_mut().zip(&b[k * n..(k + 1) * n]).for_each(|(c, &b)| *c = *c + x * b);
            }
        }
    }
    c
}

fn add<T: Real>(a: &[T], b: &[T]) -> Mat<T> {
    a.iter().zip(b).map(|(&a, &b)| a + b).collect()
}

/// (I − a)⁻¹ b by Gaussian elimination with partial pivoting. I − a is non-singular (a's columns carry less energy
/// than they receive, a product of reflectances) but for the cells of a lossless layer that totally reflect at both
/// of its smooth boundaries: a maps such a cell onto itself with weight 1 and nothing else into or out of it, so no
/// light reaches it. Those cells are taken out of the system (their rows of x are 0, as b's are).
pub(super) fn solve_one_minus<T: Real>(a: &[T], b: &[T]) -> Mat<T> {
    with_avx2!([T: Real] (a: &[T], b: &[T]) -> Mat<T> => solve_one_minus_in(a, b))
}

#[inline(always)]
fn solve_one_minus_in<T: Real>(a: &[T], b: &[T]) -> Mat<T> {
    let n = a.len().isqrt();
    let v = |k: usize| a[k].value();
    let trapped = |j: usize| {
        let leak: f64 = (0..n).filter(|&k| k != j).map(|k| v(j * n + k).abs() + v(k * n + j).abs()).sum();
        (1.0 - v(j * n + j)).abs() < 1e-12 && leak < 1e-12
    };
    let (zero, one) = (T::from(0.0), T::from(1.0));
    let mut m: Mat<T> = (0..n * n).map(|k| if k / n == k % n { one } else { zero } - a[k]).collect();
    let mut x = b.to_vec();
    for j in (0..n).filter(|&j| trapped(j)) {
        (0..n).for_each(|k| {
            m[j * n + k] = if k == j { one } else { zero };
            m[k * n + j] = if k == j { one } else { zero };
            x[j * n + k] = zero;
        });
    }
    for col in 0..n {
        pivot(&mut m, &mut x, n, col);
        let d = m[col * n + col];
        for i in col + 1..n {
            let f = m[i * n + col] / d;
            if !f.same(zero) {
                for k in col..n {
                    m[i * n + k] = m[i * n + k] - f * m[col * n + k];
                }
                for k in 0..n {
                    x[i * n + k] = x[i * n + k] - f * x[col * n + k];
                }
            }
        }
    }
    for col in (0..n).rev() {
        let d = m[col * n + col];
        for k in 0..n {
            let s: T = (col + 1..n).map(|i| m[col * n + i] * x[i * n + k]).sum();
            x[col * n + k] = (x[col * n + k] - s) / d;
        }
    }
    x
}

/// Partial pivoting: swaps into row `col` of the n × n matrix m, and of x, the row at or below it with the largest
/// |m[·][col]|.
pub(super) fn pivot<T: Real>(m: &mut [T], x: &mut [T], n: usize, col: usize) {
    let size = |i: usize| m[i * n + col].value().abs();
    let p = (col..n).max_by(|&i, &k| size(i).total_cmp(&size(k))).unwrap_or(col);
    if p != col {
        for k in 0..n {
            m.swap(p * n + k, col * n + k);
            x.swap(p * n + k, col * n + k);
        }
    }
}

/// The operator of a boundary (or a thin slab's scattering) with kernel f(w_light, w_view): light arrives on the
/// side `z_light` (w_light.z has its sign, travel direction −w_light at azimuth 0) and leaves on the side `z_view`.
fn project<T: Real>(cells: &Cells, z_light: f64, z_view: f64, f: &(dyn Fn(DVec3, DVec3) -> T + Sync)) -> Op<T> {
    let n = N_THETA;
    let phis: Vec<(f64, f64)> = (0..PHI_SAMPLES)
        .map(|p| {
            let phi = (p as f64 + 0.5) * PI / PHI_SAMPLES as f64;
            (phi.cos(), phi.sin())
        })
        .collect();
    let cosines: Vec<f64> = (0..ORDERS)
        .flat_map(|m| (0..PHI_SAMPLES).map(move |p| (m as f64 * (p as f64 + 0.5) * PI / PHI_SAMPLES as f64).cos()))
        .collect();
    let columns: Vec<Vec<T>> = (0..n)
        .into_par_iter()
        .map(|j| {
            let mut column = vec![T::from(0.0); ORDERS * n];
            let mut sums = [T::from(0.0); PHI_SAMPLES];
            for o in 0..n {
                sums.fill(T::from(0.0));
                for &(us, vs) in cells.points(j) {
                    let w_light = direction(us, (-1.0, 0.0), z_light);
                    for &(ut, vt) in cells.points(o) {
                        for (sum, &phi) in sums.iter_mut().zip(&phis) {
                            *sum = *sum + f(w_light, direction(ut, phi, z_view)) * (vs * vt);
                        }
                    }
                }
                let scale = 2.0 * PI / (PHI_SAMPLES as f64 * cells.w[o]);
                for m in 0..ORDERS {
                    let c = &cosines[m * PHI_SAMPLES..(m + 1) * PHI_SAMPLES];
                    column[m * n + o] = sums.iter().zip(c).map(|(&s, &c)| s * c).sum::<T>() * scale;
                }
            }
            column
        })
        .collect();
    (0..ORDERS).map(|m| (0..n * n).map(|k| columns[k % n][m * n + k / n]).collect()).collect()
}

/// Energy leaving each incident cell's column (order 0): Σ_o w_o S_0[o][j] / w_j.
fn column_energy<T: Real>(cells: &Cells, s: &Mat<T>, j: usize) -> T {
    (0..N_THETA).map(|o| s[o * N_THETA + j] * cells.w[o]).sum::<T>() / cells.w[j]
}

/// Rescales every order of column j of `op` so that its energy is `target(j)`.
fn rescale_columns<T: Real>(cells: &Cells, op: &mut Op<T>, target: impl Fn(usize) -> T) {
    for j in 0..N_THETA {
        let e = column_energy(cells, &op[0], j);
        if e.value() > 0.0 {
            let k = target(j) / e;
            op.iter_mut().for_each(|m| (0..N_THETA).for_each(|o| m[o * N_THETA + j] = m[o * N_THETA + j] * k));
        }
    }
}

/// What a rough interface (relative IOR `eta` below / above) seen from direction `w` (its side up, w.z > 0)
/// reflects and transmits: E over visible normals of F G2/G1 and (1 − F) G2/G1 (the weights of the reference's
/// sampling, reference.rs `scatter_interface`), on a lattice of `normals` normals (tables::lattice), in f64 or
/// in Duals by the roughness and the IOR (the normals move with the roughness, the directions they scatter to with
/// both). Seen from below (η < 1), F has a square-root cusp at the critical angle, which the lattice's normals cross as
/// the roughness or the IOR moves: there the estimate is jagged on scales of 1e-6 (models/tabulated.rs refuses
/// those gradients).
pub(super) fn interface_energy<T: Real>(mf: &Microfacet<T>, g2: G2Form, eta: T, w: DVec3, normals: usize) -> (T, T) {
    let (mut r, mut t) = (T::from(0.0), T::from(0.0));
    for (u1, u2) in super::lattice(normals) {
        let m = mf.visible_normal(w, u1, u2);
        let f = fresnel::dielectric(dot(dir(w), m), eta);
        let (o, normal) = (reflect_about(w, m), value(m));
        if o[2].value() > 0.0 {
            r = r + f * mf.g2(g2, w, o, normal) / mf.g1(w, normal);
        }
        if let Some(o) = refract_about(w, m, eta).filter(|o| o[2].value() < 0.0) {
            t = t + (T::from(1.0) - f) * mf.g2(g2, w, o, normal) / mf.g1(w, normal);
        }
    }
    (r / normals as f64, t / normals as f64)
}

/// What a rough conductor seen from `w` reflects: E over visible normals of F G2/G1, in f64 or in Duals by the
/// roughness, η and κ.
pub(super) fn conductor_energy<T: Real>(mf: &Microfacet<T>, g2: G2Form, eta: T, k: T, w: DVec3, normals: usize) -> T {
    super::lattice(normals)
        .map(|(u1, u2)| {
            let m = mf.visible_normal(w, u1, u2);
            let o = reflect_about(w, m);
            if o[2].value() > 0.0 {
                let normal = value(m);
                fresnel::conductor(dot(dir(w), m), eta, k) * mf.g2(g2, w, o, normal) / mf.g1(w, normal)
            } else {
                T::from(0.0)
            }
        })
        .sum::<T>()
        / normals as f64
}

/// The average over cell j of a directional energy e(w) (w on the +z side, azimuth 0).
fn cell_energy<T: Real>(cells: &Cells, j: usize, e: impl Fn(DVec3) -> T) -> T {
    cells.points(j).iter().map(|&(u, v)| e(direction(u, (1.0, 0.0), 1.0)) * v).sum::<T>() / cells.w[j]
}

/// Refraction through a smooth interface from a medium into one of relative IOR `r` (n_to / n_from): each incident
/// cell's u-range maps to u / r² (Snell), radiance scales by r², times 1 − F; what maps beyond u = 1 is totally
/// reflected. 1 − F is integrated over each overlap of an incident and an outgoing cell (`Cells::outside_integral`).
fn smooth_refraction<T: Real>(cells: &Cells, r: T) -> Mat<T> {
    let n = N_THETA;
    let mut m = zeros();
    let (max, min) = (
        |x: T, y: f64| if x.value() > y { x } else { T::from(y) },
        |x: T, y: f64| {
            if x.value() < y {
                x
            } else {
                T::from(y)
            }
        },
    );
    let r2 = r * r;
    let t = |u: T| fresnel::dielectric_transmittance((T::from(1.0) - u).max_c(0.0).sqrt(), r);
    for j in 0..n {
        let (a, b) = (T::from(cells.edges[j]) / r2, min(T::from(cells.edges[j + 1]) / r2, 1.0));
        for o in 0..n {
            let (c, d) = (cells.edges[o], cells.edges[o + 1]);
            let (lo, hi) = (max(a, c), min(b, d));
            if hi.value() > lo.value() {
                // r² ∫ (1 − F) du_to over the overlap = ∫ (1 − F) du_from.
                m[o * n + j] = cells.outside_integral(lo * r2, hi * r2, r, t) / (d - c);
            }
        }
    }
    m
}

/// The optical depth of the slab below the top of `s` that light crosses unscattered only by not being absorbed: its
/// σa × thickness when it does not scatter, else 0 (`node_entering` then counts the top alone).
pub fn clear_depth<T: Real>(s: &ChannelStack<T>) -> T {
    let slab = &s.slabs[0];
    match slab.sigma_s.same(T::from(0.0)) {
        true => slab.sigma_a * slab.thickness,
        false => T::from(0.0),
    }
}

/// What of the light incident from above at each table node crosses the smooth top of `s` and the clear slab below
/// it (`clear_depth`), as the solve carries it: each cell's transmittance 1 − F̄ times the Beer–Lambert cell
/// averages of the slab where its refraction lands (`smooth_refraction`'s shares), weighted as `node_values` weighs
/// the cells. The table divides by it at both nodes; tabulated's `entering` is its exact value. 1 for a top less
/// dense than the outside, whose total reflection leaves nodes without light (not factored).
fn node_entering<T: Real>(cells: &Cells, s: &ChannelStack<T>) -> Vec<T> {
    let (n, eta, depth) = (N_THETA, s.interfaces[0].eta, clear_depth(s));
    if eta.value() < 1.0 {
        return vec![T::from(1.0); NODES];
    }
    let shares = smooth_refraction(cells, eta);
    let beer: Vec<T> = (0..n).map(|o| cells.average(o, |mu| (-depth / mu).exp())).collect();
    let crossing: Mat<T> = (0..n * n).map(|k| shares[k] * beer[k / n]).collect();
    let cell = |j: usize| {
        (T::from(1.0) - cells.fresnel_average(j, eta)) * column_energy(cells, &crossing, j)
            / column_energy(cells, &shares, j)
    };
    (0..=n).map(|k| node_cells(k, n).into_iter().map(|(j, w)| cell(j) * w).sum()).collect()
}

/// A layer's four operators: reflection of light from above and from below, transmission downward and upward.
pub(super) struct Operators<T = f64> {
    pub(super) r_top: Op<T>,
    pub(super) r_bottom: Op<T>,
    pub(super) t_down: Op<T>,
    pub(super) t_up: Op<T>,
}

/// Which paths the operators carry: all of them, or only the Dirac part (the paths that meet smooth boundaries only
/// and cross the slabs unscattered), which the table leaves to the model's exact `specular`.
#[derive(Clone, Copy, PartialEq)]
pub(super) enum Paths {
    All,
    Dirac,
}

/// Operators that carry nothing.
fn none<T: Real>() -> Operators<T> {
    let z = every_order(zeros());
    Operators { r_top: z.clone(), r_bottom: z.clone(), t_down: z.clone(), t_up: z }
}

/// The operators of interface b of channel stack `s`, for `paths`: a smooth one's in Duals by its IOR, a rough one's
/// without derivatives.
pub(super) fn interface<T: Real>(cells: &Cells, s: &ChannelStack<T>, b: usize, paths: Paths) -> Operators<T> {
    let it = &s.interfaces[b];
    let eta = it.eta;
    if paths == Paths::Dirac && !s.is_delta(b) {
        return none();
    }
    if s.is_delta(b) {
        // Each cell transmits exactly what it does not reflect (the cell's average Fresnel, total internal
        // reflection included), so that a lossless layer between two smooth boundaries conserves energy.
        let side = |eta: T| {
            let r: Vec<T> = (0..N_THETA)
                .map(|j| cells.fresnel_average(j, eta))
                .map(|r| if r.value() > 1.0 { T::from(1.0) } else { r })
                .collect();
            let mut t = every_order(smooth_refraction(cells, eta));
            rescale_columns(cells, &mut t, |j| T::from(1.0) - r[j]);
            (every_order(diagonal(|j| r[j])), t)
        };
        let ((r_top, t_down), (r_bottom, t_up)) = (side(eta), side(T::from(1.0) / eta));
        return Operators { r_top, r_bottom, t_down, t_up };
    }
    let f = |w_light: DVec3, w_view: DVec3| s.boundary_f(b, w_light, w_view);
    let energy = |j: usize, eta: T| {
        let rt: Vec<(T, T)> = cells
            .points(j)
            .iter()
            .map(|&(u, _)| interface_energy(&it.mf, s.g2, eta, direction(u, (1.0, 0.0), 1.0), ENERGY_NORMALS))
            .collect();
        let avg =
            |k: fn(&(T, T)) -> T| cells.points(j).iter().zip(&rt).map(|(&(_, v), e)| k(e) * v).sum::<T>() / cells.w[j];
        (avg(|e| e.0), avg(|e| e.1))
    };
    let from_above: Vec<(T, T)> = (0..N_THETA).into_par_iter().map(|j| energy(j, eta)).collect();
    let from_below: Vec<(T, T)> = (0..N_THETA).into_par_iter().map(|j| energy(j, T::from(1.0) / eta)).collect();
    let mut layer = Operators {
        r_top: project(cells, 1.0, 1.0, &f),
        r_bottom: project(cells, -1.0, -1.0, &f),
        t_down: project(cells, 1.0, -1.0, &f),
        t_up: project(cells, -1.0, 1.0, &f),
    };
    rescale_columns(cells, &mut layer.r_top, |j| from_above[j].0);
    rescale_columns(cells, &mut layer.t_down, |j| from_above[j].1);
    rescale_columns(cells, &mut layer.r_bottom, |j| from_below[j].0);
    rescale_columns(cells, &mut layer.t_up, |j| from_below[j].1);
    layer
}

/// `$op(cells, s, b, paths)` (`interface` or `base`) where T carries derivatives: computed in Duals of boundary b's
/// own distinct moving numbers alone (`moving`, K ≤ 3; else in T) and composed into T's N by the chain rule, entry
/// by entry (`$compose`): far fewer derivatives to carry through the projection of its BSDF and its energies.
macro_rules! own_duals {
    ($op:path, $compose:ident, $cells:expr, $s:expr, $b:expr, $paths:expr) => {{
        let x = moving($s, $b);
        match x.len() {
            _ if T::DERIVATIVES == 0 => $op($cells, $s, $b, $paths),
            0 => $compose::<T, 0>($op($cells, &in_duals($s, &x), $b, $paths), &x),
            1 => $compose::<T, 1>($op($cells, &in_duals($s, &x), $b, $paths), &x),
            2 => $compose::<T, 2>($op($cells, &in_duals($s, &x), $b, $paths), &x),
            3 => $compose::<T, 3>($op($cells, &in_duals($s, &x), $b, $paths), &x),
            _ => $op($cells, $s, $b, $paths),
        }
    }};
}

/// Boundary b's distinct numbers that carry derivatives.
fn moving<T: Real>(s: &ChannelStack<T>, b: usize) -> Vec<T> {
    let mut x: Vec<T> = Vec::new();
    for v in s.boundary_numbers(b) {
        if !v.same(T::from(v.value())) && !x.iter().any(|m| m.same(v)) {
            x.push(v);
        }
    }
    x
}

/// The stack in Duals of K derivatives, one per number of `x` (the others constants): what boundary b's operators
/// read when `x` are its moving numbers.
fn in_duals<T: Real, const K: usize>(s: &ChannelStack<T>, x: &[T]) -> ChannelStack<Dual<K>> {
    s.map(|v| match x.iter().position(|m| m.same(v)) {
        Some(k) => Dual::seeded(v.value(), k, 1.0),
        None => Dual::from(v.value()),
    })
}

/// An operator in Duals of the numbers `x`, composed into T's derivatives (`Real::compose`).
fn composed<T: Real, const K: usize>(op: Op<Dual<K>>, x: &[T]) -> Op<T> {
    let x: [T; K] = std::array::from_fn(|k| x[k]);
    op.into_iter().map(|m| m.into_iter().map(|e| T::compose(e, x)).collect()).collect()
}

/// `composed` for a layer's four operators.
fn composed_operators<T: Real, const K: usize>(o: Operators<Dual<K>>, x: &[T]) -> Operators<T> {
    let c = |op| composed(op, x);
    Operators { r_top: c(o.r_top), r_bottom: c(o.r_bottom), t_down: c(o.t_down), t_up: c(o.t_up) }
}

/// The reflection operator of the base, boundary b (light from above), for `paths`.
pub(super) fn base<T: Real>(cells: &Cells, s: &ChannelStack<T>, b: usize, paths: Paths) -> Op<T> {
    if paths == Paths::Dirac && !s.is_delta(b) {
        return every_order(zeros());
    }
    match &s.base {
        Base::Conductor { mf, eta, k } if mf.is_smooth() => {
            every_order(diagonal(|j| cells.average(j, |mu| fresnel::conductor(mu, *eta, *k))))
        }
        Base::Conductor { mf, eta, k } => {
            let mut op = project(cells, 1.0, 1.0, &|wl, wv| s.boundary_f(b, wl, wv));
            let energy: Vec<T> = (0..N_THETA)
                .into_par_iter()
                .map(|j| cell_energy(cells, j, |w| conductor_energy(mf, s.g2, *eta, *k, w, ENERGY_NORMALS)))
                .collect();
            rescale_columns(cells, &mut op, |j| energy[j]);
            op
        }
        Base::Diffuse { .. } => project(cells, 1.0, 1.0, &|wl, wv| s.boundary_f(b, wl, wv)),
    }
}

/// The operators of slab i for `paths` (the Dirac part is its unscattered beam): None when it does nothing (no
/// thickness or no extinction); Interrupted when asked to stop during its doublings.
pub(super) fn slab<T: Real>(
    cells: &Cells,
    s: &ChannelStack<T>,
    i: usize,
    paths: Paths,
) -> Result<Option<Operators<T>>> {
    let sl = &s.slabs[i];
    let tau = (sl.sigma_a + sl.sigma_s) * sl.thickness;
    let zero = T::from(0.0);
    if tau.same(zero) {
        return Ok(None);
    }
    if sl.sigma_s.same(zero) || paths == Paths::Dirac {
        let t = every_order(diagonal(|j| cells.average(j, |mu| (-tau / mu).exp())));
        let r = every_order(zeros());
        return Ok(Some(Operators { r_top: r.clone(), r_bottom: r, t_down: t.clone(), t_up: t }));
    }
    // A thin layer of single scattering: L_o = (Δτ ω / μ_o) ∫ p L dω (both sides alike: the phase function is
    // symmetric), each column's scattered energy made exactly Δτ ω ⟨1/μ_j⟩ (the discrete phase function integrates
    // to one), then doubled 2^k times up to τ.
    let omega = sl.sigma_s / (sl.sigma_a + sl.sigma_s);
    let doublings = (tau.value() / THIN).log2().ceil().max(0.0) as i32;
    let dtau = tau / 2f64.powi(doublings);
    let phase = |wl: DVec3, wv: DVec3| henyey_greenstein((-wl).dot(wv), sl.g) / (wl.z * wv.z).abs();
    let mut back = project(cells, 1.0, 1.0, &phase);
    let mut forward = project(cells, 1.0, -1.0, &phase);
    for j in 0..N_THETA {
        let e = column_energy(cells, &back[0], j) + column_energy(cells, &forward[0], j);
        let k = dtau * omega * cells.average(j, |mu| 1.0 / mu) / e;
        for op in [&mut back, &mut forward] {
            op.iter_mut().for_each(|m| (0..N_THETA).for_each(|o| m[o * N_THETA + j] = m[o * N_THETA + j] * k));
        }
    }
    let direct = diagonal(|j| cells.average(j, |mu| (-dtau / mu).exp()));
    let stopped = AtomicBool::new(false);
    let (r, t): (Op<T>, Op<T>) = back
        .into_par_iter()
        .zip(forward)
        .map(|(mut r, f)| {
            let mut t = add(&direct, &f);
            for _ in 0..doublings {
                if crate::interrupt::requested() {
                    stopped.store(true, Ordering::Relaxed); // this operator is incomplete: the slab is Interrupted
                    break;
                }
                // Two copies of the layer: R' = R + T (I − R R)⁻¹ R T, T' = T (I − R R)⁻¹ T.
                let x = solve_one_minus(&mul(&r, &r), &t);
                r = add(&r, &mul(&mul(&t, &r), &x));
                t = mul(&t, &x);
            }
            (r, t)
        })
        .unzip();
    if stopped.load(Ordering::Relaxed) {
        return Err(crate::error::Error::Interrupted);
    }
    Ok(Some(Operators { r_top: r.clone(), r_bottom: r, t_down: t.clone(), t_up: t }))
}

/// Layer `a` over a stack of reflection `r` (order by order): a.R_top + a.T_up (I − R a.R_bottom)⁻¹ R a.T_down,
/// without a.R_top when `with_top` is false.
fn over<T: Real>(a: &Operators<T>, r: Op<T>, with_top: bool) -> Op<T> {
    r.into_par_iter()
        .enumerate()
        .map(|(m, r)| {
            let x = solve_one_minus(&mul(&r, &a.r_bottom[m]), &mul(&r, &a.t_down[m]));
            let below = mul(&a.t_up[m], &x);
            if with_top {
                add(&a.r_top[m], &below)
            } else {
                below
            }
        })
        .collect()
}

/// The reflection of channel stack `s` less its top boundary's own reflection (which the model evaluates exactly),
/// order by order, for `paths`; Interrupted when asked to stop (interrupt.rs), checked layer by layer.
pub(super) fn reflection_below_top<T: Real>(
    cells: &Cells,
    s: &ChannelStack<T>,
    paths: Paths,
    shared: &Shared<T>,
) -> Result<Op<T>> {
    let n = s.interfaces.len();
    if n == 0 {
        return Ok(every_order(zeros()));
    }
    let mut r = own_duals!(base, composed, cells, s, n, paths);
    for i in (0..n).rev() {
        crate::interrupt::check()?;
        if let Some(sl) = slab(cells, s, i, paths)? {
            r = over(&sl, r, true);
        }
        r = over(&shared.interface(cells, s, i, paths), r, i > 0);
    }
    Ok(r)
}

/// The interfaces' operators that the channels of one table have solved, for the channels after them: an interface
/// of equal roughness and IOR in two channels (most coats, whose channels differ below them) is projected once. Only
/// those are kept: a dispersive coat's channels share nothing, and keeping each channel's operators (8 MiB per interface
/// in f64) would hold them all at once.
pub(super) struct Shared<T> {
    recurring: Vec<Interface<T>>,
    kept: RefCell<Vec<Projected<T>>>,
}

/// An interface's operators for some paths.
struct Projected<T> {
    interface: Interface<T>,
    paths: Paths,
    ops: Rc<Operators<T>>,
}

impl<T: Real> Shared<T> {
    /// For a table whose channels' interfaces are `all`.
    pub(super) fn new(all: &[Interface<T>]) -> Shared<T> {
        let recurring = all.iter().enumerate().filter(|&(i, x)| all[..i].contains(x)).map(|(_, x)| *x).collect();
        Shared { recurring, kept: RefCell::new(Vec::new()) }
    }

    /// `interface(cells, s, b, paths)`, projected once per recurring interface and paths.
    pub(super) fn interface(&self, cells: &Cells, s: &ChannelStack<T>, b: usize, paths: Paths) -> Rc<Operators<T>> {
        let interface = s.interfaces[b];
        if let Some(p) = self.kept.borrow().iter().find(|p| (p.interface, p.paths) == (interface, paths)) {
            return p.ops.clone();
        }
        let ops = Rc::new(own_duals!(self::interface, composed_operators, cells, s, b, paths));
        if self.recurring.contains(&interface) {
            self.kept.borrow_mut().push(Projected { interface, paths, ops: ops.clone() });
        }
        ops
    }
}

/// The cells a table node (x = k / N_THETA, k = 0 … N_THETA) interpolates, with their weights: the two cells it
/// separates, the one cell at either end.
pub(super) fn node_cells(k: usize, n: usize) -> Vec<(usize, f64)> {
    match k {
        0 => vec![(0, 1.0)],
        k if k == n => vec![(n - 1, 1.0)],
        k => vec![(k - 1, 0.5), (k, 0.5)],
    }
}

/// The table of `model="tabulated"`: f less the top boundary's reflection at the zenith nodes x = k / N_THETA (the
/// cells' edges, k = 0 … N_THETA, both θi and θo) × N_PHI azimuths y = sin(φ/2) = p / (N_PHI − 1), φ ∈ [0, π] between
/// the travel directions (φ = π − the azimuth between wi and wo), per channel: index (pair(i, o) · N_PHI + p) ·
/// channels + c (`node_values`); the ringing of the truncated series below zero is clipped. Interrupted when asked to
/// stop (interrupt.rs).
pub fn tabulate(stack: &Stack, surface: Microsurface) -> Result<Vec<f32>> {
    let channel = |c: usize| ChannelStack::new(stack, c, surface);
    let values = node_values(stack.channels, channel, |c| channel_key(stack, c))?;
    Ok(values.into_iter().map(|f| f.max(0.0) as f32).collect())
}

/// f less the top boundary's reflection at the table's nodes, unclipped, in f64 or in Duals (the table's derivatives
/// by the parameters that `channel(c)`'s numbers carry): `tabulate`'s layout for `channels` channel stacks
/// `channel(c)`, those of equal `key(c)` solved once. A node's Fourier coefficients are those of the cells beside it,
/// averaged; at θ = 0 only order 0 remains (f does not depend on the azimuth there). Reciprocal (the average of
/// (i, o) and (o, i), stored once). Below a smooth top: without the Dirac part (`ChannelStack::dirac_reflectance`,
/// which the model adds exactly), and divided at both nodes by what enters through the top and its clear slab
/// (`node_entering`, as the solve carries it), which vanishes at grazing angles like cos θ and which the cells
/// discretize coarsely where refraction packs many outside cells into one inside: the model multiplies the
/// interpolation by the exact values, so that the table interpolates only what varies slowly.
pub fn node_values<T: Real, K: PartialEq>(
    channels: usize,
    channel: impl Fn(usize) -> ChannelStack<T>,
    key: impl Fn(usize) -> K,
) -> Result<Vec<T>> {
    let cells = Cells::new();
    let (n, ch) = (N_THETA, channels);
    let mut table = vec![T::from(0.0); PAIRS * N_PHI * ch];
    let mut done: Vec<(K, usize)> = Vec::new();
    let shared = Shared::new(&(0..ch).flat_map(|c| channel(c).interfaces).collect::<Vec<_>>());
    let cosines: Vec<f64> = (0..N_PHI)
        .flat_map(|p| {
            let phi = 2.0 * (p as f64 / (N_PHI - 1) as f64).asin();
            (0..ORDERS).map(move |m| (m as f64 * phi).cos())
        })
        .collect();
    for c in 0..ch {
        // Channels with equal optical constants share one solution.
        let key = key(c);
        if let Some(&(_, c0)) = done.iter().find(|(k, _)| *k == key) {
            for k in 0..PAIRS * N_PHI {
                table[k * ch + c] = table[k * ch + c0];
            }
            continue;
        }
        done.push((key, c));
        let s = channel(c);
        // Below a smooth top, f / (Āi Āo): what enters through the top and its clear slab, steep near grazing,
        // factored out of what the table interpolates (the model multiplies by the exact values).
        let t = match s.is_delta(0) {
            true => node_entering(&cells, &s),
            false => vec![T::from(1.0); NODES],
        };
        let mut r = reflection_below_top(&cells, &s, Paths::All, &shared)?;
        if s.is_delta(0) {
            // Below a smooth top, smooth boundaries reflect Dirac lobes that cells would blur: the model adds them
            // exactly (`specular`), so the table keeps the rest.
            let dirac = reflection_below_top(&cells, &s, Paths::Dirac, &shared)?;
            r.iter_mut().zip(&dirac).for_each(|(r, d)| r.iter_mut().zip(d).for_each(|(r, &d)| *r = *r - d));
        }
        // ā_m(o, j) = S_m[o][j] / (π (1 + δ_m0) w_j), symmetrized.
        let a = |m: usize, o: usize, j: usize| r[m][o * n + j] / (PI * if m == 0 { 2.0 } else { 1.0 } * cells.w[j]);
        let coefficient = |m: usize, o: usize, j: usize| (a(m, o, j) + a(m, j, o)) * 0.5;
        for o in 0..NODES {
            for i in 0..=o {
                let orders = if i == 0 || o == 0 { 1 } else { ORDERS };
                let mut am = [T::from(0.0); ORDERS];
                for (ci, wi) in node_cells(i, N_THETA) {
                    for (co, wo) in node_cells(o, N_THETA) {
                        (0..orders).for_each(|m| am[m] = am[m] + coefficient(m, co, ci) * (wi * wo));
                    }
                }
                let transmitted = t[i] * t[o];
                for p in 0..N_PHI {
                    let f: T = am.iter().zip(&cosines[p * ORDERS..(p + 1) * ORDERS]).map(|(&a, &c)| a * c).sum();
                    table[(pair(i, o) * N_PHI + p) * ch + c] = f / transmitted;
                }
            }
        }
    }
    Ok(table)
}

/// What channel c of `stack` is made of (two channels with equal keys have equal tables).
pub fn channel_key(stack: &Stack, c: usize) -> Vec<f64> {
    use crate::stack::Layer;
    stack
        .layers
        .iter()
        .flat_map(|l| match l {
            Layer::Dielectric { ior, sigma_a, sigma_s, .. } => vec![ior[c], sigma_a[c], sigma_s[c]],
            Layer::Conductor { ior, k, .. } => vec![ior[c], k[c]],
            Layer::Diffuse { albedo, .. } => vec![albedo[c]],
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::models::common::testing::dielectric;
    use crate::stack::Layer;

    /// The energy leaving every column of an operator (order 0), light from each incident cell.
    fn energies(cells: &Cells, op: &Op) -> Vec<f64> {
        (0..N_THETA).map(|j| column_energy(cells, &op[0], j)).collect()
    }

    fn channel(layers: Vec<Layer>) -> ChannelStack {
        ChannelStack::new(&Stack::new(layers, 1.0).unwrap(), 0, crate::models::reference_surface())
    }

    fn slab_layer(sigma_a: f64, sigma_s: f64, thickness: f64, g: f64) -> Layer {
        let (ior, alpha, angle) = (vec![1.0], (0.0, 0.0), 0.0);
        Layer::Dielectric { ior, alpha, angle, thickness, sigma_a: vec![sigma_a], sigma_s: vec![sigma_s], g }
    }

    #[test]
    fn solving_one_minus_a_sums_its_neumann_series() {
        // (I − A)⁻¹ B = Σ Aᵏ B for A of norm below one: a pseudo-random A with row sums of 0.6.
        let n = N_THETA;
        let a: Mat = (0..n * n).map(|k| 1.2 / n as f64 * ((k * 7919 % 101) as f64 / 100.0)).collect();
        let b: Mat = (0..n * n).map(|k| ((k * 104_729 % 97) as f64 / 96.0) - 0.5).collect();
        let (mut sum, mut term) = (b.clone(), b.clone());
        for _ in 0..200 {
            term = mul(&a, &term);
            sum = add(&sum, &term);
        }
        let x = solve_one_minus(&a, &b);
        let worst = x.iter().zip(&sum).map(|(x, s)| (x - s).abs()).fold(0.0, f64::max);
        assert!(worst < 1e-12, "{worst}");
    }

    #[test]
    fn a_lambertian_base_projects_to_its_constant_order_zero() {
        // f = ρ/π: the cell-averaged Fourier coefficient ā₀ is ρ/π everywhere, every other order 0.
        let s = channel(vec![Layer::Diffuse { albedo: vec![0.7], roughness: 0.0 }]);
        let cells = Cells::new();
        let op = base(&cells, &s, s.interfaces.len(), Paths::All);
        for (m, order) in op.iter().enumerate() {
            for o in 0..N_THETA {
                for j in 0..N_THETA {
                    let a = order[o * N_THETA + j] / (PI * if m == 0 { 2.0 } else { 1.0 } * cells.w[j]);
                    let exact = if m == 0 { 0.7 / PI } else { 0.0 };
                    assert!((a - exact).abs() < 1e-13, "order {m}, cells ({o}, {j}): {a}");
                }
            }
        }
    }

    #[test]
    fn a_lossless_scattering_slab_conserves_energy() {
        // ω = 1: every column of R + T carries all the light it receives, whatever τ and g, up to the grid's
        // quadrature of the phase function, which the doublings carry along: measured worst 1.9e-4 (τ = 0.1),
        // 2.5e-4 (τ = 1), 3.1e-4 (τ = 4).
        let cells = Cells::new();
        for (tau, g) in [(0.1, 0.0), (1.0, -0.3), (4.0, 0.6)] {
            let s = channel(vec![slab_layer(0.0, tau, 1.0, g), Layer::Diffuse { albedo: vec![0.0], roughness: 0.0 }]);
            let ops = slab(&cells, &s, 0, Paths::All).unwrap().unwrap();
            for (r, t) in energies(&cells, &ops.r_top).iter().zip(energies(&cells, &ops.t_down)) {
                assert!((r + t - 1.0).abs() < 5e-4, "τ = {tau}, g = {g}: R + T = {}", r + t);
            }
        }
    }

    #[test]
    fn an_absorbing_slab_transmits_beer_lambert() {
        // σs = 0: no reflection, and each cell transmits its average of e^{−τ/μ} straight down.
        let cells = Cells::new();
        let s = channel(vec![slab_layer(0.8, 0.0, 0.5, 0.0), Layer::Diffuse { albedo: vec![0.0], roughness: 0.0 }]);
        let ops = slab(&cells, &s, 0, Paths::All).unwrap().unwrap();
        let t = energies(&cells, &ops.t_down);
        for (j, t) in t.iter().enumerate() {
            let exact = cells.average(j, |mu| (-0.4 / mu).exp());
            assert!((t - exact).abs() < 1e-14 && energies(&cells, &ops.r_top)[j] == 0.0, "cell {j}: {t} vs {exact}");
        }
    }

    #[test]
    fn a_smooth_interface_reflects_and_transmits_all_it_receives() {
        // Per cell R + T = 1 from both sides (η = 1.5 from above; 1/1.5 from below, where cells beyond the critical
        // angle reflect everything and the one that straddles it transmits its refracting part): each cell
        // transmits what its average Fresnel does not reflect.
        let cells = Cells::new();
        let s =
            channel(vec![dielectric(1.5, 0.0, 0.0, 0.0, 0.0), Layer::Diffuse { albedo: vec![0.0], roughness: 0.0 }]);
        let ops = interface(&cells, &s, 0, Paths::All);
        for (r, t) in [(&ops.r_top, &ops.t_down), (&ops.r_bottom, &ops.t_up)] {
            for (j, (r, t)) in energies(&cells, r).iter().zip(energies(&cells, t)).enumerate() {
                assert!((r + t - 1.0).abs() < 1e-12 && (0.0..=1.0).contains(r), "cell {j}: R = {r}, T = {t}");
            }
        }
        let critical = (0..N_THETA).find(|&j| cells.edges[j + 1] > 1.0 / 2.25).unwrap();
        assert!(energies(&cells, &ops.r_bottom)[critical] < 1.0);
        assert!(energies(&cells, &ops.t_up)[critical + 1..].iter().all(|&t| t == 0.0));
    }

    #[test]
    fn light_trapped_between_two_total_internal_reflections_is_left_out() {
        // η 1.5 over 1.2: the cells of the 1.5 layer beyond sin²θ = (1.2/1.5)² totally reflect at both of its
        // boundaries, and no light reaches them; (I − R_top R_bottom) is singular there. A lossless stack over a
        // white Lambertian base reflects everything: the layer's operators stay finite and conserve energy.
        let lambert = Layer::Diffuse { albedo: vec![1.0], roughness: 0.0 };
        let s = channel(vec![dielectric(1.5, 0.0, 1.0, 0.0, 0.0), dielectric(1.2, 0.0, 1.0, 0.0, 0.0), lambert]);
        let cells = Cells::new();
        let below = over(&interface(&cells, &s, 1, Paths::All), base(&cells, &s, s.interfaces.len(), Paths::All), true);
        let r = over(&interface(&cells, &s, 0, Paths::All), below, true);
        assert!(r.iter().all(|m| m.iter().all(|v| v.is_finite())));
        for (j, e) in energies(&cells, &r).iter().enumerate() {
            // Measured: 1 − 1.1e-16 … 1 + 1.4e-15 (without leaving the trapped cells out: not finite).
            assert!((e - 1.0).abs() < 1e-12, "cell {j}: {e}");
        }
    }
}
