//! Bindings of the wgpu path (src/gpu): the adapter, and evaluation on it. Directions are checked and normalised
//! on the CPU as for `eval` (arrays.rs), then evaluated on the GPU in float32.

use super::api::{given_inputs, parse_options, parse_stack, prepared, prepared_model};
use super::arrays::{batch, Kind};
use super::oat::OatMaterial;
use crate::gpu;
use crate::render::{pinhole, Shape, Texture};
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
    gpu::models()
}

/// The pairs of a query (float32 rows of 6), its per-element inputs (`gpu::run`'s) and the batch shape.
type Elements = (Vec<f32>, Vec<Option<Texture>>, Vec<usize>);

/// Checked (already broadcast) arrays as float32: the first two, 3-vectors (directions normalised), as rows of 6; each
/// of the model's per-element inputs (`slot`: its array's index, or None) as a texture of one row of n texels; and the
/// batch shape.
fn elements<'py>(
    py: Python<'py>,
    arrays: &[(&str, &Bound<'py, PyAny>, Kind)],
    slot: &[Option<usize>],
) -> PyResult<Elements> {
    let widths: Vec<usize> = arrays.iter().map(|(_, _, k)| k.width()).collect();
    let rows = batch(py, arrays, widths.iter().sum(), |r, o| {
        let mut at = 0;
        for (row, w) in r.iter().zip(&widths) {
            o[at..at + w].copy_from_slice(&row[..*w]);
            at += w;
        }
    })?;
    let rows = rows.call_method1("astype", ("float32",))?;
    let rows = rows.cast::<PyArrayDyn<f32>>()?;
    let shape = rows.shape()[..rows.ndim() - 1].to_vec();
    let flat = rows.readonly().as_slice()?.to_vec();
    let k: usize = widths.iter().sum();
    let n = flat.len() / k;
    let column = |j: usize| {
        let (at, w) = (widths[..j].iter().sum::<usize>(), widths[j]);
        let data = flat.chunks_exact(k).flat_map(|r| r[at..at + w].iter().map(|&x| x as f64)).collect();
        Texture { width: n, height: 1, comps: w, data }
    };
    let inputs = slot.iter().map(|j| j.map(column)).collect();
    let pairs = flat.chunks_exact(k).flat_map(|r| r[..6].iter().copied()).collect();
    Ok((pairs, inputs, shape))
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
    let (flat, _, _) = elements(py, &[("wi", wi, Kind::Direction), ("wo", wo, Kind::Direction)], &[])?;
    Ok(py.detach(|| gpu::resident_seconds(model, &stack, &args, &flat, repeats))?)
}

/// Seconds to read `bytes` back from the device (gpu::readback_seconds).
#[pyfunction]
pub fn gpu_readback_seconds(py: Python<'_>, bytes: usize, repeats: usize) -> PyResult<f64> {
    Ok(py.detach(|| gpu::readback_seconds(bytes, repeats))?)
}

/// f(wi, wo) on the GPU: (..., channels) float32, for (already broadcast) directions (..., 3) and per-element inputs.
#[pyfunction]
#[pyo3(signature = (layers, ext_ior, model, wi, wo, options=None, inputs=None))]
#[allow(clippy::too_many_arguments)]
pub fn eval_gpu<'py>(
    py: Python<'py>,
    layers: &Bound<'py, PyList>,
    ext_ior: f64,
    model: &str,
    wi: &Bound<'py, PyAny>,
    wo: &Bound<'py, PyAny>,
    options: Option<&Bound<'py, PyDict>>,
    inputs: Option<&Bound<'py, PyDict>>,
) -> PyResult<Bound<'py, PyAny>> {
    query(
        py,
        gpu::Query::Eval,
        layers,
        ext_ior,
        model,
        [("wi", wi, Kind::Direction), ("wo", wo, Kind::Direction)],
        options,
        inputs,
    )
}

/// Stack.sample on the GPU: (..., 3 + channels + 1) float32 rows (wi, weight, pdf) for (already broadcast) wo and u
/// and per-element inputs.
#[pyfunction]
#[pyo3(signature = (layers, ext_ior, model, wo, u, options=None, inputs=None))]
#[allow(clippy::too_many_arguments)]
pub fn sample_gpu<'py>(
    py: Python<'py>,
    layers: &Bound<'py, PyList>,
    ext_ior: f64,
    model: &str,
    wo: &Bound<'py, PyAny>,
    u: &Bound<'py, PyAny>,
    options: Option<&Bound<'py, PyDict>>,
    inputs: Option<&Bound<'py, PyDict>>,
) -> PyResult<Bound<'py, PyAny>> {
    query(
        py,
        gpu::Query::Sample,
        layers,
        ext_ior,
        model,
        [("wo", wo, Kind::Direction), ("u", u, Kind::Range(3, 0.0, 1.0))],
        options,
        inputs,
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
        None,
    )
}

