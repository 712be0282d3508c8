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


@pytest.mark.parametrize("roughness", [0.3, (0.4, 0.1)])
def test_principled_of_a_bare_conductor_is_its_schlick_ggx_lobe(rng, roughness):
    """lamina.mitsuba.principled where principled and lamina coincide: a bare rough conductor becomes principled's
    metallic lobe, Schlick's Fresnel with F0 the conductor's normal-incidence reflectance, GGX of the conductor's own
    (alpha_x, alpha_y) and separable Smith. Mitsuba evaluating the mapped dict equals that lobe from lamina's
    primitives. (principled's larger alpha lies along the tangent and it has no tangent rotation, so an anisotropic
    layer maps exactly only with alpha_x >= alpha_y at angle 0.)"""
    eta, k = np.array([0.2, 0.45, 1.4]), np.array([3.6, 2.5, 1.9])
    stack = lamina.Stack([lamina.Conductor(tuple(eta), tuple(k), roughness)])
    wi, wo, h = _pairs(rng)
    theirs = mitsuba_f(lm.principled(stack), wi, wo)
    f0 = np.ravel(lamina.optics.fresnel_conductor(1.0, eta, k))
    lobe = lamina.optics.ndf(h, roughness) * lamina.optics.masking_shadowing(wi, wo, h, roughness, g2="separable")
    ours = lamina.optics.fresnel_schlick(np.sum(wi * h, -1)[:, None], f0) * (lobe / (4 * wi[:, 2] * wo[:, 2]))[:, None]
    np.testing.assert_allclose(theirs, ours, rtol=RTOL, atol=1e-6 * ours.max())
