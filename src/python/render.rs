//! Bindings of the renderer (src/render): one call renders a band of image rows for a batch of stacks, with the
//! GIL released; python/lamina/renderer.py loops over bands (progress bar, Ctrl-C) and builds the scene.

use super::api::{parse_stack, prepared_model, reference_surface};
use super::interrupt::interruptible;
use crate::render::env::{self, Environment};
use crate::render::mesh::{self, Mesh};
use crate::render::{io, render_rows, Camera, Light, Scene, Shader, Shape, Texture};
use crate::transport::ChannelStack;
use glam::DVec3;
use numpy::{PyArray1, PyArrayMethods, PyReadonlyArray2, PyReadonlyArray3, PyUntypedArrayMethods};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList, PyTuple};

/// A texture from a C-contiguous float64 array (height, width, 1 or 3).
pub fn texture(a: PyReadonlyArray3<'_, f64>) -> PyResult<Texture> {
    let s = a.shape();
    Ok(Texture { height: s[0], width: s[1], comps: s[2], data: a.as_slice()?.to_vec() })
}

/// Rows of a C-contiguous (n, k) float64 array.
fn rows<const K: usize>(a: &PyReadonlyArray2<'_, f64>) -> PyResult<Vec<[f64; K]>> {
    Ok(a.as_slice()?.chunks_exact(K).map(|c| std::array::from_fn(|k| c[k])).collect())
}

/// The shape: "sphere", "plane", or a mesh as (positions (n, 3), normals (n, 3), uvs (n, 2), tangents (n, 3) or
/// None, triangles (m, 3) as float64 vertex indices), checked by python/lamina/renderer.py.
pub fn shape(obj: &Bound<'_, PyAny>) -> PyResult<Shape> {
    if let Ok(name) = obj.extract::<String>() {
        return match name.as_str() {
            "sphere" => Ok(Shape::Sphere),
            "plane" => Ok(Shape::Plane),
            _ => Err(PyValueError::new_err(format!("shape must be 'sphere', 'plane' or a lamina.Mesh, got {name:?}"))),
        };
    }
    type Arrays<'py> = (
        PyReadonlyArray2<'py, f64>,
        PyReadonlyArray2<'py, f64>,
        PyReadonlyArray2<'py, f64>,
        Option<PyReadonlyArray2<'py, f64>>,
        PyReadonlyArray2<'py, f64>,
    );
    let (p, n, uv, t, tris): Arrays = obj.extract()?;
    let v3 = |a: &PyReadonlyArray2<'_, f64>| -> PyResult<Vec<DVec3>> {
        Ok(rows::<3>(a)?.into_iter().map(DVec3::from_array).collect())
    };
    let triangles = rows::<3>(&tris)?.into_iter().map(|t| t.map(|i| i as usize)).collect();
    let tangents = t.as_ref().map(v3).transpose()?;
    Ok(Shape::Mesh(Mesh::new(v3(&p)?, v3(&n)?, rows::<2>(&uv)?, tangents, triangles)?))
}

/// The camera: None (orthographic) or (origin, target, vertical field of view in radians).
pub fn camera(camera: Option<([f64; 3], [f64; 3], f64)>) -> Camera {
    match camera {
        None => Camera::Orthographic,
        Some((o, t, fov)) => Camera::Perspective { origin: DVec3::from_array(o), target: DVec3::from_array(t), fov },
    }
}

/// One light from (kind, a 3-vector, RGB): ("directional", towards the light, irradiance) or ("point", position,
/// intensity).
pub fn light(kind: &str, v: [f64; 3], rgb: [f64; 3]) -> PyResult<Light> {
    match kind {
        "directional" => Ok(Light::Directional { direction: DVec3::from_array(v).normalize(), irradiance: rgb }),
        "point" => Ok(Light::Point { position: DVec3::from_array(v), intensity: rgb }),
        _ => Err(PyValueError::new_err(format!("light kind must be 'directional' or 'point', got {kind:?}"))),
    }
}

