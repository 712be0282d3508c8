"""The Monte Carlo reference walk against closed forms, quadrature of exact BRDFs and its own statistics.

Tolerances: 3 standard errors (SE) of the estimate, plus the measured error of the deterministic quadrature it is
compared with where there is one."""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest

import lamina
from scipy import stats


def direction(theta_deg: float, phi: float = 0.0) -> np.ndarray:
    t = np.radians(theta_deg)
    return np.array([np.sin(t) * np.cos(phi), np.sin(t) * np.sin(phi), np.cos(t)])


def quadrature_albedo(stack, wi, nt, npp, **kw):
    t = (np.arange(nt) + 0.5) * (np.pi / 2 / nt)
    p = (np.arange(npp) + 0.5) * (2 * np.pi / npp)
    T, P = np.meshgrid(t, p, indexing="ij")
    wo = np.stack([np.sin(T) * np.cos(P), np.sin(T) * np.sin(P), np.cos(T)], -1)
    w = (np.cos(T) * np.sin(T))[..., None] * (np.pi / 2 / nt) * (2 * np.pi / npp)
    return np.sum(stack.eval(wi, wo, **kw) * w, axis=(0, 1))


@pytest.mark.parametrize("theta", [0.0, 60.0, 85.0])
@pytest.mark.parametrize("roughness", [0.2, (0.15, 0.6)])
def test_single_rough_conductor_albedo_equals_quadrature(theta, roughness):
    stack = lamina.Stack([lamina.Conductor((0.2, 0.45, 1.4), (3.6, 2.5, 1.9), roughness, angle=0.4)])
    wi = direction(theta, 0.3)
    ref, se = stack.albedo(wi, "reference", samples=400_000, seed=1)
    quad = stack.albedo(wi)
    quad_err = np.abs(quad - quadrature_albedo(stack, wi, 256, 512))  # measured convergence of the quadrature
    assert np.all(np.abs(ref - quad) <= 3 * se + quad_err), f"{ref} ± {se} vs {quad} (quadrature ±{quad_err})"


def test_smooth_coat_over_lambert_albedo_equals_closed_form():
    """Albedo = F(θi) (the delta reflection) + ∫ ρ(1−Fi)(1−Fo)/(πη²(1−ρF̄)) cos θo dωo."""
    stack = lamina.materials.plastic((0.9, 0.5, 0.1), ior=1.5)
    for theta in (0.0, 45.0, 80.0):
        wi = direction(theta)
        ref, se = stack.albedo(wi, "reference", samples=400_000, seed=2)
        closed = lamina.optics.fresnel_dielectric(wi[2], 1.5) + stack.albedo(wi)
        assert np.all(np.abs(ref - closed) <= 3 * se + 1e-5), f"θ={theta}: {ref} ± {se} vs {closed}"


def test_absorbing_slab_under_smooth_coat_equals_closed_form():
    """Smooth coat, Beer–Lambert slab (σ_a d), Lambert base ρ: with μ the cosine inside the slab,
    A = ρ ∫2μ e^{−τ/μ}(1 − F_int(μ)) dμ / (1 − ρ ∫2μ e^{−2τ/μ} F_int(μ) dμ), albedo = F(θi) + (1 − F(θi)) e^{−τ/μt} A.
    The 1-D integrals use a 1e6-point midpoint rule (error ~1e-9)."""
    eta, tau, rho = 1.5, 0.5, 0.8
    stack = lamina.Stack([lamina.Dielectric(eta, thickness=2.0, sigma_a=tau / 2.0), lamina.Diffuse(rho)])
    mu = (np.arange(1_000_000) + 0.5) / 1_000_000
    f_int = lamina.optics.fresnel_dielectric(mu, 1 / eta)
    escape = np.mean(2 * mu * np.exp(-tau / mu) * (1 - f_int))
    back = np.mean(2 * mu * np.exp(-2 * tau / mu) * f_int)
    for theta in (0.0, 50.0, 85.0):
        wi = direction(theta)
        f_i = lamina.optics.fresnel_dielectric(wi[2], eta)
        mu_t = np.sqrt(1 - (1 - wi[2] ** 2) / eta**2)
        closed = f_i + (1 - f_i) * np.exp(-tau / mu_t) * rho * escape / (1 - rho * back)
        ref, se = stack.albedo(wi, "reference", samples=400_000, seed=3)
        assert np.all(np.abs(ref - closed) <= 3 * se + 1e-8), f"θ={theta}: {ref} ± {se} vs {closed}"


@pytest.mark.parametrize("layers", [
    [lamina.Dielectric(1.5), lamina.Diffuse(1.0)],
    [lamina.Dielectric(1.5, thickness=1.0, sigma_s=3.0, g=0.6), lamina.Dielectric(1.3, thickness=0.5, sigma_s=1.0, g=-0.3), lamina.Diffuse(1.0)],
])
def test_white_furnace(layers):
    """Lossless smooth interfaces and scattering (non-absorbing) slabs over a white Lambertian base reflect all light."""
    ref, se = lamina.Stack(layers).albedo(direction(35.0), "reference", samples=200_000, seed=4)
    assert np.all(np.abs(ref - 1) <= 3 * se + 1e-12), f"{ref} ± {se}"


