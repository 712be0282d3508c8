//! FGD(cos θ, α, η, κ): directional albedo of one rough GGX interface (separable Smith) with the exact Fresnel
//! reflectance of the relative complex IOR η + iκ (κ = 0: dielectric, total internal reflection for η < 1), as
//! used by Belcour 2018 for the energy of a reflection. Axes: cos θ uniform in [0, 1] (32 nodes), α uniform in
//! [0, 1] (32), η log-uniform in [0.02, 8] (48), √(κ / 12) uniform in [0, 1] (24); quadrilinear interpolation,
//! clamped at the ends. Each entry is a 256-point stratified visible-normal quadrature, E[F(wi·m) G2/G1].

use super::Grid;
use crate::dual::Real;
use crate::optics::distribution::{Distribution, G2Form, Microfacet};
use crate::optics::fresnel;
use crate::optics::reflect;
use glam::DVec3;
use rayon::prelude::*;
use std::sync::OnceLock;

pub const N_MU: usize = 32;
pub const N_ALPHA: usize = 32;
pub const N_ETA: usize = 48;
pub const N_KAPPA: usize = 24;
pub const ETA_MIN: f64 = 0.02;
pub const ETA_MAX: f64 = 8.0;
pub const KAPPA_MAX: f64 = 12.0;
const QUADRATURE: usize = 256;

pub struct Fgd {
    grid: Grid<4, 1>,
}

fn mu_at(i: usize) -> f64 {
    (i as f64 / (N_MU - 1) as f64).max(1e-3)
}

fn alpha_at(i: usize) -> f64 {
    i as f64 / (N_ALPHA - 1) as f64
}

fn eta_at(i: usize) -> f64 {
    ETA_MIN * (ETA_MAX / ETA_MIN).powf(i as f64 / (N_ETA - 1) as f64)
}

fn kappa_at(i: usize) -> f64 {
    KAPPA_MAX * (i as f64 / (N_KAPPA - 1) as f64).powi(2)
}

impl Fgd {
    /// Generates the table (a few seconds on two cores).
    pub fn generate() -> Fgd {
        let cells: Vec<Vec<f32>> = (0..N_MU * N_ALPHA)
            .into_par_iter()
            .map(|cell| {
                let (mu, alpha) = (mu_at(cell / N_ALPHA), alpha_at(cell % N_ALPHA));
                let wi = DVec3::new((1.0 - mu * mu).sqrt(), 0.0, mu);
                // Quadrature nodes: cosines wi·m and weights G2/G1 of stratified visible normals.
                let nodes: Vec<(f64, f64)> = if alpha == 0.0 {
                    vec![(mu, 1.0)]
                } else {
                    let mf = Microfacet::new(Distribution::Ggx, alpha, alpha, 0.0);
                    super::visible_normals(&mf, wi, QUADRATURE)
                        .into_iter()
                        .map(|m| {
                            let wo = reflect(wi, m);
                            let w = if wo.z > 0.0 { mf.g2(G2Form::Separable, wi, wo, m) / mf.g1(wi, m) } else { 0.0 };
                            (wi.dot(m), w / QUADRATURE as f64)
                        })
                        .collect()
                };
                let mut out = Vec::with_capacity(N_ETA * N_KAPPA);
                for e in 0..N_ETA {
                    for k in 0..N_KAPPA {
                        let (eta, kappa) = (eta_at(e), kappa_at(k));
                        out.push(nodes.iter().map(|&(c, w)| w * fresnel::conductor(c, eta, kappa)).sum::<f64>() as f32);
                    }
                }
                out
            })
            .collect();
        Fgd { grid: Grid::new([N_MU, N_ALPHA, N_ETA, N_KAPPA], cells.concat()) }
    }

    /// The node values [μ][α][η][κ], as the GPU uploads them (shaders/albedo_scaling.wgsl).
    pub fn data(&self) -> &[f32] {
        self.grid.data()
    }

    /// Quadrilinear lookup of FGD(μ, α, η, κ), in f64 or in Duals (the derivative of the interpolant).
    pub fn lookup<T: Real>(&self, mu: T, alpha: T, eta: T, kappa: T) -> T {
        let eta = (eta / ETA_MIN).ln() / (ETA_MAX / ETA_MIN).ln();
        self.grid.lookup([mu, alpha, eta, (kappa / KAPPA_MAX).max_c(0.0).sqrt()])[0]
    }
}

/// The FGD table: loaded from the cache when present, else generated and cached.
pub fn fgd() -> &'static Fgd {
    static TABLE: OnceLock<Fgd> = OnceLock::new();
    TABLE.get_or_init(|| {
        let name = format!("fgd-{N_MU}x{N_ALPHA}x{N_ETA}x{N_KAPPA}.f32");
        let data = super::shared(&name, N_MU * N_ALPHA * N_ETA * N_KAPPA, || Fgd::generate().grid.data().to_vec());
        Fgd { grid: Grid::new([N_MU, N_ALPHA, N_ETA, N_KAPPA], data) }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fgd_matches_exact_values_at_nodes_and_limits() {
        let t = fgd();
        // α = 0: plain Fresnel.
        assert!((t.lookup(1.0, 0.0, eta_at(30), 0.0) - fresnel::dielectric(1.0, eta_at(30))).abs() < 1e-6);
        // Between nodes, against a 4096-point quadrature of the definition.
        let (mu, alpha, eta, kappa) = (0.63, 0.27, 1.5, 0.0);
        let mf = Microfacet::new(Distribution::Ggx, alpha, alpha, 0.0);
        let wi = DVec3::new((1.0f64 - mu * mu).sqrt(), 0.0, mu);
        let n = 4096;
        let exact: f64 = (0..n)
            .map(|k| {
                let m = mf.sample_visible(wi, (k as f64 + 0.5) / n as f64, (k as f64 * 0.618_033_988_749_895).fract());
                let wo = reflect(wi, m);
                if wo.z <= 0.0 {
                    0.0
                } else {
                    fresnel::conductor(wi.dot(m), eta, kappa) * mf.g2(G2Form::Separable, wi, wo, m) / mf.g1(wi, m)
                }
            })
            .sum::<f64>()
            / n as f64;
        let got = t.lookup(mu, alpha, eta, kappa);
        assert!((got - exact).abs() < 2e-3, "{got} vs {exact}");
    }
}
