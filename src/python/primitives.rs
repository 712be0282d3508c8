//! Bindings of the optics primitives and tables, for plotting, teaching and cross-checks.

use super::arrays::{batch, vec3, Kind};
use crate::bsdf;
use crate::optics::distribution::{G2Form, Microfacet};
use crate::optics::fresnel::{self, FresnelForm};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;

/// Steinberg's table values (t, s) at (μ, α, η) in the `lut` form ('tabulated' or 'fitted'): (..., 2).
#[pyfunction]
pub fn steinberg_lut<'py>(
    py: Python<'py>,
    mu: &Bound<'py, PyAny>,
    alpha: &Bound<'py, PyAny>,
    eta: &Bound<'py, PyAny>,
    lut: &str,
) -> PyResult<Bound<'py, PyAny>> {
    let fitted = crate::error::parse_choice("lut", lut, &crate::models::steinberg::LUTS, &[false, true])?;
    let table = py.detach(crate::tables::steinberg::steinberg);
    super::warn_pending(py);
    let inputs = [("mu", mu, Kind::Values(1)), ("alpha", alpha, Kind::Values(1)), ("eta", eta, Kind::Values(1))];
    batch(py, &inputs, 2, |r, o| {
        let (mu, alpha, eta) = (r[0][0], r[1][0], r[2][0]);
        let (t, s) = if fitted { table.fitted(mu, alpha, eta) } else { table.tabulated(mu, alpha, eta) };
        o.copy_from_slice(&[t, s]);
    })
}

/// Positive reals: (0, inf).
const POSITIVE: (f64, f64) = (f64::MIN_POSITIVE, f64::MAX);
/// Non-negative reals.
const NON_NEGATIVE: (f64, f64) = (0.0, f64::MAX);
/// Cosines of directions above the surface.
const COSINE: (f64, f64) = (0.0, 1.0);

/// A scalar-per-element kernel of `M` inputs, each of shape (..., 1) with values in its closed range.
fn scalar_kernel<'py, const M: usize>(
    py: Python<'py>,
    inputs: [(&str, &Bound<'py, PyAny>, (f64, f64)); M],
    f: impl Fn([f64; M]) -> f64 + Sync,
) -> PyResult<Bound<'py, PyAny>> {
    let inputs: Vec<_> = inputs.iter().map(|&(n, a, (lo, hi))| (n, a, Kind::Range(1, lo, hi))).collect();
    batch(py, &inputs, 1, |r, o| o[0] = f(std::array::from_fn(|j| r[j][0])))
}

/// Exact dielectric reflectance; cos_i in [−1, 1] (negative: from inside), eta > 0.
#[pyfunction]
pub fn fresnel_dielectric<'py>(
    py: Python<'py>,
    cos_i: &Bound<'py, PyAny>,
    eta: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyAny>> {
    scalar_kernel(py, [("cos_i", cos_i, (-1.0, 1.0)), ("eta", eta, POSITIVE)], |[c, e]| fresnel::dielectric(c, e))
}

/// Conductor reflectance of η + iκ in the form named by `form` ('exact', 'schlick' or 'lazanyi').
#[pyfunction]
pub fn fresnel_conductor<'py>(
    py: Python<'py>,
    cos_i: &Bound<'py, PyAny>,
    eta: &Bound<'py, PyAny>,
    k: &Bound<'py, PyAny>,
    form: &str,
) -> PyResult<Bound<'py, PyAny>> {
    let form = form.parse::<FresnelForm>()?;
    let inputs = [("cos_i", cos_i, COSINE), ("eta", eta, POSITIVE), ("k", k, NON_NEGATIVE)];
    scalar_kernel(py, inputs, |[c, e, k]| form.conductor(c, e, k))
}

/// Schlick's approximation; cos_i and f0 in [0, 1].
#[pyfunction]
pub fn fresnel_schlick<'py>(
    py: Python<'py>,
    cos_i: &Bound<'py, PyAny>,
    f0: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyAny>> {
    scalar_kernel(py, [("cos_i", cos_i, COSINE), ("f0", f0, (0.0, 1.0))], |[c, f]| fresnel::schlick(c, f))
}

/// Hemispherical average of the dielectric Fresnel reflectance; eta > 0.
#[pyfunction]
pub fn fresnel_diffuse_reflectance<'py>(py: Python<'py>, eta: &Bound<'py, PyAny>) -> PyResult<Bound<'py, PyAny>> {
    scalar_kernel(py, [("eta", eta, POSITIVE)], |[e]| fresnel::diffuse_reflectance(e))
}

/// A microfacet distribution as Python passes it: (alpha_x, alpha_y, angle, distribution).
#[derive(FromPyObject)]
pub struct MicrofacetSpec(f64, f64, f64, String);

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
        Ok(Microfacet::new(distribution.parse()?, alpha_x, alpha_y, angle))
    }
}

#[pyfunction]
pub fn microfacet_d<'py>(py: Python<'py>, m: &Bound<'py, PyAny>, mf: MicrofacetSpec) -> PyResult<Bound<'py, PyAny>> {
    let mf = mf.build()?;
    batch(py, &[("m", m, Kind::Direction)], 1, |r, o| o[0] = mf.d(vec3(&r[0])))
}

#[pyfunction]
pub fn microfacet_lambda<'py>(
    py: Python<'py>,
    w: &Bound<'py, PyAny>,
    mf: MicrofacetSpec,
) -> PyResult<Bound<'py, PyAny>> {
    let mf = mf.build()?;
    batch(py, &[("w", w, Kind::Direction)], 1, |r, o| o[0] = mf.lambda(vec3(&r[0])))
}

#[pyfunction]
pub fn microfacet_g2<'py>(
    py: Python<'py>,
    wi: &Bound<'py, PyAny>,
    wo: &Bound<'py, PyAny>,
    m: &Bound<'py, PyAny>,
    mf: MicrofacetSpec,
    g2: &str,
) -> PyResult<Bound<'py, PyAny>> {
    let (mf, form) = (mf.build()?, g2.parse::<G2Form>()?);
    let inputs = [("wi", wi, Kind::Direction), ("wo", wo, Kind::Direction), ("m", m, Kind::Direction)];
    batch(py, &inputs, 1, |r, o| o[0] = mf.g2(form, vec3(&r[0]), vec3(&r[1]), vec3(&r[2])))
}

#[pyfunction]
pub fn sample_visible<'py>(
    py: Python<'py>,
    wi: &Bound<'py, PyAny>,
    u: &Bound<'py, PyAny>,
    mf: MicrofacetSpec,
) -> PyResult<Bound<'py, PyAny>> {
    let mf = mf.build()?;
    batch(py, &[("wi", wi, Kind::Direction), ("u", u, Kind::Range(2, 0.0, 1.0))], 3, |r, o| {
        let wi = vec3(&r[0]);
        if wi.z > 0.0 {
            o.copy_from_slice(&mf.sample_visible(wi, r[1][0].clamp(0.0, 1.0), r[1][1].clamp(0.0, 1.0)).to_array());
        }
    })
}

#[pyfunction]
pub fn pdf_visible<'py>(
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
pub fn interface_bsdf<'py>(
    py: Python<'py>,
    kind: &str,
    wi: &Bound<'py, PyAny>,
    wo: &Bound<'py, PyAny>,
    eta: Vec<f64>,
    k: Vec<f64>,
    mf: MicrofacetSpec,
    g2: &str,
) -> PyResult<Bound<'py, PyAny>> {
    let (mf, form) = (mf.build()?, g2.parse::<G2Form>()?);
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
pub fn jacobian<'py>(
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
