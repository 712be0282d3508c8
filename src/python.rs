//! Thin PyO3 bindings: NumPy arrays in, NumPy arrays out. Inputs arrive already broadcast to one batch shape
//! (python/lamina/_arrays.py); here they are checked, gathered into f64 rows and evaluated in parallel with rayon
//! while the GIL is released. No Rust panic crosses this boundary: bad input becomes ValueError / TypeError.

use crate::bsdf;
use crate::models::belcour::Tir;
use crate::models::{self, Options, BLOCK, MODELS};
use crate::optics::fresnel::{self, FresnelForm};
use crate::optics::microfacet::{Distribution, G2Form, Microfacet};
use crate::reference;
use crate::stack::{Error, Layer, Stack};
use glam::DVec3;
use numpy::ndarray::IxDyn;
use numpy::{PyArrayDyn, PyArrayMethods, PyReadonlyArrayDyn, PyUntypedArrayMethods};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};
use rayon::prelude::*;
use std::sync::atomic::{AtomicUsize, Ordering};

impl From<Error> for PyErr {
    fn from(e: Error) -> PyErr {
        PyValueError::new_err(e.to_string())
    }
}

/// How an input array is checked: a direction (3-vector, finite, non-zero, normalised here) or finite values.
#[derive(Clone, Copy, PartialEq)]
enum Kind {
    Direction,
    Values(usize),
}

impl Kind {
    fn width(self) -> usize {
        match self {
            Kind::Direction => 3,
            Kind::Values(k) => k,
        }
    }
}

/// The elements of one input array in logical (C) order: NumPy's own memory when it is contiguous, else a copy.
enum Data<'a> {
    F64(&'a [f64]),
    F32(&'a [f32]),
    Copied(Vec<f64>),
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
            Data::Copied(v) => transpose(&v[range], w, cols),
        }
    }
}

/// Widest row a kernel reads from one input (directions: 3).
const MAX_WIDTH: usize = 3;
/// The most arrays a kernel takes.
const MAX_INPUTS: usize = 4;
type Row = [f64; MAX_WIDTH];

/// One block of at most BLOCK rows, gathered into columns (structure of arrays): component c of input j in row r
/// is cols[j][c][r]. Directions are normalised.
struct Block {
    len: usize,
    cols: [[[f64; BLOCK]; MAX_WIDTH]; MAX_INPUTS],
}

impl Block {
    /// The columns of input j, each of length `len`.
    fn columns(&self, j: usize) -> [&[f64]; MAX_WIDTH] {
        std::array::from_fn(|c| &self.cols[j][c][..self.len])
    }

    /// Checks and normalises input j (width w) in place; the first bad row as (row, zero-length), if any. The loops
    /// are branch-free so that they vectorize (with AVX2 when the CPU has it); a block with a bad row is scanned
    /// again to find it.
    fn validate(&mut self, j: usize, kind: Kind) -> Option<(usize, bool)> {
        #[cfg(target_arch = "x86_64")]
        if models::has_avx2() {
            // SAFETY: the CPU supports every feature the function is compiled for.
            return unsafe { self.validate_avx2(j, kind) };
        }
        self.validate_portable(j, kind)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    unsafe fn validate_avx2(&mut self, j: usize, kind: Kind) -> Option<(usize, bool)> {
        self.validate_portable(j, kind)
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
        };
        if !bad {
            return None;
        }
        (0..self.len).find_map(|r| {
            let finite = cols[..w].iter().all(|col| col[r].is_finite());
            (!finite || cols[..w].iter().all(|col| col[r] == 0.0)).then_some((r, finite))
        })
    }
}

/// No input row was rejected. A rejection is encoded as (row · MAX_INPUTS + input) · 2 + reason, reason 0 for
/// NaN/Inf and 1 for a zero-length direction, so that the smallest code is the first bad row.
const NO_ERROR: usize = usize::MAX;

