"""The float32 engine (src/engine): float32 directions are evaluated in float32 lanes by the models that have a lane
kernel (`microfacet`'s rough GGX conductor, `tabulated`, `belcour`'s interpolated table, the single-pass walks of
`steinberg` and `weidlich_wilkie`, `albedo_scaling`, and the improved variants' transport_fit after their model's own
kernel); float64 directions keep the float64 path. Here the float32 result is held to the
float64 one on the same float32 inputs, on the suite, the held-out population and the fuzz's extreme stacks and pairs.

The bound (issue "Engine"): relative 1e-5 where f ≥ 1e-3 of the peak, absolute 1e-8 of the peak elsewhere, and 0 below
the horizon on both paths. A float32 unit direction is unit only to its rounding (±3e-8 per component), and a GGX
lobe's half vector h = wi + wo magnifies that by 1/|h| and its value by 1/α: the float64 path normalises exactly, and
no float32 representation of the directions can. Where the top's lobe is rough, the 1e-5 holds; for sharp lobes and
nearly opposite pairs the measured relative error follows 4e-7 / (α |wi + wo|) (α = 0.01: 1.6e-5 at |h| ≥ 1,
5.5e-5 at |h| ≈ 0.3; α = 0.05: 2.0e-5 at |h| ≈ 0.2), which is the bound asserted there (`_conditioning`). A table's
coordinates are float32 too: at grazing angles, where a table changes steeply from node to node, their rounding
(2e-6 of a node) moves f by up to 1.2e-5 (measured, held-out population); that is bounded by four times the float64
result's own change when the directions move by their float32 rounding (`_sensitivity`).
"""

from __future__ import annotations

import sys
from pathlib import Path

import lamina
import numpy as np
import pytest
from conftest import random_hemisphere
from lamina.materials import SUITE, metal, population, suite

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "scripts"))
import fuzz  # noqa: E402

ISOTROPIC = [name for name in SUITE if name != "anisotropic-coat-metal"]
#: Models with a lobe of every interface's roughness (`_conditioning`).
WALKS_EVERY_LAYER = ("belcour", "steinberg", "weidlich_wilkie", "albedo_scaling")


def _conditioning(stack, wi, wo, model="") -> np.ndarray:
    """The relative error float32 directions allow in a GGX lobe of the top boundary, per pair: 4e-7 / (α |wi + wo|)
    with α the top's smaller roughness (at least Microfacet's MIN_ALPHA, 1e-4); 0 for a smooth or diffuse top.
    `belcour`'s lobes carry the roughness of every interface, and `steinberg` adds a lobe at every interface: there α
    is the smallest of any rough layer, whose lobe (for belcour anisotropic, with its small eigenvalue taken from
    float32 roughness matrices) is as sharp as that."""
    interfaces = [layer for layer in stack.layers if isinstance(layer, (lamina.Dielectric, lamina.Conductor))]
    if model in WALKS_EVERY_LAYER:
        rough = [a for layer in interfaces for a in np.atleast_1d(layer.roughness) if a > 0]
    else:
        top = np.atleast_1d(stack.layers[0].roughness) if stack.layers[0] in interfaces else np.zeros(1)
        rough = list(top) if top.max() > 0 else []
    if not rough:
        return np.zeros(len(wi))
    h = np.linalg.norm(
        wi.astype(np.float64) / np.linalg.norm(wi, axis=-1, keepdims=True)
        + wo.astype(np.float64) / np.linalg.norm(wo, axis=-1, keepdims=True),
        axis=-1,
    )
    return 4e-7 / (max(min(rough), 1e-4) * np.maximum(h, 1e-30))


def _sensitivity(stack, model, wi, wo, **options) -> np.ndarray:
    """The largest change of the float64 result when every component of the directions moves by up to one float32
    ulp (two random perturbations)."""
    rng = np.random.default_rng(7)
    f = stack.eval(wi.astype(np.float64), wo.astype(np.float64), model, **options)
    worst = np.zeros_like(f)
    for _ in range(2):
        bumped = [w.astype(np.float64) * (1 + rng.uniform(-1, 1, w.shape) * 2.0**-23) for w in (wi, wo)]
        worst = np.maximum(worst, np.abs(stack.eval(*bumped, model, **options) - f))
    return worst


