//! Thin PyO3 bindings: NumPy arrays in, NumPy arrays out. `arrays` checks, gathers and evaluates the (already
//! broadcast) inputs in parallel with the GIL released; `api` binds the stack and the model catalogue; `primitives`
//! the optics primitives and tables; `reference` the Monte Carlo reference. No Rust panic crosses this boundary:
//! bad input becomes ValueError / TypeError.

mod api;
mod arrays;
#[cfg(feature = "gpu")]
mod gpu;
mod interrupt;
mod oat;
mod primitives;
mod reference;
mod render;

use pyo3::prelude::*;

/// Issues the cache's pending warning (src/cache.rs), if any, as a Python UserWarning: after work that may have written
/// the cache, with Python's lock held.
pub fn warn_pending(py: Python<'_>) {
    let Some(message) = crate::cache::take_warning() else { return };
    let category = py.get_type::<pyo3::exceptions::PyUserWarning>();
    let message = std::ffi::CString::new(message.replace('\0', " ")).unwrap_or_default();
    // Under a warnings filter of "error" the warning cannot be raised from here (the work is done): it is shown.
    if let Err(e) = PyErr::warn(py, &category, &message, 1) {
        e.print(py);
    }
}

#[pymodule]
fn _lamina(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let names: Vec<&str> = crate::models::entries().map(|i| i.name).collect();
    m.add("MODELS", names)?;
    m.add("DEVICES", crate::device::DEVICES.to_vec())?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add("SOURCE_HASH", crate::SOURCE_HASH)?;
    m.add("REFERENCE_MAX_DEPTH", crate::reference::MAX_DEPTH)?;
    m.add("OAT_POISSON_DISC", crate::oat::POISSON_DISC.to_vec())?;
    m.add("OAT_VARIANTS", crate::oat::Technique::NAMES.to_vec())?;
    m.add("OAT_BORDERS", crate::render::Border::NAMES.to_vec())?;
    m.add_function(wrap_pyfunction!(api::check_layer, m)?)?;
    m.add_function(wrap_pyfunction!(api::check_stack, m)?)?;
    m.add_function(wrap_pyfunction!(api::catalogue, m)?)?;
    m.add_function(wrap_pyfunction!(api::use_gpu, m)?)?;
    m.add_function(wrap_pyfunction!(api::cache_read, m)?)?;
    m.add_function(wrap_pyfunction!(api::cache_write, m)?)?;
    m.add_function(wrap_pyfunction!(api::cache_root, m)?)?;
    m.add_function(wrap_pyfunction!(api::eval, m)?)?;
    m.add_function(wrap_pyfunction!(api::sample_stack, m)?)?;
    m.add_function(wrap_pyfunction!(api::pdf, m)?)?;
    m.add_function(wrap_pyfunction!(api::specular, m)?)?;
    m.add_function(wrap_pyfunction!(api::eval_grad, m)?)?;
    m.add_function(wrap_pyfunction!(api::reference_sample, m)?)?;
    m.add_function(wrap_pyfunction!(primitives::steinberg_lut, m)?)?;
    m.add_function(wrap_pyfunction!(primitives::fresnel_dielectric, m)?)?;
    m.add_function(wrap_pyfunction!(primitives::fresnel_conductor, m)?)?;
    m.add_function(wrap_pyfunction!(primitives::fresnel_schlick, m)?)?;
    m.add_function(wrap_pyfunction!(primitives::fresnel_diffuse_reflectance, m)?)?;
    m.add_function(wrap_pyfunction!(primitives::microfacet_d, m)?)?;
    m.add_function(wrap_pyfunction!(primitives::microfacet_lambda, m)?)?;
    m.add_function(wrap_pyfunction!(primitives::microfacet_g2, m)?)?;
    m.add_function(wrap_pyfunction!(primitives::sample_visible, m)?)?;
    m.add_function(wrap_pyfunction!(primitives::pdf_visible, m)?)?;
    m.add_function(wrap_pyfunction!(primitives::interface_bsdf, m)?)?;
    m.add_function(wrap_pyfunction!(primitives::jacobian, m)?)?;
    m.add_function(wrap_pyfunction!(reference::reference_tally, m)?)?;
    m.add_function(wrap_pyfunction!(reference::reference_f, m)?)?;
    m.add_function(wrap_pyfunction!(reference::belcour_lobes, m)?)?;
    #[cfg(feature = "gpu")]
    {
        m.add_function(wrap_pyfunction!(gpu::gpu_adapter, m)?)?;
        m.add_function(wrap_pyfunction!(gpu::gpu_models, m)?)?;
        m.add_function(wrap_pyfunction!(gpu::_gpu_lose_after, m)?)?;
        m.add_function(wrap_pyfunction!(gpu::eval_gpu, m)?)?;
        m.add_function(wrap_pyfunction!(gpu::sample_gpu, m)?)?;
        m.add_function(wrap_pyfunction!(gpu::pdf_gpu, m)?)?;
        m.add_function(wrap_pyfunction!(gpu::gpu_resident_seconds, m)?)?;
        m.add_function(wrap_pyfunction!(gpu::gpu_readback_seconds, m)?)?;
        m.add_function(wrap_pyfunction!(gpu::render_gpu, m)?)?;
        m.add_function(wrap_pyfunction!(gpu::render_oat_gpu, m)?)?;
    }
    m.add_function(wrap_pyfunction!(render::render, m)?)?;
    m.add_function(wrap_pyfunction!(oat::oat_parallax, m)?)?;
    m.add_function(wrap_pyfunction!(oat::oat_poisson_filter, m)?)?;
    m.add_function(wrap_pyfunction!(oat::oat_light_map, m)?)?;
    m.add_function(wrap_pyfunction!(oat::render_oat, m)?)?;
    m.add_function(wrap_pyfunction!(oat::oat_slab_exit, m)?)?;
    m.add_class::<oat::OatMaterial>()?;
    m.add_function(wrap_pyfunction!(render::sky, m)?)?;
    m.add_function(wrap_pyfunction!(render::read_image, m)?)?;
    m.add_function(wrap_pyfunction!(render::read_obj, m)?)?;
    m.add_function(wrap_pyfunction!(render::write_png, m)?)?;
    m.add_function(wrap_pyfunction!(render::write_exr, m)?)?;
    Ok(())
}