/// Evaluates `kernel` on every block of rows of the (already broadcast) inputs, in parallel with the GIL released,
/// writing straight into a new NumPy array of shape batch + (out_k,): float32 when every input is float32, else
/// float64. The kernel receives a block and its zeroed output, rows of out_k values in f64. Rows are validated on
/// the way (NaN/Inf, zero-length directions) and the first bad one raises ValueError.
fn batch_blocks<'py>(
    py: Python<'py>,
    inputs: &[(&str, &Bound<'py, PyAny>, Kind)],
    out_k: usize,
    kernel: impl Fn(&Block, &mut [f64]) + Sync,
) -> PyResult<Bound<'py, PyAny>> {
    assert!(inputs.len() <= MAX_INPUTS && out_k > 0);
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
    // Borrow contiguous NumPy memory; copy only strided inputs.
    let (mut it64, mut it32) = (f64s.iter(), f32s.iter());
    let data: Vec<Data> = inputs
        .iter()
        .map(|(_, obj, _)| {
            if obj.extract::<PyReadonlyArrayDyn<'py, f64>>().is_ok() {
                let a = it64.next().unwrap();
                match a.as_slice() {
                    Ok(s) if a.is_c_contiguous() => Data::F64(s),
                    _ => Data::Copied(a.as_array().iter().copied().collect()),
                }
            } else {
                let a = it32.next().unwrap();
                match a.as_slice() {
                    Ok(s) if a.is_c_contiguous() => Data::F32(s),
                    _ => Data::Copied(a.as_array().iter().map(|&x| x as f64).collect()),
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
    let result = if f64s.is_empty() {
        let array = unsafe { PyArrayDyn::<f32>::new(py, IxDyn(&shape), false) };
        let slice = unsafe { array.as_slice_mut() }.expect("new arrays are contiguous");
        py.detach(|| fill(slice, out_k, &eval_block));
        array.into_any()
    } else {
        let array = unsafe { PyArrayDyn::<f64>::new(py, IxDyn(&shape), false) };
        let slice = unsafe { array.as_slice_mut() }.expect("new arrays are contiguous");
        py.detach(|| fill(slice, out_k, &eval_block));
        array.into_any()
    };
    let bad = first_bad.into_inner();
    if bad != NO_ERROR {
        let (row, j, zero_length) = (bad / 2 / MAX_INPUTS, bad / 2 % MAX_INPUTS, bad % 2 == 1);
        let what = if zero_length { "a zero-length direction" } else { "NaN or Inf" };
        return Err(PyValueError::new_err(format!("{} contains {what} (row {row} of {n})", inputs[j].0)));
    }
    Ok(result)
}

/// `batch_blocks` for a kernel of one row: `kernel(rows, out)` with rows[j] the (normalised) row of input j.
fn batch<'py>(
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
        x as f32
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

fn vec3(row: &Row) -> DVec3 {
    DVec3::new(row[0], row[1], row[2])
}

fn parse_distribution(name: &str) -> PyResult<Distribution> {
    match name {
        "ggx" => Ok(Distribution::Ggx),
        "beckmann" => Ok(Distribution::Beckmann),
        _ => Err(PyValueError::new_err(format!("distribution must be 'ggx' or 'beckmann', got {name:?}"))),
    }
}

fn parse_g2(name: &str) -> PyResult<G2Form> {
    match name {
        "separable" => Ok(G2Form::Separable),
        "height_correlated" => Ok(G2Form::HeightCorrelated),
        "v_cavity" => Ok(G2Form::VCavity),
        _ => Err(PyValueError::new_err(format!(
            "g2 must be 'separable', 'height_correlated' or 'v_cavity', got {name:?}"
        ))),
    }
}

fn parse_fresnel(name: &str) -> PyResult<FresnelForm> {
    match name {
        "exact" => Ok(FresnelForm::Exact),
        "schlick" => Ok(FresnelForm::Schlick),
        "lazanyi" => Ok(FresnelForm::Lazanyi),
        _ => Err(PyValueError::new_err(format!("fresnel must be 'exact', 'schlick' or 'lazanyi', got {name:?}"))),
    }
}

fn item<'py, T: FromPyObjectOwned<'py>>(d: &Bound<'py, PyDict>, key: &str, i: usize) -> PyResult<T> {
    let v = d.get_item(key)?.ok_or_else(|| PyValueError::new_err(format!("layer {i}: missing {key}")))?;
    v.extract::<T>().map_err(|e| PyTypeError::new_err(format!("layer {i}: {key}: {}", Into::<PyErr>::into(e))))
}

/// Builds a validated Stack from the per-channel layer dictionaries made by python/lamina/layers.py.
fn parse_stack(layers: &Bound<'_, PyList>, ext_ior: f64) -> PyResult<Stack> {
    let mut out = Vec::with_capacity(layers.len());
    for (i, obj) in layers.iter().enumerate() {
        let d = obj.cast::<PyDict>().map_err(|_| PyTypeError::new_err(format!("layer {i} must be a dict")))?;
        let kind: String = item(d, "kind", i)?;
        out.push(match kind.as_str() {
            "dielectric" => Layer::Dielectric {
                ior: item(d, "ior", i)?,
                alpha: item(d, "roughness", i)?,
                angle: item(d, "angle", i)?,
                thickness: item(d, "thickness", i)?,
                sigma_a: item(d, "sigma_a", i)?,
                sigma_s: item(d, "sigma_s", i)?,
                g: item(d, "g", i)?,
            },
            "conductor" => Layer::Conductor {
                ior: item(d, "ior", i)?,
                k: item(d, "k", i)?,
                alpha: item(d, "roughness", i)?,
                angle: item(d, "angle", i)?,
            },
            "diffuse" => Layer::Diffuse { albedo: item(d, "albedo", i)?, roughness: item(d, "roughness", i)? },
            other => return Err(PyValueError::new_err(format!("layer {i}: unknown kind {other:?}"))),
        });
    }
    Ok(Stack::new(out, ext_ior)?)
}

/// Validates a stack description and that `model` can evaluate it; raises ValueError otherwise.
#[pyfunction]
#[pyo3(signature = (layers, ext_ior, model=None))]
fn check_stack(layers: &Bound<'_, PyList>, ext_ior: f64, model: Option<&str>) -> PyResult<usize> {
    let stack = parse_stack(layers, ext_ior)?;
    if let Some(m) = model {
        models::prepare(m, &stack, &Options::for_model(m))?;
    }
    Ok(stack.channels)
}

/// A two-way option: false for `a`, true for `b`, ValueError naming `name` otherwise.
fn parse_choice(name: &str, value: &str, a: &str, b: &str) -> PyResult<bool> {
    match value {
        v if v == a => Ok(false),
        v if v == b => Ok(true),
        v => Err(PyValueError::new_err(format!("{name} must be {a:?} or {b:?}, got {v:?}"))),
    }
}

/// Model options from keyword arguments: the defaults of `model` (Options::for_model), overridden by the known
/// keys of `options`; an unknown key is a TypeError.
fn parse_options(model: &str, options: Option<&Bound<'_, PyDict>>) -> PyResult<Options> {
    let mut o = Options::for_model(model);
    let Some(d) = options else { return Ok(o) };
    for (key, value) in d.iter() {
        let key: String = key.extract()?;
        let text = || -> PyResult<String> {
            value.extract::<String>().map_err(|_| PyTypeError::new_err(format!("{key} must be a string")))
        };
        let flag = || -> PyResult<bool> {
            value.extract::<bool>().map_err(|_| PyTypeError::new_err(format!("{key} must be a bool")))
        };
        match key.as_str() {
            "distribution" => o.distribution = parse_distribution(&text()?)?,
            "g2" => o.g2 = parse_g2(&text()?)?,
            "fresnel" => o.fresnel = parse_fresnel(&text()?)?,
            "symmetric" => o.symmetric = flag()?,
            "cosines" => o.belcour.real_cosines = parse_choice("cosines", &text()?, "frozen", "real")?,
            "jacobian" => o.belcour.jacobian_j21 = parse_choice("jacobian", &text()?, "j12", "j21")?,
            "energy" => o.belcour.fresnel_energy = parse_choice("energy", &text()?, "fgd", "fresnel")?,
            "tir" => {
                o.belcour.tir = match text()?.as_str() {
                    "off" => Tir::Off,
                    "transmittance" => Tir::Transmittance,
                    "fraction" => Tir::Fraction,
                    v => {
                        return Err(PyValueError::new_err(format!(
                            "tir must be \"off\", \"transmittance\" or \"fraction\", got {v:?}"
                        )))
                    }
                }
            }
            "tabulated" => o.belcour_table = flag()?,
            "lut" => o.steinberg_fitted = parse_choice("lut", &text()?, "tabulated", "fitted")?,
            "precomputed" => o.elek_precomputed = flag()?,
            "clamp_roughness" => o.clamp_roughness = flag()?,
            "eta2" => o.eta2 = flag()?,
            _ => {
                return Err(PyTypeError::new_err(format!(
                    "unknown model option {key:?}; options are distribution, g2, fresnel, symmetric, cosines, \
                     jacobian, energy, tir, tabulated (belcour), lut (steinberg), precomputed (weidlich_wilkie), \
                     clamp_roughness, eta2 (steinberg, weidlich_wilkie)"
                )))
            }
        }
    }
    Ok(o)
}

/// f(wi, wo) of a stack under a model: (..., channels). With `flake_normal` (..., 3) and `distance` (..., 1)
/// (model 'weidlich_wilkie' only) the base is evaluated about normalize(flake + max(distance, 1) ẑ).
#[pyfunction]
#[pyo3(signature = (layers, ext_ior, model, wi, wo, options=None, flake_normal=None, distance=None))]
#[allow(clippy::too_many_arguments)]
fn eval_stack<'py>(
    py: Python<'py>,
    layers: &Bound<'py, PyList>,
    ext_ior: f64,
    model: &str,
    wi: &Bound<'py, PyAny>,
    wo: &Bound<'py, PyAny>,
    options: Option<&Bound<'py, PyDict>>,
    flake_normal: Option<&Bound<'py, PyAny>>,
    distance: Option<&Bound<'py, PyAny>>,
) -> PyResult<Bound<'py, PyAny>> {
    let stack = parse_stack(layers, ext_ior)?;
    let opts = parse_options(model, options)?;
    let prepared = models::prepare(model, &stack, &opts)?;
    let dirs = [("wi", wi, Kind::Direction), ("wo", wo, Kind::Direction)];
    match (flake_normal, distance, &*prepared) {
        (None, None, _) => {
            batch_blocks(py, &dirs, stack.channels, |b, o| prepared.eval_block(b.columns(0), b.columns(1), o))
        }
        (Some(flake), Some(dist), models::Evaluator::WeidlichWilkie(p)) => batch(
            py,
            &[dirs[0], dirs[1], ("flake_normal", flake, Kind::Values(3)), ("distance", dist, Kind::Values(1))],
            stack.channels,
            |r, o| p.eval_flake(vec3(&r[0]), vec3(&r[1]), vec3(&r[2]), r[3][0], o),
        ),
        (Some(_), Some(_), _) => Err(PyValueError::new_err(format!(
            "flake_normal: flakes are a feature of model 'weidlich_wilkie', got model {model:?}"
        ))),
        _ => Err(PyValueError::new_err("flake_normal and distance must be given together")),
    }
}

/// Elek's copper patina: f = (1 − w) f_bare + w f_patina with w = 1 − smoothstep(extent − transition,
/// extent + transition, mask) per element (model 'weidlich_wilkie'; see models/weidlich_wilkie.rs).
#[pyfunction]
#[pyo3(signature = (bare, patina, ext_ior, tint, extent, transition, wi, wo, mask, options=None))]
#[allow(clippy::too_many_arguments)]
fn eval_patina<'py>(
    py: Python<'py>,
    bare: &Bound<'py, PyList>,
    patina: &Bound<'py, PyList>,
    ext_ior: f64,
    tint: Vec<f64>,
    extent: f64,
    transition: f64,
    wi: &Bound<'py, PyAny>,
    wo: &Bound<'py, PyAny>,
    mask: &Bound<'py, PyAny>,
    options: Option<&Bound<'py, PyDict>>,
) -> PyResult<Bound<'py, PyAny>> {
    let (bare, patina) = (parse_stack(bare, ext_ior)?, parse_stack(patina, ext_ior)?);
    for (name, v, lo, hi) in [("extent", extent, 0.0, 1.0), ("transition", transition, 0.0, 1.0)] {
        if !(lo..=hi).contains(&v) {
            return Err(PyValueError::new_err(format!("{name} must be in [{lo}, {hi}], got {v}")));
        }
    }
    if let Some(t) = tint.iter().find(|t| !(0.0..=1.0).contains(*t)) {
        return Err(PyValueError::new_err(format!("tint must be in [0, 1], got {t}")));
    }
    let opts = parse_options("weidlich_wilkie", options)?;
    let p = models::weidlich_wilkie::Patina::new(&bare, &patina, tint, extent, transition, &opts)?;
    let inputs = [("wi", wi, Kind::Direction), ("wo", wo, Kind::Direction), ("mask", mask, Kind::Values(1))];
    batch(py, &inputs, patina.channels, |r, o| p.eval(vec3(&r[0]), vec3(&r[1]), r[2][0], o))
}

