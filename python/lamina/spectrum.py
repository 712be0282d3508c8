"""Spectra: sampled spectral quantities, measured complex-IOR tables, and conversion of spectral results to
CIE 1931 XYZ and linear sRGB under D65."""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache, lru_cache
from pathlib import Path

import numpy as np

_DATA = Path(__file__).parent / "data"

#: Wavelengths (nm) at which RGB-mode evaluation samples spectral parameters: the red, green and blue
#: wavelengths of Elek 2010's RGB optical constants.
RGB_WAVELENGTHS = (690.0, 550.0, 450.0)

#: Materials with a shipped measured complex-IOR table (python/lamina/data/ior/<name>.csv, sources in each file).
IOR_MATERIALS = ("Au", "Ag", "Cu", "Al", "Cr", "Cu2O")


@dataclass(frozen=True, eq=False)
class Spectrum:
    """A spectral quantity sampled at increasing `wavelengths_nm`; linear interpolation between samples and the
    end values held constant outside them."""

    wavelengths_nm: np.ndarray
    values: np.ndarray
    #: Where the values come from (a measured table's name), for messages.
    name: str = ""
    #: False for measured tables: evaluating outside the measured range raises ValueError.
    extrapolate: bool = True

    def __init__(self, wavelengths_nm, values, name: str = "", extrapolate: bool = True):
        wl = np.asarray(wavelengths_nm, dtype=np.float64)
        v = np.asarray(values, dtype=np.float64)
        if wl.ndim != 1 or v.shape != wl.shape or wl.size < 1:
            raise ValueError(f"wavelengths_nm and values must be 1-D of equal length, got {wl.shape} and {v.shape}")
        if not (np.all(np.isfinite(wl)) and np.all(np.isfinite(v))):
            raise ValueError("wavelengths_nm and values must be finite (no NaN or Inf)")
        if np.any(np.diff(wl) <= 0) or wl[0] <= 0:
            raise ValueError("wavelengths_nm must be positive and strictly increasing")
        object.__setattr__(self, "wavelengths_nm", wl)
        object.__setattr__(self, "values", v)
        object.__setattr__(self, "name", str(name))
        object.__setattr__(self, "extrapolate", bool(extrapolate))

    def __call__(self, wavelengths_nm) -> np.ndarray:
        wl = np.asarray(wavelengths_nm, dtype=np.float64)
        lo, hi = self.wavelengths_nm[0], self.wavelengths_nm[-1]
        if not self.extrapolate and np.any((wl < lo) | (wl > hi)):
            outside = wl[(wl < lo) | (wl > hi)]
            raise ValueError(
                f"wavelengths: {outside.min():g} nm lies outside the measured range {lo:g}-{hi:g} nm of "
                f"{self.name or 'this spectrum'}"
            )
        return np.interp(wl, self.wavelengths_nm, self.values)

    def __eq__(self, other) -> bool:
        return (
            isinstance(other, Spectrum)
            and np.array_equal(self.wavelengths_nm, other.wavelengths_nm)
            and np.array_equal(self.values, other.values)
            and self.extrapolate == other.extrapolate
        )

    def __hash__(self) -> int:
        return hash((self.wavelengths_nm.tobytes(), self.values.tobytes(), self.extrapolate))

    def __repr__(self) -> str:
        return (
            f"Spectrum({self.wavelengths_nm[0]:g}-{self.wavelengths_nm[-1]:g} nm, {self.wavelengths_nm.size} samples)"
        )


@cache
def ior(material: str) -> tuple[Spectrum, Spectrum]:
    """Measured complex refractive index (n, k) of `material` (one of IOR_MATERIALS) as two Spectra."""
    if material not in IOR_MATERIALS:
        raise ValueError(f"material must be one of {IOR_MATERIALS}, got {material!r}")
    lines = [ln for ln in (_DATA / "ior" / f"{material}.csv").read_text().splitlines() if ln and ln[0] != "#"]
    assert lines[0] == "wavelength_nm,n,k", f"unexpected header in {material}.csv"
    t = np.loadtxt(lines[1:], delimiter=",")
    return (
        Spectrum(t[:, 0], t[:, 1], f"n of {material}", extrapolate=False),
        Spectrum(t[:, 0], t[:, 2], f"k of {material}", extrapolate=False),
    )


@lru_cache(maxsize=1)
def _cie() -> np.ndarray:
    return np.loadtxt(_DATA / "cie1931_2deg_d65.csv", delimiter=",", comments="#")


def _interpolation_matrix(wavelengths: np.ndarray, grid: np.ndarray) -> np.ndarray:
    """(len(grid), len(wavelengths)) matrix of piecewise-linear interpolation weights, ends held constant."""
    return np.stack([np.interp(grid, wavelengths, e) for e in np.eye(wavelengths.size)], axis=1)


def xyz_weights(wavelengths_nm) -> np.ndarray:
    """(n, 3) matrix W such that values @ W is the CIE XYZ of a reflectance-like spectrum sampled at
    `wavelengths_nm`, lit by D65 and normalised so that a perfect white reflector has Y = 1 (CIE 015:2018 eq. 7.1–7.3,
    linear interpolation onto the 1 nm CIE grid, 360–830 nm)."""
    wl = np.asarray(wavelengths_nm, dtype=np.float64)
    if wl.ndim != 1 or wl.size < 1 or np.any(np.diff(wl) <= 0) or not np.all(np.isfinite(wl)):
        raise ValueError("wavelengths_nm must be a finite, strictly increasing 1-D array")
    cie = _cie()
    lit = cie[:, 1:4] * cie[:, 4:5]
    return _interpolation_matrix(wl, cie[:, 0]).T @ lit / lit[:, 1].sum()


#: Linear sRGB (IEC 61966-2-1, D65 white) from CIE XYZ.
XYZ_TO_SRGB = np.array(
    [
        [3.2404542, -1.5371385, -0.4985314],
        [-0.9692660, 1.8760108, 0.0415560],
        [0.0556434, -0.2040259, 1.0572252],
    ]
)


def to_xyz(wavelengths_nm, values) -> np.ndarray:
    """CIE XYZ (D65, white Y = 1) of spectral results `values` (..., n) sampled at `wavelengths_nm` (n,)."""
    v = np.asarray(values, dtype=np.float64)
    wl = np.asarray(wavelengths_nm, dtype=np.float64)
    if v.shape[-1:] != wl.shape:
        raise ValueError(f"values must have shape (..., {wl.size}) to match wavelengths_nm, got {v.shape}")
    return v @ xyz_weights(wl)


def to_srgb(wavelengths_nm, values) -> np.ndarray:
    """Linear sRGB (D65) of spectral results `values` (..., n) sampled at `wavelengths_nm` (n,)."""
    return to_xyz(wavelengths_nm, values) @ XYZ_TO_SRGB.T
