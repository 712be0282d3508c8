//! Bindings of the wgpu path (src/gpu): the adapter, and evaluation on it. Directions are checked and normalised
//! on the CPU as for `eval` (arrays.rs), then evaluated on the GPU in float32.

use super::api::{parse_options, parse_stack};
use super::arrays::{batch, Kind};
use super::oat::OatMaterial;
use crate::gpu;
use crate::render::{pinhole, Shape};
use numpy::{PyArrayDyn, PyArrayMethods, PyReadonlyArray3, PyUntypedArrayMethods};
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

/// Fault injection for lamina's tests (tests/faults.py): the GPU destroys itself after `dispatches` more dispatches,
/// as a lost device would stop.
#[pyfunction]
pub fn _gpu_lose_after(dispatches: i64) -> PyResult<()> {
    gpu::lose_after(dispatches).map_err(|e| PyRuntimeError::new_err(e.to_string()))
}

/// The models with a GPU implementation.
#[pyfunction]
pub fn gpu_models() -> Vec<&'static str> {
    gpu::MODELS.iter().map(|(name, _)| *name).collect()
}

/// Two checked (already broadcast) arrays of 3-vectors (directions normalised) as float32 rows of 6, and the batch
/// shape.
fn pairs<'py>(py: Python<'py>, arrays: [(&str, &Bound<'py, PyAny>, Kind); 2]) -> PyResult<(Vec<f32>, Vec<usize>)> {
    let pairs = batch(py, &arrays, 6, |r, o| {
        o[..3].copy_from_slice(&r[0]);
        o[3..].copy_from_slice(&r[1]);
    })?;
    let pairs = pairs.call_method1("astype", ("float32",))?;
    let pairs = pairs.cast::<PyArrayDyn<f32>>()?;
    let shape = pairs.shape()[..pairs.ndim() - 1].to_vec();
    let flat = pairs.readonly().as_slice()?.to_vec();
    Ok((flat, shape))
}

/// Seconds per evaluation of the pairs with everything resident on the device (gpu::resident_seconds).
#[pyfunction]
#[pyo3(signature = (layers, ext_ior, model, wi, wo, repeats, options=None))]
#[allow(clippy::too_many_arguments)]
pub fn gpu_resident_seconds<'py>(
    py: Python<'py>,
    layers: &Bound<'py, PyList>,
    ext_ior: f64,
    model: &str,
    wi: &Bound<'py, PyAny>,
    wo: &Bound<'py, PyAny>,
    repeats: usize,
    options: Option<&Bound<'py, PyDict>>,
) -> PyResult<f64> {
    let stack = parse_stack(layers, ext_ior)?;
    let (_, args) = parse_options(model, options)?;
    let (flat, _) = pairs(py, [("wi", wi, Kind::Direction), ("wo", wo, Kind::Direction)])?;
    Ok(py.detach(|| gpu::resident_seconds(model, &stack, &args, &flat, repeats))?)
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
    query(
        py,
        gpu::Query::Eval,
        layers,
        ext_ior,
        model,
        [("wi", wi, Kind::Direction), ("wo", wo, Kind::Direction)],
        options,
    )
}

/// Stack.sample on the GPU: (..., 3 + channels + 1) float32 rows (wi, weight, pdf) for (already broadcast) wo and u.
#[pyfunction]
#[pyo3(signature = (layers, ext_ior, model, wo, u, options=None))]
pub fn sample_gpu<'py>(
    py: Python<'py>,
    layers: &Bound<'py, PyList>,
    ext_ior: f64,
    model: &str,
    wo: &Bound<'py, PyAny>,
    u: &Bound<'py, PyAny>,
    options: Option<&Bound<'py, PyDict>>,
) -> PyResult<Bound<'py, PyAny>> {
    query(
        py,
        gpu::Query::Sample,
        layers,
        ext_ior,
        model,
        [("wo", wo, Kind::Direction), ("u", u, Kind::Range(3, 0.0, 1.0))],
        options,
    )
}

/// Stack.pdf on the GPU: (..., 1) float32 for (already broadcast) wi and wo.
#[pyfunction]
#[pyo3(signature = (layers, ext_ior, model, wi, wo, options=None))]
pub fn pdf_gpu<'py>(
    py: Python<'py>,
    layers: &Bound<'py, PyList>,
    ext_ior: f64,
    model: &str,
    wi: &Bound<'py, PyAny>,
    wo: &Bound<'py, PyAny>,
    options: Option<&Bound<'py, PyDict>>,
) -> PyResult<Bound<'py, PyAny>> {
    query(
        py,
        gpu::Query::Pdf,
        layers,
        ext_ior,
        model,
        [("wi", wi, Kind::Direction), ("wo", wo, Kind::Direction)],
        options,
    )
}

