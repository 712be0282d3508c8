"""The NumPy API contract: broadcasting, dtypes, strides, horizons, and errors that name the parameter."""

from __future__ import annotations

import subprocess
import sys
import threading

import lamina
import numpy as np
import pytest
from conftest import random_hemisphere


@pytest.fixture
def gold():
    return lamina.Stack([lamina.materials.metal("Au", roughness=(0.2, 0.35), angle=0.3)])


def test_models_listed():
    assert "microfacet" in lamina.MODELS


def test_broadcasting_shapes(gold, rng):
    wi = random_hemisphere(rng, 4).reshape(4, 1, 3)
    wo = random_hemisphere(rng, 5)
    f = gold.eval(wi, wo)
    assert f.shape == (4, 5, 3)
    for i in range(4):
        for j in range(5):
            np.testing.assert_array_equal(f[i, j], gold.eval(wi[i, 0], wo[j]))
    assert gold.eval(wi[0, 0], wo[0]).shape == (3,)
    assert gold.eval(wi[0, 0], wo[0], wavelengths=np.linspace(400, 700, 7)).shape == (7,)


def test_dtypes_and_strides(gold, rng):
    wi, wo = random_hemisphere(rng, 64), random_hemisphere(rng, 64)
    ref = gold.eval(wi, wo)
    assert ref.dtype == np.float64
    f32 = gold.eval(wi.astype(np.float32), wo.astype(np.float32))
    assert f32.dtype == np.float32
    np.testing.assert_allclose(
        f32, gold.eval(wi.astype(np.float32).astype(np.float64), wo.astype(np.float32).astype(np.float64)), rtol=1e-6
    )
    assert gold.eval(wi.astype(np.float32), wo).dtype == np.float64
    # Non-contiguous views: every other row, Fortran order, a transposed (3, n) array viewed as (n, 3).
    big = np.empty((128, 3))
    big[::2] = wi
    np.testing.assert_array_equal(gold.eval(big[::2], wo), ref)
    np.testing.assert_array_equal(gold.eval(np.asfortranarray(wi), wo), ref)
    np.testing.assert_array_equal(gold.eval(np.ascontiguousarray(wi.T).T, wo[::-1][::-1]), ref)
    np.testing.assert_array_equal(gold.eval(wi.tolist(), wo), ref)  # nested lists are fine


def test_directions_need_not_be_unit(gold, rng):
    wi, wo = random_hemisphere(rng, 16), random_hemisphere(rng, 16)
    np.testing.assert_allclose(gold.eval(3.0 * wi, 0.2 * wo), gold.eval(wi, wo), rtol=1e-12)


def test_below_horizon_is_zero(gold):
    up, down = np.array([0.1, 0.2, 0.9]), np.array([0.1, 0.2, -0.9])
    grazing = np.array([1.0, 0.0, 0.0])
    for wi, wo in [(up, down), (down, up), (down, down), (grazing, up), (up, grazing)]:
        assert np.all(gold.eval(wi, wo) == 0)


