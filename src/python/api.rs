//! Bindings of the stack and the model catalogue: one entry point each for eval, sample, pdf and the Dirac
//! reflection, whatever the model; a model's options and per-element inputs are checked against its catalogue
//! entry (models/mod.rs).

use super::arrays::{batch, batch_blocks, engine_f32, vec3, Block, Kind, MAX_INPUTS};
use super::interrupt::interruptible;
use crate::engine::Rows;
use crate::error::{value_error, Error};
use crate::models::common::mixture::{self, weight_factor};
use crate::models::common::options::microsurface;
use crate::models::{self, Args, ModelInfo, OptionKind, Value};
use crate::reference::{self, Exit};
use crate::sampling::Rng;
use crate::stack::{Layer, Stack};
use crate::transport::{ChannelStack, Microsurface};
use glam::DVec3;
use numpy::PyReadonlyArrayDyn;
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict, PyList, PyString};
use std::sync::Arc;

fn item<'py, T: FromPyObjectOwned<'py>>(d: &Bound<'py, PyDict>, key: &str, i: usize) -> PyResult<T> {
    let v = d.get_item(key)?.ok_or_else(|| PyValueError::new_err(format!("layer {i}: missing {key}")))?;
    v.extract::<T>().map_err(|e| PyTypeError::new_err(format!("layer {i}: {key}: {}", Into::<PyErr>::into(e))))
}

/// One layer from its per-channel dictionary (made by python/lamina/layers.py).
fn parse_layer(obj: &Bound<'_, PyAny>, i: usize) -> PyResult<Layer> {
    let d = obj.cast::<PyDict>().map_err(|_| PyTypeError::new_err(format!("layer {i} must be a dict")))?;
    let kind: String = item(d, "kind", i)?;
    Ok(match kind.as_str() {
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
    })
}

/// Builds a validated Stack from the per-channel layer dictionaries.
pub fn parse_stack(layers: &Bound<'_, PyList>, ext_ior: f64) -> PyResult<Stack> {
    let layers = layers.iter().enumerate().map(|(i, obj)| parse_layer(&obj, i)).collect::<PyResult<Vec<_>>>()?;
    Ok(Stack::new(layers, ext_ior)?)
}

/// Validates one layer on its own (at construction, before any stack); `name` starts the messages.
#[pyfunction]
pub fn check_layer(layer: &Bound<'_, PyAny>, name: &str) -> PyResult<()> {
    let l = parse_layer(layer, 0)?;
    let channels = match &l {
        Layer::Dielectric { ior, .. } | Layer::Conductor { ior, .. } => ior.len(),
        Layer::Diffuse { albedo, .. } => albedo.len(),
    };
    Ok(l.check(name, channels)?)
}

/// Validates a stack description and that `model` can evaluate it with its default options.
#[pyfunction]
#[pyo3(signature = (layers, ext_ior, model=None))]
pub fn check_stack(py: Python<'_>, layers: &Bound<'_, PyList>, ext_ior: f64, model: Option<&str>) -> PyResult<usize> {
    let stack = parse_stack(layers, ext_ior)?;
    if let Some(m) = model {
        prepared_model(py, &stack, m, None)?;
    }
    Ok(stack.channels)
}

/// An option's value from Python: a bool, a string, a number or a sequence of numbers.
fn option_value(key: &str, v: &Bound<'_, PyAny>) -> PyResult<Value> {
    if v.is_instance_of::<PyBool>() {
        return Ok(Value::Flag(v.extract()?));
    }
    if v.is_instance_of::<PyString>() {
        return Ok(Value::Text(v.extract()?));
    }
    if let Ok(x) = v.extract::<f64>() {
        return Ok(Value::Number(x));
    }
    v.extract::<Vec<f64>>()
        .map(Value::List)
        .map_err(|_| PyTypeError::new_err(format!("{key} must be a bool, a string, a number or numbers, got {v}")))
}

/// The stack, its model prepared with the given options, and the model's catalogue entry.
pub(crate) fn prepared(
    py: Python<'_>,
    layers: &Bound<'_, PyList>,
    ext_ior: f64,
    model: &str,
    options: Option<&Bound<'_, PyDict>>,
) -> PyResult<(Stack, Arc<dyn models::Model>, &'static ModelInfo)> {
    let stack = parse_stack(layers, ext_ior)?;
    let (p, info) = prepared_model(py, &stack, model, options)?;
    Ok((stack, p, info))
}