/// A per-element query of `model` on the GPU for two checked arrays: (..., query.width(channels)) float32.
fn query<'py>(
    py: Python<'py>,
    query: gpu::Query,
    layers: &Bound<'py, PyList>,
    ext_ior: f64,
    model: &str,
    arrays: [(&str, &Bound<'py, PyAny>, Kind); 2],
    options: Option<&Bound<'py, PyDict>>,
) -> PyResult<Bound<'py, PyAny>> {
    let stack = parse_stack(layers, ext_ior)?;
    let (_, args) = parse_options(model, options)?;
    if let Some(why) = gpu::refusal(model, &args, false) {
        return Err(pyo3::exceptions::PyValueError::new_err(why));
    }
    let (flat, mut shape) = pairs(py, arrays)?;
    let values = py.detach(|| gpu::run(query, model, &stack, &args, &flat))?;
    shape.push(query.width(stack.channels));
    numpy::PyArray1::from_vec(py, values).reshape(shape).map(|a| a.into_any())
}

/// Renders stacks on the GPU: (stacks, height, width, 3) float32. `stacks` is a list of (layers, ext_ior); `shape`
/// "sphere", "plane" or a mesh; `camera` None (orthographic) or (origin, target, fov in radians); `lights` (kind,
/// vector, rgb) and `env` (None or (map, scale, rotation), sampled `spp` times per pixel from `seed`) as for render.
#[pyfunction]
#[pyo3(signature = (stacks, model, options, shape, camera, lights, width, height, env=None, spp=1, seed=0))]
#[allow(clippy::too_many_arguments)]
pub fn render_gpu<'py>(
    py: Python<'py>,
    stacks: &Bound<'py, PyList>,
    model: &str,
    options: Option<&Bound<'py, PyDict>>,
    shape: &Bound<'py, PyAny>,
    camera: Option<([f64; 3], [f64; 3], f64)>,
    lights: Vec<(String, [f64; 3], [f64; 3])>,
    width: usize,
    height: usize,
    env: Option<(PyReadonlyArray3<'py, f64>, f64, f64)>,
    spp: usize,
    seed: u64,
) -> PyResult<Bound<'py, PyAny>> {
    let (_, args) = parse_options(model, options)?;
    let mut parsed = Vec::new();
    for item in stacks.iter() {
        let (layers, ext_ior): (Bound<'py, PyList>, f64) = item.extract()?;
        parsed.push(parse_stack(&layers, ext_ior)?);
    }
    let mut scene = scene(shape, camera, lights, width, height)?;
    scene.env = env.map(super::render::environment).transpose()?.map(|e| e.gpu_data(spp, seed));
    let image = py.detach(|| gpu::render(model, &parsed, &args, &scene))?;
    numpy::PyArray1::from_vec(py, image).reshape([parsed.len(), height, width, 3]).map(|a| a.into_any())
}

/// The GPU's scene: the shape ("sphere", "plane" or a mesh's arrays, as for render), the camera (None:
/// orthographic) and the lights (kind, vector, rgb).
fn scene(
    shape: &Bound<'_, PyAny>,
    camera: Option<([f64; 3], [f64; 3], f64)>,
    lights: Vec<(String, [f64; 3], [f64; 3])>,
    width: usize,
    height: usize,
) -> PyResult<gpu::Scene> {
    let (shape, mesh) = match super::render::shape(shape)? {
        Shape::Sphere => (0, None),
        Shape::Plane => (1, None),
        Shape::Mesh(mesh) => (2, Some(mesh.gpu_arrays())),
    };
    let camera = camera.map(|(o, t, fov)| {
        let o = glam::DVec3::from_array(o);
        let [forward, right, up] = pinhole(o, glam::DVec3::from_array(t), fov, width as f64 / height as f64);
        [o, forward, right, up].map(|v| v.as_vec3().to_array())
    });
    let rows = lights.iter().map(|(kind, v, rgb)| Ok(gpu::light_rows(&super::render::light(kind, *v, *rgb)?)));
    let rows = rows.collect::<PyResult<Vec<_>>>()?;
    Ok(gpu::Scene { width, height, shape, mesh, camera, lights: rows, env: None })
}

/// Renders Oat materials on the GPU: (materials, height, width, 3) float32, the arguments as for render_gpu, and
/// meshes too.
#[pyfunction]
#[pyo3(signature = (materials, shape, camera, lights, width, height))]
pub fn render_oat_gpu<'py>(
    py: Python<'py>,
    materials: Vec<Py<OatMaterial>>,
    shape: &Bound<'py, PyAny>,
    camera: Option<([f64; 3], [f64; 3], f64)>,
    lights: Vec<(String, [f64; 3], [f64; 3])>,
    width: usize,
    height: usize,
) -> PyResult<Bound<'py, PyAny>> {
    let prepared: Vec<_> = materials.iter().map(|m| m.get().0.clone()).collect();
    let scene = scene(shape, camera, lights, width, height)?;
    let image = py.detach(|| crate::oat::gpu::render(&prepared, &scene))?;
    numpy::PyArray1::from_vec(py, image).reshape([prepared.len(), height, width, 3]).map(|a| a.into_any())
}
