"""Shared fixtures: random directions and the Mitsuba 3 harness.

Mitsuba's llvm_ad_* variants need a system libLLVM (>= 16 here, see tests/libllvm.py). The Makefile installs
Debian's libllvm19 when running as root; DRJIT_LIBLLVM_PATH is pointed at the best one found. Without it every
Mitsuba comparison still runs, on scalar_* variants (slower, same checks), and the pytest header says so.
"""

from __future__ import annotations

import functools
import json
import os
from pathlib import Path

import numpy as np
import pytest
from libllvm import find as find_libllvm

if not os.environ.get("DRJIT_LIBLLVM_PATH"):
    # With no usable libLLVM, point Dr.Jit at none rather than let its own search load LLVM 15 (which aborts):
    # the LLVM backend then fails to initialise cleanly and the comparisons run on scalar_* variants.
    os.environ["DRJIT_LIBLLVM_PATH"] = find_libllvm() or "/nonexistent/libLLVM-16-or-newer.so"

import lamina  # noqa: E402
from hypothesis import settings  # noqa: E402

try:
    import drjit as dr
    import mitsuba as mi
except Exception as error:  # noqa: BLE001 (scripts/device_check.sh's machine may lack it: Mitsuba's checks fail)
    dr = mi = None
    NO_MITSUBA = f"{error}: every comparison with Mitsuba fails (make test-deps installs it)"

# Property tests draw the same examples on every run (a clean checkout passes or fails the same way); set
# LAMINA_HYPOTHESIS_EXPLORE=1 to draw fresh ones, e.g. with more examples, and pin what they find with @example.
settings.register_profile("deterministic", derandomize=True, database=None)
settings.register_profile("explore", derandomize=False)
settings.load_profile("explore" if os.environ.get("LAMINA_HYPOTHESIS_EXPLORE") == "1" else "deterministic")


def _pick_rgb_variant() -> str:
    if mi is None:
        return "scalar_rgb"
    try:
        mi.set_variant("llvm_ad_rgb")
        return "llvm_ad_rgb"
    except Exception:  # libLLVM missing or too old: the scalar variant computes the same BSDFs
        return "scalar_rgb"


MI_RGB = _pick_rgb_variant()


def pytest_report_header(config):
    if mi is None:
        return f"mitsuba: {NO_MITSUBA}"
    note = "" if MI_RGB.startswith("llvm") else " (no libLLVM >= 16 found: Mitsuba checks run on scalar_rgb)"
    path = os.environ.get("DRJIT_LIBLLVM_PATH")
    return f"mitsuba {mi.__version__}: RGB comparisons on {MI_RGB}{note}; DRJIT_LIBLLVM_PATH={path}"


def unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def oren_nayar_albedo_limits(sigma: float) -> tuple[float, float]:
    """Directional albedo per unit ρ of the qualitative Oren–Nayar lobe (1994 eq. 30) at θi = 0 and θi → 90°:
    A and A + B/2 (at grazing sin α = 1, β = θo and ∫ max(0, cos φ) sin²θo dω / π = 1/2). For σ below ~0.3 rad the
    grazing value exceeds 1: the qualitative model is not energy-conserving there, so no stack on it can be held to
    an albedo of 1."""
    s2 = sigma * sigma
    a, b = 1 - 0.5 * s2 / (s2 + 0.33), 0.45 * s2 / (s2 + 0.09)
    return a, a + b / 2


def uv_sphere_mesh(lat: int, lon: int):
    """A latitude-longitude unit sphere mesh of lat x lon quads (normals = positions, the analytic sphere's uv
    chart)."""
    th, ph = np.meshgrid(np.linspace(0, np.pi, lat + 1), np.linspace(-np.pi, np.pi, lon + 1), indexing="ij")
    p = np.stack([np.sin(th) * np.sin(ph), np.cos(th), np.sin(th) * np.cos(ph)], -1).reshape(-1, 3)
    uv = np.stack([0.5 + ph / (2 * np.pi), th / np.pi], -1).reshape(-1, 2)
    idx = np.arange((lat + 1) * (lon + 1)).reshape(lat + 1, lon + 1)
    a, b, c, d = idx[:-1, :-1], idx[:-1, 1:], idx[1:, :-1], idx[1:, 1:]
    tris = np.concatenate([np.stack([a, c, b], -1).reshape(-1, 3), np.stack([b, c, d], -1).reshape(-1, 3)])
    return lamina.Mesh(p, tris, normals=p, uvs=uv)


def random_hemisphere(rng: np.random.Generator, n: int, min_cos: float = 0.02) -> np.ndarray:
    """n directions uniform on the upper hemisphere with cos θ >= min_cos."""
    z = rng.uniform(min_cos, 1.0, n)
    phi = rng.uniform(0.0, 2 * np.pi, n)
    s = np.sqrt(1 - z * z)
    return np.stack([s * np.cos(phi), s * np.sin(phi), z], axis=-1)


