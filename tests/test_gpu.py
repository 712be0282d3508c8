"""The wgpu path against the CPU: every microfacet configuration, and Belcour, Steinberg, Weidlich–Wilkie, albedo
scaling and tabulated on the suite with their options (variant="improved", lamina's transport_fit, included), random
stacks, spectral and dispersive channels and inputs longer than one
dispatch agree to 1e-4 relative on values above 1e-6 of the peak (the issue's criterion; the float32 shader against
the float64 core measures about 1e-5 at worst), plus where f is ill-conditioned in float32 what 4-ulp changes of the
inputs alone move the float64 result by. Runs on whatever adapter wgpu finds: lavapipe in CI (make test installs it
when root). Without an adapter these tests fail, saying how to get one, unless LAMINA_SKIP_GPU=1."""

import os

import faults
import lamina
import numpy as np
import pytest
from conftest import uv_sphere_mesh
from hypothesis import assume, example, given, settings
from hypothesis import strategies as st
from lamina import gpu, materials

if gpu.adapter() is None:
    why = gpu._adapter()[1]
    if os.environ.get("LAMINA_SKIP_GPU") == "1":
        pytest.skip(f"LAMINA_SKIP_GPU=1: GPU parity tests not run ({why})", allow_module_level=True)
    raise RuntimeError(f"no GPU adapter for the parity tests: {why}")

RTOL = 1e-4


