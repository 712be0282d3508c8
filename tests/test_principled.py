"""Mitsuba 3's `principled` against lamina's primitives where their formulas coincide (Mitsuba 3.9,
src/bsdfs/principled.cpp), and lamina.mitsuba.principled's mapping of a stack onto it.

Where they coincide:
- the metallic lobe (metallic 1, spec_tint 0): Schlick's Fresnel with F0 = base_color, GGX D with alpha = roughness²
  (at least 1e-3), separable Smith G, over 4 cos θi cos θo;
- the specular lobe of a dielectric (metallic 0, black base_color, no sheen): the exact dielectric Fresnel with
  principled's eta, the same D and G.
Where they do not (documented in docs/validation.md): the clearcoat (GTR1 with a fixed G of alpha 0.25, Schlick F0
0.04, no 1/(4 cos θi cos θo), added on top without attenuating the base) and Burley's diffuse with retro-reflection.

Tolerance: Mitsuba evaluates in float32; the pairs stay away from the horizon (cos θ ≥ 0.05), where float32 rounding
of D·G·F stays below 1e-4 relative, measured; asserted at 5e-4."""

from __future__ import annotations

import lamina
import numpy as np
import pytest
from conftest import mitsuba_f, random_hemisphere
from lamina import mitsuba as lm

RTOL = 5e-4


def _pairs(rng, n=2000):
    wi, wo = random_hemisphere(rng, n, 0.05), random_hemisphere(rng, n, 0.05)
    return wi, wo, (wi + wo) / np.linalg.norm(wi + wo, axis=-1, keepdims=True)


@pytest.mark.parametrize("roughness", [0.2, 0.5, 0.8])
def test_metallic_lobe_is_schlick_ggx_separable(rng, roughness):
    f0 = np.array([0.95, 0.64, 0.54])
    wi, wo, h = _pairs(rng)
    alpha = max(roughness**2, 1e-3)
    ours = (
        lamina.optics.fresnel_schlick(np.sum(wi * h, -1)[:, None], f0)
        * (lamina.optics.ndf(h, alpha) * lamina.optics.masking_shadowing(wi, wo, h, alpha, g2="separable"))[:, None]
        / (4 * wi[:, 2:3] * wo[:, 2:3])
    )
    bsdf = {"type": "principled", "metallic": 1.0, "roughness": roughness, "spec_tint": 0.0}
    bsdf["base_color"] = {"type": "rgb", "value": f0.tolist()}
    theirs = mitsuba_f(bsdf, wi, wo)
    np.testing.assert_allclose(theirs, ours, rtol=RTOL, atol=1e-6 * ours.max())


@pytest.mark.parametrize("eta", [1.33, 1.5, 2.0])
def test_specular_lobe_is_the_rough_dielectric_reflection(rng, eta):
    wi, wo, _ = _pairs(rng)
    ours = lamina.optics.rough_dielectric(wi, wo, eta, 0.3**2, g2="separable")
    bsdf = {"type": "principled", "metallic": 0.0, "roughness": 0.3, "eta": eta, "spec_tint": 0.0}
    bsdf["base_color"] = {"type": "rgb", "value": [0.0, 0.0, 0.0]}
    theirs = mitsuba_f(bsdf, wi, wo)
    np.testing.assert_allclose(
        theirs, np.broadcast_to(ours.reshape(-1, 1), theirs.shape), rtol=RTOL, atol=1e-6 * ours.max()
    )


def test_principled_mapping():
    """lamina.mitsuba.principled's documented choices, on stacks where each one applies."""
    gold = lamina.materials.suite("rough-coat-rough-copper")
    d = lm.principled(gold)
    cu = gold.layers[1]._resolve(None)
    f0 = lamina.optics.fresnel_conductor(1.0, np.asarray(cu["ior"]) / 1.5, np.asarray(cu["k"]) / 1.5)
    assert d["metallic"] == 1.0 and np.allclose(d["base_color"]["value"], np.ravel(f0))
    assert d["clearcoat"] == 1.0 and d["clearcoat_gloss"] == 0.0  # alpha 0.2 > 0.1: as rough as principled allows
    assert d["roughness"] == pytest.approx(np.sqrt(np.hypot(0.35, 0.2))) and d["anisotropic"] == 0.0  # ... and more
    glossy = lm.principled(lamina.Stack([lamina.Dielectric(1.5, 0.05), lamina.materials.metal("Cu", 0.3)]))
    assert glossy["clearcoat_gloss"] == pytest.approx(0.05 / 0.099) and glossy["roughness"] == pytest.approx(
        np.sqrt(0.3)
    )
    varnish = lm.principled(lamina.materials.suite("varnished-diffuse"))  # smooth coat: its Dirac is left out
    assert varnish["metallic"] == 0.0 and "eta" not in varnish and "clearcoat" not in varnish
    expected = np.array([0.6, 0.35, 0.15]) * np.exp(-2 * np.array([0.1, 0.35, 0.9]))
    assert np.allclose(varnish["base_color"]["value"], expected)
    aniso = lm.principled(lamina.Stack([lamina.materials.metal("Al", (0.4, 0.1))]))
    r2, aspect = aniso["roughness"] ** 2, np.sqrt(1 - 0.9 * aniso["anisotropic"])
    assert sorted((r2 / aspect, r2 * aspect)) == pytest.approx([0.1, 0.4])
