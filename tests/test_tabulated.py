"""model="tabulated": the stack solved once by Fourier-series adding-doubling (tables/adding_doubling.rs; anisotropic
stacks on a grid of both azimuths, tables/anisotropic.rs) and interpolated. Against the reference on the suite (the
issue's goal: mean lobe error ≤ 2% at θi ≤ 80°, the anisotropic coat included), the limits it states, and its on-disk
cache. The solvers' exact cases (a smooth coat over Lambert, an index-matched coat, a lossless stack's energy; the
anisotropic solver's isotropic limit, rotation and reciprocity) are Rust tests (models/tabulated.rs)."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pytest
from conftest import random_hemisphere
from lamina import Dielectric, Diffuse, Param, Stack
from lamina.atlas import lobe_errors
from lamina.materials import SUITE, metal, suite
from lamina.reference import SUITE_THETAS, suite_directions

LOW = np.array(SUITE_THETAS) <= 80.0


def _error_and_floor(name, suite_reference):
    """Mean lobe error at θi ≤ 80° against the 20k-path reference, and the reference's own expected L1 noise there
    (√(2/π) Σ SE / Σ|f|, which a perfect model would show)."""
    wi, wo, f, se = suite_reference(name)
    err = lobe_errors(suite(name).eval(wi, wo, "tabulated"), f)[LOW].mean()
    floor = np.sqrt(2 / np.pi) * (se.sum(axis=(1, 2)) / np.abs(f).sum(axis=(1, 2)))[LOW].mean()
    return err, floor


@pytest.mark.parametrize("name", SUITE)
def test_each_suite_material_is_within_two_percent_of_the_reference(name, suite_reference):
    # The goal (2%) plus the reference's own noise, which dominates three-layer (measured: 0.08% to 2.3%; the
    # anisotropic coat 0.98%: 1.9% at θi = 0, 0.8%, 1.0% and 0.15% at 30, 60 and 80°).
    err, floor = _error_and_floor(name, suite_reference)
    assert err <= 0.02 + floor, f"{name}: lobe error {err:.4f}, reference noise {floor:.4f}"


def test_the_suite_mean_meets_the_goal(suite_reference):
    # Measured: 0.98% over the seven isotropic materials (noise included), 0.98% with the anisotropic coat.
    errors = [_error_and_floor(name, suite_reference)[0] for name in SUITE]
    assert np.mean(errors) <= 0.02, errors


def test_the_anisotropic_coats_albedo_meets_the_goal(suite_reference_albedo):
    """The issue's goal for anisotropic stacks: the albedo within 0.01 of the reference's (200k paths per angle,
    green). Measured: within 0.0007 at θi ≤ 80° (the reference's standard error 0.00085) and 0.0040 at 87° (Belcour
    +0.04 to +0.24, Steinberg −0.15 to −0.21)."""
    wi, reference, se = suite_reference_albedo("anisotropic-coat-metal")
    signed = suite("anisotropic-coat-metal").albedo(wi, "tabulated")[:, 1] - reference
    assert np.all(np.abs(signed) <= 0.01), signed
    assert np.all(np.abs(signed[LOW]) <= 3 * se[LOW]), (signed, se)


def test_anisotropic_stacks_are_tabulated_within_their_budget(tmp_path):
    """Yamaguchi's case (anisotropic roughness, a tangent angle per layer) is solved on a grid of both azimuths: the
    issue's budget of 64 MiB per RGB table; no gradients (the isotropic solve's Duals) and no GPU kernel yet, each a
    clear error. A single opaque layer is its own top, evaluated exactly (model="microfacet")."""
    env = {**os.environ, "LAMINA_CACHE": str(tmp_path)}
    script = "import lamina; lamina.materials.suite('anisotropic-coat-metal').eval([0, 0, 1], [0, 0, 1], 'tabulated')"
    subprocess.check_call([sys.executable, "-c", script], env=env)
    (table,) = (tmp_path / "tables").rglob("tabulated-*.f32")
    assert table.stat().st_size <= 64 * 2**20
    template = Stack([Dielectric(1.5, (0.1, 0.4), angle=0.5, thickness=Param("t", 0.0, 2.0)), metal("Al", 0.2)])
    with pytest.raises(ValueError, match="no gradients for anisotropic stacks"):
        template.eval_grad([0, 0, 1], [0, 0, 1], "tabulated", t=0.5)
    brushed = Stack([metal("Al", (0.15, 0.45), angle=0.5)])
    wi, wo = np.array([0.3, 0.1, 0.9]), np.array([-0.2, 0.4, 0.8])
    assert np.array_equal(brushed.eval(wi, wo, "tabulated"), brushed.eval(wi, wo, "microfacet"))


def test_the_reference_options_reach_the_table(rng):
    """distribution and g2 change the solution as they change the reference (Beckmann vs GGX tails)."""
    stack = Stack([Dielectric(1.5, 0.3), metal("Cu", 0.3)])
    wi, wo = rng.normal(size=(2, 100, 3))
    wi[:, 2], wo[:, 2] = np.abs(wi[:, 2]), np.abs(wo[:, 2])
    ggx = stack.eval(wi, wo, "tabulated")
    assert not np.allclose(ggx, stack.eval(wi, wo, "tabulated", distribution="beckmann"), rtol=1e-3)
    assert not np.allclose(ggx, stack.eval(wi, wo, "tabulated", g2="separable"), rtol=1e-3)


SCRIPT = """
import json, lamina
s = lamina.materials.suite("rough-coat-rough-copper")
print(json.dumps(s.eval([0.3, 0.1, 0.9], [[0.0, 0.0, 1.0], [-0.2, 0.4, 0.8]], "tabulated").tolist()))
"""


def test_tables_are_cached_on_disk_keyed_by_the_stack(tmp_path):
    env = {**os.environ, "LAMINA_CACHE": str(tmp_path)}
    run = lambda: json.loads(subprocess.check_output([sys.executable, "-c", SCRIPT], env=env, text=True))  # noqa: E731
    first = run()
    files = list((tmp_path / "tables").rglob("tabulated-*.f32"))
    assert len(files) == 1
    # The memory budget: ≤ 16 MiB per isotropic stack (RGB here).
    assert files[0].stat().st_size <= 16 * 2**20
    assert run() == first
    # Another stack (rough-coat-rough-copper with a rougher coat), another file.
    subprocess.check_call(
        [
            sys.executable,
            "-c",
            "import lamina; lamina.Stack([lamina.Dielectric(1.5, 0.25), lamina.materials.metal('Cu', 0.35)])"
            ".eval([0, 0, 1], [0, 0, 1], 'tabulated')",
        ],
        env=env,
    )
    assert len(list((tmp_path / "tables").rglob("tabulated-*.f32"))) == 2


@pytest.mark.parametrize("name", ["rough-coat-rough-copper", "three-layer", "scattering-slab"])
def test_tabulated_is_reciprocal_on_layered_stacks(name, rng):
    """Helmholtz reciprocity through the whole stack: the table keeps each reciprocal pair once and interpolates (θi,
    θo) symmetrically, and the top's own reflection is exact, so f(wi, wo) = f(wo, wi) to rounding."""
    stack = suite(name)
    wi, wo = random_hemisphere(rng, 5000, 0.02), random_hemisphere(rng, 5000, 0.02)
    a, b = stack.eval(wi, wo, "tabulated"), stack.eval(wo, wi, "tabulated")
    np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-15 * a.max())


