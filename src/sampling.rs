//! Random numbers and direction sampling shared by the Monte Carlo code. Every sample has its own stream, seeded
//! from (seed, sample index), so results depend on neither the thread count nor the evaluation order.

use crate::dual::Real;
use glam::DVec3;
use std::f64::consts::PI;

/// SplitMix64 (Steele, Lea and Flood 2014): a small generator whose outputs pass BigCrush; one per sample.
#[derive(Clone, Debug)]
pub struct Rng(u64);

impl Rng {
    /// The stream of sample `index` under `seed`.
    pub fn new(seed: u64, index: u64) -> Rng {
        let mut r = Rng(seed ^ 0x9E37_79B9_7F4A_7C15u64.wrapping_mul(index.wrapping_add(1)));
        r.next_u64();
        r
    }

    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// A seed for the streams of one configuration: mixes `seed` with the bit patterns of `values` (e.g. the
    /// directions of a query), so different queries get independent streams while each stays reproducible.
    pub fn seed_for(seed: u64, values: &[f64]) -> u64 {
        values.iter().fold(seed, |acc, v| Rng(acc ^ v.to_bits()).next_u64())
    }

    /// Uniform in [0, 1) with 53 random bits.
    pub fn uniform(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }
}

/// Cosine-weighted direction on the upper hemisphere (Malley's method); pdf = cos θ / π.
pub fn cosine_hemisphere(u1: f64, u2: f64) -> DVec3 {
    let r = u1.sqrt();
    let phi = 2.0 * PI * u2;
    DVec3::new(r * phi.cos(), r * phi.sin(), (1.0 - u1).max(0.0).sqrt())
}

/// Henyey–Greenstein phase function p(cos θ) = (1 − g²) / (4π (1 + g² − 2g cos θ)^{3/2}), θ the scattering angle.
pub fn henyey_greenstein<T: Real>(cos_theta: f64, g: T) -> T {
    let d = g * g + 1.0 - g * 2.0 * cos_theta;
    (T::from(1.0) - g * g) / (d * (4.0 * PI) * d.sqrt())
}

/// Samples a new propagation direction scattered from `dir` by Henyey–Greenstein with asymmetry g (inversion of
/// its CDF, e.g. pbrt-v4 §11.3.1); exact, so the sampling weight is 1.
pub fn sample_henyey_greenstein(dir: DVec3, g: f64, u1: f64, u2: f64) -> DVec3 {
    let cos_theta = if g.abs() < 1e-4 {
        1.0 - 2.0 * u1
    } else {
        let s = (1.0 - g * g) / (1.0 + g - 2.0 * g * u1);
        ((1.0 + g * g - s * s) / (2.0 * g)).clamp(-1.0, 1.0)
    };
    let sin_theta = (1.0 - cos_theta * cos_theta).max(0.0).sqrt();
    let phi = 2.0 * PI * u2;
    let (t, b) = orthonormal_basis(dir);
    sin_theta * phi.cos() * t + sin_theta * phi.sin() * b + cos_theta * dir
}

/// Two tangents completing the unit vector `n` to an orthonormal basis (Duff et al. 2017).
pub fn orthonormal_basis(n: DVec3) -> (DVec3, DVec3) {
    let sign = 1.0f64.copysign(n.z);
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    (DVec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x), DVec3::new(b, sign + n.y * n.y * a, -n.y))
}

/// The power heuristic with β = 2 (Veach 1997 eq. 9.13): the weight of a sample drawn with density `pdf` against
/// one other strategy of density `other` for the same direction.
#[inline]
pub fn power_heuristic(pdf: f64, other: f64) -> f64 {
    if pdf <= 0.0 {
        0.0
    } else {
        pdf * pdf / (pdf * pdf + other * other)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn streams_are_deterministic_and_distinct() {
        let a: Vec<u64> = (0..4).map(|_| Rng::new(7, 3).next_u64()).collect();
        assert!(a.windows(2).all(|w| w[0] == w[1]));
        assert_ne!(Rng::new(7, 3).next_u64(), Rng::new(7, 4).next_u64());
        assert_ne!(Rng::new(7, 3).next_u64(), Rng::new(8, 3).next_u64());
        let mut r = Rng::new(1, 1);
        let mean = (0..100_000).map(|_| r.uniform()).sum::<f64>() / 1e5;
        assert!((mean - 0.5).abs() < 4.0 * (1.0 / 12.0f64 / 1e5).sqrt());
    }

    #[test]
    fn query_seeds_differ_per_query_and_repeat() {
        assert_eq!(Rng::seed_for(1, &[0.5, 0.25]), Rng::seed_for(1, &[0.5, 0.25]));
        assert_ne!(Rng::seed_for(1, &[0.5, 0.25]), Rng::seed_for(1, &[0.25, 0.5]));
        assert_ne!(Rng::seed_for(1, &[0.5]), Rng::seed_for(2, &[0.5]));
    }

    #[test]
    fn henyey_greenstein_sampling_matches_its_mean_cosine() {
        // E[cos θ] = g for HG.
        for g in [-0.7, 0.0, 0.3, 0.9] {
            let mut r = Rng::new(3, 0);
            let n = 200_000;
            let mean = (0..n)
                .map(|_| sample_henyey_greenstein(DVec3::new(0.6, 0.0, 0.8), g, r.uniform(), r.uniform()))
                .map(|w| w.dot(DVec3::new(0.6, 0.0, 0.8)))
                .sum::<f64>()
                / n as f64;
            assert!((mean - g).abs() < 5e-3, "g = {g}: {mean}");
        }
    }

    #[test]
    fn basis_is_orthonormal() {
        for n in [DVec3::Z, -DVec3::Z, DVec3::new(0.3, -0.4, 0.5).normalize(), DVec3::new(0.0, 1.0, 1e-9).normalize()] {
            let (t, b) = orthonormal_basis(n);
            assert!((t.length() - 1.0).abs() < 1e-12 && (b.length() - 1.0).abs() < 1e-12);
            assert!(t.dot(n).abs() < 1e-12 && b.dot(n).abs() < 1e-12 && t.dot(b).abs() < 1e-12);
        }
    }
}