/// `model` prepared for `stack` with the options given from Python, and its catalogue entry. A preparation that is
/// not cached (a table to build, seconds for `tabulated`) runs where Ctrl-C stops it.
pub fn prepared_model(
    py: Python<'_>,
    stack: &Stack,
    model: &str,
    options: Option<&Bound<'_, PyDict>>,
) -> PyResult<(Arc<dyn models::Model>, &'static ModelInfo)> {
    let (info, args) = parse_options(model, options)?;
    let prepared = match models::cached(model, stack, &args) {
        Some(p) => p,
        None => interruptible(py, || models::prepare(model, stack, &args))?,
    };
    Ok((prepared, info))
}

/// `model`'s entry and its options from a Python dict, checked against its table (models::parse: an option it
/// does not take is a TypeError listing its options and per-element inputs).
pub fn parse_options(model: &str, options: Option<&Bound<'_, PyDict>>) -> PyResult<(&'static ModelInfo, Args)> {
    let mut given = Vec::new();
    for (k, v) in options.into_iter().flat_map(|d| d.iter()) {
        let key: String = k.extract()?;
        given.push((key.clone(), option_value(&key, &v)?));
    }
    Ok(models::parse(model, &given)?)
}

/// The reference's microsurface from its options in a Python dict (`distribution`, `g2`).
pub fn reference_surface(options: Option<&Bound<'_, PyDict>>) -> PyResult<Microsurface> {
    Ok(microsurface(&parse_options("reference", options)?.1)?)
}

