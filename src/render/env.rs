//! Environment lighting: an equirectangular radiance map, its importance sampling (a piecewise-constant 2D
//! distribution over the pixels, weighted by luminance and sin θ: pbrt-v4 §12.5.2), and the built-in sky.
//!
//! World frame: +y is up; the default camera looks along −z. Pixel column u ∈ [0, 1) of the map is the azimuth
//! φ = 2π (u − 0.5) − rotation measured from −z towards +x; row v ∈ [0, 1) is the polar angle θ = π v from +y. So the
//! centre of the map is what the default camera sees behind the object.

use glam::DVec3;
use std::f64::consts::{PI, TAU};

/// Luminance of linear Rec. 709 RGB (ITU-R BT.709).
pub fn luminance(c: [f64; 3]) -> f64 {
    0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]
}

/// A 1D piecewise-constant distribution and its CDF (pbrt-v4 §A.4.1).
struct Pdf1 {
    func: Vec<f64>,
    cdf: Vec<f64>,
    integral: f64,
}

impl Pdf1 {
    fn new(func: Vec<f64>) -> Pdf1 {
        let n = func.len() as f64;
        let mut cdf = vec![0.0; func.len() + 1];
        for i in 0..func.len() {
            cdf[i + 1] = cdf[i] + func[i] / n;
        }
        let integral = cdf[func.len()];
        if integral > 0.0 {
            cdf.iter_mut().for_each(|c| *c /= integral);
        } else {
            cdf.iter_mut().enumerate().for_each(|(i, c)| *c = i as f64 / n);
        }
        Pdf1 { func, cdf, integral }
    }

    /// A continuous sample in [0, 1) and its density.
    fn sample(&self, u: f64) -> (f64, f64) {
        let n = self.func.len();
        let i = self.cdf.partition_point(|&c| c <= u).clamp(1, n) - 1;
        let width = self.cdf[i + 1] - self.cdf[i];
        let du = if width > 0.0 { (u - self.cdf[i]) / width } else { 0.5 };
        ((i as f64 + du.clamp(0.0, 1.0)) / n as f64, self.density(i))
    }

    /// The function, its CDF and its integral in one row, as shaders/env.wgsl reads a distribution.
    fn gpu_row(&self) -> impl Iterator<Item = f32> + '_ {
        self.func.iter().chain(&self.cdf).chain([&self.integral]).map(|&x| x as f32)
    }

    fn density(&self, i: usize) -> f64 {
        if self.integral > 0.0 {
            self.func[i] / self.integral
        } else {
            1.0
        }
    }
}

/// An equirectangular environment map of linear RGB radiance, with its sampling distribution.
pub struct Environment {
    width: usize,
    height: usize,
    /// Row-major RGB radiance, already multiplied by the light's scale.
    rgb: Vec<[f64; 3]>,
    rotation: f64,
    rows: Vec<Pdf1>,
    marginal: Pdf1,
}

impl Environment {
    /// A map of `height` rows and `width` columns of RGB radiance (row-major), scaled by `scale` and rotated by
    /// `rotation` radians about +y.
    pub fn new(width: usize, height: usize, rgb: Vec<[f64; 3]>, scale: f64, rotation: f64) -> Environment {
        let rgb: Vec<[f64; 3]> = rgb.into_iter().map(|c| c.map(|x| x * scale)).collect();
        let rows: Vec<Pdf1> = (0..height)
            .map(|j| {
                let sin_theta = (PI * (j as f64 + 0.5) / height as f64).sin();
                Pdf1::new((0..width).map(|i| luminance(rgb[j * width + i]).max(0.0) * sin_theta).collect())
            })
            .collect();
        let marginal = Pdf1::new(rows.iter().map(|r| r.integral).collect());
        Environment { width, height, rgb, rotation, rows, marginal }
    }

    /// The map as shaders/env.wgsl reads it: its parameters (EnvParams, with `spp` and `seed` for the renderer), the
    /// RGB radiance (3 values per texel) and the distributions (the marginal over the rows, then each row's).
    pub fn gpu_data(&self, spp: usize, seed: u64) -> ([u32; 8], Vec<f32>, Vec<f32>) {
        let seed = (seed ^ (seed >> 32)) as u32;
        let words =
            [self.width as u32, self.height as u32, spp as u32, seed, (self.rotation as f32).to_bits(), 0, 0, 0];
        let rgb = self.rgb.iter().flatten().map(|&x| x as f32).collect();
        let dists = self.marginal.gpu_row().chain(self.rows.iter().flat_map(Pdf1::gpu_row)).collect();
        (words, rgb, dists)
    }

    /// Map coordinates (u, v) ∈ [0, 1)² of the world direction d.
    fn uv(&self, d: DVec3) -> (f64, f64) {
        let phi = d.x.atan2(-d.z) + self.rotation;
        ((phi / TAU + 0.5).rem_euclid(1.0), d.y.clamp(-1.0, 1.0).acos() / PI)
    }

    /// The world direction of map coordinates (u, v).
    fn direction(&self, u: f64, v: f64) -> DVec3 {
        let (phi, theta) = (TAU * (u - 0.5) - self.rotation, PI * v);
        DVec3::new(theta.sin() * phi.sin(), theta.cos(), -theta.sin() * phi.cos())
    }

    fn texel(&self, u: f64, v: f64) -> (usize, usize) {
        (
            ((u * self.width as f64) as usize).min(self.width - 1),
            ((v * self.height as f64) as usize).min(self.height - 1),
        )
    }