def mitsuba_f(bsdf: dict, wi: np.ndarray, wo: np.ndarray, variant: str = MI_RGB, wavelengths=None) -> np.ndarray:
    """f(wi, wo) of a Mitsuba 3 BSDF in lamina's convention (light arrives along wi, leaves along wo), shape (n, c).

    Mitsuba works in radiance mode with si.wi the direction towards the camera (lamina's wo) and eval's wo towards
    the light (lamina's wi); it returns f·|cos θ| of its wo, so we divide by |wi.z|."""
    if mi is None:
        raise RuntimeError(f"mitsuba: {NO_MITSUBA}")
    mi.set_variant(variant)
    b = mi.load_dict(bsdf)
    ctx = mi.BSDFContext()
    if variant.startswith("llvm"):
        si = dr.zeros(mi.SurfaceInteraction3f, len(wi))
        si.wi = mi.Vector3f(np.ascontiguousarray(wo.T, dtype=np.float32))
        value = np.array(b.eval(ctx, si, mi.Vector3f(np.ascontiguousarray(wi.T, dtype=np.float32)))).T
    else:
        rows = []
        for a, o in zip(wi, wo):
            si = dr.zeros(mi.SurfaceInteraction3f)
            si.wi = mi.Vector3f(*map(float, o))
            if wavelengths is not None:
                si.wavelengths = mi.Spectrum(list(wavelengths))
            rows.append(np.array(b.eval(ctx, si, mi.Vector3f(*map(float, a)))).ravel())
        value = np.array(rows)
    return value.astype(np.float64) / np.abs(wi[:, 2:3])


@pytest.fixture
def rng():
    return np.random.default_rng(20261122)


@pytest.fixture(scope="session")
def suite_reference(tmp_path_factory):
    """Reference f of a suite material on the suite grid, 20k paths per direction (seed 0), computed afresh in this
    session (a regression guard must not trust a stale cache) and shared by every model's guard:
    name -> (wi, wo, f, stderr)."""
    import os

    from lamina import reference as R

    cache = tmp_path_factory.mktemp("reference-cache")
    results = {}

    def get(name: str):
        if name not in results:
            old = os.environ.get("LAMINA_CACHE")
            os.environ["LAMINA_CACHE"] = str(cache)
            try:
                results[name] = R.suite_reference(name, samples=20_000)
            finally:
                if old is None:
                    del os.environ["LAMINA_CACHE"]
                else:
                    os.environ["LAMINA_CACHE"] = old
        return results[name]

    return get


@pytest.fixture(scope="session")
def suite_reference_albedo():
    """lamina.reference.suite_reference_albedo (200k paths, seed 0), green channel, once per session:
    name -> (wi (5, 3), albedo (5,), standard error (5,))."""
    from lamina import reference as R

    results = {}

    def get(name: str):
        if name not in results:
            wi, albedo, se = R.suite_reference_albedo(name)
            results[name] = (wi, albedo[:, 1], se[:, 1])
        return results[name]

    return get


@functools.cache
def validation() -> dict:
    """What scripts/validation_report.py measured of the models on the suite (docs/validation.json): per model and
    material the lobe error at each incident angle with its reference's noise floor, and the signed albedo error
    (green) with the reference's standard error."""
    return json.loads((Path(__file__).resolve().parents[1] / "docs" / "validation.json").read_text())


def check_as_measured(model: str, name: str, suite_reference, suite_reference_albedo):
    """`model` on suite material `name` is as accurate as docs/validation.json says, both ways: its lobe error at
    θi ∈ {0, 30, 60}° within 3 of the reference's noise floors of the measured one, its signed albedo error at every
    angle within 3 reference standard errors. (The reference is deterministic: the band is what it can resolve.)"""
    measured = validation()["suite"][model][name]
    stack = lamina.materials.suite(name)
    wi, wo, f, se = suite_reference(name)
    total = np.abs(f).sum(axis=(1, 2))
    err = np.abs(stack.eval(wi, wo, model) - f).sum(axis=(1, 2)) / total
    floor = np.sqrt(2 / np.pi) * se.sum(axis=(1, 2)) / total
    low = slice(0, 3)
    assert np.all(np.abs(err - measured["lobe"])[low] <= 3 * floor[low]), (err[low], measured["lobe"][:3], floor[low])
    wi_albedo, reference, reference_se = suite_reference_albedo(name)
    signed = stack.albedo(wi_albedo, model)[:, 1] - reference
    assert np.all(np.abs(signed - measured["albedo"]) <= 3 * reference_se), (signed, measured["albedo"])


def _varnished_b() -> np.ndarray:
    """b = ∫ 2μ e^{−2τ/μ} F(μ, 1/η) dμ for the suite's varnished-diffuse (η 1.5, τ = σa d per channel): the share of
    the base's diffuse light that comes back to it through its slab and the coat (μ the cosine inside; 1e6-point
    midpoint rule, error ~1e-9)."""
    mu = (np.arange(1_000_000) + 0.5) / 1_000_000
    f_int = lamina.optics.fresnel_dielectric(mu, 1 / 1.5)
    tau = np.array([0.1, 0.35, 0.9])
    return np.array([np.mean(2 * mu * np.exp(-2 * t / mu) * f_int) for t in tau])


def varnished_diffuse(wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
    """The exact f of the suite's varnished-diffuse (a smooth coat of η 1.5 over a slab of τ = (0.1, 0.35, 0.9) over
    Lambert ρ = (0.6, 0.35, 0.15)), every inter-reflection summed: ρ (1 − F(θi)) (1 − F(θo)) e^{−τ(1/μi′ + 1/μo′)}
    / (π η² (1 − ρ b)), μ′ the cosines refracted into the coat. varnished_diffuse.b is b (_varnished_b)."""
    eta, rho, tau = 1.5, np.array([0.6, 0.35, 0.15]), np.array([0.1, 0.35, 0.9])
    ci, co = wi[..., 2:3], wo[..., 2:3]
    inside = [np.sqrt(1 - (1 - c**2) / eta**2) for c in (ci, co)]
    t = (1 - lamina.optics.fresnel_dielectric(ci, eta)) * (1 - lamina.optics.fresnel_dielectric(co, eta))
    return rho * t * np.exp(-tau * (1 / inside[0] + 1 / inside[1])) / (np.pi * eta**2 * (1 - rho * varnished_diffuse.b))


varnished_diffuse.b = _varnished_b()