/// Steinberg's table values (t, s) at (μ, α, η) in the `lut` form ('tabulated' or 'fitted'): (..., 2).
#[pyfunction]
fn steinberg_lut<'py>(
    py: Python<'py>,
    mu: &Bound<'py, PyAny>,
    alpha: &Bound<'py, PyAny>,
    eta: &Bound<'py, PyAny>,
    lut: &str,
) -> PyResult<Bound<'py, PyAny>> {
    let fitted = parse_choice("lut", lut, "tabulated", "fitted")?;
    let table = crate::tables::steinberg::steinberg();
    let inputs = [("mu", mu, Kind::Values(1)), ("alpha", alpha, Kind::Values(1)), ("eta", eta, Kind::Values(1))];
    batch(py, &inputs, 2, |r, o| {
        let (mu, alpha, eta) = (r[0][0], r[1][0], r[2][0]);
        let (t, s) = if fitted { table.fitted(mu, alpha, eta) } else { table.tabulated(mu, alpha, eta) };
        o.copy_from_slice(&[t, s]);
    })
}

/// A scalar-per-element kernel of `m` inputs, each of shape (..., 1).
fn scalar_kernel<'py, const M: usize>(
    py: Python<'py>,
    names: [&str; M],
    args: [&Bound<'py, PyAny>; M],
    f: impl Fn([f64; M]) -> f64 + Sync,
) -> PyResult<Bound<'py, PyAny>> {
    let inputs: Vec<_> = names.iter().zip(args).map(|(n, a)| (*n, a, Kind::Values(1))).collect();
    batch(py, &inputs, 1, |r, o| o[0] = f(std::array::from_fn(|j| r[j][0])))
}