/// The per-element inputs given for a model: (name, array, check) in the order given, and for each of the model's
/// inputs the index of its array among all inputs (after the `first` direction arrays).
pub(crate) type Given<'a, 'py> = (Vec<(String, Bound<'py, PyAny>, Kind)>, Vec<Option<usize>>, &'a ModelInfo);

pub(crate) fn given_inputs<'a, 'py>(
    info: &'a ModelInfo,
    model: &dyn models::Model,
    inputs: Option<&Bound<'py, PyDict>>,
    first: usize,
) -> PyResult<Given<'a, 'py>> {
    let mut arrays = Vec::new();
    let mut slot = vec![None; info.inputs.len()];
    for (k, v) in inputs.into_iter().flat_map(|d| d.iter()) {
        let key: String = k.extract()?;
        let j = info.input(&key)?;
        let spec = info.inputs[j];
        slot[j] = Some(first + arrays.len());
        arrays.push((key, v, Kind::Range(spec.width, spec.range.0, spec.range.1)));
    }
    if first + arrays.len() > MAX_INPUTS {
        return Err(PyValueError::new_err("too many per-element inputs"));
    }
    model.check_inputs(&slot.iter().map(|s| s.is_some()).collect::<Vec<_>>())?;
    Ok((arrays, slot, info))
}

/// The prepared model, the stack's channel count, and every input array: the two given first (directions or
/// uniform numbers), then the model's per-element inputs with, for each of the model's inputs, its array's index.
type Call<'a, 'py> = (Arc<dyn models::Model>, usize, Vec<(&'a str, &'a Bound<'py, PyAny>, Kind)>, Vec<Option<usize>>);

#[allow(clippy::too_many_arguments)]
fn call<'a, 'py>(
    layers: &Bound<'py, PyList>,
    ext_ior: f64,
    model: &str,
    first: [(&'a str, &'a Bound<'py, PyAny>, Kind); 2],
    options: Option<&Bound<'py, PyDict>>,
    inputs: Option<&Bound<'py, PyDict>>,
    arrays: &'a mut Vec<(String, Bound<'py, PyAny>, Kind)>,
) -> PyResult<Call<'a, 'py>> {
    let (stack, p, info) = prepared(layers.py(), layers, ext_ior, model, options)?;
    let (given, slot, _) = given_inputs(info, &*p, inputs, 2)?;
    *arrays = given;
    let mut all = first.to_vec();
    all.extend(arrays.iter().map(|(n, a, k)| (n.as_str(), a, *k)));
    Ok((p, stack.channels, all, slot))
}

/// Whether `device` ("cpu", "gpu" or "auto") means the GPU for `model` with `options` whose result is float32 anyway
/// when `float32`; `model` None: Oat's materials, which the GPU always takes. The rule is device.rs's; ValueError /
/// RuntimeError where "gpu" cannot be had.
#[pyfunction]
#[pyo3(signature = (device, model=None, options=None, float32=true))]
pub fn use_gpu(
    py: Python<'_>,
    device: &str,
    model: Option<&str>,
    options: Option<&Bound<'_, PyDict>>,
    float32: bool,
) -> PyResult<bool> {
    let args = model.map(|m| parse_options(m, options)).transpose()?;
    let refusal = || -> Option<String> {
        let (m, (_, args)) = (model?, args.as_ref()?);
        gpu_refusal(m, args)
    };
    // The first call may create the GPU's device (seconds): without Python's lock.
    Ok(py.detach(|| crate::device::choose(device, refusal, float32))?)
}

#[cfg(feature = "gpu")]
use crate::gpu::{refusal as gpu_refusal, support as gpu_support};

/// Without the GPU path no model runs there.
#[cfg(not(feature = "gpu"))]
fn gpu_support(_: &str) -> String {
    "no (built without the gpu feature)".into()
}

/// Without the GPU path there is no adapter, so device::choose never asks.
#[cfg(not(feature = "gpu"))]
fn gpu_refusal(_: &str, _: &Args) -> Option<String> {
    None
}

/// The payload of lamina's cache entry at `path` when it is there and intact (src/cache.rs), else None.
#[pyfunction]
pub fn cache_read<'py>(py: Python<'py>, path: std::path::PathBuf) -> Option<Bound<'py, pyo3::types::PyBytes>> {
    crate::cache::read(&path).map(|payload| pyo3::types::PyBytes::new(py, &payload))
}

/// Writes `payload` as lamina's cache entry at `path`, atomically (src/cache.rs); a cache that cannot be written
/// warns (once per process).
#[pyfunction]
pub fn cache_write(py: Python<'_>, path: std::path::PathBuf, payload: &[u8]) {
    crate::cache::write(&path, payload);
    super::warn_pending(py);
}

/// The root of lamina's cache ($LAMINA_CACHE, else ~/.cache/lamina), or None without either.
#[pyfunction]
pub fn cache_root() -> Option<std::path::PathBuf> {
    crate::cache::root()
}

/// The catalogue: one dict per model (name, summary, options, inputs, properties, and its word on the GPU).
#[pyfunction]
#[pyo3(name = "models")]
pub fn catalogue<'py>(py: Python<'py>) -> PyResult<Vec<Bound<'py, PyDict>>> {
    models::entries()
        .map(|m| {
            let d = PyDict::new(py);
            d.set_item("name", m.name)?;
            d.set_item("summary", m.summary)?;
            let options = PyList::empty(py);
            for o in m.options {
                let od = PyDict::new(py);
                od.set_item("name", o.name)?;
                od.set_item("doc", o.doc)?;
                match o.kind {
                    OptionKind::Choice { .. } | OptionKind::Variant { .. } => {
                        od.set_item("kind", "choice")?;
                        od.set_item("choices", o.choices())?;
                        od.set_item(
                            "default",
                            match o.default() {
                                Value::Text(t) => t,
                                _ => unreachable!("a choice's default is one of its strings"),
                            },
                        )?;
                    }
                    OptionKind::Flag { default } => {
                        od.set_item("kind", "flag")?;
                        od.set_item("choices", vec![false, true])?;
                        od.set_item("default", default)?;
                    }
                    OptionKind::Number { lo, hi, default } | OptionKind::Channels { lo, hi, default } => {
                        let channels = matches!(o.kind, OptionKind::Channels { .. });
                        od.set_item("kind", if channels { "channels" } else { "number" })?;
                        od.set_item("range", (lo, hi))?;
                        od.set_item("default", default)?;
                    }
                }
                options.append(od)?;
            }
            d.set_item("options", options)?;
            let inputs = PyList::empty(py);
            for i in m.inputs {
                let id = PyDict::new(py);
                id.set_item("name", i.name)?;
                id.set_item("width", i.width)?;
                id.set_item("range", i.range)?;
                id.set_item("doc", i.doc)?;
                inputs.append(id)?;
            }
            d.set_item("inputs", inputs)?;
            let p = m.properties;
            let props = PyDict::new(py);
            props.set_item("reciprocal", p.reciprocal)?;
            props.set_item("energy_conserving", p.energy_conserving)?;
            props.set_item("anisotropic", p.anisotropic)?;
            props.set_item("spectral", p.spectral)?;
            d.set_item("properties", props)?;
            d.set_item("gpu", gpu_support(m.name))?;
            d.set_item("gradients", m.gradients.to_vec())?;
            Ok(d)
        })
        .collect()
}

