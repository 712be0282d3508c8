"""lamina materials inside Mitsuba 3 (lamina.mitsuba.register / bsdf): eval is lamina's f·cos θ (Mitsuba's si.wi is
lamina's wo), Mitsuba's own chi-square test passes on every model's sampling, the delta component of smooth tops, and
a sphere rendered by Mitsuba agrees with lamina.render within Monte Carlo noise.

Mitsuba's chi-square tools run only in JIT variants (llvm_ad_rgb): without a libLLVM >= 16 those tests fail (the
Makefile installs Debian's libllvm19 when root)."""

from __future__ import annotations

import drjit as dr
import lamina
import lamina.mitsuba as lm
import mitsuba as mi
import numpy as np
import pytest
from conftest import MI_RGB, random_hemisphere

#: (model, stack) for every model but the reference; the smooth-topped gold clear coat exercises the delta component.
CASES = [
    ("microfacet", lamina.Stack([lamina.materials.metal("Au", 0.25)])),
    ("belcour", lamina.materials.suite("rough-coat-rough-copper")),
    ("belcour", lamina.materials.suite("gold-clearcoat")),
    ("steinberg", lamina.materials.suite("rough-coat-rough-copper")),
    ("weidlich_wilkie", lamina.materials.suite("varnished-diffuse")),
    ("albedo_scaling", lamina.materials.suite("rough-coat-rough-copper")),
    ("tabulated", lamina.materials.suite("gold-clearcoat")),
]
IDS = [f"{m}-{i}" for i, (m, _) in enumerate(CASES)]


def _jit():
    if not MI_RGB.startswith("llvm"):
        pytest.fail("Mitsuba's chi-square test and renders with a Python BSDF need llvm_ad_rgb (a libLLVM >= 16)")
    mi.set_variant(MI_RGB)
    lm.register()


@pytest.mark.parametrize("variant", sorted({"scalar_rgb", MI_RGB}))
@pytest.mark.parametrize(("model", "stack"), CASES, ids=IDS)
def test_eval_is_f_cos(rng, variant, model, stack):
    mi.set_variant(variant)
    lm.register()
    wi, wo = (
        random_hemisphere(rng, 64 if variant == "scalar_rgb" else 2000),
        random_hemisphere(rng, 64 if variant == "scalar_rgb" else 2000),
    )
    theirs = lm.eval_f(lm.bsdf(stack, model), wi, wo)  # Mitsuba's eval / cos θi
    ours = stack.eval(wi, wo, model)
    np.testing.assert_allclose(theirs, ours, rtol=2e-6, atol=1e-7 * ours.max())  # float32 round trip


@pytest.mark.parametrize(("model", "stack"), CASES, ids=IDS)
@pytest.mark.parametrize("wi", [[0.0, 0.0, 1.0], [0.6, 0.0, 0.8], [0.0, 0.95, 0.31225]])
def test_mitsuba_chi2(model, stack, wi):
    """Mitsuba's own chi-square test of the glossy component's sampling against its pdf (significance 0.01)."""
    _jit()
    from mitsuba.chi2 import BSDFAdapter, ChiSquareTest, SphericalDomain

    ctx = mi.BSDFContext(mi.TransportMode.Radiance, +mi.BSDFFlags.GlossyReflection, 0)
    sample, pdf = BSDFAdapter(lm.PLUGIN, lm.bsdf(stack, model), wi=wi, ctx=ctx)
    test = ChiSquareTest(SphericalDomain(), sample, pdf, sample_dim=3, sample_count=200_000)
    assert test.run(0.01, test_count=len(CASES) * 3, quiet=True), test.messages


def test_delta_component_of_a_smooth_top(rng):
    _jit()
    stack = lamina.materials.suite("gold-clearcoat")
    b = mi.load_dict(lm.bsdf(stack, "belcour"))
    assert b.component_count() == 2 and mi.has_flag(b.flags(), mi.BSDFFlags.DeltaReflection)
    assert mi.load_dict(lm.bsdf(lamina.materials.suite("frosted-metal"))).component_count() == 1
    wo = random_hemisphere(rng, 500)
    si = dr.zeros(mi.SurfaceInteraction3f, len(wo))
    si.wi = mi.Vector3f(np.ascontiguousarray(wo.T, dtype=np.float32))
    u = rng.uniform(size=(3, len(wo))).astype(np.float32)
    ctx = mi.BSDFContext(mi.TransportMode.Radiance, +mi.BSDFFlags.DeltaReflection, 1)
    bs, weight = b.sample(ctx, si, mi.Float(u[0]), mi.Point2f(u[1:]))
    np.testing.assert_allclose(np.array(bs.wo).T, wo * [-1, -1, 1], atol=1e-6)
    np.testing.assert_allclose(np.array(weight).T, stack.specular(wo, "belcour"), rtol=1e-5)
    # Both components: every glossy sample's weight is eval / pdf, with the component choice in both.
    bs, weight = b.sample(mi.BSDFContext(), si, mi.Float(u[0]), mi.Point2f(u[1:]))
    glossy = (np.array(bs.sampled_type) == int(mi.BSDFFlags.GlossyReflection)) & (np.array(bs.pdf) > 0)
    assert 0.2 < glossy.mean() < 1.0  # rejected samples (pdf 0, weight 0) left out
    ev, pdf = b.eval_pdf(mi.BSDFContext(), si, bs.wo)
    expected = np.array(ev).T[glossy] / np.array(pdf)[glossy, None]
    np.testing.assert_allclose(np.array(weight).T[glossy], expected, rtol=1e-4)


