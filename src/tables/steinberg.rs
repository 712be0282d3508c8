//! Steinberg's two integrals without closed form, for one rough GGX dielectric interface seen from above along a
//! direction v of cosine μ, relative IOR η (below / above) and roughness α (plus the TIR fraction that Belcour's TIR
//! step takes, tabulated with them since it integrates over the same visible normals):
//! - t(μ, α, η): the mean Fresnel transmission over the microfacets visible from v, E_{m∼D_v}[1 − F(v·m, η)];
//! - s(μ, α, η): the sine of the mean refracted direction, normalize(E_{m∼D_v}[refract(v, m)]) over the
//!   refractions that go down (total internal reflections and refractions that leave the macro-surface are
//!   discarded); it lies in the plane of incidence, opposite to v. When nothing refracts, s = 1 (and t ≈ 0);
//! - p(μ, α, η): the fraction of visible normals at which v is totally internally reflected (η < 1 only);
//! - T(μ, α, η): what a single-scattering rough interface actually transmits, E_{m∼D_v}[(1 − F(v·m, η)) G2/G1]
//!   over the refractions that go down, with the height-correlated Smith G2 of v and the refracted direction
//!   (Heitz 2014 eq. 99): t without the light that the microsurface masks on its way down, which R + T = 1 ignores
//!   (lamina's `microfacet_transmission` correction).
//!
//! Tabulated form: μ uniform in [0, 1] (64 nodes), α uniform in [0, 1] (32), η log-uniform in [1/4, 4] (48),
//! 512 stratified visible normals per (μ, α); trilinear interpolation of t, p and of s / sin θ (constant, 1/η, for a
//! smooth interface, so that interpolation keeps Snell's law exact; interpolating s itself lets the view-to-slab map
//! deviate from Snell near μ = 1, where it is steep, and the albedo of a smooth coat then exceeds 1). Fitted form (Steinberg's article): per
//! (α, η) node, t ≈ m((erf(aμ − b) + 1) + cμ) + d (0 ≤ c, m ≤ 1) and s ≈ a₁e^{a₂μ} + b₁e^{b₂μ}, fitted to the
//! tabulated μ column by weighted Levenberg–Marquardt (weights 10 at μ = 0 and 100 at μ = 1 for t, 10 at both ends
//! for s), bilinear in (α, log η) between nodes. The fit error against the table is reported in docs/validation.md.

use super::{fit, node_real, shared, visible_normals, Grid};
use crate::dual::Real;
use crate::optics::distribution::{Distribution, Microfacet};
use crate::optics::fresnel;
use crate::optics::refract;
use glam::DVec3;
use rayon::prelude::*;
use std::sync::OnceLock;

pub const N_MU: usize = 64;
pub const N_ALPHA: usize = 32;
pub const N_ETA: usize = 48;
pub const ETA_MIN: f64 = 0.25;
pub const ETA_MAX: f64 = 4.0;
const QUADRATURE: usize = 512;
/// Values per table node: t, s / sin θ, p, T.
const STRIDE: usize = 4;
const T_PARAMS: usize = 5;
const S_PARAMS: usize = 4;

pub fn mu_at(i: usize) -> f64 {
    (i as f64 / (N_MU - 1) as f64).clamp(1e-3, 1.0 - 1e-9)
}

pub fn alpha_at(i: usize) -> f64 {
    i as f64 / (N_ALPHA - 1) as f64
}

pub fn eta_at(i: usize) -> f64 {
    ETA_MIN * (ETA_MAX / ETA_MIN).powf(i as f64 / (N_ETA - 1) as f64)
}

fn eta_coord<T: Real>(eta: T) -> T {
    (eta / ETA_MIN).ln() / (ETA_MAX / ETA_MIN).ln()
}

