"""model="tabulated": the stack solved once by Fourier-series adding-doubling (tables/adding_doubling.rs) and
interpolated. Against the reference on the suite (the issue's goal: mean lobe error ≤ 2% at θi ≤ 80°), the limits it
states (isotropic stacks only), and its on-disk cache. The solver's exact cases (a smooth coat over Lambert, an
index-matched coat, a lossless stack's energy) are Rust tests (models/tabulated.rs)."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pytest
from conftest import random_hemisphere
from lamina import Dielectric, Stack
from lamina.atlas import lobe_errors
from lamina.materials import SUITE, metal, suite
from lamina.reference import SUITE_THETAS

LOW = np.array(SUITE_THETAS) <= 80.0
ISOTROPIC = [name for name in SUITE if name != "anisotropic-coat-metal"]


def _error_and_floor(name, suite_reference):
    """Mean lobe error at θi ≤ 80° against the 20k-path reference, and the reference's own expected L1 noise there
    (√(2/π) Σ SE / Σ|f|, which a perfect model would show)."""
    wi, wo, f, se = suite_reference(name)
    err = lobe_errors(suite(name).eval(wi, wo, "tabulated"), f)[LOW].mean()
    floor = np.sqrt(2 / np.pi) * (se.sum(axis=(1, 2)) / np.abs(f).sum(axis=(1, 2)))[LOW].mean()
    return err, floor


@pytest.mark.parametrize("name", ISOTROPIC)
def test_each_suite_material_is_within_two_percent_of_the_reference(name, suite_reference):
    # The goal (2%) plus the reference's own noise, which dominates three-layer (measured: 0.08% to 2.3%).
    err, floor = _error_and_floor(name, suite_reference)
    assert err <= 0.02 + floor, f"{name}: lobe error {err:.4f}, reference noise {floor:.4f}"


def test_the_suite_mean_meets_the_goal(suite_reference):
    # Measured: 0.98% over the seven isotropic materials (noise included).
    errors = [_error_and_floor(name, suite_reference)[0] for name in ISOTROPIC]
    assert np.mean(errors) <= 0.02, errors


def test_anisotropic_stacks_raise_a_clear_error():
    with pytest.raises(ValueError, match=r"isotropic stacks: layer 0 \(Dielectric\) has roughness \(0.1, 0.4\)"):
        suite("anisotropic-coat-metal").eval([0, 0, 1], [0, 0, 1], "tabulated")
    # A single opaque layer is its own top, evaluated exactly (model="microfacet"), anisotropic or not.
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
