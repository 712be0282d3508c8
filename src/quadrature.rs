//! Numerical quadrature shared by the tables and the models.

use crate::dual::Real;

/// Nodes and weights of n-point Gauss–Legendre quadrature on [-1, 1] (Newton iteration on P_n).
pub fn gauss_legendre(n: usize) -> Vec<(f64, f64)> {
    (1..=n)
        .map(|i| {
            let mut x = (std::f64::consts::PI * (i as f64 - 0.25) / (n as f64 + 0.5)).cos();
            loop {
                let (mut p0, mut p1) = (1.0, x);
                for k in 2..=n {
                    let p2 = ((2 * k - 1) as f64 * x * p1 - (k - 1) as f64 * p0) / k as f64;
                    (p0, p1) = (p1, p2);
                }
                let dp = n as f64 * (x * p1 - p0) / (x * x - 1.0);
                let dx = p1 / dp;
                x -= dx;
                if dx.abs() < 1e-15 {
                    return (x, 2.0 / ((1.0 - x * x) * dp * dp));
                }
            }
        })
        .collect()
}

/// Integral of `f` over [a, b] by composite 24-point Gauss–Legendre quadrature over `pieces` sub-intervals (in f64,
/// or in Duals where the bounds or the integrand carry derivatives).
pub fn integrate<T: Real>(f: impl Fn(T) -> T, a: T, b: T, pieces: usize) -> T {
    let nodes = gauss_legendre(24);
    let h = (b - a) / pieces as f64;
    let zero = T::from(0.0);
    (0..pieces)
        .map(|p| {
            let mid = a + h * (p as f64 + 0.5);
            nodes.iter().fold(zero, |s, &(x, w)| s + f(mid + h * 0.5 * x) * w) * h * 0.5
        })
        .fold(zero, |s, v| s + v)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quadrature_is_exact_for_polynomials() {
        assert!((integrate(|x| x.powi(7) - 3.0 * x * x, 0.0, 2.0, 1) - (32.0 - 8.0)).abs() < 1e-12);
    }
}
