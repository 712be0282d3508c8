"""model="albedo_scaling", the production coat model: reductions to the exact single interfaces, the smooth coat's
closed form, the scale 1 − E(μ) against the coat's own albedo, energy conservation and reciprocity."""

from __future__ import annotations

import lamina
import numpy as np
import pytest
from lamina import Conductor, Dielectric, Diffuse, Stack
from lamina.materials import metal, suite


def unit(w):
    w = np.asarray(w, dtype=float)
    return w / np.linalg.norm(w, axis=-1, keepdims=True)


def hemisphere(rng, n):
    w = rng.normal(size=(n, 3))
    w[:, 2] = np.abs(w[:, 2]) + 0.02
    return unit(w)


def test_single_interfaces_are_the_exact_model(rng):
    wi, wo = hemisphere(rng, 2000), hemisphere(rng, 2000)
    for stack in (Stack([metal("Au", 0.3)]), Stack([metal("Al", (0.1, 0.4), angle=0.7)]), Stack([Diffuse(0.5, 0.4)])):
        np.testing.assert_allclose(
            stack.eval(wi, wo, "albedo_scaling"), stack.eval(wi, wo, g2="separable"), rtol=1e-13, atol=1e-300
        )


def test_smooth_coat_over_lambert_is_the_closed_form(rng):
    """E of a smooth interface is its Fresnel reflectance: f = (1 − F(θi))(1 − F(θo)) ρ/π off the mirror direction
    (no inter-reflections and no 1/η²: what the production standards leave out), and the coat's own reflection is
    the Dirac part."""
    wi, wo = hemisphere(rng, 500), hemisphere(rng, 500)
    f_int = lambda c: lamina.optics.fresnel_dielectric(c, 1.5)  # noqa: E731
    expected = (1 - f_int(wi[:, 2])) * (1 - f_int(wo[:, 2])) * 0.6 / np.pi
    stack = Stack([Dielectric(1.5), Diffuse(0.6)])
    np.testing.assert_allclose(stack.eval(wi, wo, "albedo_scaling")[:, 0], expected, rtol=1e-13)
    np.testing.assert_allclose(stack.specular(wo, "albedo_scaling")[:, 0], f_int(wo[:, 2]), rtol=1e-13)
    view = stack.eval(wi, wo, "albedo_scaling", scaling="view")[:, 0]
    np.testing.assert_allclose(view, (1 - f_int(wo[:, 2])) * 0.6 / np.pi, rtol=1e-13)


@pytest.mark.parametrize("scaling", ["reciprocal", "view"])
def test_what_lies_beneath_is_scaled_by_one_minus_the_coat_albedo(scaling):
    """π (f_white − f_black) of a rough coat over white and black Lambert is the scale S; it equals (1 − E(θi))
    (1 − E(θo)) (or 1 − E(θo)) with E the coat's albedo integrated from the model itself. Tolerance 2e-3: the largest
    difference measured is 7e-4 (the FGD table's quadrature and interpolation against a 512 x 1024 midpoint sum)."""
    coat = Dielectric(1.5, 0.3)
    white, black = Stack([coat, Diffuse(1.0)]), Stack([coat, Diffuse(0.0)])
    t = np.radians([10, 40, 70, 85])
    w = np.stack([np.sin(t), 0 * t, np.cos(t)], -1)
    albedo = black.albedo(w, "albedo_scaling", scaling=scaling)[:, 0]
    wi, wo = w[:, None, :], (w * [-1, 1, 1])[None, :, :]
    s = (
        np.pi
        * (
            white.eval(wi, wo, "albedo_scaling", scaling=scaling)
            - black.eval(wi, wo, "albedo_scaling", scaling=scaling)
        )[..., 0]
    )
    light = 1 - albedo[:, None] if scaling == "reciprocal" else 1.0
    np.testing.assert_allclose(s, np.broadcast_to(light * (1 - albedo[None, :]), s.shape), atol=2e-3)


