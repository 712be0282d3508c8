//! Array plumbing of the bindings: inputs (already broadcast to one batch shape by python/lamina/_arrays.py) are
//! checked, gathered into f64 blocks of rows (structure of arrays) and evaluated in parallel with rayon while the
//! GIL is released, in chunks between which Ctrl-C is honoured; outputs are allocated by NumPy (MemoryError, not an
//! abort, when they do not fit) and written in place: float32 when every input is float32, else float64.

use crate::engine::Rows;
use crate::models::BLOCK;
use glam::DVec3;
use numpy::{PyArrayDyn, PyArrayMethods, PyReadonlyArrayDyn, PyUntypedArrayMethods};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use rayon::prelude::*;
use std::sync::atomic::{AtomicUsize, Ordering};

/// How an input array is checked: a direction (3-vector, finite, non-zero, normalised here), finite values, or
/// values in a closed range.
#[derive(Clone, Copy, PartialEq)]
pub enum Kind {
    Direction,
    Values(usize),
    Range(usize, f64, f64),
}

impl Kind {
    pub fn width(self) -> usize {
        match self {
            Kind::Direction => 3,
            Kind::Values(k) | Kind::Range(k, ..) => k,
        }
    }
}

/// A non-contiguous (strided or broadcast) input, read in place: no copy, whatever its size.
struct Strided<T> {
    ptr: *const T,
    /// The batch axes' lengths and strides (in elements), and the stride of the last (vector) axis.
    dims: Vec<usize>,
    strides: Vec<isize>,
    last: isize,
}

// SAFETY: the pointer reads a NumPy array that the caller keeps borrowed read-only for the whole evaluation.
unsafe impl<T: Sync> Sync for Strided<T> {}
unsafe impl<T: Sync> Send for Strided<T> {}

impl<T: Copy + Into<f64>> Strided<T> {
    fn new(a: numpy::ndarray::ArrayViewD<'_, T>) -> Self {
        let nd = a.ndim();
        Strided {
            ptr: a.as_ptr(),
            dims: a.shape()[..nd - 1].to_vec(),
            strides: a.strides()[..nd - 1].to_vec(),
            last: a.strides()[nd - 1],
        }
    }

    fn gather(&self, w: usize, start: usize, len: usize, cols: &mut [[f64; BLOCK]; MAX_WIDTH]) {
        for r in 0..len {
            let (mut i, mut offset) = (start + r, 0isize);
            for (&n, &stride) in self.dims.iter().zip(&self.strides).rev() {
                offset += (i % n) as isize * stride;
                i /= n;
            }
            for (c, col) in cols.iter_mut().enumerate().take(w) {
                // SAFETY: the offset is that of element (row, c) inside the borrowed array.
                col[r] = unsafe { *self.ptr.offset(offset + c as isize * self.last) }.into();
            }
        }
    }
}

/// The elements of one input array in logical (C) order: NumPy's own memory, contiguous or strided.
enum Data<'a> {
    F64(&'a [f64]),
    F32(&'a [f32]),
    Strided64(Strided<f64>),
    Strided32(Strided<f32>),
}

impl Data<'_> {
    /// Rows start..start + len of this (..., w) input into the columns cols[0..w][0..len].
    fn gather(&self, w: usize, start: usize, len: usize, cols: &mut [[f64; BLOCK]; MAX_WIDTH]) {
        fn transpose<T: Copy + Into<f64>>(src: &[T], w: usize, cols: &mut [[f64; BLOCK]; MAX_WIDTH]) {
            for (r, row) in src.chunks_exact(w).enumerate() {
                for (c, &x) in row.iter().enumerate() {
                    cols[c][r] = x.into();
                }
            }
        }
        let range = start * w..(start + len) * w;
        match self {
            Data::F64(s) => transpose(&s[range], w, cols),
            Data::F32(s) => transpose(&s[range], w, cols),
            Data::Strided64(v) => v.gather(w, start, len, cols),
            Data::Strided32(v) => v.gather(w, start, len, cols),
        }
    }
}

/// Widest row a kernel reads from one input (directions: 3).
pub const MAX_WIDTH: usize = 3;
/// The most arrays a kernel takes (two directions and a model's per-element inputs).
pub const MAX_INPUTS: usize = 6;
pub type Row = [f64; MAX_WIDTH];

/// One block of at most BLOCK rows, gathered into columns (structure of arrays): component c of input j in row r
/// is cols[j][c][r]. Directions are normalised.
pub struct Block {
    pub len: usize,
    pub cols: [[[f64; BLOCK]; MAX_WIDTH]; MAX_INPUTS],
}

impl Block {
    /// The columns of input j, each of length `len`.
    pub fn columns(&self, j: usize) -> [&[f64]; MAX_WIDTH] {
        std::array::from_fn(|c| &self.cols[j][c][..self.len])
    }

