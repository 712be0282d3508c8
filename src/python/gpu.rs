//! Bindings of the wgpu path (src/gpu): the adapter, and evaluation on it. Directions are checked and normalised
//! on the CPU as for `eval` (arrays.rs), then evaluated on the GPU in float32.

use super::api::{parse_options, parse_stack};
use super::arrays::{batch, Kind};
use crate::gpu;
use numpy::{PyArrayDyn, PyArrayMethods, PyUntypedArrayMethods};
use pyo3::exceptions::PyRuntimeError;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

/// The adapter lamina uses: {"name", "device_type", "backend", "driver"}; RuntimeError saying how to get one when
/// there is none.
#[pyfunction]
pub fn gpu_adapter(py: Python<'_>) -> PyResult<Bound<'_, PyDict>> {
    let g = py.detach(gpu::gpu).map_err(|e| PyRuntimeError::new_err(e.to_string()))?;
    let d = PyDict::new(py);
    d.set_item("name", &g.info.name)?;
    d.set_item("device_type", format!("{:?}", g.info.device_type))?;
    d.set_item("backend", format!("{:?}", g.info.backend))?;
    d.set_item("driver", format!("{} {}", g.info.driver, g.info.driver_info))?;
    Ok(d)
}

/// The models with a GPU implementation.
#[pyfunction]
pub fn gpu_models() -> Vec<&'static str> {
    gpu::MODELS.iter().map(|(name, _)| *name).collect()
}

/// f(wi, wo) on the GPU: (..., channels) float32, for (already broadcast) directions (..., 3).
#[pyfunction]
#[pyo3(signature = (layers, ext_ior, model, wi, wo, options=None))]
pub fn eval_gpu<'py>(
    py: Python<'py>,
    layers: &Bound<'py, PyList>,
    ext_ior: f64,
    model: &str,
    wi: &Bound<'py, PyAny>,
    wo: &Bound<'py, PyAny>,
    options: Option<&Bound<'py, PyDict>>,
) -> PyResult<Bound<'py, PyAny>> {
    let stack = parse_stack(layers, ext_ior)?;
    let (opts, _) = parse_options(model, options)?;
    if !gpu::supports(model) {
        gpu::kernel(model, &stack, &opts)?; // the error naming the GPU models
    }
    let dirs = [("wi", wi, Kind::Direction), ("wo", wo, Kind::Direction)];
    let pairs = batch(py, &dirs, 6, |r, o| {
        o[..3].copy_from_slice(&r[0]);
        o[3..].copy_from_slice(&r[1]);
    })?;
    let pairs = pairs.call_method1("astype", ("float32",))?;
    let pairs = pairs.cast::<PyArrayDyn<f32>>()?;
    let mut shape = pairs.shape().to_vec();
    let readonly = pairs.readonly();
    let flat = readonly.as_slice()?;
    let f = py.detach(|| gpu::eval(model, &stack, &opts, flat))?;
    *shape.last_mut().expect("(..., 6)") = stack.channels;
    numpy::PyArray1::from_vec(py, f).reshape(shape).map(|a| a.into_any())
}