#[pyfunction]
fn fresnel_dielectric<'py>(
    py: Python<'py>,
    cos_i: &Bound<'py, PyAny>,
    eta: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyAny>> {
    scalar_kernel(py, ["cos_i", "eta"], [cos_i, eta], |[c, e]| fresnel::dielectric(c, e))
}

/// Conductor reflectance of η + iκ in the form named by `form` ('exact', 'schlick' or 'lazanyi').
#[pyfunction]
fn fresnel_conductor<'py>(
    py: Python<'py>,
    cos_i: &Bound<'py, PyAny>,
    eta: &Bound<'py, PyAny>,
    k: &Bound<'py, PyAny>,
    form: &str,
) -> PyResult<Bound<'py, PyAny>> {
    let form = parse_fresnel(form)?;
    scalar_kernel(py, ["cos_i", "eta", "k"], [cos_i, eta, k], |[c, e, k]| form.conductor(c, e, k))
}

#[pyfunction]
fn fresnel_schlick<'py>(
    py: Python<'py>,
    cos_i: &Bound<'py, PyAny>,
    f0: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyAny>> {
    scalar_kernel(py, ["cos_i", "f0"], [cos_i, f0], |[c, f]| fresnel::schlick(c, f))
}

#[pyfunction]
fn fresnel_diffuse_reflectance<'py>(py: Python<'py>, eta: &Bound<'py, PyAny>) -> PyResult<Bound<'py, PyAny>> {
    scalar_kernel(py, ["eta"], [eta], |[e]| fresnel::diffuse_reflectance(e))
}