@pytest.mark.parametrize(
    "make, match",
    [
        (lambda: lamina.Stack([]), "layers"),
        (lambda: lamina.Stack([lamina.Dielectric(1.5)]), "opaque base"),
        (lambda: lamina.Stack([lamina.Diffuse(0.5), lamina.Diffuse(0.5)]), "opaque"),
        (lambda: lamina.Stack([lamina.Conductor(0.2, 3.0, roughness=1.2)]), r"roughness must be in \[0, 1\]"),
        (lambda: lamina.Stack([lamina.Conductor(0.2, 3.0, roughness=(0.1, -0.1))]), r"roughness must be in \[0, 1\]"),
        (lambda: lamina.Stack([lamina.Conductor(0.0, 3.0)]), r"ior must be in \(0, inf\)"),
        (lambda: lamina.Stack([lamina.Conductor(0.2, -1.0)]), r"k must be in \[0, inf\)"),
        (
            lambda: lamina.Stack([lamina.Dielectric(-1.5), lamina.Diffuse(0.5)]),
            r"Dielectric: ior must be in \(0, inf\)",
        ),
        (lambda: lamina.Stack([lamina.Dielectric(1.5, thickness=-1), lamina.Diffuse(0.5)]), "thickness"),
        (lambda: lamina.Stack([lamina.Dielectric(1.5, sigma_a=np.nan), lamina.Diffuse(0.5)]), "sigma_a"),
        (lambda: lamina.Stack([lamina.Dielectric(1.5, g=1.0), lamina.Diffuse(0.5)]), r"g must be in \(-1, 1\)"),
        (lambda: lamina.Stack([lamina.Diffuse(1.5)]), r"albedo must be in \[0, 1\]"),
        (lambda: lamina.Stack([lamina.Diffuse((0.5, 0.5))]), "albedo"),
        (lambda: lamina.Stack([lamina.Diffuse(0.5)], ext_ior=0.0), "ext_ior"),
        (lambda: lamina.Stack([lamina.Diffuse(0.5, roughness=2.0)]), "roughness"),
        (lambda: lamina.Spectrum([500, 400], [1, 2]), "increasing"),
        (lambda: lamina.Spectrum([400, 500], [1, np.inf]), "finite"),
    ],
)
def test_bad_stacks_raise_value_error_naming_the_parameter(make, match):
    with pytest.raises(ValueError, match=match):
        make()


def test_type_errors():
    with pytest.raises(TypeError, match="layers"):
        lamina.Stack(["gold"])
    with pytest.raises(TypeError, match="roughness"):
        lamina.Conductor(0.2, 3.0, roughness="rough")._resolve(None)
    with pytest.raises(TypeError, match="albedo"):
        lamina.Stack([lamina.Diffuse("white")])
    stack = lamina.Stack([lamina.Diffuse(0.5)])
    with pytest.raises(TypeError, match="wi"):
        stack.eval(np.array(["a", "b", "c"]), [0, 0, 1.0])
    with pytest.raises(TypeError, match="wo"):
        stack.eval([0, 0, 1.0], np.array([1 + 1j, 0, 1]))


@pytest.mark.parametrize(
    "wi, wo, match",
    [
        ([np.nan, 0, 1], [0, 0, 1], "wi contains NaN or Inf"),
        ([0, 0, 1], [np.inf, 0, 1], "wo contains NaN or Inf"),
        ([0, 0, 0], [0, 0, 1], "wi contains a zero-length direction"),
        (np.ones((4, 2)), [0, 0, 1], r"wi must have shape \(\.\.\., 3\)"),
        (np.ones((4, 3)), np.ones((5, 3)), "do not broadcast"),
    ],
)
def test_bad_arrays(wi, wo, match):
    with pytest.raises(ValueError, match=match):
        lamina.Stack([lamina.Diffuse(0.5)]).eval(np.asarray(wi, float), np.asarray(wo, float))


def test_bad_options():
    stack = lamina.Stack([lamina.Conductor(0.2, 3.0, 0.3)])
    for kw, match in [
        ({"model": "belcour2"}, "model must be one of"),
        ({"distribution": "phong"}, "distribution"),
        ({"g2": "smith"}, "g2"),
        ({"fresnel": "fast"}, "fresnel"),
    ]:
        with pytest.raises(ValueError, match=match):
            stack.eval([0, 0, 1.0], [0, 0, 1.0], **kw)
    with pytest.raises(ValueError, match="layered model"):
        lamina.Stack([lamina.Dielectric(1.5, 0.2), lamina.Diffuse(0.5)]).eval([0, 0, 1.0], [0, 0, 1.0])
    with pytest.raises(ValueError, match=r"alpha_x \(roughness\) must be in \(0, 1\]"):
        lamina.optics.ndf([0, 0, 1.0], 0.0)