def _compare(stack, model, wi, wo, **options) -> float:
    """Asserts the bound (with `_conditioning`); returns the worst relative error where f ≥ 1e-3 of the peak."""
    a = stack.eval(wi, wo, model, **options)
    assert a.dtype == np.float32
    a = a.astype(np.float64)
    b = stack.eval(wi.astype(np.float64), wo.astype(np.float64), model, **options)
    below = (wi[..., 2] <= 0) | (wo[..., 2] <= 0)
    assert (a[below] == 0).all() and (b[below] == 0).all(), "f is 0 below the horizon on both paths"
    peak = b.max()
    if peak == 0:
        assert (a == 0).all()
        return 0.0
    big = b >= 1e-3 * peak
    rel = np.maximum(1e-5, _conditioning(stack, wi, wo, model))[:, None]
    # Below 1e-12 the float64 path's own rounding (of a Fresnel term that vanishes, η = 1, κ = 0) is compared
    # absolutely.
    bound = np.maximum(np.where(big, rel * b, np.maximum(1e-8, rel) * peak), 1e-12)
    err = np.abs(a - b)
    if (err > bound).any():
        bound += 4 * _sensitivity(stack, model, wi, wo, **options)
    bad = err > bound
    assert not bad.any(), f"{stack!r} {model}: f32 {a[bad][:3]} vs f64 {b[bad][:3]}"
    return float((err[big] / b[big]).max()) if big.any() else 0.0