/// f(wi, wo) of a stack under a model: (..., channels). `inputs` maps the model's per-element inputs to arrays
/// (..., width) broadcast with the directions.
#[pyfunction]
#[pyo3(signature = (layers, ext_ior, model, wi, wo, options=None, inputs=None))]
#[allow(clippy::too_many_arguments)]
pub fn eval<'py>(
    py: Python<'py>,
    layers: &Bound<'py, PyList>,
    ext_ior: f64,
    model: &str,
    wi: &Bound<'py, PyAny>,
    wo: &Bound<'py, PyAny>,
    options: Option<&Bound<'py, PyDict>>,
    inputs: Option<&Bound<'py, PyDict>>,
) -> PyResult<Bound<'py, PyAny>> {
    let mut arrays = Vec::new();
    let dirs = [("wi", wi, Kind::Direction), ("wo", wo, Kind::Direction)];
    let (p, channels, all, slot) = call(layers, ext_ior, model, dirs, options, inputs, &mut arrays)?;
    if all.len() == 2 {
        if let Some(f) = engine_f32(py, wi, wo, channels, |wi, wo, out| p.eval_f32(wi, wo, None, out))? {
            return Ok(f);
        }
    }
    batch_blocks(py, &all, channels, |b, o| {
        p.eval_block(b.columns(0), b.columns(1), &input_columns(b, &slot)[..slot.len()], o)
    })
}

/// Importance sampling: for viewing directions wo and uniform numbers u (..., 3) in [0, 1], (..., 3 + channels + 1)
/// rows of (wi, weight = f·cos θi / pdf, pdf per unit solid angle).
#[pyfunction]
#[pyo3(name = "sample", signature = (layers, ext_ior, model, wo, u, options=None, inputs=None))]
#[allow(clippy::too_many_arguments)]
pub fn sample_stack<'py>(
    py: Python<'py>,
    layers: &Bound<'py, PyList>,
    ext_ior: f64,
    model: &str,
    wo: &Bound<'py, PyAny>,
    u: &Bound<'py, PyAny>,
    options: Option<&Bound<'py, PyDict>>,
    inputs: Option<&Bound<'py, PyDict>>,
) -> PyResult<Bound<'py, PyAny>> {
    let mut arrays = Vec::new();
    let first = [("wo", wo, Kind::Direction), ("u", u, Kind::Range(3, 0.0, 1.0))];
    let (p, c, all, slot) = call(layers, ext_ior, model, first, options, inputs, &mut arrays)?;
    if all.len() == 2 {
        if let Some(rows) = engine_f32(py, wo, u, 3 + c + 1, |wo, u, out| p.sample_f32(wo, u, out))? {
            return Ok(rows);
        }
    }
    // Float32 rows without per-element inputs: f at the sampled directions by the float32 engine, as `eval` gives it
    // for float32 directions.
    let float32 =
        slot.iter().all(Option::is_none) && [wo, u].iter().all(|a| a.extract::<PyReadonlyArrayDyn<f32>>().is_ok());
    let k = 3 + c + 1;
    batch_blocks(py, &all, k, |b, o| {
        // Block by block: the directions and pdfs row by row, then f of the whole block.
        let n = b.len;
        let ([ox, oy, oz], [u0, u1, u2]) = (b.columns(0), b.columns(1));
        let (mut wi, mut pdf) = ([[0.0; models::BLOCK]; 3], [0.0; models::BLOCK]);
        for r in 0..n {
            let (w, density) = mixture::sample(&*p, DVec3::new(ox[r], oy[r], oz[r]), [u0[r], u1[r], u2[r]]);
            o[r * k..r * k + 3].copy_from_slice(&w.to_array());
            // A lost sample's f is not needed (weight 0): the normal stands in for its direction, which may be NaN.
            let w = if density > 0.0 { w } else { DVec3::Z };
            (wi[0][r], wi[1][r], wi[2][r], pdf[r]) = (w.x, w.y, w.z, density);
        }
        let wi = wi.each_ref().map(|c| &c[..n]);
        let mut f = vec![0.0; n * c];
        if !(float32 && eval_f32_rows(&*p, wi, b.columns(0), &mut f)) {
            f.fill(0.0);
            p.eval_block(wi, b.columns(0), &input_columns(b, &slot)[..slot.len()], &mut f);
        }
        for (r, (o, f)) in o.chunks_exact_mut(k).zip(f.chunks_exact(c)).enumerate() {
            let factor = weight_factor(DVec3::new(wi[0][r], wi[1][r], wi[2][r]), pdf[r]);
            o[3..3 + c].iter_mut().zip(f).for_each(|(w, f)| *w = f * factor);
            o[3 + c] = pdf[r];
        }
    })
}