/// t, s, p and T of one (μ, α, η) by quadrature over `normals` (the visible normals from v of `mf`), or exactly
/// for a smooth interface (Fresnel and Snell).
fn integrate(mf: &Microfacet, v: DVec3, normals: &[DVec3], eta: f64) -> [f64; STRIDE] {
    if normals.is_empty() {
        let sin_t = (1.0 - v.z * v.z).sqrt() / eta;
        let t = 1.0 - fresnel::dielectric(v.z, eta);
        return [t, sin_t.min(1.0), (sin_t > 1.0) as u8 as f64, t];
    }
    let (mut t, mut p, mut transmitted) = (0.0, 0.0, 0.0);
    let mut mean = DVec3::ZERO;
    let lambda_v = mf.lambda(v);
    for &m in normals {
        let f_t = 1.0 - fresnel::dielectric(v.dot(m), eta);
        t += f_t;
        match refract(v, m, eta) {
            None => p += 1.0,
            Some(d) if d.z < 0.0 => {
                mean += d;
                // G2/G1 of the height-correlated Smith form: (1 + Λ(v)) / (1 + Λ(v) + Λ(d)).
                transmitted += f_t * (1.0 + lambda_v) / (1.0 + lambda_v + mf.lambda(d));
            }
            Some(_) => {}
        }
    }
    let n = normals.len() as f64;
    let len = mean.length();
    let s = if len > 0.0 { (mean.x.hypot(mean.y) / len).min(1.0) } else { 1.0 };
    [t / n, s, p / n, transmitted / n]
}

/// Transmission model m((erf(aμ − b) + 1) + cμ) + d, parameters (a, b, c, d, m).
pub fn t_model<T: Real>(p: &[f64; T_PARAMS], mu: T) -> T {
    ((mu * p[0] - p[1]).erf() + 1.0 + mu * p[2]) * p[4] + p[3]
}

/// Refraction model a₁e^{a₂μ} + b₁e^{b₂μ}, parameters (a₁, a₂, b₁, b₂).
pub fn s_model<T: Real>(p: &[f64; S_PARAMS], mu: T) -> T {
    (mu * p[1]).exp() * p[0] + (mu * p[3]).exp() * p[2]
}

pub struct Steinberg {
    /// [μ][α][η][t, s / sin θ, p, T]
    table: Grid<3, STRIDE>,
    /// [α][η][a, b, c, d, m, a₁, a₂, b₁, b₂]
    fits: Vec<f32>,
}

impl Steinberg {
    fn generate_table() -> Vec<f32> {
        let mut table: Vec<f32> = (0..N_MU * N_ALPHA)
            .into_par_iter()
            .flat_map_iter(|cell| {
                let (mu, alpha) = (mu_at(cell / N_ALPHA), alpha_at(cell % N_ALPHA));
                let v = DVec3::new((1.0 - mu * mu).sqrt(), 0.0, mu);
                let mf = Microfacet::new(Distribution::Ggx, alpha, alpha, 0.0);
                let normals = if alpha == 0.0 { vec![] } else { visible_normals(&mf, v, QUADRATURE) };
                (0..N_ETA).flat_map(move |e| {
                    let [t, s, p, transmitted] = integrate(&mf, v, &normals, eta_at(e));
                    [t as f32, (s / v.x) as f32, p as f32, transmitted as f32]
                })
            })
            .collect();
        // At μ = 1 the ratio s / sin θ is 0/0 (and quadrature noise over a vanishing sine): take its limit from the
        // neighbouring node (s / sin θ is even in θ, so the error is O(θ²)).
        let row = N_ALPHA * N_ETA * STRIDE;
        for k in (1..row).step_by(STRIDE) {
            table[(N_MU - 1) * row + k] = table[(N_MU - 2) * row + k];
        }
        table
    }