def _directions(n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    return random_hemisphere(rng, n).astype(np.float32), random_hemisphere(rng, n).astype(np.float32)


@pytest.mark.parametrize("name", SUITE)
def test_tabulated_in_float32_is_within_1e5_of_float64_on_the_suite(name):
    # Measured: 7.0e-6 at most on these pairs (7.7e-6 on docs/benchmarks.md's 100,000); the anisotropic coat 7.9e-6.
    wi, wo = _directions(20_000, 1)
    assert _compare(suite(name), "tabulated", wi, wo) <= 1e-5


@pytest.mark.parametrize("options", [{}, {"symmetric": True}, {"g2": "separable"}])
@pytest.mark.parametrize("name", SUITE)
def test_belcour_in_float32_is_within_1e5_of_float64_on_the_suite(name, options):
    # The interpolated table read in float32 lanes, the anisotropic coat's roughness matrices eigen-decomposed there.
    # Measured on these pairs: 8.1e-6 at most (the anisotropic coat), 5e-6 on the isotropic stacks.
    wi, wo = _directions(20_000, 1)
    assert _compare(suite(name), "belcour", wi, wo, **options) <= 1e-5


def test_belcour_on_the_held_out_population_and_the_fuzz_in_float32():
    # The held-out population (seed 2, anisotropic stacks included) and the fuzz's extreme stacks and pairs, with the
    # bounds of `_compare`; no NaN, Inf or negative value on the fuzz's pairs.
    def represented(stack) -> bool:
        try:
            stack.eval([0, 0, 1.0], [0, 0, 1.0], "belcour")
        except ValueError as e:
            assert "Lambertian diffuse base" in str(e)  # the one stack belcour refuses, and says so
            return False
        return True

    wi, wo = _directions(5_000, 4)
    checked = [_compare(s, "belcour", wi, wo) for _, s in population(8, seed=2) if represented(s)]
    assert len(checked) >= 4
    rng = np.random.default_rng(5)
    for _ in range(40):
        stack = fuzz.random_stack(rng)
        wi, wo = fuzz.directions(rng, 2000, np.float32)
        if not represented(stack):
            continue
        f = stack.eval(wi, wo, "belcour")
        assert np.isfinite(f).all() and (f >= 0).all()
        _compare(stack, "belcour", wi, wo)


@pytest.mark.parametrize("options", [{}, {"microfacet_transmission": True}, {"g2": "separable", "eta2": False}])
@pytest.mark.parametrize("name", SUITE)
def test_steinberg_in_float32_is_within_1e5_of_float64_on_the_suite(name, options):
    # The single-pass walk in float32 lanes, each coat's table sliced at its α and η (the anisotropic coat's at its η
    # over (μ, α), read at each direction's projected roughness). Measured on these pairs with the default options:
    # 8.5e-6 at most (the anisotropic coat), 4.7e-6 on the isotropic stacks.
    wi, wo = _directions(20_000, 1)
    assert _compare(suite(name), "steinberg", wi, wo, **options) <= 1e-5


@pytest.mark.parametrize("options", [{}, {"distribution": "ggx"}, {"eta2": False}])
@pytest.mark.parametrize("name", SUITE)
def test_weidlich_wilkie_in_float32_is_within_1e5_of_float64_on_the_suite(name, options):
    # The walk in float32 lanes with V-cavity lobes of Beckmann (or GGX) normals. Measured on these pairs with the
    # default options: 5.4e-6 at most on the isotropic stacks, 1.7e-5 on the anisotropic coat (a nearly opposite pair,
    # |wi + wo| = 0.16, within its conditioning 4e-7 / (α |wi + wo|) = 2.5e-5).
    wi, wo = _directions(20_000, 1)
    worst = _compare(suite(name), "weidlich_wilkie", wi, wo, **options)
    assert name == "anisotropic-coat-metal" or worst <= 1e-5


@pytest.mark.parametrize("options", [{}, {"scaling": "view"}, {"roughening": False, "g2": "height_correlated"}])
@pytest.mark.parametrize("name", SUITE)
def test_albedo_scaling_in_float32_is_within_1e5_of_float64_on_the_suite(name, options):
    # The lobes in lanes, 1 − E from the FGD table sliced in μ at each interface's α, η and κ. Measured on these pairs
    # with the default options: 8.5e-6 at most (three-layer), 3.4e-6 on rough-coat-rough-copper. Without the
    # roughening, frosted metal's base keeps its α = 0.02: within that lobe's conditioning (`_compare`), 1.9e-5.
    wi, wo = _directions(20_000, 1)
    worst = _compare(suite(name), "albedo_scaling", wi, wo, **options)
    assert (name == "frosted-metal" and "roughening" in options) or worst <= 1e-5


@pytest.mark.parametrize("model", ["belcour", "steinberg", "weidlich_wilkie"])
@pytest.mark.parametrize("name", ISOTROPIC)
def test_the_improved_variants_in_float32_are_within_1e5_of_float64_on_the_suite(name, model):
    # The model's own lanes, then transport_fit's s f + a in lanes, its zenith nodes counted from the nearer end
    # (`zenith_node_lanes`: from the normal, the grazing fit moved by 3e-5). Measured on these pairs: 8.9e-6 at most
    # (three-layer), varnished diffuse 9e-7; weidlich_wilkie's three-layer 1.15e-5, as its published variant's
    # (the Beckmann tail's conditioning, docs/benchmarks.md "float32 engine").
    wi, wo = _directions(20_000, 1)
    worst = _compare(suite(name), model, wi, wo, variant="improved")
    assert worst <= (2e-5 if model == "weidlich_wilkie" else 1e-5)


@pytest.mark.parametrize("model", ["steinberg", "weidlich_wilkie", "albedo_scaling"])
def test_the_walks_on_the_held_out_population_and_the_fuzz_in_float32(model):
    # As belcour's: the held-out population and the fuzz's extreme stacks and pairs within `_compare`'s bounds, no
    # NaN, Inf or negative value.
    wi, wo = _directions(5_000, 4)
    for _, stack in population(8, seed=2):
        _compare(stack, model, wi, wo)
    rng = np.random.default_rng(5)
    for _ in range(40):
        stack = fuzz.random_stack(rng)
        wi, wo = fuzz.directions(rng, 2000, np.float32)
        try:
            f = stack.eval(wi, wo, model)
        except ValueError:
            continue  # an IOR outside Steinberg's tables, which it names
        assert np.isfinite(f).all() and (f >= 0).all()
        _compare(stack, model, wi, wo)


@pytest.mark.parametrize(
    "distribution,g2",
    [
        ("ggx", "separable"),
        ("ggx", "height_correlated"),
        ("beckmann", "separable"),
        ("beckmann", "height_correlated"),
        ("beckmann", "v_cavity"),
    ],
)
@pytest.mark.parametrize("material", ["Au", "Cu", "Al"])
def test_the_rough_conductor_in_float32_is_within_1e5_of_float64(material, distribution, g2):
    # Roughness 0.1–1, isotropic, anisotropic and rotated: 1e-5 on every pair for GGX (measured: 6.9e-6 at most on
    # these pairs, 1.06e-5 for roughness (0.1, 0.5) on docs/benchmarks.md's 100,000: at the bound). Beckmann's
    # D = exp(−q) / …, q = tan²θh / α², turns the float32 rounding of its exponent (a few ulp of q) into a relative
    # error of about q · 3e-7, q ≈ 30 on the lobe's flanks still above 1e-3 of the peak: 1.5e-5 (measured 1.004e-5,
    # its Smith Λ from the lanes' erfc; `_compare` holds every pair to the float64 model's own conditioning).
    wi, wo = _directions(20_000, 2)
    worst = 0.0
    for roughness in [0.1, 0.3, 1.0, (0.1, 0.5)]:
        stack = lamina.Stack([metal(material, roughness, angle=0.3)])
        worst = max(worst, _compare(stack, "microfacet", wi, wo, distribution=distribution, g2=g2))
    assert worst <= (1e-5 if distribution == "ggx" else 1.5e-5)


@pytest.mark.parametrize("roughness", [1e-3, 0.01, 0.05, (0.05, 0.5)])
def test_a_sharp_lobe_is_within_its_conditioning(roughness):
    # The bound 4e-7 / (α |wi + wo|) where it exceeds 1e-5 (module docstring). Measured worst relative error:
    # 5.6e-5 (α = 1e-3), 4.3e-5 (α = 0.01), 1.7e-5 (α = 0.05), 2.1e-5 ((0.05, 0.5)).
    wi, wo = _directions(50_000, 3)
    _compare(lamina.Stack([metal("Cu", roughness, angle=0.3)]), "microfacet", wi, wo)


def test_the_held_out_population_in_float32():
    # The first 8 stacks of the held-out population (seed 2) under `tabulated` (their single-metal members are
    # `microfacet`'s exact conductor). Measured: 1.2e-5 at most (a grazing wo, module docstring).
    wi, wo = _directions(5_000, 4)
    worst = 0.0
    for _, stack in population(8, seed=2):
        worst = max(worst, _compare(stack, "tabulated", wi, wo))
    assert worst <= 2e-5


def test_the_fuzz_stacks_and_pairs_in_float32():
    # The fuzz's extremes (roughness 0, 1e-6 and 1, IORs near 1, κ = 0, ext_ior 1.33; directions at the normal, at
    # grazing, denormal zeniths, mirror pairs, below the horizon), with the bound of their top's conditioning.
    rng = np.random.default_rng(5)
    for _ in range(40):
        stack = fuzz.random_stack(rng)
        wi, wo = fuzz.directions(rng, 2000, np.float32)
        single = lamina.Stack(stack.layers[-1:], ext_ior=stack.ext_ior)
        for s, model in [(single, "microfacet"), (stack, "tabulated")]:
            try:
                s.eval([0, 0, 1.0], [0, 0, 1.0], model)
            except ValueError:
                continue  # the model cannot represent this stack, and says so
            f = s.eval(wi, wo, model)
            assert np.isfinite(f).all() and (f >= 0).all()
            _compare(s, model, wi, wo)


def test_float32_directions_need_not_be_unit_length():
    # The engine normalises in lanes: directions scaled by 1e-3 and 1e3 give the unit directions' f (within the
    # float32 normalisation's rounding; measured 3e-6 apart at most).
    wi, wo = _directions(10_000, 6)
    for stack, model in [(lamina.Stack([metal("Au", 0.3)]), "microfacet"), (suite("gold-clearcoat"), "tabulated")]:
        f = stack.eval(wi, wo, model)
        for scale in [np.float32(1e-3), np.float32(1e3)]:
            g = stack.eval(wi * scale, wo / scale, model)
            assert np.allclose(g, f, rtol=1e-5, atol=1e-8 * f.max())


@pytest.mark.parametrize("bad", [np.nan, np.inf, 0.0])
def test_a_bad_float32_row_raises_what_float64_raises(bad):
    # A row the engine does not take sends the call to the careful path, which names the input and the row.
    wi, wo = _directions(100, 8)
    wi[57] = (bad, 0.0, 0.0) if bad != 0 else (0.0, 0.0, 0.0)
    _same_error_in_both_dtypes(lamina.Stack([metal("Au", 0.3)]).eval, "row 57", wi, wo)


def _same_error_in_both_dtypes(call, match: str, *arrays):
    """call(*arrays) raises a ValueError matching `match`, the same message with float32 and with float64 arrays."""
    messages = []
    for dtype in (np.float32, np.float64):
        with pytest.raises(ValueError, match=match) as e:
            call(*(a.astype(dtype) for a in arrays))
        messages.append(str(e.value))
    assert messages[0] == messages[1]


def test_broadcast_and_strided_float32_inputs_give_the_packed_result():
    # One broadcast direction (stride 0) is splat in lanes; a strided view takes the careful path: same values.
    wi, wo = _directions(1000, 9)
    stack = lamina.Stack([metal("Cu", 0.2)])
    packed = stack.eval(np.repeat(wi[:1], 1000, axis=0), wo)
    assert np.array_equal(stack.eval(wi[0], wo), packed)
    strided = np.zeros((1000, 6), np.float32)
    strided[:, ::2] = wo
    f = stack.eval(wi, strided[:, ::2])
    assert np.allclose(f, stack.eval(wi, wo), rtol=2e-6)


@pytest.mark.parametrize(
    "model,options",
    [
        ("belcour", {}),
        ("steinberg", {}),
        ("weidlich_wilkie", {"distribution": "ggx"}),
        ("weidlich_wilkie", {}),
        ("albedo_scaling", {}),
        ("tabulated", {}),
    ],
)
def test_float32_sample_weights_carry_the_float32_f(model, options):
    # For float32 inputs `Stack.sample` of a layered model samples in lanes (models/common/mixture_lanes.rs: belcour,
    # steinberg, weidlich_wilkie with GGX or Beckmann interfaces, albedo_scaling, tabulated). Each weight is
    # `eval`'s float32 f at the returned wi times cos θi / pdf, to the float32 rounding of the stored weight, wi and
    # pdf (1e-6), and of wo, which the sampler normalises in float64 first (`_conditioning`). Against float64 from
    # the same u: the same samples kept, wi within 4e-6 of the float64 sampler's (measured 3.6e-6; Beckmann's slopes,
    # a root of their CDF found to its float32 rounding, which the density's tails magnify (optics/lanes.rs
    # `beckmann_slopes`): 99% within 1e-5, all within 2e-4, measured 3.3e-6 and 3.2e-5), the pdf within
    # 1e-5 of the float64 pdf at the returned wi (measured 4.7e-6), and each weight within `_compare`'s bound of the
    # float64 model's f cos θi / pdf at the returned wi (measured 1.1e-6 in lanes, 6.4e-6 at most; a grazing wi's
    # float32 rounding alone moves the weight by up to 2.8e-3 from the float64 sampler's own, which is why the
    # float64 side is evaluated at the float32 direction).
    stack = suite("rough-coat-rough-copper")
    rng = np.random.default_rng(12)
    wo = random_hemisphere(rng, 20_000).astype(np.float32)
    u = rng.random((20_000, 3)).astype(np.float32)
    wi, weight, pdf = stack.sample(wo, u, model, **options)
    assert weight.dtype == np.float32
    valid = pdf > 0
    assert valid.mean() > 0.5 and (weight[~valid] == 0).all()
    f = stack.eval(wi[valid], wo[valid], model, **options).astype(np.float64)
    expected = f * wi[valid, 2:3].astype(np.float64) / pdf[valid, None]
    bound = np.maximum(1e-6, 2 * _conditioning(stack, wi[valid], wo[valid], model))[:, None]
    big = expected >= 1e-3 * expected.max()
    err = np.abs(weight[valid].astype(np.float64) - expected)
    assert (err <= np.where(big, bound * expected, 1e-8 * expected.max())).all()
    wi64, _, pdf64 = stack.sample(wo.astype(np.float64), u.astype(np.float64), model, **options)
    assert np.array_equal(valid, pdf64 > 0)
    gap = np.abs(wi[valid] - wi64[valid]).max(axis=-1)
    if model == "weidlich_wilkie" and not options:
        assert np.quantile(gap, 0.99) <= 1e-5 and gap.max() <= 2e-4
    else:
        assert gap.max() <= 4e-6
    wi_, wo_ = wi[valid].astype(np.float64), wo[valid].astype(np.float64)
    pdf_at = stack.pdf(wi_, wo_, model, **options)
    assert np.allclose(pdf[valid], pdf_at, rtol=1e-5, atol=0)
    weight64 = stack.eval(wi_, wo_, model, **options) * wi_[:, 2:3] / pdf_at[:, None]
    big = weight64 >= 1e-3 * weight64.max()
    rel = np.maximum(1e-5, 2 * _conditioning(stack, wi[valid], wo[valid], model))[:, None]
    err = np.abs(weight[valid] - weight64)
    assert (err <= np.where(big, rel * weight64, 1e-8 * weight64.max()) + 1e-7 * weight64).all()


@pytest.mark.parametrize("distribution", ["ggx", "beckmann"])
@pytest.mark.parametrize("roughness", [0.01, 0.05, 0.3, 1.0, (0.1, 0.5)])
def test_the_rough_conductors_float32_sampler_draws_the_float64_samples(roughness, distribution):
    # `microfacet`'s float32 sampler (visible normals in lanes, optics/lanes.rs ggx_sample_reflection) draws, from the
    # same u, the float64 sampler's samples to float32. Where the visible-normal map is singular (the disk's rim) its
    # float32 arithmetic moves wi: 99.9% of the wi within 2e-5 of float64's (measured 1.3e-5 at α = 0.01, 1.6e-6 at
    # α ≥ 0.1). The pdf follows D(m): within 1e-5 + 4e-7 / α² (measured 1.6e-3 at α = 0.01, 3e-6 at α = 0.3).
    # Beckmann (beckmann_sample_reflection): its slopes are a root of their CDF found to float32's rounding, which
    # the density's tails magnify: 99.9% within 1e-4 (measured 4.1e-5 at α = 1, 5e-7 at α = 0.01); its pdf, whose
    # exponential would magnify that move, is compared with float64's at the returned wi, within the same bound
    # (measured 9.1e-4 at α = 0.01, 2.9e-6 at α = 1). Each
    # weight is the float32 f of `eval` at its wi times cos θi / pdf within `_conditioning` (a grazing wi's cosine
    # magnifies float32's rounding of wi); the mean weight (the albedo's estimate) is float64's within 1e-4
    # (measured 5.6e-5).
    stack = lamina.Stack([metal("Au", roughness, angle=0.3)])
    rng = np.random.default_rng(13)
    wo = random_hemisphere(rng, 50_000).astype(np.float32)
    u = rng.random((50_000, 3)).astype(np.float32)
    wi, weight, pdf = stack.sample(wo, u, distribution=distribution)
    wi64, weight64, pdf64 = stack.sample(wo.astype(np.float64), u.astype(np.float64), distribution=distribution)
    assert wi.dtype == weight.dtype == pdf.dtype == np.float32
    assert np.array_equal(pdf > 0, pdf64 > 0)
    kept = pdf > 0
    alpha = min(np.atleast_1d(roughness))
    gap = np.abs(wi[kept] - wi64[kept]).max(axis=-1)
    if distribution == "ggx":
        assert np.quantile(gap, 0.999) <= 2e-5
        assert np.allclose(pdf[kept], pdf64[kept], rtol=1e-5 + 4e-7 / alpha**2, atol=0)
    else:
        assert np.quantile(gap, 0.999) <= 1e-4
        pdf_at = stack.pdf(wi[kept].astype(np.float64), wo[kept].astype(np.float64), distribution=distribution)
        assert np.allclose(pdf[kept], pdf_at, rtol=1e-5 + 4e-7 / alpha**2, atol=0)
    assert (weight[~kept] == 0).all()
    f = stack.eval(wi[kept], wo[kept], distribution=distribution).astype(np.float64)
    expected = f * wi[kept, 2:3] / pdf[kept, None]
    bound = np.maximum(1e-5, 4 * _conditioning(stack, wi[kept], wo[kept]))[:, None]
    assert (np.abs(weight[kept] - expected) <= bound * expected + 1e-8 * expected.max()).all()
    assert np.allclose(weight.mean(axis=0), weight64.mean(axis=0), rtol=1e-4)


def test_the_float32_sampler_below_the_horizon_and_on_bad_u():
    # A wo below the horizon samples the normal with weight and pdf 0, as the float64 sampler; a u outside [0, 1]
    # sends the call to the float64 path, which names it.
    stack = lamina.Stack([metal("Cu", 0.2)])
    wo = np.array([[0.3, 0.0, -0.9], [0.0, 0.6, 0.8]], np.float32)
    u = np.full((2, 3), 0.4, np.float32)
    wi, weight, pdf = stack.sample(wo, u)
    assert (wi[0] == [0, 0, 1]).all() and (weight[0] == 0).all() and pdf[0] == 0 and pdf[1] > 0
    u[1, 2] = 1.5
    _same_error_in_both_dtypes(stack.sample, "u", wo, u)