def test_slab_scales_by_beer_lambert_along_the_refracted_directions(rng):
    wi, wo = hemisphere(rng, 300), hemisphere(rng, 300)
    clear = Stack([Dielectric(1.5, 0.2), Diffuse(0.8)])
    tinted = Stack([Dielectric(1.5, 0.2, thickness=0.7, sigma_a=(0.1, 0.5, 2.0)), Diffuse(0.8)])
    top = Stack([Dielectric(1.5, 0.2), Diffuse(0.0)])
    mu = lambda w: np.sqrt(1 - (1 - w[:, 2] ** 2) / 1.5**2)  # noqa: E731
    transmittance = np.exp(-0.7 * np.array([0.1, 0.5, 2.0]) * (1 / mu(wi) + 1 / mu(wo))[:, None])
    below = lambda s: s.eval(wi, wo, "albedo_scaling") - top.eval(wi, wo, "albedo_scaling")  # noqa: E731
    np.testing.assert_allclose(below(tinted), below(clear) * transmittance, rtol=1e-12, atol=1e-300)


@pytest.mark.parametrize("name", sorted(lamina.materials.SUITE))
def test_energy_conservation_and_reciprocity(name, rng):
    stack = suite(name)
    u = np.random.default_rng(1).random((200_000, 3))
    for theta in (0.0, 45.0, 80.0, 88.0):
        wo = np.array([np.sin(np.radians(theta)), 0.0, np.cos(np.radians(theta))])
        _, weight, _ = stack.sample(wo, u, "albedo_scaling")
        albedo = weight.mean(axis=0) + stack.specular(wo, "albedo_scaling")
        se = weight.std(axis=0) / np.sqrt(len(u))
        assert np.all(albedo <= 1 + 4 * se + 2e-3), (theta, albedo, se)  # 2e-3: the E table, as above
    a, b = hemisphere(rng, 500), hemisphere(rng, 500)
    np.testing.assert_allclose(stack.eval(a, b, "albedo_scaling"), stack.eval(b, a, "albedo_scaling"), rtol=1e-12)


def test_a_conductor_ends_the_stack_and_options_are_checked():
    stack = Stack([Dielectric(1.5, 0.1), Conductor(0.2, 3.0, 0.3)])
    w = np.array([0.0, 0.0, 1.0])
    assert np.all(np.isfinite(stack.eval(w, unit([0.3, 0, 1]), "albedo_scaling")))
    with pytest.raises(ValueError, match="scaling must be one of"):
        stack.eval(w, w, "albedo_scaling", scaling="both")
    with pytest.raises(TypeError, match="has no option 'lut'"):
        stack.eval(w, w, "albedo_scaling", lut="fitted")


def test_openpbr_roughening_of_what_lies_beneath(rng):
    """Under a rough coat of α_c a layer of α is evaluated at α′ = √min(1, α² + 2α_c²) (OpenPBR's r′ = (r⁴ + 2r_c⁴)^¼
    with r = √α), per tangent axis, down the stack; roughening=False keeps the layers' own roughness."""
    wi, wo = hemisphere(rng, 400), hemisphere(rng, 400)
    n, k = (0.2, 0.45, 1.4), (3.6, 2.5, 1.9)
    stack = Stack([Dielectric(1.5, (0.3, 0.1)), Conductor(n, k, (0.1, 0.4))])
    alpha = (np.sqrt(0.1**2 + 2 * 0.3**2), np.sqrt(min(1.0, 0.4**2 + 2 * 0.1**2)))
    same = Stack([Dielectric(1.5, (0.3, 0.1)), Conductor(n, k, alpha)])
    np.testing.assert_allclose(
        stack.eval(wi, wo, "albedo_scaling"), same.eval(wi, wo, "albedo_scaling", roughening=False), rtol=1e-12
    )
    assert not np.allclose(stack.eval(wi, wo, "albedo_scaling"), stack.eval(wi, wo, "albedo_scaling", roughening=False))
