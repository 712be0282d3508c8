//! Evaluation in blocks of rows: every `Model::eval_block` takes up to BLOCK direction pairs as columns. The helpers
//! here evaluate one pair, a fan of directions at one wo, a block row by row, and compile a model's block loop for
//! AVX2 + FMA when the CPU has them.

use crate::models::Model;
use glam::DVec3;

/// Rows per evaluation block (`Model::eval_block`).
pub const BLOCK: usize = 64;

/// The most per-element inputs a model declares.
pub const MAX_INPUTS: usize = 4;

/// f(wi, wo) of one pair (a block of one row) with the pair's per-element input values (at most MAX_INPUTS).
pub fn eval_one(model: &dyn Model, wi: DVec3, wo: DVec3, inputs: &[Option<[f64; 3]>], out: &mut [f64]) {
    let cols: [[[f64; 1]; 3]; MAX_INPUTS] =
        std::array::from_fn(|j| inputs.get(j).copied().flatten().unwrap_or_default().map(|x| [x]));
    let block: [Option<[&[f64]; 3]>; MAX_INPUTS] =
        std::array::from_fn(|j| inputs.get(j).copied().flatten().map(|_| cols[j].each_ref().map(|c| &c[..])));
    out.fill(0.0);
    model.eval_block([&[wi.x], &[wi.y], &[wi.z]], [&[wo.x], &[wo.y], &[wo.z]], &block[..inputs.len()], out);
}

/// f(wi, wo) for many wi and one wo with one set of per-element input values: out[k] is f at wis[k] (3 channels),
/// evaluated in blocks of BLOCK rows (a renderer's samples at one pixel).
pub fn eval_fan(model: &dyn Model, wo: DVec3, inputs: &[Option<[f64; 3]>], wis: &[DVec3], out: &mut [[f64; 3]]) {
    if wis.len() <= 4 {
        // A few directions (a pixel under point lights): one row at a time, without zeroing a block's scratch.
        for (wi, o) in wis.iter().zip(out.iter_mut()) {
            eval_one(model, *wi, wo, inputs, o);
        }
        return;
    }
    let mut cols = [[[0.0; BLOCK]; 3]; 2];
    let inputs_cols: [[[f64; BLOCK]; 3]; MAX_INPUTS] =
        std::array::from_fn(|j| inputs.get(j).copied().flatten().unwrap_or_default().map(|x| [x; BLOCK]));
    (0..3).for_each(|c| cols[1][c] = [wo[c]; BLOCK]);
    let mut f = [0.0; 3 * BLOCK];
    for (chunk, dst) in wis.chunks(BLOCK).zip(out.chunks_mut(BLOCK)) {
        let n = chunk.len();
        for (r, w) in chunk.iter().enumerate() {
            (0..3).for_each(|c| cols[0][c][r] = w[c]);
        }
        let block: [Option<[&[f64]; 3]>; MAX_INPUTS] = std::array::from_fn(|j| {
            inputs.get(j).copied().flatten().map(|_| inputs_cols[j].each_ref().map(|c| &c[..n]))
        });
        f[..3 * n].fill(0.0);
        model.eval_block(
            cols[0].each_ref().map(|c| &c[..n]),
            cols[1].each_ref().map(|c| &c[..n]),
            &block[..inputs.len()],
            &mut f[..3 * n],
        );
        for (d, v) in dst.iter_mut().zip(f.chunks_exact(3)) {
            *d = [v[0], v[1], v[2]];
        }
    }
}

/// Row r of a block's direction columns.
#[inline(always)]
pub fn row(w: [&[f64]; 3], r: usize) -> DVec3 {
    DVec3::new(w[0][r], w[1][r], w[2][r])
}

/// A block evaluated row by row with `eval(r, wi, wo, out_row)`: the block path of what has no vectorized form.
#[inline(always)]
pub fn eval_rows(
    wi: [&[f64]; 3],
    wo: [&[f64]; 3],
    out: &mut [f64],
    mut eval: impl FnMut(usize, DVec3, DVec3, &mut [f64]),
) {
    let k = out.len() / wi[0].len();
    for (r, o) in out.chunks_exact_mut(k).enumerate() {
        eval(r, row(wi, r), row(wo, r), o);
    }
}

/// The body of a `Model::eval_block` that runs `$p.eval_columns(wi, wo, out)` (an `#[inline(always)]` method of
/// type `$ty`) through `with_avx2!`.
macro_rules! simd_columns {
    ($ty:ty, $p:expr, $wi:expr, $wo:expr, $out:expr) => {{
        let (p, wi, wo, out) = ($p, $wi, $wo, $out);
        $crate::engine::with_avx2!(
            [] (p: &$ty, wi: [&[f64]; 3], wo: [&[f64]; 3], out: &mut [f64]) => p.eval_columns(wi, wo, out)
        )
    }};
}
pub(crate) use simd_columns;