    /// Checks and normalises input j (width w) in place; the first bad row as (row, zero-length), if any. The loops
    /// are branch-free so that they vectorize (with AVX2 when the CPU has it); a block with a bad row is scanned
    /// again to find it.
    fn validate(&mut self, j: usize, kind: Kind) -> Option<(usize, bool)> {
        let block = self;
        crate::engine::with_avx2!(
            [] (block: &mut Block, j: usize, kind: Kind) -> Option<(usize, bool)> => block.validate_portable(j, kind)
        )
    }

    #[inline(always)]
    fn validate_portable(&mut self, j: usize, kind: Kind) -> Option<(usize, bool)> {
        let (w, n) = (kind.width(), self.len);
        let cols = &mut self.cols[j];
        // Columns sliced to the row count: no bounds checks in the loops, which lets them vectorize.
        let bad = match kind {
            Kind::Direction => {
                let [x, y, z] = cols.each_mut().map(|c| &mut c[..n]);
                let mut bad = false;
                for r in 0..n {
                    let len2 = x[r] * x[r] + y[r] * y[r] + z[r] * z[r];
                    bad |= (x[r] + y[r] + z[r]) * 0.0 != 0.0 || len2 == 0.0; // NaN·0 and ±Inf·0 are NaN
                }
                if !bad {
                    for r in 0..n {
                        let inv = 1.0 / (x[r] * x[r] + y[r] * y[r] + z[r] * z[r]).sqrt();
                        (x[r], y[r], z[r]) = (x[r] * inv, y[r] * inv, z[r] * inv);
                    }
                }
                bad
            }
            Kind::Values(_) => cols[..w].iter().any(|c| c[..n].iter().fold(0.0, |acc, x| acc + x * 0.0) != 0.0),
            Kind::Range(_, lo, hi) => cols[..w].iter().any(|c| c[..n].iter().any(|x| !(lo..=hi).contains(x))),
        };
        if !bad {
            return None;
        }
        (0..self.len).find_map(|r| {
            let finite = cols[..w].iter().all(|col| col[r].is_finite());
            let out_of_range = match kind {
                Kind::Range(_, lo, hi) => cols[..w].iter().any(|col| !(lo..=hi).contains(&col[r])),
                _ => false,
            };
            let zero = kind == Kind::Direction && cols[..w].iter().all(|col| col[r] == 0.0);
            (!finite || zero || out_of_range).then_some((r, finite && zero))
        })
    }
}

/// No input row was rejected. A rejection is encoded as (row · MAX_INPUTS + input) · 2 + reason, reason 0 for
/// NaN/Inf or a value out of range and 1 for a zero-length direction, so that the smallest code is the first bad row.
const NO_ERROR: usize = usize::MAX;

/// Rows per chunk of a long evaluation: between chunks the GIL is taken back to check for Ctrl-C.
const CHUNK_ROWS: usize = 1 << 20;