def _ball_scene(stack, n: int, spp: int, light: np.ndarray):
    """A unit sphere of `stack` (belcour) under a directional light, orthographic along −z, box filter, n x n."""
    return mi.load_dict(
        {
            "type": "scene",
            "integrator": {"type": "path", "max_depth": 2},
            "sensor": {
                "type": "orthographic",
                "to_world": mi.ScalarTransform4f().look_at(origin=[0, 0, 10], target=[0, 0, 0], up=[0, 1, 0]),
                "film": {"type": "hdrfilm", "width": n, "height": n, "rfilter": {"type": "box"}, "pixel_format": "rgb"},
                "sampler": {"type": "independent", "sample_count": spp},
            },
            "ball": {"type": "sphere", "bsdf": lm.bsdf(stack, "belcour")},
            "sun": {
                "type": "directional",
                "direction": (-light).tolist(),
                "irradiance": {"type": "rgb", "value": [1.0] * 3},
            },
        }
    )


def test_sphere_rendered_by_mitsuba_matches_lamina_render():
    """A rough-coated copper ball under a directional light, 32x32, orthographic: Mitsuba's path tracer (16 renders
    of 16 spp, box filter) against lamina.render supersampled 8x8 per pixel (the box filter's pixel average). On
    pixels lit and inside the disc at all four corners, z = |difference| / SE with SE from the 16 renders (15 dof):
    mean z² is 15/13 ≈ 1.15 for noise alone (measured 1.10), asserted ≤ 1.3; every |z| ≤ 6."""
    _jit()
    stack, n = lamina.materials.suite("rough-coat-rough-copper"), 32
    light = np.array([0.4, 0.5, 0.77]) / np.linalg.norm([0.4, 0.5, 0.77])
    scene = _ball_scene(stack, n, 16, light)
    renders = np.array([np.array(mi.render(scene, seed=10 + k)) for k in range(16)])
    mean, se = renders.mean(0), renders.std(0, ddof=1) / 4
    fine = lamina.render(
        stack, "belcour", width=8 * n, height=8 * n, lights=[lamina.DirectionalLight(light, (1, 1, 1))]
    )
    ours = fine.reshape(n, 8, n, 8, 3).mean(axis=(1, 3))
    c = np.arange(n + 1) / n * 2 - 1
    x, y = np.meshgrid(c, -c)
    lit = (x * light[0] + y * light[1] + np.sqrt(np.clip(1 - x * x - y * y, 0, None)) * light[2] > 0.05) & (
        x * x + y * y < 0.95
    )
    ok = lit[:-1, :-1] & lit[1:, :-1] & lit[:-1, 1:] & lit[1:, 1:]
    assert ok.sum() > 500
    z = np.abs(mean - ours)[ok] / se[ok]
    assert np.mean(z**2) <= 1.3 and z.max() <= 6.0, (np.mean(z**2), z.max())


def test_bad_materials():
    stack = lamina.materials.suite("rough-coat-rough-copper")
    with pytest.raises(ValueError, match="reference"):
        lm.bsdf(stack, "reference")
    with pytest.raises(TypeError, match="option"):
        lm.bsdf(stack, "belcour", lut="fitted")
    with pytest.raises(ValueError, match="model"):
        lm.bsdf(stack, "nonsense")


def test_renders_in_scalar_rgb():
    """The plugin in a scalar_rgb scene (one Python call per lane): a 16x16 ball, 16 spp; its mean over lit interior
    pixels matches lamina.render's supersampled image within 4 standard errors of the pixel-to-pixel mean."""
    mi.set_variant("scalar_rgb")
    lm.register()
    stack, n = lamina.materials.suite("rough-coat-rough-copper"), 16
    light = np.array([0.4, 0.5, 0.77]) / np.linalg.norm([0.4, 0.5, 0.77])
    scene = _ball_scene(stack, n, 16, light)
    theirs = np.array(mi.render(scene, seed=3))
    fine = lamina.render(
        stack, "belcour", width=8 * n, height=8 * n, lights=[lamina.DirectionalLight(light, (1, 1, 1))]
    )
    ours = fine.reshape(n, 8, n, 8, 3).mean(axis=(1, 3))
    c = (np.arange(n) + 0.5) / n * 2 - 1
    x, y = np.meshgrid(c, -c)
    inside = x * x + y * y < 0.7
    d = (theirs - ours)[inside].mean(axis=-1)
    assert abs(d.mean()) <= 4 * d.std(ddof=1) / np.sqrt(d.size), (d.mean(), d.std())