/// A block's per-element input columns in the order of the model's inputs (`slot`: the block input holding each, if
/// given).
fn input_columns<'b>(b: &'b Block, slot: &[Option<usize>]) -> [Option<[&'b [f64]; 3]>; MAX_INPUTS] {
    let mut cols = [None; MAX_INPUTS];
    for (c, s) in cols.iter_mut().zip(slot) {
        *c = s.map(|k| b.columns(k));
    }
    cols
}

/// f of a block's rows (columns of unit directions) by the model's float32 lanes, into `out` as float64; false where
/// the model has none for them.
fn eval_f32_rows(p: &dyn models::Model, wi: [&[f64]; 3], wo: [&[f64]; 3], out: &mut [f64]) -> bool {
    let rows = |w: [&[f64]; 3]| (0..w[0].len()).flat_map(|r| w.map(|c| c[r] as f32)).collect::<Vec<f32>>();
    let (wi, wo) = (rows(wi), rows(wo));
    let mut f = vec![0.0f32; out.len()];
    let ok = p.eval_f32(Rows::Packed(&wi), Rows::Packed(&wo), None, &mut f);
    out.iter_mut().zip(&f).for_each(|(o, &f)| *o = f as f64);
    ok
}

/// The sampling pdf of wi given wo per unit solid angle: (..., 1).
#[pyfunction]
#[pyo3(signature = (layers, ext_ior, model, wi, wo, options=None))]
#[allow(clippy::too_many_arguments)]
pub fn pdf<'py>(
    py: Python<'py>,
    layers: &Bound<'py, PyList>,
    ext_ior: f64,
    model: &str,
    wi: &Bound<'py, PyAny>,
    wo: &Bound<'py, PyAny>,
    options: Option<&Bound<'py, PyDict>>,
) -> PyResult<Bound<'py, PyAny>> {
    let (_, p, _) = prepared(py, layers, ext_ior, model, options)?;
    let dirs = [("wi", wi, Kind::Direction), ("wo", wo, Kind::Direction)];
    batch(py, &dirs, 1, |r, o| o[0] = mixture::pdf(&*p, vec3(&r[0]), vec3(&r[1])))
}