/// Renders rows first..first + rows of every stack: float32 (stacks, rows, width, 3) linear RGB radiance. `stacks` is
/// a list of (layers, ext_ior); `textures` maps the model's per-element inputs to (h, w, c) arrays looked up by uv;
/// An environment light from (map (h, w, 3), scale, rotation).
pub fn environment((map, scale, rotation): (PyReadonlyArray3<'_, f64>, f64, f64)) -> PyResult<Environment> {
    let s = map.shape();
    let rgb = map.as_slice()?.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect();
    Ok(Environment::new(s[1], s[0], rgb, scale, rotation))
}

/// `camera` is None (orthographic) or (origin, target, fov in radians); `env` is None or (map (h, w, 3), scale,
/// rotation).
#[pyfunction]
#[pyo3(signature = (stacks, model, options, textures, shape, camera, lights, env, width, height, spp, seed, first, rows))]
#[allow(clippy::too_many_arguments)]
pub fn render<'py>(
    py: Python<'py>,
    stacks: &Bound<'py, PyList>,
    model: &str,
    options: Option<&Bound<'py, PyDict>>,
    textures: Option<&Bound<'py, PyDict>>,
    shape: &Bound<'py, PyAny>,
    camera: Option<([f64; 3], [f64; 3], f64)>,
    lights: Vec<(String, [f64; 3], [f64; 3])>,
    env: Option<(PyReadonlyArray3<'py, f64>, f64, f64)>,
    width: usize,
    height: usize,
    spp: usize,
    seed: u64,
    first: usize,
    rows: usize,
) -> PyResult<Bound<'py, PyAny>> {
    let (shape, camera) = (self::shape(shape)?, self::camera(camera));
    let lights = lights.iter().map(|(k, v, rgb)| light(k, *v, *rgb)).collect::<PyResult<Vec<_>>>()?;
    let env = env.map(environment).transpose()?;
    let mut shaders = Vec::new();
    for (k, item) in stacks.iter().enumerate() {
        let pair =
            item.cast::<PyTuple>().map_err(|_| PyTypeError::new_err("stacks must be (layers, ext_ior) pairs"))?;
        let (layers, ext_ior) = (pair.get_item(0)?, pair.get_item(1)?.extract::<f64>()?);
        let layers = layers.cast::<PyList>()?;
        let stack = parse_stack(layers, ext_ior)?;
        if stack.channels != 3 {
            return Err(PyValueError::new_err(format!("stacks[{k}]: render takes RGB stacks (3 channels)")));
        }
        shaders.push(if model == "reference" {
            let surface = reference_surface(options)?;
            Shader::Reference((0..3).map(|c| ChannelStack::new(&stack, c, surface)).collect())
        } else {
            let (p, info) = prepared_model(py, &stack, model, options)?;
            let mut slots: Vec<Option<Texture>> = info.inputs.iter().map(|_| None).collect();
            for (name, a) in textures.into_iter().flat_map(|d| d.iter()) {
                let j = info.input(&name.extract::<String>()?)?;
                slots[j] = Some(texture(a.extract()?)?);
            }
            p.check_inputs(&slots.iter().map(|s| s.is_some()).collect::<Vec<_>>())?;
            Shader::Model { model: p, textures: slots }
        });
    }
    let scene = Scene { shape, camera, lights, env, width, height, spp, seed };
    let out = interruptible(py, || {
        let mut out = vec![0f32; shaders.len() * rows * width * 3];
        render_rows(&scene, &shaders, first, &mut out)?;
        Ok(out)
    })?;
    PyArray1::from_vec(py, out).reshape([shaders.len(), rows, width, 3]).map(|a| a.into_any())
}

/// The built-in sky (`width` x `width`/2 equirectangular RGB radiance, without its sun), the direction towards the
/// sun and the sun's irradiance.
#[pyfunction]
pub fn sky<'py>(py: Python<'py>, width: usize) -> PyResult<(Bound<'py, PyAny>, [f64; 3], [f64; 3])> {
    let (w, h, rgb) = env::sky_map(width.max(2));
    let flat: Vec<f64> = rgb.into_iter().flatten().collect();
    let map = PyArray1::from_vec(py, flat).reshape([h, w, 3])?.into_any();
    Ok((map, env::SUN.normalize().to_array(), env::SUN_IRRADIANCE))
}

/// Reads an OBJ file: (positions, normals (empty if none), uvs (empty if none), triangles), as lists.
#[pyfunction]
pub fn read_obj(path: &str) -> PyResult<mesh::ObjArrays> {
    Ok(mesh::read_obj(path)?)
}

/// Reads a .hdr, .exr or PNG file as float32 (height, width, 3) RGB.
#[pyfunction]
pub fn read_image<'py>(py: Python<'py>, path: &str) -> PyResult<Bound<'py, PyAny>> {
    let (w, h, rgb) = py.detach(|| io::read_rgb(path))?;
    PyArray1::from_vec(py, rgb).reshape([h, w, 3]).map(|a| a.into_any())
}

/// Writes (height, width, 3) uint8 sRGB as a PNG.
#[pyfunction]
pub fn write_png(path: &str, image: PyReadonlyArray3<'_, u8>) -> PyResult<()> {
    let s = image.shape();
    Ok(io::write_png(path, s[1], s[0], image.as_slice()?.to_vec())?)
}

/// Writes (height, width, 3) float32 linear RGB as OpenEXR.
#[pyfunction]
pub fn write_exr(path: &str, image: PyReadonlyArray3<'_, f32>) -> PyResult<()> {
    let s = image.shape();
    Ok(io::write_exr(path, s[1], s[0], image.as_slice()?.to_vec())?)
}
