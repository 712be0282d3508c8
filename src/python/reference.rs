//! Bindings of the Monte Carlo reference and of Belcour's lobe statistics.

use super::api::{parse_stack, reference_surface};
use crate::models::belcour;
use crate::reference;
use crate::transport::ChannelStack;
use glam::DVec3;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};
use rayon::prelude::*;

/// Lobe energies (n, lobes, channels), covariances (n, lobes, [xx, xy, yy]) and GGX (αx, αy, angle) (n, lobes, 3).
type Lobes = (Vec<Vec<Vec<f64>>>, Vec<Vec<[f64; 3]>>, Vec<Vec<[f64; 3]>>);

/// Belcour 2018 / Yamaguchi 2019 lobes for unit viewing directions `wo` (rows, z > 0): energies and covariances.
#[pyfunction]
pub fn belcour_lobes(layers: &Bound<'_, PyList>, ext_ior: f64, wo: Vec<[f64; 3]>) -> PyResult<Lobes> {
    let stack = parse_stack(layers, ext_ior)?;
    // Lobes come straight from the adding-doubling: no evaluation table is needed.
    let p = belcour::prepare(&stack, &belcour::Options { interpolated: false, ..belcour::Options::default() })?;
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
#[pyo3(signature = (layers, ext_ior, wi, first, samples, seed, n_theta=1, n_phi=1, options=None))]
#[allow(clippy::too_many_arguments)]
pub fn reference_tally<'py>(
    py: Python<'py>,
    layers: &Bound<'py, PyList>,
    ext_ior: f64,
    wi: [f64; 3],
    first: u64,
    samples: u64,
    seed: u64,
    n_theta: usize,
    n_phi: usize,
    options: Option<&Bound<'py, PyDict>>,
) -> PyResult<Sums> {
    let stack = parse_stack(layers, ext_ior)?;
    let surface = reference_surface(options)?;
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
                let cs = ChannelStack::new(&stack, c, surface);
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
#[pyo3(signature = (layers, ext_ior, wi, wo, first, samples, seed, options=None))]
#[allow(clippy::too_many_arguments)]
pub fn reference_f<'py>(
    py: Python<'py>,
    layers: &Bound<'py, PyList>,
    ext_ior: f64,
    wi: Vec<[f64; 3]>,
    wo: Vec<[f64; 3]>,
    first: u64,
    samples: u64,
    seed: u64,
    options: Option<&Bound<'py, PyDict>>,
) -> PyResult<Sums> {
    let stack = parse_stack(layers, ext_ior)?;
    let surface = reference_surface(options)?;
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
                let cs = ChannelStack::new(&stack, c, surface);
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
