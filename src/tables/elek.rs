//! Elek 2010's precomputed shading tables: a 1D Fresnel table per interface and channel (128 samples of F over
//! cos θ in [0, 1], linear interpolation) and one 2D table of the Beckmann distribution D(cos θh, m) (512 × 512,
//! cos θh stored through the non-linear coordinate u = cos⁸θh, which puts most nodes near the peak at cos θh = 1;
//! m uniform in [0, 1]; bilinear interpolation). The D table takes ~10 ms to build, so it is built per process and
//! not cached on disk.

use super::Grid;
use crate::optics::distribution::MIN_ALPHA;
use std::f64::consts::PI;
use std::sync::OnceLock;

pub const FRESNEL_SAMPLES: usize = 128;
pub const D_SIZE: usize = 512;

/// F(cos θ) sampled at 128 cosines uniform in [0, 1], and beside it the transmittance 1 − F computed without
/// cancellation (lamina's addition: 1 − F of the stored F loses precision at grazing incidence, where F → 1).
pub struct FresnelTable(Grid<1, 2>);

impl FresnelTable {
    /// The table of `f_t`, which gives (F, 1 − F) at a cosine.
    pub fn new(f_t: impl Fn(f64) -> (f64, f64)) -> Self {
        let data = (0..FRESNEL_SAMPLES)
            .flat_map(|i| {
                let (f, t) = f_t(i as f64 / (FRESNEL_SAMPLES - 1) as f64);
                [f as f32, t as f32]
            })
            .collect();
        FresnelTable(Grid::new([FRESNEL_SAMPLES], data))
    }

    /// F at `cos_theta`, linearly interpolated.
    pub fn lookup(&self, cos_theta: f64) -> f64 {
        self.0.lookup([cos_theta])[0]
    }

    /// 1 − F at `cos_theta`, linearly interpolated.
    pub fn transmittance(&self, cos_theta: f64) -> f64 {
        self.0.lookup([cos_theta])[1]
    }

    /// The samples (F, 1 − F) per cosine, as the GPU uploads them.
    pub fn samples(&self) -> &[f32] {
        self.0.data()
    }
}

/// Isotropic Beckmann D (Walter et al. 2007 eq. 25) of roughness m at cos θh.
fn beckmann(cos_h: f64, m: f64) -> f64 {
    let m = m.max(MIN_ALPHA);
    if cos_h <= 0.0 {
        return 0.0;
    }
    let c2 = cos_h * cos_h;
    (-(1.0 - c2) / (c2 * m * m)).exp() / (PI * m * m * c2 * c2)
}

/// [m][u] with u = cos⁸θh.
pub struct BeckmannTable(Grid<2, 1>);

impl BeckmannTable {
    /// The samples [m][u], as the GPU uploads them (shaders/weidlich_wilkie.wgsl).
    pub fn samples(&self) -> &[f32] {
        self.0.data()
    }

    pub fn lookup(&self, cos_h: f64, m: f64) -> f64 {
        self.0.lookup([m, cos_h.max(0.0).powi(8)])[0]
    }
}

pub fn beckmann_table() -> &'static BeckmannTable {
    static TABLE: OnceLock<BeckmannTable> = OnceLock::new();
    TABLE.get_or_init(|| {
        let step = 1.0 / (D_SIZE - 1) as f64;
        let data = (0..D_SIZE * D_SIZE)
            .map(|k| beckmann(((k % D_SIZE) as f64 * step).powf(1.0 / 8.0), (k / D_SIZE) as f64 * step) as f32)
            .collect();
        BeckmannTable(Grid::new([D_SIZE, D_SIZE], data))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tables_are_exact_at_nodes() {
        let t = beckmann_table();
        let (cos_h, m) = ((300.0f64 / 511.0).powf(1.0 / 8.0), 100.0 / 511.0);
        assert!((t.lookup(cos_h, m) / beckmann(cos_h, m) - 1.0).abs() < 1e-5);
        let f = FresnelTable::new(|c| (c * c, 1.0 - c * c));
        assert!((f.lookup(1.0) - 1.0).abs() < 1e-7 && (f.lookup(0.5) - 0.25).abs() < 1e-4);
        assert!((f.transmittance(0.5) - 0.75).abs() < 1e-4);
    }
}