/// A microfacet distribution as Python passes it: (alpha_x, alpha_y, angle, distribution).
#[derive(FromPyObject)]
struct MicrofacetSpec(f64, f64, f64, String);

impl MicrofacetSpec {
    fn build(&self) -> PyResult<Microfacet> {
        let MicrofacetSpec(alpha_x, alpha_y, angle, ref distribution) = *self;
        for (name, a) in [("alpha_x", alpha_x), ("alpha_y", alpha_y)] {
            if !(a > 0.0 && a <= 1.0) {
                return Err(PyValueError::new_err(format!("{name} (roughness) must be in (0, 1], got {a}")));
            }
        }
        if !angle.is_finite() {
            return Err(PyValueError::new_err(format!("angle must be finite radians, got {angle}")));
        }
        Ok(Microfacet::new(parse_distribution(distribution)?, alpha_x, alpha_y, angle))
    }
}

#[pyfunction]
fn microfacet_d<'py>(py: Python<'py>, m: &Bound<'py, PyAny>, mf: MicrofacetSpec) -> PyResult<Bound<'py, PyAny>> {
    let mf = mf.build()?;
    batch(py, &[("m", m, Kind::Direction)], 1, |r, o| o[0] = mf.d(vec3(&r[0])))
}

#[pyfunction]
fn microfacet_lambda<'py>(py: Python<'py>, w: &Bound<'py, PyAny>, mf: MicrofacetSpec) -> PyResult<Bound<'py, PyAny>> {
    let mf = mf.build()?;
    batch(py, &[("w", w, Kind::Direction)], 1, |r, o| o[0] = mf.lambda(vec3(&r[0])))
}

#[pyfunction]
fn microfacet_g2<'py>(
    py: Python<'py>,
    wi: &Bound<'py, PyAny>,
    wo: &Bound<'py, PyAny>,
    m: &Bound<'py, PyAny>,
    mf: MicrofacetSpec,
    g2: &str,
) -> PyResult<Bound<'py, PyAny>> {
    let (mf, form) = (mf.build()?, parse_g2(g2)?);
    let inputs = [("wi", wi, Kind::Direction), ("wo", wo, Kind::Direction), ("m", m, Kind::Direction)];
    batch(py, &inputs, 1, |r, o| o[0] = mf.g2(form, vec3(&r[0]), vec3(&r[1]), vec3(&r[2])))
}