/// f and its gradient with respect to layer parameters (Differentiable::gradient): (..., channels × (1 + n_params)),
/// per channel f and then ∂f/∂p of each parameter. `seeds`: (parameter, layer, field, channel or −1 for every channel,
/// scale) tuples (models::Seed).
#[pyfunction]
#[pyo3(signature = (layers, ext_ior, model, wi, wo, seeds, n_params, options=None))]
#[allow(clippy::too_many_arguments)]
pub fn eval_grad<'py>(
    py: Python<'py>,
    layers: &Bound<'py, PyList>,
    ext_ior: f64,
    model: &str,
    wi: &Bound<'py, PyAny>,
    wo: &Bound<'py, PyAny>,
    seeds: Vec<(usize, usize, String, i64, f64)>,
    n_params: usize,
    options: Option<&Bound<'py, PyDict>>,
) -> PyResult<Bound<'py, PyAny>> {
    let stack = parse_stack(layers, ext_ior)?;
    let (_, args) = parse_options(model, options)?;
    let seeds = seeds
        .into_iter()
        .map(|(param, layer, field, channel, scale)| {
            if param >= n_params || layer >= stack.layers.len() || channel >= stack.channels as i64 {
                return value_error(format!(
                    "a seed names parameter {param} of {n_params}, layer {layer} of {} and channel {channel} of {}",
                    stack.layers.len(),
                    stack.channels
                ));
            }
            Ok(models::Seed { param, layer, field: field.parse()?, channel: usize::try_from(channel).ok(), scale })
        })
        .collect::<crate::error::Result<Vec<_>>>()?;
    // tabulated's gradient solves the stack (seconds): without the GIL, where Ctrl-C stops it.
    let p = interruptible(py, || models::prepare_gradient(model, &stack, &args))?;
    let g = interruptible(py, || p.gradient(&seeds, n_params))?;
    let dirs = [("wi", wi, Kind::Direction), ("wo", wo, Kind::Direction)];
    batch_blocks(py, &dirs, stack.channels * (n_params + 1), |b, o| g(b.columns(0), b.columns(1), o))
}

/// The Dirac (mirror) reflection at wo per channel: (..., channels).
#[pyfunction]
#[pyo3(signature = (layers, ext_ior, model, wo, options=None))]
pub fn specular<'py>(
    py: Python<'py>,
    layers: &Bound<'py, PyList>,
    ext_ior: f64,
    model: &str,
    wo: &Bound<'py, PyAny>,
    options: Option<&Bound<'py, PyDict>>,
) -> PyResult<Bound<'py, PyAny>> {
    let (stack, p, _) = prepared(py, layers, ext_ior, model, options)?;
    batch(py, &[("wo", wo, Kind::Direction)], stack.channels, |r, o| p.specular(vec3(&r[0]), o))
}

/// The reference's sampling: one random walk per row from the viewing direction wo (seeded by the row's u), in the
/// channel that u[0] picks; its exit direction is wi (reciprocity) and its throughput, times the number of channels,
/// that channel's weight (the others 0). (..., 3 + channels + 1) rows as `sample`, with pdf 0: a walk's exit
/// density has no closed form. Dirac paths are included.
#[pyfunction]
#[pyo3(signature = (layers, ext_ior, wo, u, options=None))]
pub fn reference_sample<'py>(
    py: Python<'py>,
    layers: &Bound<'py, PyList>,
    ext_ior: f64,
    wo: &Bound<'py, PyAny>,
    u: &Bound<'py, PyAny>,
    options: Option<&Bound<'py, PyDict>>,
) -> PyResult<Bound<'py, PyAny>> {
    let stack = parse_stack(layers, ext_ior)?;
    let surface = reference_surface(options)?;
    let c = stack.channels;
    let stacks: Vec<ChannelStack> = (0..c).map(|k| ChannelStack::new(&stack, k, surface)).collect();
    let inputs = [("wo", wo, Kind::Direction), ("u", u, Kind::Range(3, 0.0, 1.0))];
    batch(py, &inputs, 3 + c + 1, |r, o| {
        let wo = vec3(&r[0]);
        if wo.z <= 0.0 {
            return;
        }
        let k = ((r[1][0] * c as f64) as usize).min(c - 1);
        let mut rng = Rng::new(Rng::seed_for(0, &r[1]), 0);
        if let Exit::Escaped { dir, weight } = reference::trace(&stacks[k], wo, &mut rng) {
            o[..3].copy_from_slice(&dir.to_array());
            o[3 + k] = weight * c as f64;
        }
    })
}

impl From<Error> for PyErr {
    fn from(e: Error) -> PyErr {
        match e {
            Error::Value(s) => PyValueError::new_err(s),
            Error::Type(s) => PyTypeError::new_err(s),
            Error::Device(s) => pyo3::exceptions::PyRuntimeError::new_err(s),
            Error::Interrupted => pyo3::exceptions::PyKeyboardInterrupt::new_err("interrupted"),
        }
    }
}
