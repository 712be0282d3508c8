//! Weighted non-linear least squares (Levenberg–Marquardt with a finite-difference Jacobian and box bounds), for
//! the closed-form fits of Steinberg's tables.

/// Minimises Σ w_k (model(p, x_k) − y_k)² over p within [lo, hi] from `start`; returns (p, weighted RMS residual).
pub fn levenberg_marquardt<const P: usize>(
    model: impl Fn(&[f64; P], f64) -> f64,
    xs: &[f64],
    ys: &[f64],
    weights: &[f64],
    start: [f64; P],
    lo: [f64; P],
    hi: [f64; P],
) -> ([f64; P], f64) {
    let cost = |p: &[f64; P]| -> f64 {
        xs.iter().zip(ys).zip(weights).map(|((&x, &y), &w)| w * (model(p, x) - y).powi(2)).sum()
    };
    let clamp = |p: [f64; P]| -> [f64; P] { std::array::from_fn(|j| p[j].clamp(lo[j], hi[j])) };
    let mut p = clamp(start);
    let mut c = cost(&p);
    let mut lambda = 1e-3;
    for _ in 0..300 {
        // Normal equations (JᵀWJ + λ diag JᵀWJ) δ = JᵀW r.
        let mut jtj = [[0.0; P]; P];
        let mut jtr = [0.0; P];
        for ((&x, &y), &w) in xs.iter().zip(ys).zip(weights) {
            let f = model(&p, x);
            let grad: [f64; P] = std::array::from_fn(|j| {
                let h = 1e-7 * p[j].abs().max(1e-3);
                let mut q = p;
                q[j] += h;
                (model(&q, x) - f) / h
            });
            for a in 0..P {
                jtr[a] += w * grad[a] * (y - f);
                for b in 0..P {
                    jtj[a][b] += w * grad[a] * grad[b];
                }
            }
        }
        let mut improved = false;
        while lambda < 1e10 {
            let mut m = jtj;
            for a in 0..P {
                m[a][a] += lambda * jtj[a][a].max(1e-12);
            }
            let Some(delta) = solve(m, jtr) else { break };
            let q = clamp(std::array::from_fn(|j| p[j] + delta[j]));
            let cq = cost(&q);
            if cq.is_finite() && cq < c {
                let done = c - cq < 1e-14 * c.max(1e-300);
                (p, c, lambda) = (q, cq, (lambda * 0.3).max(1e-12));
                improved = !done;
                break;
            }
            lambda *= 10.0;
        }
        if !improved {
            break;
        }
    }
    (p, (c / weights.iter().sum::<f64>()).sqrt())
}

/// Solves the P×P system by Gaussian elimination with partial pivoting (None when singular).
fn solve<const P: usize>(mut m: [[f64; P]; P], mut b: [f64; P]) -> Option<[f64; P]> {
    for col in 0..P {
        let piv = (col..P).max_by(|&i, &j| m[i][col].abs().total_cmp(&m[j][col].abs()))?;
        if m[piv][col].abs() < 1e-300 {
            return None;
        }
        m.swap(col, piv);
        b.swap(col, piv);
        for row in col + 1..P {
            let f = m[row][col] / m[col][col];
            let pivot_row = m[col];
            for (x, p) in m[row][col..].iter_mut().zip(&pivot_row[col..]) {
                *x -= f * p;
            }
            b[row] -= f * b[col];
        }
    }
    let mut x = [0.0; P];
    for row in (0..P).rev() {
        let s: f64 = (row + 1..P).map(|k| m[row][k] * x[k]).sum();
        x[row] = (b[row] - s) / m[row][row];
    }
    Some(x)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn recovers_the_parameters_of_an_exact_model() {
        let model = |p: &[f64; 4], x: f64| p[0] * (p[1] * x).exp() + p[2] * (p[3] * x).exp();
        let truth = [0.7, -2.0, 0.2, 1.5];
        let xs: Vec<f64> = (0..50).map(|i| i as f64 / 49.0).collect();
        let ys: Vec<f64> = xs.iter().map(|&x| model(&truth, x)).collect();
        let w = vec![1.0; xs.len()];
        let (p, rms) = levenberg_marquardt(model, &xs, &ys, &w, [1.0, -1.0, 0.1, 1.0], [-10.0; 4], [10.0; 4]);
        assert!(rms < 1e-9, "{p:?} {rms}");
    }
}
