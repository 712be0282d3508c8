//! Bindings of Oat 2006 (src/oat): its primitives on row arrays, the light map, and materials that `render_oat`
//! renders in bands of rows like `render`. python/lamina/oat.py checks shapes and ranges.

use super::render::{camera, shape, texture};
use crate::oat::{self, InnerLayer, Material, Prepared, Technique};
use crate::render::{render_rows, Border, Light, Scene, Shader, Texture};
use glam::DVec3;
use numpy::{PyArray1, PyArrayMethods, PyReadonlyArray1, PyReadonlyArray2, PyReadonlyArray3};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use rayon::prelude::*;
use std::sync::Arc;

fn lights(items: Vec<(String, [f64; 3], [f64; 3])>) -> PyResult<Vec<Light>> {
    items.iter().map(|(k, v, rgb)| super::render::light(k, *v, *rgb)).collect()
}

/// Oat 2006 Listing 1 on rows: uv (n, 2), view and normal (n, 3), thickness (n,) and texel (u, v) sizes; returns
/// (n, 3): uv_inner and s.
#[pyfunction]
pub fn oat_parallax<'py>(
    py: Python<'py>,
    uv: PyReadonlyArray2<'py, f64>,
    view: PyReadonlyArray2<'py, f64>,
    normal: PyReadonlyArray2<'py, f64>,
    thickness: PyReadonlyArray1<'py, f64>,
    texel: [f64; 2],
) -> PyResult<Bound<'py, PyAny>> {
    let (uv, v, n, d) = (uv.as_slice()?, view.as_slice()?, normal.as_slice()?, thickness.as_slice()?);
    let rows = d.len();
    let mut out = vec![0.0; rows * 3];
    py.detach(|| {
        out.par_chunks_mut(3).enumerate().for_each(|(k, o)| {
            let at = |a: &[f64]| DVec3::new(a[3 * k], a[3 * k + 1], a[3 * k + 2]);
            let (w, s) = oat::parallax([uv[2 * k], uv[2 * k + 1]], at(v), at(n), d[k], texel);
            o.copy_from_slice(&[w[0], w[1], s]);
        })
    });
    PyArray1::from_vec(py, out).reshape([rows, 3]).map(|a| a.into_any())
}

/// Oat 2006 Listing 2 on rows: the 13-tap Poisson disc mean of `image` (h, w, c) at uv (n, 2) with radius (n,)
/// texels; returns (n, c).
#[pyfunction]
pub fn oat_poisson_filter<'py>(
    py: Python<'py>,
    image: PyReadonlyArray3<'py, f64>,
    uv: PyReadonlyArray2<'py, f64>,
    radius: PyReadonlyArray1<'py, f64>,
    texel: [f64; 2],
    border: &str,
) -> PyResult<Bound<'py, PyAny>> {
    let (image, border) = (texture(image)?, border.parse::<Border>()?);
    let (uv, r) = (uv.as_slice()?, radius.as_slice()?);
    let c = image.comps;
    let mut out = vec![0.0; r.len() * c];
    py.detach(|| {
        out.par_chunks_mut(c).enumerate().for_each(|(k, o)| {
            let v = oat::poisson_filter(&image, [uv[2 * k], uv[2 * k + 1]], r[k], texel, border);
            o.copy_from_slice(&v[..c]);
        })
    });
    PyArray1::from_vec(py, out).reshape([r.len(), c]).map(|a| a.into_any())
}

/// Oat 2006 step 2: the light map (h, w, 3) of `shape` for the outer normal map (h, w, 3) and the lights.
#[pyfunction]
pub fn oat_light_map<'py>(
    py: Python<'py>,
    normal_map: PyReadonlyArray3<'py, f64>,
    shape: &Bound<'py, PyAny>,
    lights: Vec<(String, [f64; 3], [f64; 3])>,
    dilate_passes: usize,
) -> PyResult<Bound<'py, PyAny>> {
    let (normals, shape, lights) = (texture(normal_map)?, self::shape(shape)?, self::lights(lights)?);
    let map = py.detach(|| oat::light_map(&shape, &normals, &lights, dilate_passes));
    PyArray1::from_vec(py, map.data).reshape([map.height, map.width, 3]).map(|a| a.into_any())
}