#[pyfunction]
fn sample_visible<'py>(
    py: Python<'py>,
    wi: &Bound<'py, PyAny>,
    u: &Bound<'py, PyAny>,
    mf: MicrofacetSpec,
) -> PyResult<Bound<'py, PyAny>> {
    let mf = mf.build()?;
    batch(py, &[("wi", wi, Kind::Direction), ("u", u, Kind::Values(2))], 3, |r, o| {
        let wi = vec3(&r[0]);
        if wi.z > 0.0 {
            o.copy_from_slice(&mf.sample_visible(wi, r[1][0].clamp(0.0, 1.0), r[1][1].clamp(0.0, 1.0)).to_array());
        }
    })
}

#[pyfunction]
fn pdf_visible<'py>(
    py: Python<'py>,
    wi: &Bound<'py, PyAny>,
    m: &Bound<'py, PyAny>,
    mf: MicrofacetSpec,
) -> PyResult<Bound<'py, PyAny>> {
    let mf = mf.build()?;
    batch(py, &[("wi", wi, Kind::Direction), ("m", m, Kind::Direction)], 1, |r, o| {
        o[0] = mf.pdf_visible(vec3(&r[0]), vec3(&r[1]))
    })
}

/// Rough conductor or dielectric BSDF of one interface, one output channel per entry of `eta`.
#[pyfunction]
#[allow(clippy::too_many_arguments)]
fn interface_bsdf<'py>(
    py: Python<'py>,
    kind: &str,
    wi: &Bound<'py, PyAny>,
    wo: &Bound<'py, PyAny>,
    eta: Vec<f64>,
    k: Vec<f64>,
    mf: MicrofacetSpec,
    g2: &str,
) -> PyResult<Bound<'py, PyAny>> {
    let (mf, form) = (mf.build()?, parse_g2(g2)?);
    if eta.is_empty() || eta.len() != k.len() {
        return Err(PyValueError::new_err(format!(
            "eta and k need the same number (> 0) of channels, got {} and {}",
            eta.len(),
            k.len()
        )));
    }
    if let Some(e) = eta.iter().find(|e| !(e.is_finite() && **e > 0.0)) {
        return Err(PyValueError::new_err(format!("eta must be in (0, inf), got {e}")));
    }
    if let Some(x) = k.iter().find(|x| !(x.is_finite() && **x >= 0.0)) {
        return Err(PyValueError::new_err(format!("k must be in [0, inf), got {x}")));
    }
    let conductor = match kind {
        "conductor" => true,
        "dielectric" => false,
        _ => return Err(PyValueError::new_err(format!("kind must be 'conductor' or 'dielectric', got {kind:?}"))),
    };
    batch(py, &[("wi", wi, Kind::Direction), ("wo", wo, Kind::Direction)], eta.len(), |r, o| {
        let (wi, wo) = (vec3(&r[0]), vec3(&r[1]));
        for (c, out) in o.iter_mut().enumerate() {
            *out = if conductor {
                bsdf::rough_conductor(&mf, form, eta[c], k[c], wi, wo)
            } else {
                bsdf::rough_dielectric(&mf, form, eta[c], wi, wo)
            };
        }
    })
}

/// Jacobians of the projected reflection (eta = None) or refraction map, (..., 4) row-major 2x2; NaN marks total
/// internal reflection (the Python layer turns it into a ValueError).
#[pyfunction]
#[pyo3(signature = (theta_i, xh, yh, eta=None, exact=true))]
fn jacobian<'py>(
    py: Python<'py>,
    theta_i: &Bound<'py, PyAny>,
    xh: &Bound<'py, PyAny>,
    yh: &Bound<'py, PyAny>,
    eta: Option<&Bound<'py, PyAny>>,
    exact: bool,
) -> PyResult<Bound<'py, PyAny>> {
    use crate::optics::jacobian as jac;
    let flat = |m: Option<[[f64; 2]; 2]>, o: &mut [f64]| match m {
        Some(m) => o.copy_from_slice(&[m[0][0], m[0][1], m[1][0], m[1][1]]),
        None => o.fill(f64::NAN),
    };
    let mut inputs =
        vec![("theta_i", theta_i, Kind::Values(1)), ("xh", xh, Kind::Values(1)), ("yh", yh, Kind::Values(1))];
    if let Some(e) = eta {
        inputs.push(("eta", e, Kind::Values(1)));
    }
    batch(py, &inputs, 4, |r, o| {
        let (t, x, y) = (r[0][0], r[1][0], r[2][0]);
        let m = match (r.get(3).map(|e| e[0]), exact) {
            (None, true) => Some(jac::reflect(t, x, y)),
            (None, false) => Some(jac::reflect_first_order(t)),
            (Some(e), true) => jac::refract(t, e, x, y),
            (Some(e), false) => jac::refract_first_order(t, e),
        };
        flat(m, o)
    })
}