def test_smooth_conductor_has_no_finite_lobe():
    f = lamina.Stack([lamina.Conductor(0.2, 3.0, roughness=0.0)]).eval([0.3, 0, 0.95], [-0.3, 0, 0.95])
    assert np.all(f == 0)


def test_concurrent_calls_from_threads(gold, rng):
    """The GIL is released during evaluation; concurrent calls from Python threads return the serial results."""
    wi, wo = random_hemisphere(rng, 50_000), random_hemisphere(rng, 50_000)
    ref = gold.eval(wi, wo)
    out = [None] * 4

    def work(i):
        out[i] = gold.eval(wi, wo)

    threads = [threading.Thread(target=work, args=(i,)) for i in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    for o in out:
        np.testing.assert_array_equal(o, ref)


def test_cli_plot_writes_png(tmp_path):
    res = subprocess.run(
        [sys.executable, "-m", "lamina.cli", "plot", "--material", "copper", "--out", str(tmp_path)],
        capture_output=True,
        text=True,
        check=True,
    )
    png = tmp_path / "copper_microfacet_slices.png"
    assert png.exists() and png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n", res.stdout + res.stderr
    assert png.stat().st_size > 10_000


def test_prepared_models_are_reused_only_for_equal_arguments(rng):
    """lamina keeps the last 16 prepared models (Belcour's tables) keyed by model, stack and options: a stack that
    differs in its last digit, or other options, must not reuse them; one evicted and prepared again gives the same
    bits."""

    def stack(ior):
        return lamina.Stack([lamina.Dielectric(ior, 0.2), lamina.materials.metal("Cu", 0.35)])

    wi, wo = random_hemisphere(rng, 2000), random_hemisphere(rng, 2000)
    first = stack(1.5).eval(wi, wo, "belcour")
    assert not np.array_equal(stack(1.5 + 1e-12).eval(wi, wo, "belcour"), first)
    assert not np.array_equal(stack(1.5).eval(wi, wo, "belcour", symmetric=True), first)
    for k in range(20):  # evicts the first one
        stack(1.2 + 0.01 * k).eval(wi[:1], wo[:1], "belcour")
    np.testing.assert_array_equal(stack(1.5).eval(wi, wo, "belcour"), first)


def test_cli_version_models_and_one_line_errors(tmp_path):
    run = lambda *a: subprocess.run([sys.executable, "-m", "lamina.cli", *a], capture_output=True, text=True)  # noqa: E731
    assert run("--version").stdout.strip() == f"lamina {lamina.__version__}"
    listing = run("models").stdout
    assert all(m in listing for m in lamina.MODELS) and "lut = 'tabulated'" in listing
    bad = run("plot", "--material", "coated-copper", "--model", "microfacet", "--out", str(tmp_path))
    assert bad.returncode == 2 and "Traceback" not in bad.stderr
    assert bad.stderr.startswith("lamina: error: model 'microfacet'") and bad.stderr.count("\n") == 1
    bad = run("plot", "--thetas", "0,x", "--out", str(tmp_path))
    assert bad.returncode == 2 and "--thetas must be comma-separated numbers" in bad.stderr


def test_import_lamina_makes_its_public_modules_available():
    """`import lamina` is enough for every public module; the optional dependencies (dask, Mitsuba, matplotlib) load
    only when a function needs them."""
    import subprocess
    import sys

    code = (
        "import sys, lamina\n"
        "mods = ('reference', 'materials', 'optics', 'oat', 'atlas', 'plot', 'dask', 'mitsuba', 'renderer', 'gpu')\n"
        "assert all(hasattr(lamina, m) for m in mods), [m for m in mods if not hasattr(lamina, m)]\n"
        "heavy = {'dask', 'mitsuba', 'matplotlib'} & set(sys.modules)\n"
        "assert not heavy, sorted(heavy)\n"
        "print(lamina.materials.SUITE)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == f"Factories({list(lamina.materials.SUITE)})"