def test_a_smooth_interface_under_a_smooth_top_is_a_dirac_lobe(tmp_path, monkeypatch):
    """Two smooth interfaces over rough copper: the inner interface's mirror reflection leaves the stack as a Dirac
    lobe (the reference's f leaves it out). The table leaves it out too and `specular` adds it, exact: once the table
    blurred it into its cells (lobe error 2.40 at θi = 0). The lobe error is the suite's goal (2%) plus the
    reference's noise; the albedo with the Dirac part is the reference's (Dirac paths included) within 3 standard
    errors and the table's own energy loss (0.3%: a lossless stack's albedo, models/tabulated.rs). Measured: lobe
    error 0.4-2.7% with noise 0.5-1.7%; albedo within 0.0017."""
    monkeypatch.setenv("LAMINA_CACHE", str(tmp_path))
    stack = Stack([Dielectric(1.5, 0.0, thickness=0.5), Dielectric(1.3, 0.0, thickness=0.5), metal("Cu", 0.5)])
    wi, wo = suite_directions()
    f, se = stack.reference(wi, wo, samples=20_000, seed=0, progress=False)
    noise = np.sqrt(2 / np.pi) * se.sum(axis=(1, 2)) / np.abs(f).sum(axis=(1, 2))
    err = lobe_errors(stack.eval(wi, wo, "tabulated"), f)
    assert np.all(err <= 0.02 + noise), (err, noise)
    t = np.radians(SUITE_THETAS)
    w = np.stack([np.sin(t), np.zeros_like(t), np.cos(t)], -1)
    albedo, albedo_se = stack.albedo(w, "reference", samples=100_000, seed=1, progress=False)
    mirror = w * [-1.0, -1.0, 1.0]
    tab = stack.albedo(w, "tabulated") + stack.specular(mirror, "tabulated")
    assert np.all(np.abs(tab - albedo) <= 3 * albedo_se + 0.003), (tab, albedo, albedo_se)


def test_the_cache_keeps_to_its_bound_removing_the_least_recently_used(tmp_path, monkeypatch):
    """Three tables of 0.8 MiB each in a cache bounded at 2 MiB ($LAMINA_CACHE_LIMIT_MB): the third write removes the
    first table (the least recently used), and the cache keeps the other two (src/cache.rs `prune`)."""
    monkeypatch.setenv("LAMINA_CACHE", str(tmp_path))
    monkeypatch.setenv("LAMINA_CACHE_LIMIT_MB", "2")
    z = np.array([0.0, 0.0, 1.0])
    tables, seen = [], set()
    for eta in (1.31, 1.32, 1.33):
        Stack([Dielectric(eta), Diffuse((0.6, 0.3, 0.2))]).eval(z, z, "tabulated")
        tables.append(set(tmp_path.rglob("tabulated-*.f32")) - seen)
        seen |= tables[-1]
    left = set(tmp_path.rglob("tabulated-*.f32"))
    assert all(len(t) == 1 for t in tables), tables
    assert left == tables[1] | tables[2], (left, tables)
    assert sum(p.stat().st_size for p in left) <= 2 << 20