    /// Radiance arriving from the world direction d (nearest texel).
    pub fn radiance(&self, d: DVec3) -> [f64; 3] {
        let (u, v) = self.uv(d);
        let (i, j) = self.texel(u, v);
        self.rgb[j * self.width + i]
    }

    /// Samples a world direction with density ∝ luminance: (direction, radiance, pdf per unit solid angle).
    pub fn sample(&self, u1: f64, u2: f64) -> (DVec3, [f64; 3], f64) {
        let (v, pv) = self.marginal.sample(u1);
        let (_, j) = self.texel(0.0, v);
        let (u, pu) = self.rows[j].sample(u2);
        let d = self.direction(u, v);
        let sin_theta = (PI * v).sin();
        let pdf = if sin_theta > 0.0 { pu * pv / (2.0 * PI * PI * sin_theta) } else { 0.0 };
        (d, self.radiance(d), pdf)
    }

    /// The density of `sample` at the world direction d, per unit solid angle.
    pub fn pdf(&self, d: DVec3) -> f64 {
        let (u, v) = self.uv(d);
        let (i, j) = self.texel(u, v);
        let sin_theta = (PI * v).sin();
        if sin_theta <= 0.0 {
            return 0.0;
        }
        self.marginal.density(j) * self.rows[j].density(i) / (2.0 * PI * PI * sin_theta)
    }
}

/// Direction towards the built-in sky's sun (elevation 33°, to the upper left and in front of the object).
pub const SUN: DVec3 = DVec3::new(-0.5, 0.545, 0.673);
/// Irradiance of the built-in sun on a surface facing it (linear RGB, slightly warm).
pub const SUN_IRRADIANCE: [f64; 3] = [3.0, 2.85, 2.6];

/// The built-in procedural sky (radiance, without the sun, which is a directional light SUN): blue at the zenith,
/// bright and warmer at the horizon, a glow around the sun, and a dark warm-grey ground below the horizon. A
/// smooth stand-in for a daylight capture, so that nothing has to be downloaded; not a physical sky model.
pub fn sky_radiance(d: DVec3) -> [f64; 3] {
    let zenith = [0.12, 0.26, 0.6];
    let horizon = [0.5, 0.55, 0.6];
    let ground = [0.12, 0.1, 0.08];
    let glow = 1.5 * (-(1.0 - d.dot(SUN.normalize())).max(0.0) / 0.01).exp();
    if d.y < 0.0 {
        let t = (-d.y).min(1.0).powf(0.35);
        return std::array::from_fn(|c| horizon[c] * 0.4 * (1.0 - t) + ground[c] * t);
    }
    let t = d.y.powf(0.45);
    std::array::from_fn(|c| horizon[c] * (1.0 - t) + zenith[c] * t + glow * [1.0, 0.9, 0.7][c])
}

/// The built-in sky as a `width` x `width`/2 equirectangular map (row-major RGB).
pub fn sky_map(width: usize) -> (usize, usize, Vec<[f64; 3]>) {
    let height = width / 2;
    let env = Environment::new(1, 1, vec![[0.0; 3]], 1.0, 0.0);
    let rgb = (0..height)
        .flat_map(|j| (0..width).map(move |i| (i, j)))
        .map(|(i, j)| sky_radiance(env.direction((i as f64 + 0.5) / width as f64, (j as f64 + 0.5) / height as f64)))
        .collect();
    (width, height, rgb)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::Rng;

    fn test_map() -> Environment {
        let (w, h, rgb) = sky_map(64);
        Environment::new(w, h, rgb, 1.0, 0.4)
    }

    #[test]
    fn directions_round_trip_through_map_coordinates() {
        let env = test_map();
        for (u, v) in [(0.1, 0.2), (0.5, 0.5), (0.9, 0.8), (0.33, 0.01)] {
            let (u2, v2) = env.uv(env.direction(u, v));
            assert!((u - u2).abs() < 1e-12 && (v - v2).abs() < 1e-12, "{u} {v} -> {u2} {v2}");
        }
        // The map's centre lies behind the object as the default camera sees it (−z), before rotation.
        let plain = Environment::new(1, 1, vec![[1.0; 3]], 1.0, 0.0);
        assert!((plain.direction(0.5, 0.5) - DVec3::NEG_Z).length() < 1e-12);
    }

    #[test]
    fn sampling_density_matches_pdf_and_integrates_the_map() {
        // E[L(d) / pdf(d)] over samples is ∫ L dω (per channel); the pdf returned by sample equals pdf(d); and a
        // uniform estimate of ∫ L dω agrees.
        let env = test_map();
        let n = 200_000;
        let mut rng = Rng::new(3, 0);
        let (mut by_sampling, mut uniform) = ([0.0; 3], [0.0; 3]);
        for _ in 0..n {
            let (d, l, pdf) = env.sample(rng.uniform(), rng.uniform());
            assert!((pdf - env.pdf(d)).abs() <= 1e-6 * pdf, "{pdf} vs {}", env.pdf(d));
            let z = 1.0 - 2.0 * rng.uniform();
            let phi = TAU * rng.uniform();
            let r = (1.0 - z * z).sqrt();
            let lu = env.radiance(DVec3::new(r * phi.cos(), z, r * phi.sin()));
            for c in 0..3 {
                by_sampling[c] += l[c] / pdf / n as f64;
                uniform[c] += lu[c] * 4.0 * PI / n as f64;
            }
        }
        for c in 0..3 {
            // The uniform estimate's relative standard error is below 0.5% for this smooth map.
            assert!((by_sampling[c] / uniform[c] - 1.0).abs() < 0.015, "{by_sampling:?} vs {uniform:?}");
        }
    }
}