def test_rough_coat_loses_energy_but_never_creates_it():
    """Rough interfaces lose the energy of single-scattering microfacets (reported in docs/validation.md)."""
    stack = lamina.Stack([lamina.Dielectric(1.5, roughness=0.6), lamina.Diffuse(1.0)])
    ref, se = stack.albedo(direction(60.0), "reference", samples=200_000, seed=5)
    assert np.all(ref <= 1 + 3 * se) and np.all(ref < 0.99)


def test_lobe_of_rough_conductor_matches_exact_brdf():
    """Binned brute-force lobe vs the exact f·cos θo averaged over each bin (8 x 8 sub-quadrature): chi-square over
    the bins holding > 1% of the peak (p > 1e-4)."""
    stack = lamina.Stack([lamina.Conductor(0.2, 3.6, roughness=(0.25, 0.45), angle=0.3)])
    wi = direction(40.0, 1.0)
    f_cos, se, (te, pe) = stack.reference_lobe(wi, bins=(12, 24), samples=1_000_000, seed=6)
    f_cos, se = f_cos[..., 0], se[..., 0]
    exact = np.zeros_like(f_cos)
    sub = (np.arange(8) + 0.5) / 8
    for i in range(12):
        t = te[i] + sub * (te[i + 1] - te[i])
        for j in range(24):
            p = pe[j] + sub * (pe[j + 1] - pe[j])
            T, P = np.meshgrid(t, p, indexing="ij")
            wo = np.stack([np.sin(T) * np.cos(P), np.sin(T) * np.sin(P), np.cos(T)], -1)
            fc = stack.eval(wi, wo)[..., 0] * np.cos(T)
            exact[i, j] = np.sum(fc * np.sin(T)) / np.sum(np.sin(T))
    keep = (exact > 0.01 * exact.max()) & (se > 0)
    chi2 = np.sum(((f_cos[keep] - exact[keep]) / se[keep]) ** 2)
    p = stats.chi2.sf(chi2, keep.sum())
    assert p > 1e-4, f"chi2 {chi2:.1f} over {keep.sum()} bins (p = {p:.2g})"


def test_standard_error_shrinks_as_inverse_sqrt_n():
    stack = lamina.Stack([lamina.Dielectric(1.5, roughness=0.3, thickness=1, sigma_a=0.3), lamina.Diffuse(0.7)])
    _, se1 = stack.albedo(direction(30.0), "reference", samples=50_000, seed=7)
    _, se4 = stack.albedo(direction(30.0), "reference", samples=200_000, seed=8)
    ratio = se4 / se1
    assert np.all((ratio > 0.45) & (ratio < 0.55)), ratio


def test_deterministic_and_independent_of_threads():
    code = ("import lamina, numpy as np; s = lamina.Stack([lamina.Dielectric(1.5, 0.3, thickness=1, sigma_s=1.0), "
            "lamina.Diffuse(0.7)]); print(repr(s.albedo(np.array([0.3, 0, 0.95]), 'reference', samples=300_000, "
            "seed=11)[0].tolist()))")
    runs = [subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                           env={**os.environ, "RAYON_NUM_THREADS": n}).stdout for n in ("1", "2")]
    assert runs[0] == runs[1] and runs[0].strip()
    s = lamina.Stack([lamina.Conductor(0.2, 3.0, 0.3)])
    a = s.albedo(direction(20.0), "reference", samples=10_000, seed=3)
    b = s.albedo(direction(20.0), "reference", samples=10_000, seed=3)
    c = s.albedo(direction(20.0), "reference", samples=10_000, seed=4)
    np.testing.assert_array_equal(a[0], b[0])
    assert not np.array_equal(a[0], c[0])


def test_spectral_reference_and_errors():
    n, k = lamina.spectrum.ior("Cu")
    s = lamina.Stack([lamina.Dielectric(1.5, 0.1), lamina.Conductor(n, k, 0.2)])
    a, se = s.albedo(np.array([[0, 0, 1.0], [0.5, 0, 0.8]]), "reference", samples=20_000, wavelengths=[450, 550, 650])
    assert a.shape == se.shape == (2, 3) and np.all((a > 0) & (a < 1))
    with pytest.raises(ValueError, match="samples"):
        s.albedo([0, 0, 1.0], "reference", samples=1)
    with pytest.raises(ValueError, match="seed"):
        s.albedo([0, 0, 1.0], "reference", seed=-1)
    with pytest.raises(ValueError, match="above the surface"):
        s.albedo([0, 0, -1.0], "reference")
    with pytest.raises(ValueError, match="single direction"):
        s.reference_lobe(np.ones((2, 3)))