    /// Fits both closed forms to every (α, η) column of the table; along α each fit starts from its neighbour's.
    fn generate_fits(table: &[f32]) -> Vec<f32> {
        let xs: Vec<f64> = (0..N_MU).map(mu_at).collect();
        let edge = |inner: f64, last: f64| -> Vec<f64> {
            (0..N_MU)
                .map(|i| {
                    if i == 0 {
                        10.0
                    } else if i == N_MU - 1 {
                        last
                    } else {
                        inner
                    }
                })
                .collect()
        };
        let (wt, ws) = (edge(1.0, 100.0), edge(1.0, 10.0));
        let column = |a: usize, e: usize, k: usize| -> Vec<f64> {
            let sin = |m: usize| if k == 1 { (1.0 - mu_at(m).powi(2)).sqrt() } else { 1.0 };
            (0..N_MU).map(|m| table[((m * N_ALPHA + a) * N_ETA + e) * STRIDE + k] as f64 * sin(m)).collect()
        };
        let per_eta: Vec<Vec<f32>> = (0..N_ETA)
            .into_par_iter()
            .map(|e| {
                let mut out = vec![0f32; N_ALPHA * (T_PARAMS + S_PARAMS)];
                let (mut prev_t, mut prev_s) = ([8.0, 1.0, 0.0, 0.0, 0.5], [-0.5, 3.0, 1.0, -1.0]);
                for a in 0..N_ALPHA {
                    let (ts, ss) = (column(a, e, 0), column(a, e, 1));
                    let inf = 1e3;
                    let best_t =
                        [prev_t, [0.0, 0.0, 0.0, 0.0, 0.5], [5.0, 0.0, 0.0, 0.0, 0.5], [20.0, 1.0, 0.0, 0.0, 0.5]]
                            .into_iter()
                            .map(|start| {
                                fit::levenberg_marquardt(
                                    t_model,
                                    &xs,
                                    &ts,
                                    &wt,
                                    start,
                                    [-inf, -inf, 0.0, -inf, 0.0],
                                    [inf, inf, 1.0, inf, 1.0],
                                )
                            })
                            .min_by(|x, y| x.1.total_cmp(&y.1))
                            .unwrap()
                            .0;
                    let best_s = [prev_s, [1.0, -1.0, 0.0, 0.0], [-0.5, 3.0, 1.0, -1.0], [0.7, -0.5, -0.01, 4.0]]
                        .into_iter()
                        .map(|start| fit::levenberg_marquardt(s_model, &xs, &ss, &ws, start, [-inf; 4], [inf; 4]))
                        .min_by(|x, y| x.1.total_cmp(&y.1))
                        .unwrap()
                        .0;
                    (prev_t, prev_s) = (best_t, best_s);
                    let dst = &mut out[a * (T_PARAMS + S_PARAMS)..(a + 1) * (T_PARAMS + S_PARAMS)];
                    for (d, v) in dst.iter_mut().zip(best_t.iter().chain(&best_s)) {
                        *d = *v as f32;
                    }
                }
                out
            })
            .collect();
        // Reorder [η][α] → [α][η].
        let stride = T_PARAMS + S_PARAMS;
        let mut fits = vec![0f32; N_ALPHA * N_ETA * stride];
        for (e, col) in per_eta.iter().enumerate() {
            for a in 0..N_ALPHA {
                fits[(a * N_ETA + e) * stride..(a * N_ETA + e + 1) * stride]
                    .copy_from_slice(&col[a * stride..(a + 1) * stride]);
            }
        }
        fits
    }

    /// Trilinear interpolation in (μ, α, log η) of the node values [t, s / sin θ, p, T].
    fn interpolate<T: Real>(&self, mu: T, alpha: T, eta: T) -> [T; STRIDE] {
        self.table.lookup([mu, alpha, eta_coord(eta)])
    }

    /// The table's node values [μ][α][η][t, s / sin θ, p, T] and the fits' [α][η][a, b, c, d, m, a₁, a₂, b₁, b₂], as
    /// the GPU uploads them (shaders/steinberg.wgsl).
    pub fn gpu_data(&self) -> (&[f32], &[f32]) {
        (self.table.data(), &self.fits)
    }

    /// The table at one interface's fixed α and η, [t, 1 − s / sin θ, T] at each node of μ: linear interpolation in
    /// μ of this slice is the trilinear lookup (`tabulated`, `transmitted`) exactly (issue "Engine": tables sliced at
    /// `prepare`). 1 − s / sin θ rather than s / sin θ: its float32 rounding is relative to what refraction needs
    /// (walk_lanes::refracted_up).
    pub fn slice(&self, alpha: f64, eta: f64) -> Vec<f32> {
        let at = |i: usize| {
            let [t, s, _, big_t] = self.table.lookup([i as f64 / (N_MU - 1) as f64, alpha, eta_coord(eta)]);
            [t as f32, (1.0 - s) as f32, big_t as f32]
        };
        (0..N_MU).flat_map(at).collect()
    }