/// Lobe energies (n, lobes, channels), covariances (n, lobes, [xx, xy, yy]) and GGX (αx, αy, angle) (n, lobes, 3).
type Lobes = (Vec<Vec<Vec<f64>>>, Vec<Vec<[f64; 3]>>, Vec<Vec<[f64; 3]>>);

/// Belcour 2018 / Yamaguchi 2019 lobes for unit viewing directions `wo` (rows, z > 0): energies and covariances.
#[pyfunction]
fn belcour_lobes(layers: &Bound<'_, PyList>, ext_ior: f64, wo: Vec<[f64; 3]>) -> PyResult<Lobes> {
    let stack = parse_stack(layers, ext_ior)?;
    // Lobes come straight from the adding-doubling: no evaluation table is needed.
    let p = models::belcour::prepare(&stack, &Options { belcour_table: false, ..Options::default() })?;
    if let Some(w) = wo.iter().find(|w| !(w.iter().all(|x| x.is_finite()) && w[2] > 0.0)) {
        return Err(PyValueError::new_err(format!("wi must point above the surface (z > 0), got {w:?}")));
    }
    let lobes: Vec<_> = wo.iter().map(|w| p.lobes(DVec3::from_array(*w).normalize())).collect();
    Ok((
        lobes.iter().map(|l| l.iter().map(|lobe| lobe.energy.clone()).collect()).collect(),
        lobes.iter().map(|l| l.iter().map(|lobe| [lobe.cov.xx, lobe.cov.xy, lobe.cov.yy]).collect()).collect(),
        lobes.iter().map(|l| l.iter().map(|lobe| lobe.roughness().into()).collect()).collect(),
    ))
}

/// Per-channel sums and sums of squares of Monte Carlo estimates, and truncated-path counts per channel.
type Sums = (Vec<Vec<f64>>, Vec<Vec<f64>>, Vec<u64>);

/// Brute-force random walk from one direction `wi` (unit, z > 0) over paths `first..first + samples`, tallying the
/// escaping energy in `n_theta` x `n_phi` bins uniform in (θo, φo) (1 x 1: the albedo). Returns the per-channel
/// sums, sums of squares (each (channels, bins)) and truncated-path counts, to be merged by the caller.
#[pyfunction]
#[pyo3(signature = (layers, ext_ior, wi, first, samples, seed, n_theta=1, n_phi=1, distribution="ggx", g2="height_correlated"))]
#[allow(clippy::too_many_arguments)]
fn reference_tally<'py>(
    py: Python<'py>,
    layers: &Bound<'py, PyList>,
    ext_ior: f64,
    wi: [f64; 3],
    first: u64,
    samples: u64,
    seed: u64,
    n_theta: usize,
    n_phi: usize,
    distribution: &str,
    g2: &str,
) -> PyResult<Sums> {
    let stack = parse_stack(layers, ext_ior)?;
    let (dist, g2) = (parse_distribution(distribution)?, parse_g2(g2)?);
    let wi = DVec3::from_array(wi);
    if !wi.is_finite() || wi.z <= 0.0 || (wi.length() - 1.0).abs() > 1e-9 {
        return Err(PyValueError::new_err(format!("wi must be a unit direction above the surface (z > 0), got {wi}")));
    }
    if samples == 0 || n_theta == 0 || n_phi == 0 {
        return Err(PyValueError::new_err("samples, n_theta and n_phi must be positive"));
    }
    let bin = |d: DVec3| {
        let t = ((d.z.clamp(-1.0, 1.0).acos() / std::f64::consts::FRAC_PI_2) * n_theta as f64) as usize;
        let p = ((d.y.atan2(d.x).rem_euclid(std::f64::consts::TAU) / std::f64::consts::TAU) * n_phi as f64) as usize;
        Some(t.min(n_theta - 1) * n_phi + p.min(n_phi - 1))
    };
    let tallies: Vec<reference::Tally> = py.detach(|| {
        (0..stack.channels)
            .map(|c| {
                let cs = reference::ChannelStack::new(&stack, c, dist, g2);
                reference::run(&cs, wi, (first, samples), seed, n_theta * n_phi, bin)
            })
            .collect()
    });
    Ok((
        tallies.iter().map(|t| t.sum.clone()).collect(),
        tallies.iter().map(|t| t.sum_sq.clone()).collect(),
        tallies.iter().map(|t| t.truncated).collect(),
    ))
}

