"""The model catalogue and the hardened boundary: lamina.models() describes every model, the docstring and README
are generated from it, every bad input of scripts/reliability.py is refused with ValueError / TypeError, a
hypothesis-driven fuzz finds no NaN, Inf or negative value, results do not depend on the thread count, stacks are
values that pickle, Ctrl-C stops a long evaluation, and an output too large raises MemoryError."""

from __future__ import annotations

import importlib.util
import os
import pickle
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import lamina
import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from lamina import Conductor, Dielectric, Diffuse, Stack
from lamina.catalogue import markdown_table

ROOT = Path(__file__).resolve().parents[1]


def _script(name: str):
    spec = importlib.util.spec_from_file_location(name, ROOT / "scripts" / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_catalogue_describes_every_model():
    models = lamina.models()
    # Every entry is a model= that evaluates (the analytic ones a stack they represent, the reference last).
    gold, coat = Stack([lamina.materials.metal("Au", 0.2)]), lamina.materials.suite("rough-coat-rough-copper")
    for m in models:
        stack = gold if m.name == "microfacet" else coat
        kw = {"samples": 200} if m.name == "reference" else {}
        f = stack.eval([0.0, 0.0, 1.0], [0.3, 0.0, 0.95], m.name, **kw)
        assert f.shape == (3,) and np.all(np.isfinite(f)) and np.all(f > 0), m.name
    assert models[-1].name == "reference" and all(m.name != "reference" for m in models[:-1])
    with pytest.raises(ValueError, match="model must be one of"):
        gold.eval([0.0, 0.0, 1.0], [0.3, 0.0, 0.95], "phong")
    for m in models:
        assert m.summary and isinstance(m.reciprocal, bool) and isinstance(m.energy_conserving, bool)
        for name, o in m.options.items():
            assert o.name == name and o.doc
            if o.choices is not None:
                assert o.default in o.choices, (m.name, name)
            else:
                assert o.range[0] <= o.default <= o.range[1], (m.name, name)
        for i in m.inputs.values():
            assert i.width in (1, 3) and i.range[0] < i.range[1] and i.doc
    ww = next(m for m in models if m.name == "weidlich_wilkie")
    assert ww.options["distribution"].default == "beckmann" and ww.options["g2"].default == "v_cavity"
    assert set(ww.inputs) == {"flake_normal", "distance", "mask"}


def test_every_option_default_is_what_eval_uses(rng):
    """Passing every option at its catalogue default changes nothing, bit for bit."""
    wi, wo = rng.normal(size=(200, 3)), rng.normal(size=(200, 3))
    wi[:, 2], wo[:, 2] = np.abs(wi[:, 2]), np.abs(wo[:, 2])
    for m in (m for m in lamina.models() if m.name != "reference"):  # the analytic models
        stack = lamina.materials.suite("rough-coat-rough-copper" if m.name != "microfacet" else "frosted-metal")
        stack = Stack(stack.layers[-1:]) if m.name == "microfacet" else stack
        defaults = {k: o.default for k, o in m.options.items()}
        assert np.array_equal(stack.eval(wi, wo, m.name, **defaults), stack.eval(wi, wo, m.name)), m.name


def test_docstring_and_readme_are_generated_from_the_catalogue():
    doc = Stack.eval.__doc__
    for m in lamina.models():
        assert f'"{m.name}"' in doc
        for name in list(m.options) + list(m.inputs):
            assert name in doc, (m.name, name)
    readme = (ROOT / "README.md").read_text()
    assert markdown_table() in readme, "README's model table is stale: run `make readme`"


def test_readme_chart_table_is_generated_from_the_chart_data():
    import json
    import sys

    sys.path.insert(0, str(ROOT / "scripts"))
    from readme_tables import chart_table

    chart = json.loads((ROOT / "docs" / "speed_accuracy.json").read_text())
    assert chart_table(chart) in (ROOT / "README.md").read_text(), "README's chart table is stale: run `make readme`"


def test_model_names_and_foreign_options_are_refused():
    stack, w = lamina.materials.preset("coated-copper"), np.array([0.0, 0.0, 1.0])
    with pytest.raises(ValueError, match="'reference'"):
        stack.eval(w, w, "phong")
    with pytest.raises(TypeError, match="model must be a string"):
        stack.eval(w, w, None)
    with pytest.raises(TypeError, match="model 'belcour' has no option 'lut'"):
        stack.eval(w, w, "belcour", lut="fitted")
    with pytest.raises(TypeError, match="symmetric must be a bool"):
        stack.eval(w, w, "belcour", symmetric="yes")
    with pytest.raises(ValueError, match=r"extent must be in \[0, 1\]"):
        stack.eval(w, w, "weidlich_wilkie", extent=2.0)


@pytest.mark.parametrize("case", range(len(_script("reliability").bad_inputs())))
def test_bad_input_is_refused_with_value_or_type_error(case):
    description, fn = _script("reliability").bad_inputs()[case]
    with pytest.raises((ValueError, TypeError)):
        fn()


_EXTREME_ALPHA = st.sampled_from([0.0, 1e-6, 1.0, 0.3, 0.05])


@st.composite
def stacks(draw):
    coats = [
        Dielectric(
            draw(st.sampled_from([1.0 + 1e-9, 1.0001, 1.5, 2.5, 0.9])),
            (draw(_EXTREME_ALPHA), draw(_EXTREME_ALPHA)),
            angle=draw(st.floats(-3, 3)),
            thickness=draw(st.sampled_from([0.0, 1e-6, 1.0, 1e4])),
            sigma_a=draw(st.sampled_from([0.0, 0.5, 1e6])),
            sigma_s=draw(st.sampled_from([0.0, 2.0, 1e6])),
            g=draw(st.sampled_from([0.0, 0.999, -0.999])),
        )
        for _ in range(draw(st.integers(0, 2)))
    ]
    base = draw(
        st.sampled_from(
            [
                Conductor(0.2, 3.0, draw(_EXTREME_ALPHA)),
                Diffuse(draw(st.sampled_from([0.0, 1.0, 0.5])), draw(st.sampled_from([0.0, 1.0]))),
            ]
        )
    )
    return Stack(coats + [base])


def _special_directions(dtype):
    tiny = np.finfo(dtype).smallest_subnormal * 4
    rng = np.random.default_rng(0)
    w = rng.normal(size=(64, 3))
    w[:, 2] = np.abs(w[:, 2])
    wi = np.concatenate([w, [[0, 0, 1.0]] * 4, w[:8] * (1, 1, 0), w[:8] * (1, 1, 0) + (0, 0, tiny)])
    wo = np.concatenate(
        [
            w[::-1],
            [[0, 0, 1.0], [0.5, 0, tiny], [1, 0, 0], [0, 0, 1.0]],
            w[:8] * (-1, -1, 0),
            w[:8] * (-1, -1, 0) + (0, 0, tiny),
        ]
    )
    return wi.astype(dtype), wo.astype(dtype)


#: What each fuzzed model may refuse a stack for: Belcour an Oren–Nayar base, Steinberg a relative IOR off its tables.
REFUSALS = {
    "belcour": "takes a Lambertian diffuse base",
    "steinberg": "tabulates relative IORs",
    "weidlich_wilkie": "^$",
    "albedo_scaling": "^$",
}


@settings(max_examples=40, deadline=None)
@given(
    stack=stacks(),
    model=st.sampled_from(["belcour", "steinberg", "weidlich_wilkie", "albedo_scaling"]),
    option=st.sampled_from(
        [{}, {"symmetric": True}, {"tir": "fraction"}, {"lut": "fitted"}, {"fresnel": "lazanyi"}, {"precomputed": True}]
    ),
)
def test_fuzz_no_nan_inf_or_negative(stack, model, option):
    option = {k: v for k, v in option.items() if k in lamina.catalogue.model(model).options}
    for dtype in (np.float64, np.float32):
        wi, wo = _special_directions(dtype)
        try:
            f = stack.eval(wi, wo, model, **option)
        except ValueError as e:  # a model that cannot represent the stack says so, in its own words
            assert re.search(REFUSALS[model], str(e)), (model, str(e))
            assume(False)  # hypothesis fails the test (health check) when most examples end here
        assert np.all(np.isfinite(f)) and np.all(f >= 0), (model, option, f[~np.isfinite(f) | (f < 0)])


def test_known_edge_cases_are_finite_and_zero_where_promised():
    # wi below the horizon with symmetric Belcour (was NaN), a slab of infinite optical depth (was NaN), a float32
    # grazing mirror pair with denormal z (was Inf), lazanyi at grazing (was −1e-17).
    assert np.all(Stack([Conductor(1.5, 3, 0.3)]).eval([1, 0, 0], [-1, 0, 0], "belcour", symmetric=True) == 0)
    slab = Stack([Dielectric(1.5, 0.2, thickness=1e10, sigma_s=1e300), Diffuse(0.5)])
    assert np.all(np.isfinite(slab.eval([0, 0, 1.0], [0.3, 0, 0.9], "belcour")))
    tiny = np.float32(1e-44)
    f = Stack([Conductor(1.5, 3, 0.0001)]).eval(
        np.array([0.6, 0, tiny], np.float32), np.array([-0.6, 0, tiny], np.float32)
    )
    assert f.dtype == np.float32 and np.all(np.isfinite(f))
    ww = lamina.materials.preset("coated-copper").eval(
        [0, 0, 1.0], [1.0, 0, 1e-300], "weidlich_wilkie", fresnel="lazanyi"
    )
    assert np.all(ww >= 0)
    # An index-matched conductor (η = 1, κ = 0: F = 0) at grazing cosines (was NaN and −1e-10 in the fuzz).
    matched = Stack([Conductor(1.0, 0.0, (0.3, 1e-6))])
    wi, wo = np.array([[0.2, -0.2, 2e-323], [0.5, 0.6, 0.4]]), np.array([[-0.16, -0.23, 0.36], [-0.5, -0.6, 0.4]])
    for model, opts in [
        ("microfacet", {"distribution": "beckmann"}),
        ("microfacet", {"g2": "separable"}),
        ("steinberg", {"lut": "fitted"}),
        ("weidlich_wilkie", {"precomputed": True}),
    ]:
        f = matched.eval(wi, wo, model, **opts)
        assert np.all(np.isfinite(f)) and np.all(f >= 0), (model, opts, f)


def test_empty_wavelengths_and_zero_rows_name_the_parameter():
    gold = Stack([lamina.materials.metal("Au", 0.2)])
    w = np.array([0.0, 0.0, 1.0])
    for call in (
        lambda: gold.eval(w, w, wavelengths=[]),
        lambda: gold.albedo(w, "reference", wavelengths=[]),
        lambda: gold.reference(w, w, wavelengths=[]),
    ):
        with pytest.raises(ValueError, match="wavelengths must be a non-empty"):
            call()
    for call in (
        lambda: gold.reference(np.zeros((0, 3)), np.zeros((0, 3))),
        lambda: gold.albedo(np.zeros((0, 3)), "reference"),
        lambda: gold.lobes(np.zeros((0, 3))),
    ):
        with pytest.raises(ValueError, match="at least one direction"):
            call()
    with pytest.raises(ValueError, match=r"outside the measured range .* of n of Au"):
        gold.eval(w, w, wavelengths=[100.0])


def test_output_too_large_raises_memory_error():
    gold = Stack([lamina.materials.metal("Au", 0.2)])
    with pytest.raises(MemoryError):
        gold.eval(np.zeros((10**6, 1, 3)) + (0, 0, 1), np.zeros((1, 10**6, 3)) + (0, 0, 1))


_THREADS_SCRIPT = """
import numpy as np, lamina, sys
rng = np.random.default_rng(1)
wi, wo, u = rng.normal(size=(20000, 3)), rng.normal(size=(20000, 3)), rng.random((20000, 3))
wi[:, 2], wo[:, 2] = abs(wi[:, 2]), abs(wo[:, 2])
out = [lamina.materials.suite(n).eval(wi, wo, m) for n in ("anisotropic-coat-metal", "varnished-diffuse")
       for m in ("belcour", "steinberg", "weidlich_wilkie")]
out += list(lamina.materials.suite("rough-coat-rough-copper").sample(wo, u, "belcour"))
out += list(lamina.materials.suite("rough-coat-rough-copper").sample(wo[:200], u[:200], "reference"))
sys.stdout.buffer.write(b"".join(np.ascontiguousarray(a).tobytes() for a in out))
"""


def test_results_do_not_depend_on_the_thread_count():
    outs = [
        subprocess.run(
            [sys.executable, "-c", _THREADS_SCRIPT],
            capture_output=True,
            check=True,
            env={**os.environ, "RAYON_NUM_THREADS": n},
        ).stdout
        for n in ("1", "2")
    ]
    assert len(outs[0]) > 0 and outs[0] == outs[1]


def test_stacks_are_values_that_pickle(rng):
    n, k = lamina.spectrum.ior("Cu")
    stack = Stack(
        [Dielectric(1.5, (0.1, 0.3), angle=0.4, thickness=1.0, sigma_a=[0.1, 0.2, 0.3]), Conductor(n, k, 0.2)]
    )
    same = Stack([Dielectric(1.5, [0.1, 0.3], angle=0.4, thickness=1.0, sigma_a=(0.1, 0.2, 0.3)), Conductor(n, k, 0.2)])
    assert stack == same and hash(stack) == hash(same) and len({stack, same}) == 1
    assert stack != Stack([Dielectric(1.5, (0.1, 0.3), angle=0.4), Conductor(n, k, 0.2)])
    back = pickle.loads(pickle.dumps(stack))
    assert back == stack and hash(back) == hash(stack)
    wi, wo = rng.normal(size=(100, 3)), rng.normal(size=(100, 3))
    wi[:, 2], wo[:, 2] = np.abs(wi[:, 2]), np.abs(wo[:, 2])
    assert np.array_equal(back.eval(wi, wo, "belcour"), stack.eval(wi, wo, "belcour"))
    spectral = Stack([Dielectric(1.5, 0.2, thickness=1.0, sigma_a=0.3), Conductor(n, k, 0.2)])
    wl = np.linspace(400, 700, 7)
    again = pickle.loads(pickle.dumps(spectral))
    assert np.array_equal(
        again.eval(wi, wo, "belcour", wavelengths=wl), spectral.eval(wi, wo, "belcour", wavelengths=wl)
    )
    patina = lamina.materials.patina()
    again = pickle.loads(pickle.dumps(patina))
    assert np.array_equal(again.eval(wi, wo, 0.4), patina.eval(wi, wo, 0.4)) and "Patina(extent=0.5" in repr(patina)


def test_ctrl_c_stops_a_long_evaluation():
    code = (
        "import numpy as np, lamina, sys\n"
        "w = np.broadcast_to(np.array([0.3, 0.1, 0.9]), (60_000_000, 3))\n"
        "s = lamina.materials.suite('three-layer'); s.eval(w[:10], w[:10], 'steinberg')\n"
        "print('ready', flush=True); s.eval(w, w, 'steinberg')\n"
    )
    # The child starts with SIGINT at its default: a shell's background job (`make test &`) ignores SIGINT, a child
    # would inherit that, and Python installs no KeyboardInterrupt handler for an ignored signal.
    p = subprocess.Popen(
        [sys.executable, "-c", code],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )
    assert p.stdout.readline().strip() == "ready"
    time.sleep(1.0)
    start = time.perf_counter()
    p.send_signal(signal.SIGINT)
    try:
        _, err = p.communicate(timeout=20)
    finally:
        p.kill()
    assert "KeyboardInterrupt" in err and time.perf_counter() - start < 5, err[-500:]