    /// The table at one interface's fixed η over (μ, α), [t, 1 − s / sin θ, T] per node ([μ][α]), for anisotropic
    /// interfaces, which read it at each direction's projected roughness: bilinear interpolation of this slice is
    /// the trilinear lookup exactly.
    pub fn slice_alpha(&self, eta: f64) -> Vec<f32> {
        let at = |n: usize| {
            let (i, j) = ((n / N_ALPHA) as f64, (n % N_ALPHA) as f64);
            let [t, s, _, big_t] = self.table.lookup([i / (N_MU - 1) as f64, j / (N_ALPHA - 1) as f64, eta_coord(eta)]);
            [t as f32, (1.0 - s) as f32, big_t as f32]
        };
        (0..N_MU * N_ALPHA).flat_map(at).collect()
    }

    /// (t, s) from the table (s through s / sin θ).
    pub fn tabulated<T: Real>(&self, mu: T, alpha: T, eta: T) -> (T, T) {
        let [t, s, ..] = self.interpolate(mu, alpha, eta);
        (t, (s * (T::from(1.0) - mu * mu).max_c(0.0).sqrt()).min_c(1.0))
    }

    /// T: the energy a single-scattering rough interface transmits, with the masking of the refracted light.
    pub fn transmitted<T: Real>(&self, mu: T, alpha: T, eta: T) -> T {
        self.interpolate(mu, alpha, eta)[3].clamp_c(0.0, 1.0)
    }

    /// p: the fraction of the visible normals at which the direction is totally internally reflected.
    pub fn tir_fraction(&self, mu: f64, alpha: f64, eta: f64) -> f64 {
        self.interpolate(mu, alpha, eta)[2].clamp(0.0, 1.0)
    }

    /// (t, s) from the fitted closed forms, bilinear in (α, log η) between the fitted nodes, clamped to [0, 1].
    pub fn fitted<T: Real>(&self, mu: T, alpha: T, eta: T) -> (T, T) {
        let (j, fj) = node_real(alpha, N_ALPHA);
        let (k, fk) = node_real(eta_coord(eta), N_ETA);
        let stride = T_PARAMS + S_PARAMS;
        let (mut t, mut s) = (T::from(0.0), T::from(0.0));
        for (dj, wj) in [(0, T::from(1.0) - fj), (1, fj)] {
            for (dk, wk) in [(0, T::from(1.0) - fk), (1, fk)] {
                let w = wj * wk;
                let c = &self.fits[((j + dj) * N_ETA + k + dk) * stride..][..stride];
                let pt: [f64; T_PARAMS] = std::array::from_fn(|q| c[q] as f64);
                let ps: [f64; S_PARAMS] = std::array::from_fn(|q| c[T_PARAMS + q] as f64);
                t = t + w * t_model(&pt, mu);
                s = s + w * s_model(&ps, mu);
            }
        }
        (t.clamp_c(0.0, 1.0), s.clamp_c(0.0, 1.0))
    }
}