/// Evaluates `kernel` on every block of rows of the (already broadcast) inputs, in parallel with the GIL released,
/// writing straight into a new NumPy array of shape batch + (out_k,): float32 when every input is float32, else
/// float64. The kernel receives a block and its zeroed output, rows of out_k values in f64. Rows are validated on
/// the way (NaN/Inf, zero-length directions, ranges) and the first bad one raises ValueError. Float32 outputs are
/// clamped to the largest finite float32 (a float64 value beyond it would otherwise become Inf).
pub fn batch_blocks<'py>(
    py: Python<'py>,
    inputs: &[(&str, &Bound<'py, PyAny>, Kind)],
    out_k: usize,
    kernel: impl Fn(&Block, &mut [f64]) + Sync,
) -> PyResult<Bound<'py, PyAny>> {
    if inputs.is_empty() || inputs.len() > MAX_INPUTS {
        return Err(PyValueError::new_err(format!("at most {MAX_INPUTS} input arrays, got {}", inputs.len())));
    }
    if out_k == 0 {
        return Err(PyValueError::new_err("the stack has no channels: wavelengths must hold at least one value"));
    }
    let (mut f64s, mut f32s) = (Vec::new(), Vec::new());
    let mut shapes = Vec::new();
    for (name, obj, kind) in inputs {
        if let Ok(a) = obj.extract::<PyReadonlyArrayDyn<'py, f64>>() {
            shapes.push(a.shape().to_vec());
            f64s.push(a);
        } else if let Ok(a) = obj.extract::<PyReadonlyArrayDyn<'py, f32>>() {
            shapes.push(a.shape().to_vec());
            f32s.push(a);
        } else {
            return Err(PyTypeError::new_err(format!("{name} must be a float32 or float64 array")));
        }
        let shape = shapes.last().unwrap();
        if shape.last() != Some(&kind.width()) {
            return Err(PyValueError::new_err(format!(
                "{name} must have shape (..., {}), got {shape:?}",
                kind.width()
            )));
        }
    }
    let batch_shape = shapes[0][..shapes[0].len() - 1].to_vec();
    for (i, s) in shapes.iter().enumerate() {
        if s[..s.len() - 1] != batch_shape[..] {
            return Err(PyValueError::new_err(format!(
                "{} has batch shape {:?}, which does not match {}'s {:?}",
                inputs[i].0,
                &s[..s.len() - 1],
                inputs[0].0,
                batch_shape
            )));
        }
    }
    // Read NumPy's memory in place, contiguous or strided (broadcast inputs are never materialised).
    let (mut it64, mut it32) = (f64s.iter(), f32s.iter());
    let data: Vec<Data> = inputs
        .iter()
        .map(|(_, obj, _)| {
            if obj.extract::<PyReadonlyArrayDyn<'py, f64>>().is_ok() {
                let a = it64.next().unwrap();
                match a.as_slice() {
                    Ok(s) if a.is_c_contiguous() => Data::F64(s),
                    _ => Data::Strided64(Strided::new(a.as_array())),
                }
            } else {
                let a = it32.next().unwrap();
                match a.as_slice() {
                    Ok(s) if a.is_c_contiguous() => Data::F32(s),
                    _ => Data::Strided32(Strided::new(a.as_array())),
                }
            }
        })
        .collect();
    let kinds: Vec<Kind> = inputs.iter().map(|(_, _, k)| *k).collect();
    let n: usize = batch_shape.iter().product();
    let mut shape = batch_shape;
    shape.push(out_k);
    let first_bad = AtomicUsize::new(NO_ERROR);
    let eval_block = |start: usize, block: &mut Block, out: &mut [f64]| {
        for (j, (d, &kind)) in data.iter().zip(&kinds).enumerate() {
            d.gather(kind.width(), start, block.len, &mut block.cols[j]);
            if let Some((r, zero_length)) = block.validate(j, kind) {
                first_bad.fetch_min(((start + r) * MAX_INPUTS + j) * 2 + zero_length as usize, Ordering::Relaxed);
                return;
            }
        }
        kernel(block, out);
    };
    // NumPy allocates the output, so that an output too large raises MemoryError.
    let float32 = f64s.is_empty();
    let dtype = if float32 { "float32" } else { "float64" };
    let array = py.import("numpy")?.call_method1("empty", (shape, dtype))?;
    if float32 {
        let a = array.cast::<PyArrayDyn<f32>>()?;
        fill_chunked(py, unsafe { a.as_slice_mut() }.expect("new arrays are contiguous"), out_k, &eval_block)?;
    } else {
        let a = array.cast::<PyArrayDyn<f64>>()?;
        fill_chunked(py, unsafe { a.as_slice_mut() }.expect("new arrays are contiguous"), out_k, &eval_block)?;
    }
    let bad = first_bad.into_inner();
    if bad != NO_ERROR {
        let (row, j, zero_length) = (bad / 2 / MAX_INPUTS, bad / 2 % MAX_INPUTS, bad % 2 == 1);
        let what = match kinds[j] {
            _ if zero_length => "a zero-length direction".to_string(),
            Kind::Range(_, lo, hi) => format!("NaN, Inf or a value outside [{lo}, {hi}]"),
            _ => "NaN or Inf".to_string(),
        };
        return Err(PyValueError::new_err(format!("{} contains {what} (row {row} of {n})", inputs[j].0)));
    }
    Ok(array)
}

/// A float32 (..., 3) array as rows the engine reads in place: C-contiguous, or one row broadcast to every element
/// (every batch stride 0); None for other layouts.
fn engine_rows<'a>(a: &'a PyReadonlyArrayDyn<'_, f32>) -> Option<Rows<'a>> {
    let v = a.as_array();
    let nd = v.ndim();
    if nd == 0 || v.shape()[nd - 1] != 3 {
        return None;
    }
    if let (true, Ok(s)) = (a.is_c_contiguous(), a.as_slice()) {
        return Some(Rows::Packed(s));
    }
    let first: Vec<f32> = v.iter().take(3).copied().collect();
    (v.strides()[..nd - 1].iter().all(|&s| s == 0) && first.len() == 3)
        .then(|| Rows::Splat([first[0], first[1], first[2]]))
}