/// oat::slab_exit: (n, 2) float64, the transmitted paths' exit radii (scene units) and throughputs.
#[pyfunction]
pub fn oat_slab_exit<'py>(
    py: Python<'py>,
    thickness: f64,
    sigma_s: f64,
    sigma_a: f64,
    g: f64,
    samples: usize,
    seed: u64,
) -> PyResult<Bound<'py, PyAny>> {
    if !(thickness > 0.0 && thickness.is_finite() && sigma_s >= 0.0 && sigma_a >= 0.0 && g.abs() < 1.0) {
        return Err(PyValueError::new_err("slab: thickness > 0, sigma_s, sigma_a >= 0 and |g| < 1"));
    }
    let exits = py.detach(|| oat::slab_exit(thickness, sigma_s, sigma_a, g, samples, seed));
    let n = exits.len();
    PyArray1::from_vec(py, exits.into_iter().flatten().collect()).reshape([n, 2]).map(|a| a.into_any())
}

/// An inner layer from Python: albedo, opacity (None for the deepest) and depth.
type InnerArrays<'py> = (PyReadonlyArray3<'py, f64>, Option<PyReadonlyArray3<'py, f64>>, PyReadonlyArray3<'py, f64>);

/// An Oat material, prepared once for a render: its textures (h, w, c float64), inner layers as (albedo, opacity or
/// None, depth (h, w, 1)), and its light map for variant "full".
#[pyclass(frozen)]
pub struct OatMaterial(pub(crate) Arc<Prepared>);

#[pymethods]
impl OatMaterial {
    #[new]
    #[pyo3(signature = (outer_albedo, outer_opacity, outer_normal, inner, variant, shadowing, border, texel, dilate, light_map))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        outer_albedo: PyReadonlyArray3<'_, f64>,
        outer_opacity: PyReadonlyArray3<'_, f64>,
        outer_normal: PyReadonlyArray3<'_, f64>,
        inner: Vec<InnerArrays<'_>>,
        variant: &str,
        shadowing: bool,
        border: &str,
        texel: [f64; 2],
        dilate: usize,
        light_map: Option<PyReadonlyArray3<'_, f64>>,
    ) -> PyResult<Self> {
        let technique: Technique = variant.parse()?;
        let inner = inner
            .into_iter()
            .map(|(albedo, opacity, depth)| {
                Ok(InnerLayer {
                    albedo: texture(albedo)?,
                    opacity: opacity.map(texture).transpose()?,
                    depth: texture(depth)?,
                })
            })
            .collect::<PyResult<Vec<_>>>()?;
        let material = Material {
            outer_albedo: texture(outer_albedo)?,
            outer_opacity: texture(outer_opacity)?,
            outer_normal: texture(outer_normal)?,
            inner,
            technique,
            shadowing,
            border: border.parse::<Border>()?,
            texel,
            dilate,
        };
        let light_map: Option<Texture> = light_map.map(texture).transpose()?;
        Ok(OatMaterial(Arc::new(Prepared { material, light_map })))
    }
}

/// Renders rows first..first + rows of every Oat material: float32 (materials, rows, width, 3), as `render` does.
#[pyfunction]
#[pyo3(signature = (materials, shape, camera, lights, width, height, first, rows))]
#[allow(clippy::too_many_arguments)]
pub fn render_oat<'py>(
    py: Python<'py>,
    materials: Vec<Py<OatMaterial>>,
    shape: &Bound<'py, PyAny>,
    camera: Option<([f64; 3], [f64; 3], f64)>,
    lights: Vec<(String, [f64; 3], [f64; 3])>,
    width: usize,
    height: usize,
    first: usize,
    rows: usize,
) -> PyResult<Bound<'py, PyAny>> {
    let shaders: Vec<Shader> = materials.iter().map(|m| Shader::Surface(m.get().0.clone())).collect();
    let scene = Scene {
        shape: self::shape(shape)?,
        camera: self::camera(camera),
        lights: self::lights(lights)?,
        env: None,
        width,
        height,
        spp: 1,
        seed: 0,
    };
    let out = super::interrupt::interruptible(py, || {
        let mut out = vec![0f32; shaders.len() * rows * width * 3];
        render_rows(&scene, &shaders, first, &mut out)?;
        Ok(out)
    })?;
    PyArray1::from_vec(py, out).reshape([shaders.len(), rows, width, 3]).map(|a| a.into_any())
}