/// NEE estimates of f(wi, wo) for direction pairs (rows of unit directions above the surface), paths
/// `first..first + samples` each: per-pair, per-channel sums and sums of squares ((pairs, channels) each) and the
/// number of truncated paths per channel.
#[pyfunction]
#[pyo3(signature = (layers, ext_ior, wi, wo, first, samples, seed, distribution="ggx", g2="height_correlated"))]
#[allow(clippy::too_many_arguments)]
fn reference_f<'py>(
    py: Python<'py>,
    layers: &Bound<'py, PyList>,
    ext_ior: f64,
    wi: Vec<[f64; 3]>,
    wo: Vec<[f64; 3]>,
    first: u64,
    samples: u64,
    seed: u64,
    distribution: &str,
    g2: &str,
) -> PyResult<Sums> {
    let stack = parse_stack(layers, ext_ior)?;
    let (dist, g2) = (parse_distribution(distribution)?, parse_g2(g2)?);
    if wi.len() != wo.len() || samples == 0 {
        return Err(PyValueError::new_err("wi and wo need the same number of rows, and samples must be positive"));
    }
    let (wi, wo): (Vec<DVec3>, Vec<DVec3>) =
        (wi.into_iter().map(DVec3::from_array).collect(), wo.into_iter().map(DVec3::from_array).collect());
    if let Some(w) = wi.iter().chain(&wo).find(|w| !w.is_finite() || w.z <= 0.0 || (w.length() - 1.0).abs() > 1e-9) {
        return Err(PyValueError::new_err(format!(
            "wi and wo must be unit directions above the surface (z > 0), got {w}"
        )));
    }
    let per_channel: Vec<Vec<(f64, f64, u64)>> = py.detach(|| {
        (0..stack.channels)
            .map(|c| {
                let cs = reference::ChannelStack::new(&stack, c, dist, g2);
                (0..wi.len())
                    .into_par_iter()
                    .map(|p| reference::run_f(&cs, wi[p], wo[p], (first, samples), seed))
                    .collect()
            })
            .collect()
    });
    let pick = |k: fn(&(f64, f64, u64)) -> f64| -> Vec<Vec<f64>> {
        (0..wi.len()).map(|p| per_channel.iter().map(|ch| k(&ch[p])).collect()).collect()
    };
    Ok((pick(|t| t.0), pick(|t| t.1), per_channel.iter().map(|ch| ch.iter().map(|t| t.2).sum()).collect()))
}

#[pymodule]
fn _lamina(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("MODELS", MODELS.to_vec())?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add_function(wrap_pyfunction!(check_stack, m)?)?;
    m.add_function(wrap_pyfunction!(eval_stack, m)?)?;
    m.add_function(wrap_pyfunction!(eval_patina, m)?)?;
    m.add_function(wrap_pyfunction!(steinberg_lut, m)?)?;
    m.add_function(wrap_pyfunction!(fresnel_dielectric, m)?)?;
    m.add_function(wrap_pyfunction!(fresnel_conductor, m)?)?;
    m.add_function(wrap_pyfunction!(fresnel_schlick, m)?)?;
    m.add_function(wrap_pyfunction!(fresnel_diffuse_reflectance, m)?)?;
    m.add_function(wrap_pyfunction!(microfacet_d, m)?)?;
    m.add_function(wrap_pyfunction!(microfacet_lambda, m)?)?;
    m.add_function(wrap_pyfunction!(microfacet_g2, m)?)?;
    m.add_function(wrap_pyfunction!(sample_visible, m)?)?;
    m.add_function(wrap_pyfunction!(pdf_visible, m)?)?;
    m.add_function(wrap_pyfunction!(interface_bsdf, m)?)?;
    m.add_function(wrap_pyfunction!(reference_tally, m)?)?;
    m.add_function(wrap_pyfunction!(reference_f, m)?)?;
    m.add_function(wrap_pyfunction!(belcour_lobes, m)?)?;
    m.add_function(wrap_pyfunction!(jacobian, m)?)?;
    m.add("REFERENCE_MAX_DEPTH", crate::reference::MAX_DEPTH)?;
    Ok(())
}