/// The Steinberg tables: loaded from the cache when present, else generated (a few seconds) and cached.
pub fn steinberg() -> &'static Steinberg {
    static TABLE: OnceLock<Steinberg> = OnceLock::new();
    TABLE.get_or_init(|| {
        let dims = format!("{N_MU}x{N_ALPHA}x{N_ETA}");
        let table =
            shared(&format!("steinberg-{dims}.f32"), N_MU * N_ALPHA * N_ETA * STRIDE, Steinberg::generate_table);
        let fits = shared(&format!("steinberg-fit-{dims}.f32"), N_ALPHA * N_ETA * (T_PARAMS + S_PARAMS), || {
            Steinberg::generate_fits(&table)
        });
        Steinberg { table: Grid::new([N_MU, N_ALPHA, N_ETA], table), fits }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn smooth_limit_is_fresnel_and_snell() {
        let t = steinberg();
        let (mu, eta) = (mu_at(40), eta_at(30));
        let (tt, s) = t.tabulated(mu, 0.0, eta);
        assert!((tt - (1.0 - fresnel::dielectric(mu, eta))).abs() < 1e-6);
        assert!((t.transmitted(mu, 0.0, eta) - tt).abs() < 1e-6);
        assert!((s - (1.0 - mu * mu).sqrt() / eta).abs() < 1e-6);
    }

    #[test]
    fn tir_fraction_is_the_critical_angle_step_when_smooth_and_matches_a_fine_quadrature_when_rough() {
        let t = steinberg();
        let eta = eta_at(10); // < 1: leaving a denser medium
        let mu_c = (1.0 - eta * eta).sqrt();
        for m in [10, 30, 50, 63] {
            let mu = mu_at(m);
            assert_eq!(t.tir_fraction(mu, 0.0, eta), if mu < mu_c { 1.0 } else { 0.0 }, "μ = {mu}");
        }
        assert_eq!(t.tir_fraction(0.3, 0.6, 1.5), 0.0);
        let (mu, alpha, eta) = (0.8, 0.45, 0.7);
        let v = DVec3::new((1.0f64 - mu * mu).sqrt(), 0.0, mu);
        let mf = Microfacet::new(Distribution::Ggx, alpha, alpha, 0.0);
        let p_ref = integrate(&mf, v, &visible_normals(&mf, v, 65536), eta)[2];
        let p = t.tir_fraction(mu, alpha, eta);
        assert!(p_ref > 0.05 && (p - p_ref).abs() < 5e-3, "{p} {p_ref}");
    }

    #[test]
    fn matches_a_fine_quadrature_between_nodes() {
        // η = 1.5, α = 0.5, μ = 0.5: t, s and T from 65536 visible normals.
        let (mu, alpha, eta) = (0.5, 0.5, 1.5);
        let v = DVec3::new((1.0f64 - mu * mu).sqrt(), 0.0, mu);
        let mf = Microfacet::new(Distribution::Ggx, alpha, alpha, 0.0);
        let [t_ref, s_ref, _, transmitted_ref] = integrate(&mf, v, &visible_normals(&mf, v, 65536), eta);
        let (t, s) = steinberg().tabulated(mu, alpha, eta);
        assert!((t - t_ref).abs() < 3e-3 && (s - s_ref).abs() < 3e-3, "{t} {t_ref} {s} {s_ref}");
        let transmitted = steinberg().transmitted(mu, alpha, eta);
        assert!((transmitted - transmitted_ref).abs() < 3e-3, "{transmitted} {transmitted_ref}");
        // Masking keeps some of what the Fresnel term lets through.
        assert!(transmitted_ref < t_ref - 0.02, "{transmitted_ref} {t_ref}");
    }

    #[test]
    fn transmitted_energy_is_the_integral_of_the_rough_dielectric_btdf() {
        // T against ∫ f_t(v, wo) |cos θo| dωo of Walter et al.'s BTDF (bsdf::rough_dielectric), by Gauss–Legendre
        // in cos θo and the midpoint rule in φo (the lobe is smooth at these roughnesses).
        for (mu, alpha, eta) in [(0.5, 0.5, 1.5), (0.9, 0.3, 1.33), (0.3, 0.8, 2.0)] {
            let v = DVec3::new((1.0f64 - mu * mu).sqrt(), 0.0, mu);
            let mf = Microfacet::new(Distribution::Ggx, alpha, alpha, 0.0);
            let n_phi = 512;
            let mut integral = 0.0;
            for (x, w) in crate::quadrature::gauss_legendre(256) {
                let c = 0.5 * (x + 1.0);
                let s = (1.0 - c * c).sqrt();
                for j in 0..n_phi {
                    let phi = (j as f64 + 0.5) / n_phi as f64 * std::f64::consts::TAU;
                    let wo = DVec3::new(s * phi.cos(), s * phi.sin(), -c);
                    let f = crate::bsdf::rough_dielectric(
                        &mf,
                        crate::optics::distribution::G2Form::HeightCorrelated,
                        eta,
                        v,
                        wo,
                    );
                    integral += 0.5 * w * std::f64::consts::TAU / n_phi as f64 * f * c;
                }
            }
            let t = steinberg().transmitted(mu, alpha, eta);
            assert!((t - integral).abs() < 4e-3, "μ {mu} α {alpha} η {eta}: table {t}, integral {integral}");
        }
    }
}
