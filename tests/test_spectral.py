"""Spectral evaluation against Mitsuba 3 (scalar_spectral) and colour conversion against colour-science."""

from __future__ import annotations

import colour
import drjit as dr
import lamina
import mitsuba as mi
import numpy as np
import pytest
from conftest import mitsuba_f, random_hemisphere

# colour-science: the PyPI package `colour-science`, not the unrelated `colour`.
assert hasattr(colour, "sd_to_XYZ"), "the `colour` module must come from the colour-science package"

WAVELENGTHS = [[400.0, 470.0, 540.0, 610.0], [455.5, 550.0, 650.0, 700.0]]


def irregular(s: lamina.Spectrum) -> dict:
    return {
        "type": "irregular",
        "wavelengths": ", ".join(map(str, s.wavelengths_nm)),
        "values": ", ".join(map(str, s.values)),
    }


@pytest.mark.parametrize("metal", lamina.materials.IOR_MATERIALS)
@pytest.mark.parametrize("wavelengths", WAVELENGTHS)
def test_spectral_fresnel_against_mitsuba(metal, wavelengths):
    """Smooth conductor reflectance with lamina's measured n, k: Mitsuba samples the same tables (as `irregular`
    spectra, linear interpolation) at si.wavelengths; lamina evaluates its Fresnel at the same wavelengths.
    Same formula in float32 vs float64: 1e-5 relative."""
    n, k = lamina.spectrum.ior(metal)
    mi.set_variant("scalar_spectral")
    bsdf = mi.load_dict({"type": "conductor", "eta": irregular(n), "k": irregular(k)})
    for theta in (0.0, 40.0, 75.0, 88.0):
        t = np.radians(theta)
        si = dr.zeros(mi.SurfaceInteraction3f)
        si.wi = mi.Vector3f(float(np.sin(t)), 0.0, float(np.cos(t)))
        si.wavelengths = mi.Spectrum(wavelengths)
        _, weight = bsdf.sample(mi.BSDFContext(), si, 0.5, mi.Point2f(0.5, 0.5))  # weight = F for a mirror
        ours = lamina.optics.fresnel_conductor(np.cos(t), n(wavelengths), k(wavelengths))
        np.testing.assert_allclose(ours, np.array(weight).ravel(), rtol=1e-5)


@pytest.mark.parametrize("distribution", ["ggx", "beckmann"])
def test_spectral_rough_conductor_stack_against_mitsuba(rng, distribution):
    """End to end: Stack.eval(wavelengths=...) of a rough copper vs Mitsuba's scalar_spectral roughconductor."""
    n, k = lamina.spectrum.ior("Cu")
    wl = WAVELENGTHS[1]
    wi, wo = random_hemisphere(rng, 40, 0.1), random_hemisphere(rng, 40, 0.1)
    wo = wo * [0.3, 0.3, 1.0] - wi * [1, 1, 0] * 0.5  # bias wo towards the specular side
    wo /= np.linalg.norm(wo, axis=-1, keepdims=True)
    stack = lamina.Stack([lamina.Conductor(n, k, roughness=0.3)])
    ours = stack.eval(wi, wo, wavelengths=wl, distribution=distribution, g2="separable")
    ref = mitsuba_f(
        {"type": "roughconductor", "distribution": distribution, "alpha": 0.3, "eta": irregular(n), "k": irregular(k)},
        wi,
        wo,
        variant="scalar_spectral",
        wavelengths=wl,
    )
    assert ours.shape == ref.shape == (40, 4)
    rtol = 1e-4 if distribution == "ggx" else 7e-3  # Mitsuba's Beckmann G1 approximation, see test_mitsuba.py
    np.testing.assert_allclose(ours, ref, rtol=rtol, atol=1e-6 * ref.max())


def _colour_xyz(wavelengths, values, linear: bool = False) -> np.ndarray:
    sd = colour.SpectralDistribution(dict(zip(wavelengths, values)))
    if linear:
        sd = sd.interpolate(
            colour.SpectralShape(wavelengths[0], wavelengths[-1], 1), interpolator=colour.LinearInterpolator
        )
    cmfs = colour.MSDS_CMFS["CIE 1931 2 Degree Standard Observer"]
    return colour.sd_to_XYZ(sd, cmfs, colour.SDS_ILLUMINANTS["D65"], method="Integration") / 100.0


@pytest.mark.parametrize("metal", ["Au", "Cu", "Ag"])
def test_xyz_and_srgb_against_colour_science(metal):
    """lamina.to_xyz / to_srgb of a spectral result on the 1 nm CIE grid vs colour.sd_to_XYZ (D65, Integration) and
    colour.XYZ_to_sRGB (linear). Issue tolerance: 1e-3 absolute on a white-normalised (Y = 1) scale."""
    wl = np.arange(360.0, 831.0, 1.0)
    n, k = lamina.spectrum.ior(metal)
    refl = lamina.optics.fresnel_conductor(np.full_like(wl, 0.9), n(wl), k(wl))
    xyz = lamina.to_xyz(wl, refl)
    ref = _colour_xyz(wl, refl)
    np.testing.assert_allclose(xyz, ref, atol=1e-3)
    srgb_ref = colour.XYZ_to_sRGB(ref, apply_cctf_encoding=False)
    np.testing.assert_allclose(lamina.to_srgb(wl, refl), srgb_ref, atol=1e-3)


def test_xyz_of_coarse_spectra_against_colour_science():
    """A smooth spectrum given at 10 nm: lamina interpolates linearly onto the 1 nm CIE grid. With colour-science
    also interpolating linearly the two agree to 1e-3. (With colour-science's default Sprague interpolation they
    differ by up to 1.8e-3 on this spectrum: that is the interpolation choice, not the integration.)"""
    wl = np.arange(380.0, 781.0, 10.0)
    values = 0.5 + 0.4 * np.sin(wl / 40.0)
    np.testing.assert_allclose(lamina.to_xyz(wl, values), _colour_xyz(wl, values, linear=True), atol=1e-3)


def test_white_and_batch_shapes():
    wl = np.arange(360.0, 831.0, 5.0)
    white = lamina.to_xyz(wl, np.ones((2, 7, wl.size)))
    assert white.shape == (2, 7, 3)
    d65 = colour.xy_to_XYZ(colour.CCS_ILLUMINANTS["CIE 1931 2 Degree Standard Observer"]["D65"])
    np.testing.assert_allclose(white[0, 0], d65, atol=1e-3)
    np.testing.assert_allclose(lamina.to_srgb(wl, np.ones(wl.size)), [1, 1, 1], atol=2e-3)


def test_spectral_eval_shapes_and_errors():
    n, k = lamina.spectrum.ior("Au")
    stack = lamina.Stack([lamina.Conductor(n, k, 0.2)])
    wl = np.linspace(400, 700, 31)
    f = stack.eval([0, 0, 1.0], np.array([[0.1, 0, 1.0], [0.2, 0.1, 0.9]]), wavelengths=wl)
    assert f.shape == (2, 31)
    with pytest.raises(ValueError, match="RGB triple"):
        lamina.Stack([lamina.Diffuse((0.2, 0.3, 0.4))]).eval([0, 0, 1.0], [0, 0, 1.0], wavelengths=wl)
    with pytest.raises(ValueError, match="wavelengths"):
        stack.eval([0, 0, 1.0], [0, 0, 1.0], wavelengths=[500, np.nan])
    with pytest.raises(ValueError, match="material"):
        lamina.spectrum.ior("Unobtainium")