def _directions(n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """n pairs over the whole sphere (a quarter below the horizon on either side), not unit length."""
    rng = np.random.default_rng(seed)
    wi, wo = rng.normal(size=(2, n, 3)) * rng.uniform(0.5, 2.0, (2, n, 1))
    wi[: n // 2, 2] = np.abs(wi[: n // 2, 2])
    wo[n // 4 :, 2] = np.abs(wo[n // 4 :, 2])
    return wi, wo


def float32_conditioning(stack, wi, wo, model, wavelengths, options, seed) -> np.ndarray:
    """How far the float64 result itself moves when every input component (directions and per-element inputs) moves
    by 4 float32 ulps (the most of 4 random draws), relative to it: what any float32 evaluation may differ by on top
    of RTOL. About 1e-6 almost everywhere; up to ~1e-3 where f has an infinite slope, e.g. a Fresnel factor at the
    critical angle (η < 1)."""
    rng = np.random.default_rng(seed + 1)
    cpu = stack.eval(wi, wo, model, wavelengths=wavelengths, **options)
    spread = np.zeros_like(cpu)
    for _ in range(4):
        nudge = lambda w: w * (1 + 4 * np.finfo(np.float32).eps * rng.uniform(-1, 1, w.shape))  # noqa: E731
        # The per-element inputs (arrays among the options) are rounded to float32 too.
        moved_options = {k: nudge(v) if isinstance(v, np.ndarray) else v for k, v in options.items()}
        moved = stack.eval(nudge(wi), nudge(wo), model, wavelengths=wavelengths, **moved_options)
        spread = np.maximum(spread, np.abs(moved - cpu) / np.maximum(np.abs(cpu), 1e-300))
    return spread


def assert_parity(stack, model="microfacet", n=20_000, seed=0, wavelengths=None, **options):
    wi, wo = _directions(n, seed)
    cpu = stack.eval(wi, wo, model, wavelengths=wavelengths, **options)
    out = stack.eval(wi, wo, model, wavelengths=wavelengths, device="gpu", **options)
    assert out.dtype == np.float32 and out.shape == cpu.shape
    big = cpu > 1e-6 * cpu.max()
    rel = np.abs(out[big] - cpu[big]) / cpu[big]
    allowed = RTOL + float32_conditioning(stack, wi, wo, model, wavelengths, options, seed)[big]
    worst = np.argmax(rel - allowed)
    assert rel[worst] <= allowed[worst], f"relative difference {rel[worst]:.2e} > {allowed[worst]:.2e} at {worst}"
    assert np.median(allowed) < 2 * RTOL  # the bulk of the values stays well conditioned: no blanket loosening
    assert np.all(np.abs(out[~big]) <= 2e-6 * cpu.max())  # zeros (below the horizon) stay zero
    assert cpu.max() > 0


@pytest.mark.parametrize("material", ["gold", "brushed-aluminium", "chromium", "clay", "red-plastic"])
@pytest.mark.parametrize("g2", ["separable", "height_correlated", "v_cavity"])
def test_microfacet_presets(material, g2):
    assert_parity(materials.preset(material), g2=g2)


@pytest.mark.parametrize("options", [{"distribution": "beckmann"}, {"fresnel": "schlick"}, {"fresnel": "lazanyi"}])
def test_microfacet_options(options):
    assert_parity(materials.preset("brushed-aluminium"), **options)


def test_spectral_channels():
    assert_parity(materials.preset("gold"), wavelengths=np.arange(400.0, 701.0, 10.0))
    assert_parity(materials.preset("coated-copper"), "belcour", wavelengths=np.arange(400.0, 701.0, 20.0))


@pytest.mark.parametrize("material", sorted(materials.SUITE) + ["car-paint"])
def test_belcour_suite(material):
    stack = materials.car_paint() if material == "car-paint" else materials.suite(material)
    assert_parity(stack, "belcour")


@pytest.mark.parametrize(
    "options",
    [
        {"symmetric": True},
        {"g2": "separable"},
        {"g2": "v_cavity"},
        {"energy": "fresnel"},
        {"cosines": "real", "jacobian": "j21"},
        {"tir": "fraction"},
        {"microfacet_transmission": True},
    ],
)
@pytest.mark.parametrize("material", ["anisotropic-coat-metal", "varnished-diffuse", "three-layer"])
def test_belcour_options(material, options):
    assert_parity(materials.suite(material), "belcour", **options)


@pytest.mark.parametrize("model", ["steinberg", "weidlich_wilkie", "albedo_scaling"])
@pytest.mark.parametrize("material", sorted(materials.SUITE) + ["car-paint"])
def test_layered_models_on_the_suite(material, model):
    stack = materials.car_paint() if material == "car-paint" else materials.suite(material)
    assert_parity(stack, model)


@pytest.mark.parametrize(
    "model,options",
    [
        ("steinberg", {"lut": "fitted"}),
        ("steinberg", {"fresnel": "schlick", "g2": "v_cavity"}),
        ("steinberg", {"clamp_roughness": False, "eta2": False}),
        ("steinberg", {"interreflection": True}),
        ("steinberg", {"microfacet_transmission": True}),
        ("steinberg", {"interreflection": True, "conductor_interreflection": True, "lut": "fitted"}),
        ("steinberg", {"conductor_interreflection": True, "eta2": False}),
        ("weidlich_wilkie", {"precomputed": True}),
        ("weidlich_wilkie", {"interreflection": True}),
        ("weidlich_wilkie", {"conductor_interreflection": True, "precomputed": True}),
        ("weidlich_wilkie", {"distribution": "ggx", "g2": "height_correlated", "fresnel": "lazanyi"}),
        ("weidlich_wilkie", {"clamp_roughness": False, "eta2": False, "interreflection": True}),
        ("albedo_scaling", {"scaling": "view", "roughening": False}),
        ("albedo_scaling", {"g2": "height_correlated"}),
    ],
)
@pytest.mark.parametrize("material", ["anisotropic-coat-metal", "varnished-diffuse", "three-layer"])
def test_layered_model_options(material, model, options):
    assert_parity(materials.suite(material), model, **options)


ISOTROPIC = [m for m in sorted(materials.SUITE) if m != "anisotropic-coat-metal"]  # what tabulated takes


@pytest.mark.parametrize("material", ISOTROPIC + ["gold"])
def test_tabulated_on_the_suite(material):
    """The adding-doubling table interpolated in float32 (a single layer runs as microfacet), measured ≤ 3.4e-5."""
    stack = materials.preset(material) if material in materials.PRESETS else materials.suite(material)
    assert_parity(stack, "tabulated")


@pytest.mark.parametrize("model", ["belcour", "steinberg", "weidlich_wilkie"])
@pytest.mark.parametrize("material", sorted(materials.SUITE))
def test_improved_variants_on_the_suite(material, model):
    """transport_fit's s f + a after the model's own f (an anisotropic stack keeps the published model, as on the
    CPU): the GPU applies the CPU's fit, so parity holds as for the published models."""
    assert_parity(materials.suite(material), model, variant="improved")


@settings(max_examples=8, deadline=None)
@given(
    model=st.sampled_from(["tabulated", "belcour", "steinberg", "weidlich_wilkie"]),
    ior=st.floats(1.05, 2.5),
    coat=st.one_of(st.just(0.0), st.floats(0.05, 0.8)),
    sigma_a=st.floats(0.0, 2.0),
    base=st.floats(0.05, 0.9),
    seed=st.integers(0, 1000),
)
def test_random_isotropic_stacks_tabulated_and_improved(model, ior, coat, sigma_a, base, seed):
    """Random isotropic stacks (what the adding-doubling solver takes; α ≥ 0.05 keeps the table's lobes resolved)."""
    stack = lamina.Stack(
        [
            lamina.Dielectric(ior, coat, thickness=1.0, sigma_a=sigma_a),
            lamina.Conductor((0.2, 0.9, 1.1), (3.0, 2.6, 2.3), base),
        ]
    )
    options = {} if model == "tabulated" else {"variant": "improved"}
    assert_parity(stack, model, n=2000, seed=seed, **options)


def test_layered_models_spectral_and_dispersive():
    """Spectral channels, and a dispersive coat (an IOR per channel: one pass per channel on the CPU too)."""
    wl = np.arange(400.0, 701.0, 20.0)
    for model in ("steinberg", "weidlich_wilkie", "albedo_scaling"):
        assert_parity(materials.preset("coated-copper"), model, wavelengths=wl)
        dispersive = lamina.Stack(
            [
                lamina.Dielectric((1.45, 1.5, 1.6), 0.2, thickness=0.5, sigma_a=(0.1, 0.3, 0.6)),
                lamina.Diffuse((0.6, 0.4, 0.2), roughness=0.3),
            ]
        )
        assert_parity(dispersive, model)


def _inputs(n: int, seed: int) -> dict:
    """Per-element inputs of car paint and the patina for n elements: flakes up to ~60° from the normal (some tilting
    the base below the horizon at large spread), viewing distances and mask values over [0, 1]."""
    rng = np.random.default_rng(seed)
    flake = rng.normal(size=(n, 3)) * rng.uniform(0.0, 0.8, (n, 1))
    # The mask stays 1e-6 inside [0, 1]: float32_conditioning's nudges must not leave the allowed range.
    return dict(flake_normal=flake, distance=rng.uniform(0.0, 3.0, n), mask=rng.uniform(1e-6, 1.0 - 1e-6, n))


@pytest.mark.parametrize(
    "material,inputs,options",
    [
        ("car-paint", ["flake_normal"], {}),
        ("car-paint", ["flake_normal", "distance"], {"interreflection": True}),
        ("patina", ["mask"], {}),
        ("patina", ["mask", "flake_normal"], {"conductor_interreflection": True}),
        ("patina", ["mask"], {"clamp_roughness": False, "transition": 0.0, "tint": 0.5}),
        ("patina", ["mask"], {"eta2": False, "extent": 0.2, "tint": (0.9, 0.5, 0.2)}),
    ],
)
def test_per_element_inputs(material, inputs, options):
    """Weidlich–Wilkie's per-element inputs on the GPU: the base tilted by a flake (below its horizon: nothing), the
    patina's blend of the bare and the covered surface at each element's mask (measured ≤ 2e-5 relative, and up to
    1.3e-4 where a flake's tilt amplifies the float32 rounding: float32_conditioning covers it)."""
    if material == "patina":
        patina = materials.patina()
        stack, options = patina.stack, {**patina.params, **options}
    else:
        stack = materials.car_paint()
    given = {k: v for k, v in _inputs(20_000, 5).items() if k in inputs}
    assert_parity(stack, "weidlich_wilkie", **given, **options)


def test_per_element_inputs_in_sample():
    """Stack.sample with per-element inputs: the mixture ignores them, as on the CPU (the same lobe and direction from
    the same u), and the weight is f cos θi / pdf with the element's inputs, to RTOL plus what 4-ulp input changes
    move f by."""
    patina = materials.patina()
    rng = np.random.default_rng(9)
    wo, _ = _directions(5000, 6)
    u = rng.uniform(size=(5000, 3))
    given = _inputs(5000, 7)
    wi_c, _, p_c = patina.stack.sample(wo, u, "weidlich_wilkie", **patina.params, **given)
    wi, weight, pdf = patina.stack.sample(wo, u, "weidlich_wilkie", device="gpu", **patina.params, **given)
    ok = p_c > 0
    assert np.array_equal(pdf > 0, ok) and ok.mean() > 0.4
    assert np.abs(wi[ok] - wi_c[ok]).max() <= 1e-3
    wi64 = wi[ok].astype(np.float64)
    options = {**patina.params, **{k: v[ok] for k, v in given.items()}}
    p_ref = patina.stack.pdf(wi64, wo[ok], "weidlich_wilkie", **patina.params)
    w_ref = patina.stack.eval(wi64, wo[ok], "weidlich_wilkie", **options) * wi64[:, 2:] / p_ref[:, None]
    big = w_ref > 1e-6 * w_ref.max()
    allowed = RTOL + float32_conditioning(patina.stack, wi64, wo[ok], "weidlich_wilkie", None, options, 9)
    rel = np.abs(weight[ok] - w_ref) / np.where(big, w_ref, 1)
    assert np.all(rel[big] <= allowed[big]), np.max(rel[big] - allowed[big])


@settings(max_examples=15, deadline=None)
@given(
    model=st.sampled_from(["belcour", "steinberg", "weidlich_wilkie", "albedo_scaling"]),
    ior=st.floats(1.05, 2.5),
    # Smooth, or at least 0.01 along each axis: a lobe of roughness α (≥ 1e-4) amplifies the float32 rounding of the
    # directions (6e-8) by 1/α, so below 0.01 float32 cannot hold 1e-4.
    coat=st.one_of(st.just((0.0, 0.0)), st.tuples(st.floats(0.01, 0.8), st.floats(0.01, 0.8))),
    angle=st.floats(-3.0, 3.0),
    sigma_a=st.floats(0.0, 2.0),
    base=st.tuples(st.floats(0.02, 0.9), st.floats(0.02, 0.9)),
    seed=st.integers(0, 1000),
)
def test_random_layered_stacks(model, ior, coat, angle, sigma_a, base, seed):
    stack = lamina.Stack(
        [
            lamina.Dielectric(ior, coat, angle=angle, thickness=1.0, sigma_a=sigma_a),
            lamina.Conductor((0.2, 0.9, 1.1), (3.0, 2.6, 2.3), base, angle=-angle),
        ]
    )
    assert_parity(stack, model, n=2000, seed=seed)


@settings(max_examples=25, deadline=None)
@given(
    eta=st.floats(0.1, 4.0),
    k=st.floats(0.0, 8.0),
    ax=st.floats(0.01, 1.0),
    ay=st.floats(0.01, 1.0),
    angle=st.floats(-3.0, 3.0),
    seed=st.integers(0, 1000),
)
@example(eta=0.75, k=0.0, ax=1.0, ay=1.0, angle=0.0, seed=71)  # a half-vector 1e-5 from the critical angle (CI)
@example(eta=0.5, k=1e-5, ax=1.0, ay=1.0, angle=0.0, seed=0)  # total internal reflection with κ > 0: a² cancelled
@example(eta=1.0, k=1.0, ax=0.01, ay=1.0, angle=1.0, seed=241)  # 1.5% of the values ill-conditioned (α = 0.01)
def test_random_conductors(eta, k, ax, ay, angle, seed):
    # η + iκ near 1 + 0i reflects nothing but the rounding of a difference of equal terms (F = 0 exactly at η = 1,
    # κ = 0): below float32's resolution, and no material.
    assume(abs(eta - 1.0) > 0.05 or k > 0.05)
    stack = lamina.Stack([lamina.Conductor(eta, k, (ax, ay), angle=angle)])
    assert_parity(stack, n=2000, seed=seed)


def test_inputs_longer_than_one_dispatch():
    """2^21 + 3 pairs: two dispatches; the rows of the second agree too."""
    n = (1 << 21) + 3
    wi = np.broadcast_to(np.array([0.3, -0.2, 0.9], np.float32), (n, 3))
    wo = np.zeros((n, 3), np.float32)
    t = np.linspace(0.05, 1.5, n, dtype=np.float32)
    wo[:, 0], wo[:, 2] = np.sin(t), np.cos(t)
    stack = materials.preset("gold")
    out = stack.eval(wi, wo, device="gpu")
    np.testing.assert_allclose(out[-1000:], stack.eval(wi[-1000:], wo[-1000:]), rtol=RTOL, atol=1e-7)
    np.testing.assert_allclose(out[:1000], stack.eval(wi[:1000], wo[:1000]), rtol=RTOL, atol=1e-7)


def test_device_choice_and_errors():
    stack = materials.preset("gold")
    wi, wo = _directions(100, 1)
    auto = stack.eval(wi, wo, device="auto")
    if gpu.adapter()["device_type"] == "Cpu":  # lavapipe is no faster than the CPU path: auto keeps the CPU
        np.testing.assert_array_equal(auto, stack.eval(wi, wo))
    with pytest.raises(ValueError, match="device must be one of"):
        stack.eval(wi, wo, device="tpu")
    with pytest.raises(ValueError, match="no GPU implementation yet"):
        materials.suite("gold-clearcoat").eval(wi, wo, "reference", device="gpu")
    with pytest.raises(ValueError, match="mask: a patina stack is a Dielectric layer"):
        materials.suite("three-layer").eval(wi, wo, "weidlich_wilkie", device="gpu", mask=0.5)
    with pytest.raises(ValueError, match="mask: the patina's IOR changes per element"):
        materials.patina().stack.eval(wi, wo, "weidlich_wilkie", device="gpu", mask=0.5, precomputed=True)
    with pytest.raises(ValueError, match="transport_fit fits the stack as prepared"):
        materials.car_paint().eval(wi, wo, "weidlich_wilkie", device="gpu", flake_normal=wi, variant="improved")
    with pytest.raises(ValueError, match=r"mask contains NaN, Inf or a value outside \[0, 1\]"):
        materials.patina().stack.eval(wi, wo, "weidlich_wilkie", device="gpu", mask=1.5)
    deep = lamina.Stack([lamina.Dielectric(1.5, 0.1, thickness=0.1)] * 8 + [lamina.Conductor(0.2, 3.0, 0.2)])
    with pytest.raises(ValueError, match="at most 8 layers"):
        lamina.render(deep, "steinberg", width=4, height=4, device="gpu")
    with pytest.raises(ValueError, match="at most 8 layers"):
        deep.sample(wo, np.full(3, 0.5), "steinberg", device="gpu")
    lamina.render(deep, "steinberg", width=4, height=4, device="gpu", lights=[lamina.DirectionalLight((0, 0, 1))])
    with pytest.raises(ValueError, match="'tabulated' on the GPU takes isotropic stacks"):
        materials.suite("anisotropic-coat-metal").eval(wi, wo, "tabulated", device="gpu")
    # The catalogue says which models and options run here, from the same rule.
    for m in lamina.catalogue.models():
        assert m.gpu.startswith("yes") == (m.name in gpu.models()), m
    assert lamina.catalogue.model("belcour").gpu == "yes, but not interpolated=False"
    assert lamina.catalogue.model("reference").gpu == "no"
    with pytest.raises(ValueError, match="interpolated=False runs on the CPU only"):
        materials.suite("gold-clearcoat").eval(wi, wo, "belcour", device="gpu", interpolated=False)
    with pytest.raises(ValueError, match="wi contains a zero-length direction"):
        stack.eval(np.zeros(3), wo, device="gpu")
    with pytest.raises(ValueError, match="wo contains NaN or Inf"):
        stack.eval(wi, np.full(3, np.nan), device="gpu")
    with pytest.raises(TypeError, match="has no option"):
        stack.eval(wi, wo, device="gpu", lut="fitted")


@pytest.mark.parametrize(
    "material,model,options",
    [
        ("gold", "microfacet", {}),
        ("brushed-aluminium", "microfacet", {}),
        ("anisotropic-coat-metal", "belcour", {}),
        ("varnished-diffuse", "belcour", {}),
        ("three-layer", "steinberg", {}),
        ("car-paint", "weidlich_wilkie", {}),
        ("gold-clearcoat", "albedo_scaling", {}),
        ("rough-coat-rough-copper", "tabulated", {}),
        ("three-layer", "steinberg", {"variant": "improved"}),
    ],
)
@pytest.mark.parametrize(
    "shape,camera",
    [("sphere", None), ("plane", ((0.3, -2.0, 3.0), (0, 0, 0), 40)), ("mesh", ((0.5, 0.8, 3.0), (0, 0, 0), 45))],
)
def test_renderer_matches_the_cpu_renderer(material, model, options, shape, camera):
    """The deterministic scenes (directional and point lights): the GPU renderer and the CPU renderer, pixel by pixel,
    ≤ 1e-3 relative on pixels above 1e-6 of the peak (the issue's criterion), and a batch is the single renders. A
    mesh (a latitude-longitude sphere) is rasterized on the GPU and ray traced on the CPU: the rasterizer names the
    triangle at each pixel centre and the GPU intersects the pixel's ray with it for the barycentrics, as the CPU does
    (the rasterizer's interpolated barycentrics were 1.1e-3 to 7.5e-3 off in shading on an NVIDIA H200, 7e-6 on
    lavapipe). Silhouette pixels, where the two may pick different triangles, are left out (pixels whose 3 x 3
    neighbourhood is not entirely covered on the CPU; the rest, 34% of the image, agrees to ≤ 2.7e-5 on lavapipe, the
    car paint's flakes the worst)."""
    stack = materials.preset(material) if material in materials.PRESETS else materials.suite(material)
    stack = materials.car_paint() if material == "car-paint" else stack
    if shape == "mesh":
        shape = uv_sphere_mesh(32, 64)
    lights = [
        lamina.DirectionalLight((-0.4, 0.5, 0.8), (2.0, 1.5, 1.0)),
        lamina.PointLight((1.5, 1.0, 2.5), (8.0, 8.0, 6.0)),
    ]
    kwargs = dict(shape=shape, camera=camera, lights=lights, width=40, height=32, **options)
    cpu = lamina.render(stack, model, device="cpu", **kwargs)
    out = lamina.render([stack, stack], model, device="gpu", **kwargs)
    assert out.shape == (2, 32, 40, 3) and out.dtype == np.float32
    np.testing.assert_array_equal(out[0], out[1])
    big = cpu > 1e-6 * cpu.max()
    if isinstance(shape, lamina.Mesh):
        covered = cpu.max(axis=-1) > 0
        inner = np.ones_like(covered)
        for dj in (-1, 0, 1):
            for di in (-1, 0, 1):
                inner &= np.roll(covered, (dj, di), axis=(0, 1))
        big &= inner[..., None]
        assert inner.mean() > 0.25
    rel = np.abs(out[0][big] - cpu[big]) / cpu[big]
    assert rel.max() <= 1e-3, rel.max()
    assert np.abs(out[0][~big & (cpu <= 1e-6 * cpu.max())]).max() <= 1e-5 * cpu.max()
    assert big.mean() > 0.2


@pytest.mark.parametrize("shape", ["plane", "sphere"])
@pytest.mark.parametrize("what", ["flakes", "patina"])
def test_textured_renders_match_the_cpu_renderer(what, shape):
    """Per-element inputs as textures over the surface's uv (the nearest texel, wrapping), shared by a batch of
    stacks: the GPU's render is the CPU's pixel by pixel (≤ 1e-3 relative on pixels above 1e-6 of the peak) on the
    plane, whose uv is exact in float32. On the sphere float32 uv (atan2 and acos of the normal) moves a lookup across
    a texel edge for a few pixels, which then shade the neighbouring texel's flake or mask value (measured 0.13% of the
    pixels with a 128² mask, none with the flakes): at most 0.5% may differ more. A batch is its single renders."""
    lights = [
        lamina.DirectionalLight((-0.4, 0.5, 0.8), (2.0, 1.5, 1.0)),
        lamina.PointLight((1.5, 1.0, 2.5), (8.0, 8.0, 6.0)),
    ]
    if what == "flakes":
        stacks = [materials.car_paint(), materials.suite("gold-clearcoat")]
        inputs = dict(flake_normal=materials.flake_texture(256, 100), distance=2.0)
    else:
        patinas = [materials.patina(), materials.patina(thickness=2.0, roughness=0.1)]
        stacks = [p.stack for p in patinas]
        inputs = dict(mask=materials.patina_mask(128), **patinas[0].params)
    kwargs = dict(shape=shape, lights=lights, width=64, height=64, **inputs)
    out = lamina.render(stacks, "weidlich_wilkie", device="gpu", **kwargs)
    for image, stack in zip(out, stacks, strict=True):
        cpu = lamina.render(stack, "weidlich_wilkie", device="cpu", **kwargs)
        big = cpu > 1e-6 * cpu.max()
        rel = np.abs(image[big] - cpu[big]) / cpu[big]
        assert np.mean(rel > 1e-3) <= (0.005 if shape == "sphere" else 0.0), (np.mean(rel > 1e-3), rel.max())
        assert big.mean() > 0.2
        np.testing.assert_array_equal(image, lamina.render(stack, "weidlich_wilkie", device="gpu", **kwargs))
    assert np.any(out[0] != out[1])


@pytest.mark.parametrize(
    "model,options",
    [
        ("microfacet", {}),
        ("belcour", {}),
        ("steinberg", {}),
        ("weidlich_wilkie", {}),
        ("albedo_scaling", {}),
        ("tabulated", {}),
        ("steinberg", {"variant": "improved"}),
    ],
)
@pytest.mark.parametrize("sky", [False, True])
def test_a_batch_of_different_stacks_is_its_single_renders(model, options, sky):
    """One dispatch renders a batch: each stack's parameters and arrays (layers, Belcour's table and diffuse base,
    tabulated's tables, transport_fit's fit) sit at their offsets in shared buffers. A batch of stacks of different
    depths and kinds equals, bit for bit, each stack rendered alone (same code, same random numbers: the sampler is
    seeded by the pixel within its image). Tabulated's single layer (gold) renders in a dispatch of its own, as
    microfacet; an anisotropic stack has no fit beside stacks that have one."""
    names = {
        "microfacet": ["gold", "brushed-aluminium", "copper"],
        "belcour": ["anisotropic-coat-metal", "varnished-diffuse", "gold-clearcoat"],
        "tabulated": ["gold", "three-layer", "varnished-diffuse", "gold-clearcoat"],
    }.get(model, ["three-layer", "varnished-diffuse", "gold-clearcoat", "thick-absorbing-slab"])
    if options:
        names = ["anisotropic-coat-metal", "varnished-diffuse", "gold-clearcoat"]
    stacks = [materials.preset(n) if n in materials.PRESETS else materials.suite(n) for n in names]
    lights = [lamina.DirectionalLight((-0.4, 0.5, 0.8), (2.0, 1.5, 1.0))]
    kwargs = dict(lights=lights, width=24, height=20, device="gpu", **options)
    if sky:
        kwargs.update(lights=[lamina.EnvironmentLight("sky")], spp=4, seed=3)
    batch = lamina.render(stacks, model, **kwargs)
    assert batch.shape == (len(stacks), 20, 24, 3)
    for image, stack in zip(batch, stacks, strict=True):
        np.testing.assert_array_equal(image, lamina.render(stack, model, **kwargs))
    assert all(np.any(a != b) for a, b in zip(batch, batch[1:]))


def _block_means(images: np.ndarray, block: int) -> np.ndarray:
    """(K, H, W, 3) images -> (K, H/block, W/block, 3) block means."""
    k, h, w, c = images.shape
    return images.reshape(k, h // block, block, w // block, block, c).mean(axis=(2, 4))


@pytest.mark.parametrize(
    "material,model,shape",
    [
        ("gold", "microfacet", "sphere"),
        ("brushed-aluminium", "microfacet", "plane"),
        ("anisotropic-coat-metal", "belcour", "sphere"),
        ("three-layer", "steinberg", "sphere"),
        ("varnished-diffuse", "weidlich_wilkie", "sphere"),
        ("car-paint", "weidlich_wilkie", "mesh"),
        ("gold-clearcoat", "albedo_scaling", "sphere"),
        ("rough-coat-rough-copper", "tabulated", "sphere"),
        ("varnished-diffuse", "steinberg:improved", "sphere"),
        ("car-paint-flakes", "weidlich_wilkie", "sphere"),
        ("patina", "weidlich_wilkie", "plane"),
    ],
)
def test_environment_lit_renders_agree_statistically(material, model, shape):
    """Under the built-in sky and sun, the GPU's and the CPU's renders are two unbiased estimates of the same image
    (same estimator: environment and BSDF sampling by MIS, other random numbers). Four seeds per device, means of 4 x 4
    pixel blocks: each block's difference over its standard error (from the spread of the seeds on both devices, 6
    degrees of freedom) exceeds 3 for at most 10% of the blocks (Student's t: 2.4% expected), and the whole image's
    mean differs by at most 4 standard errors. Where the ray misses, both show the sky itself (its nearest texel)."""
    stack = materials.car_paint() if material.startswith("car-paint") else None
    stack = stack or (materials.preset(material) if material in materials.PRESETS else None)
    stack = stack or (materials.patina().stack if material == "patina" else materials.suite(material))
    kwargs = dict(width=32, height=32, spp=32, shape=uv_sphere_mesh(16, 32) if shape == "mesh" else shape)
    if material == "car-paint-flakes":
        kwargs["flake_normal"] = materials.flake_texture(256, 100)
    if material == "patina":
        kwargs.update(materials.patina().params, mask=materials.patina_mask(64))
    model, _, variant = model.partition(":")
    if variant:
        kwargs["variant"] = variant
    if shape == "plane":
        kwargs["camera"] = ((0.3, -2.0, 3.0), (0, 0, 0), 40)
    gpu_runs = np.stack([lamina.render(stack, model, device="gpu", seed=s, **kwargs) for s in range(4)])
    cpu_runs = np.stack([lamina.render(stack, model, device="cpu", seed=s, **kwargs) for s in range(4)])
    assert gpu_runs.dtype == np.float32 and np.isfinite(gpu_runs).all()
    g, c = _block_means(gpu_runs, 4), _block_means(cpu_runs, 4)
    var = (g.var(axis=0, ddof=1) + c.var(axis=0, ddof=1)) / 2
    diff = g.mean(axis=0) - c.mean(axis=0)
    noisy = var > 1e-12 * c.mean() ** 2
    z = diff[noisy] / np.sqrt(2 * var[noisy] / 4)
    assert noisy.sum() >= 30
    assert np.mean(np.abs(z) > 3) <= 0.10, np.sort(np.abs(z))[-5:]
    total = gpu_runs.mean(axis=(1, 2, 3)), cpu_runs.mean(axis=(1, 2, 3))
    se = np.sqrt((total[0].var(ddof=1) + total[1].var(ddof=1)) / 4)
    assert abs(total[0].mean() - total[1].mean()) <= 4 * se + 1e-6 * total[1].mean()
    # Pixels that miss show a texel of the sky, the CPU's but where a float32 ray near a texel's edge picks its
    # neighbour (here 0.5% of them).
    miss = np.all((gpu_runs.var(axis=0) == 0) & (cpu_runs.var(axis=0) == 0), axis=-1)
    sky = lamina.sky()
    texels = {tuple(v) for v in (sky.map * sky.scale).astype(np.float32).reshape(-1, 3)}
    assert all(tuple(v) in texels for v in gpu_runs[0][miss])
    assert np.mean(np.all(gpu_runs[0][miss] == cpu_runs[0][miss], axis=-1)) >= 0.98


@pytest.mark.parametrize(
    "material,model,options",
    [
        ("gold", "microfacet", {}),
        ("brushed-aluminium", "microfacet", {}),
        ("clay", "microfacet", {}),
        ("rough-coat-rough-copper", "belcour", {}),
        ("anisotropic-coat-metal", "belcour", {}),
        ("three-layer", "steinberg", {}),
        ("gold-clearcoat", "steinberg", {"conductor_interreflection": True}),
        ("varnished-diffuse", "weidlich_wilkie", {}),
        ("rough-coat-rough-copper", "weidlich_wilkie", {"conductor_interreflection": True}),
        ("car-paint", "weidlich_wilkie", {}),
        ("gold-clearcoat", "albedo_scaling", {}),
        ("rough-coat-rough-copper", "tabulated", {}),
        ("gold", "tabulated", {}),
        ("three-layer", "belcour", {"variant": "improved"}),
        ("varnished-diffuse", "steinberg", {"variant": "improved"}),
        ("rough-coat-rough-copper", "weidlich_wilkie", {"variant": "improved"}),
    ],
)
def test_sample_and_pdf_match_the_cpu(material, model, options):
    """Stack.sample and pdf on the GPU: from the same u the same lobe and direction as the CPU (to 1e-3: float32
    directions; Beckmann's inverted CDF in float32), with pdf 0 in the same places; at the GPU's directions its pdf is
    the CPU's to RTOL and its weight is the CPU's f cos θi / pdf to RTOL plus what 4-ulp input changes move f by."""
    stack = materials.car_paint() if material == "car-paint" else None
    stack = stack or (materials.preset(material) if material in materials.PRESETS else materials.suite(material))
    rng = np.random.default_rng(7)
    wo, _ = _directions(5000, 3)
    u = rng.uniform(size=(5000, 3))
    wi_c, _, p_c = stack.sample(wo, u, model, **options)
    wi, weight, pdf = stack.sample(wo, u, model, device="gpu", **options)
    assert wi.dtype == np.float32 and weight.shape == (5000, 3)
    assert np.array_equal(pdf > 0, p_c > 0) and np.mean(pdf > 0) > 0.4
    ok = pdf > 0
    assert np.abs(wi[ok] - wi_c[ok]).max() <= 1e-3
    assert np.all(weight[~ok] == 0)
    wi64 = wi[ok].astype(np.float64)
    p_ref = stack.pdf(wi64, wo[ok], model, **options)
    assert np.max(np.abs(pdf[ok] - p_ref) / p_ref) <= RTOL
    f = stack.eval(wi64, wo[ok], model, **options)
    w_ref = f * wi64[:, 2:] / p_ref[:, None]
    big = w_ref > 1e-6 * w_ref.max()
    allowed = RTOL + float32_conditioning(stack, wi64, wo[ok], model, None, options, 7)
    rel = np.abs(weight[ok] - w_ref) / np.where(big, w_ref, 1)
    assert np.all(rel[big] <= allowed[big]), np.max(rel[big] - allowed[big])
    wi_any, wo_any = _directions(5000, 4)  # the pdf of any pair, below the horizon included
    p_cpu = stack.pdf(wi_any, wo_any, model, **options)
    p_gpu = stack.pdf(wi_any, wo_any, model, device="gpu", **options)
    big = p_cpu > 1e-6 * p_cpu.max()
    assert np.max(np.abs(p_gpu[big] - p_cpu[big]) / p_cpu[big]) <= RTOL and np.all(p_gpu[~big] <= 1e-6 * p_cpu.max())


def test_a_gpu_fault_names_the_device_and_the_size_and_the_next_call_works():
    """A render larger than the device holds, a device lost mid-batch (tests/faults.py, in a child process)."""
    run = faults.gpu_faults()
    adapter = lamina.gpu.adapter()["name"]
    assert run["adapter"] == adapter
    for key, size in (("too large", "GiB"), ("lost", "MiB")):
        assert run[key] is not None and adapter in run[key] and size in run[key], (key, run[key])
    assert "lost" in run["lost"] and run["after too large"] > 0.0
    assert run["after lost"] < 1e-3, run["after lost"]  # the next evaluation works (parity itself: tests above)