/// f of float32 directions by the float32 engine: `eval(wi, wo, out)` over chunks of CHUNK_ROWS rows with the GIL
/// released (Ctrl-C checked in between), into a new float32 array of shape batch + (out_k,). None, before anything
/// is computed, for inputs the engine does not read (float64, other layouts), and None when `eval` declines a chunk
/// (engine::eval): the caller then takes the careful path.
pub fn engine_f32<'py>(
    py: Python<'py>,
    wi: &Bound<'py, PyAny>,
    wo: &Bound<'py, PyAny>,
    out_k: usize,
    eval: impl Fn(Rows, Rows, &mut [f32]) -> bool + Sync,
) -> PyResult<Option<Bound<'py, PyAny>>> {
    let (Ok(a), Ok(b)) = (wi.extract::<PyReadonlyArrayDyn<'py, f32>>(), wo.extract::<PyReadonlyArrayDyn<'py, f32>>())
    else {
        return Ok(None);
    };
    let (Some(ra), Some(rb)) = (engine_rows(&a), engine_rows(&b)) else { return Ok(None) };
    if a.shape() != b.shape() || out_k == 0 {
        return Ok(None);
    }
    let mut shape = a.shape()[..a.ndim() - 1].to_vec();
    shape.push(out_k);
    let array = py.import("numpy")?.call_method1("empty", (shape, "float32"))?;
    let out = unsafe { array.cast::<PyArrayDyn<f32>>()?.as_slice_mut() }.expect("new arrays are contiguous");
    for (c, chunk) in out.chunks_mut(CHUNK_ROWS * out_k).enumerate() {
        let (start, len) = (c * CHUNK_ROWS, chunk.len() / out_k);
        let (wi, wo) = (ra.rows(start, len), rb.rows(start, len));
        if !py.detach(|| eval(wi, wo, chunk)) {
            return Ok(None);
        }
        py.check_signals()?;
    }
    Ok(Some(array))
}

/// `fill` in chunks of CHUNK_ROWS rows with the GIL released, checking for Ctrl-C (KeyboardInterrupt) in between.
fn fill_chunked<T: OutElement>(
    py: Python<'_>,
    out: &mut [T],
    out_k: usize,
    f: &(dyn Fn(usize, &mut Block, &mut [f64]) + Sync),
) -> PyResult<()> {
    for (c, chunk) in out.chunks_mut(CHUNK_ROWS * out_k).enumerate() {
        py.detach(|| fill(chunk, out_k, &|start, block, scratch| f(c * CHUNK_ROWS + start, block, scratch)));
        py.check_signals()?;
    }
    Ok(())
}

/// `batch_blocks` for a kernel of one row: `kernel(rows, out)` with rows[j] the (normalised) row of input j.
pub fn batch<'py>(
    py: Python<'py>,
    inputs: &[(&str, &Bound<'py, PyAny>, Kind)],
    out_k: usize,
    kernel: impl Fn(&[Row], &mut [f64]) + Sync,
) -> PyResult<Bound<'py, PyAny>> {
    let m = inputs.len();
    batch_blocks(py, inputs, out_k, |b, out| {
        for (r, o) in out.chunks_exact_mut(out_k).enumerate() {
            let rows: [Row; MAX_INPUTS] = std::array::from_fn(|j| std::array::from_fn(|c| b.cols[j][c][r]));
            kernel(&rows[..m], o);
        }
    })
}

/// Output element types.
trait OutElement: Copy + Send + Sync {
    fn from_f64(x: f64) -> Self;
}

impl OutElement for f64 {
    fn from_f64(x: f64) -> Self {
        x
    }
}

impl OutElement for f32 {
    fn from_f64(x: f64) -> Self {
        (if x > f32::MAX as f64 { f32::MAX as f64 } else { x }) as f32
    }
}

/// Fills `out` (rows of `out_k`) in parallel, a block of BLOCK rows at a time: `f(first row, block, scratch)`
/// evaluates the block in f64 into the zeroed scratch, which is then stored as T.
fn fill<T: OutElement>(out: &mut [T], out_k: usize, f: &(dyn Fn(usize, &mut Block, &mut [f64]) + Sync)) {
    out.par_chunks_mut(BLOCK * out_k).enumerate().with_min_len(4).for_each_init(
        || (Box::new(Block { len: 0, cols: [[[0.0; BLOCK]; MAX_WIDTH]; MAX_INPUTS] }), vec![0.0f64; BLOCK * out_k]),
        |(block, scratch), (b, o)| {
            block.len = o.len() / out_k;
            let scratch = &mut scratch[..o.len()];
            scratch.fill(0.0);
            f(b * BLOCK, block, scratch);
            for (dst, &src) in o.iter_mut().zip(scratch.iter()) {
                *dst = T::from_f64(src);
            }
        },
    );
}

/// A row of an input as a vector.
pub fn vec3(row: &Row) -> DVec3 {
    DVec3::new(row[0], row[1], row[2])
}