/// A per-element query of `model` on the GPU for two checked arrays and the model's per-element inputs (checked
/// against its catalogue entry and its prepared model, as on the CPU): (..., query.width(channels)) float32.
#[allow(clippy::too_many_arguments)]
fn query<'py>(
    py: Python<'py>,
    query: gpu::Query,
    layers: &Bound<'py, PyList>,
    ext_ior: f64,
    model: &str,
    first: [(&str, &Bound<'py, PyAny>, Kind); 2],
    options: Option<&Bound<'py, PyDict>>,
    inputs: Option<&Bound<'py, PyDict>>,
) -> PyResult<Bound<'py, PyAny>> {
    let stack = parse_stack(layers, ext_ior)?;
    let (_, args) = parse_options(model, options)?;
    if let Some(why) = gpu::refusal(model, &args) {
        return Err(pyo3::exceptions::PyValueError::new_err(why));
    }
    let (given, slot) = match inputs.filter(|d| !d.is_empty()) {
        Some(d) => {
            let (_, p, info) = prepared(py, layers, ext_ior, model, options)?;
            let (given, slot, _) = given_inputs(info, &*p, Some(d), 2)?;
            (given, slot)
        }
        None => (Vec::new(), Vec::new()),
    };
    let mut arrays = first.to_vec();
    arrays.extend(given.iter().map(|(n, a, k)| (n.as_str(), a, *k)));
    let (flat, textures, mut shape) = elements(py, &arrays, &slot)?;
    let values = py.detach(|| gpu::run(query, model, &stack, &args, &flat, &textures))?;
    shape.push(query.width(stack.channels));
    numpy::PyArray1::from_vec(py, values).reshape(shape).map(|a| a.into_any())
}

/// Renders stacks on the GPU: (stacks, height, width, 3) float32. `stacks` is a list of (layers, ext_ior); `textures`
/// maps the model's per-element inputs to (h, w, c) arrays looked up by uv; `shape` "sphere", "plane" or a mesh;
/// `camera` None (orthographic) or (origin, target, fov in radians); `lights` (kind, vector, rgb) and `env` (None or
/// (map, scale, rotation), sampled `spp` times per pixel from `seed`) as for render.
#[pyfunction]
#[pyo3(signature = (stacks, model, options, textures, shape, camera, lights, width, height, env=None, spp=1, seed=0))]
#[allow(clippy::too_many_arguments)]
pub fn render_gpu<'py>(
    py: Python<'py>,
    stacks: &Bound<'py, PyList>,
    model: &str,
    options: Option<&Bound<'py, PyDict>>,
    textures: Option<&Bound<'py, PyDict>>,
    shape: &Bound<'py, PyAny>,
    camera: Option<([f64; 3], [f64; 3], f64)>,
    lights: Vec<(String, [f64; 3], [f64; 3])>,
    width: usize,
    height: usize,
    env: Option<(PyReadonlyArray3<'py, f64>, f64, f64)>,
    spp: usize,
    seed: u64,
) -> PyResult<Bound<'py, PyAny>> {
    let (info, args) = parse_options(model, options)?;
    let mut slots: Vec<Option<Texture>> = info.inputs.iter().map(|_| None).collect();
    for (name, a) in textures.into_iter().flat_map(|d| d.iter()) {
        slots[info.input(&name.extract::<String>()?)?] = Some(super::render::texture(a.extract()?)?);
    }
    let given: Vec<bool> = slots.iter().map(|s| s.is_some()).collect();
    let mut parsed = Vec::new();
    for item in stacks.iter() {
        let (layers, ext_ior): (Bound<'py, PyList>, f64) = item.extract()?;
        let stack = parse_stack(&layers, ext_ior)?;
        if given.contains(&true) {
            prepared_model(py, &stack, model, options)?.0.check_inputs(&given)?;
        }
        parsed.push(stack);
    }
    let mut scene = scene(shape, camera, lights, width, height)?;
    scene.env = env.map(super::render::environment).transpose()?.map(|e| e.gpu_data(spp, seed));
    let image = py.detach(|| gpu::render(model, &parsed, &args, &scene, &slots))?;
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
