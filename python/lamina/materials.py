"""Material presets built from the shipped measured data."""

from __future__ import annotations

import numpy as np

from .layers import Conductor, Dielectric, Diffuse, Roughness, Stack
from .spectrum import IOR_MATERIALS, RGB_WAVELENGTHS, ior


def metal(material: str, roughness: Roughness = 0.1, angle: float = 0.0) -> Conductor:
    """A conductor with the measured spectral complex IOR of `material` (one of IOR_MATERIALS)."""
    n, k = ior(material)
    return Conductor(ior=n, k=k, roughness=roughness, angle=angle)


def elek2010_rgb(material: str) -> tuple[tuple[float, float, float], tuple[float, float, float]]:
    """RGB complex IOR (n, k) at Elek 2010's wavelengths 690/550/450 nm, for 'Cu', 'Cr' and 'Cu2O' (and the other
    shipped metals). Elek's Appendix A numbers were not available to us; these are sampled from the measured tables
    (sources in python/lamina/data/ior/) at his wavelengths."""
    n, k = ior(material)
    return tuple(n(RGB_WAVELENGTHS).round(4).tolist()), tuple(k(RGB_WAVELENGTHS).round(4).tolist())


#: Elek 2010-style RGB presets (n, k) at 690/550/450 nm, see `elek2010_rgb`.
ELEK2010 = {m: elek2010_rgb(m) for m in ("Cu", "Cr", "Cu2O")}


def plastic(albedo=(0.6, 0.1, 0.08), ior: float = 1.5, roughness: Roughness = 0.0) -> Stack:
    """A dielectric coat over a Lambertian base (with roughness 0: Mitsuba's `plastic`)."""
    return Stack([Dielectric(ior, roughness), Diffuse(albedo)])


def preset(name: str) -> Stack:
    """A named single-interface material for demos and plots; see PRESETS."""
    try:
        return PRESETS[name]()
    except KeyError:
        raise ValueError(f"name must be one of {sorted(PRESETS)}, got {name!r}") from None


PRESETS = {
    "gold": lambda: Stack([metal("Au", 0.15)]),
    "silver": lambda: Stack([metal("Ag", 0.1)]),
    "copper": lambda: Stack([metal("Cu", 0.2)]),
    "aluminium": lambda: Stack([metal("Al", 0.25)]),
    "chromium": lambda: Stack([metal("Cr", 0.1)]),
    "brushed-aluminium": lambda: Stack([metal("Al", (0.05, 0.35), angle=np.pi / 4)]),
    "red-plastic": lambda: plastic(),
    "clay": lambda: Stack([Diffuse((0.55, 0.35, 0.25), roughness=0.6)]),
}

#: The material suite used for validation and benchmarks: layered stacks covering coats over metals, absorbing and
#: scattering slabs, anisotropy with rotated tangent frames and three layers. Thicknesses in arbitrary units, with
#: sigma_a / sigma_s in their inverse.
SUITE = {
    "gold-clearcoat": lambda: Stack([Dielectric(1.5), metal("Au", 0.15)]),
    "frosted-metal": lambda: Stack([Dielectric(1.5, 0.35), metal("Al", 0.02)]),
    "rough-coat-rough-copper": lambda: Stack([Dielectric(1.5, 0.2), metal("Cu", 0.35)]),
    "varnished-diffuse": lambda: Stack([Dielectric(1.5, thickness=1.0, sigma_a=(0.1, 0.35, 0.9)),
                                        Diffuse((0.6, 0.35, 0.15))]),
    "anisotropic-coat-metal": lambda: Stack([Dielectric(1.5, (0.1, 0.4), angle=0.5),
                                             metal("Al", (0.35, 0.08), angle=-0.4)]),
    "thick-absorbing-slab": lambda: Stack([Dielectric(1.5, 0.1, thickness=5.0, sigma_a=(0.05, 0.15, 0.4)),
                                           Diffuse(0.8)]),
    "three-layer": lambda: Stack([Dielectric(1.3, 0.1), Dielectric(1.6, 0.25, thickness=0.5, sigma_a=0.2),
                                  metal("Cu", 0.2)]),
    "scattering-slab": lambda: Stack([Dielectric(1.4, thickness=1.0, sigma_a=0.05, sigma_s=2.0, g=0.7),
                                      Diffuse((0.5, 0.4, 0.3))]),
}


def suite(name: str) -> Stack:
    """A material of the validation suite (see SUITE)."""
    try:
        return SUITE[name]()
    except KeyError:
        raise ValueError(f"name must be one of {sorted(SUITE)}, got {name!r}") from None


__all__ = ["SUITE", "suite", "metal", "elek2010_rgb", "ELEK2010", "plastic", "preset", "PRESETS", "IOR_MATERIALS"]
