"""Layer descriptions and the layer stack. Conventions: docs/conventions.md."""

from __future__ import annotations

from dataclasses import dataclass
from numbers import Real
from typing import Sequence, Union

import numpy as np

from . import _lamina
from ._arrays import broadcast
from .spectrum import RGB_WAVELENGTHS, Spectrum

#: A colour quantity: a scalar (grey), an RGB triple, or a Spectrum.
Colour = Union[float, Sequence[float], Spectrum]
#: A GGX/Beckmann roughness alpha in [0, 1]: isotropic scalar or (alpha_x, alpha_y) along the layer's tangent.
Roughness = Union[float, Sequence[float]]

#: Model names accepted by Stack.eval: the analytic ones (Rust) and the Monte Carlo "reference".
MODELS: tuple[str, ...] = tuple(_lamina.MODELS) + ("reference",)


def _channels(name: str, value: Colour, wavelengths) -> list[float]:
    """Resolves a colour quantity to one value per channel: RGB (wavelengths None) or the given wavelengths."""
    if isinstance(value, Spectrum):
        return value(RGB_WAVELENGTHS if wavelengths is None else wavelengths).tolist()
    if isinstance(value, Real):
        return [float(value)] * (3 if wavelengths is None else len(wavelengths))
    try:
        triple = [float(v) for v in value]
    except (TypeError, ValueError):
        raise TypeError(f"{name} must be a number, an RGB triple or a lamina.Spectrum, got {value!r}") from None
    if len(triple) != 3:
        raise ValueError(f"{name} must be a number, an RGB triple or a lamina.Spectrum, got {len(triple)} values")
    if wavelengths is not None:
        raise ValueError(f"{name} is an RGB triple; spectral evaluation (wavelengths=...) needs a scalar or a Spectrum")
    return triple


def _roughness(value: Roughness) -> tuple[float, float]:
    if isinstance(value, Real):
        return float(value), float(value)
    try:
        ax, ay = (float(v) for v in value)
    except (TypeError, ValueError):
        raise TypeError(f"roughness must be a number or an (alpha_x, alpha_y) pair, got {value!r}") from None
    return ax, ay


@dataclass(frozen=True)
class Dielectric:
    """A dielectric interface of absolute IOR `ior` over a homogeneous slab of `thickness` (scene units) with
    absorption `sigma_a` and scattering `sigma_s` coefficients (1/scene unit) and Henyey–Greenstein `g`.
    `roughness` is the GGX/Beckmann alpha (scalar or (alpha_x, alpha_y)), `angle` (radians) rotates the tangent
    frame along which alpha_x applies."""

    ior: Colour
    roughness: Roughness = 0.0
    angle: float = 0.0
    thickness: float = 0.0
    sigma_a: Colour = 0.0
    sigma_s: Colour = 0.0
    g: float = 0.0

    def _resolve(self, wavelengths) -> dict:
        return dict(
            kind="dielectric", ior=_channels("ior", self.ior, wavelengths), roughness=_roughness(self.roughness),
            angle=float(self.angle), thickness=float(self.thickness),
            sigma_a=_channels("sigma_a", self.sigma_a, wavelengths),
            sigma_s=_channels("sigma_s", self.sigma_s, wavelengths), g=float(self.g),
        )


@dataclass(frozen=True)
class Conductor:
    """An opaque conductor of absolute complex IOR `ior` + i`k` with GGX/Beckmann `roughness` and tangent `angle`."""

    ior: Colour
    k: Colour
    roughness: Roughness = 0.0
    angle: float = 0.0

    def _resolve(self, wavelengths) -> dict:
        return dict(
            kind="conductor", ior=_channels("ior", self.ior, wavelengths), k=_channels("k", self.k, wavelengths),
            roughness=_roughness(self.roughness), angle=float(self.angle),
        )


@dataclass(frozen=True)
class Diffuse:
    """An opaque diffuse base of `albedo` in [0, 1]: Lambertian when `roughness` = 0, otherwise Oren–Nayar with
    facet-slope standard deviation sigma = `roughness` radians (in [0, 1])."""

    albedo: Colour
    roughness: float = 0.0

    def _resolve(self, wavelengths) -> dict:
        return dict(kind="diffuse", albedo=_channels("albedo", self.albedo, wavelengths), roughness=float(self.roughness))


Layer = Union[Dielectric, Conductor, Diffuse]


class Stack:
    """Layers from top to bottom, ending in one opaque base (Conductor or Diffuse), under a medium of absolute
    IOR `ext_ior` (air = 1.0). Validated at construction: bad parameters raise ValueError / TypeError."""

    def __init__(self, layers: Sequence[Layer], ext_ior: float = 1.0):
        if isinstance(layers, (Dielectric, Conductor, Diffuse)):
            layers = [layers]
        self.layers = tuple(layers)
        for i, layer in enumerate(self.layers):
            if not isinstance(layer, (Dielectric, Conductor, Diffuse)):
                raise TypeError(f"layers[{i}] must be a lamina.Dielectric, Conductor or Diffuse, got {type(layer).__name__}")
        if not isinstance(ext_ior, Real):
            raise TypeError(f"ext_ior must be a number, got {ext_ior!r}")
        self.ext_ior = float(ext_ior)
        _lamina.check_stack(self._resolve(None), self.ext_ior)

    def __repr__(self) -> str:
        return f"Stack({list(self.layers)!r}, ext_ior={self.ext_ior})"

    def _resolve(self, wavelengths) -> list[dict]:
        return [layer._resolve(wavelengths) for layer in self.layers]

    def eval(self, wi, wo, model: str = "microfacet", *, wavelengths=None, flake_normal=None, distance=None,
             samples: int = 10_000, seed: int = 0, **options) -> np.ndarray:
        """The BRDF f(wi, wo), not multiplied by cos θo.

        wi, wo: directions (..., 3) in the local frame (z = normal), both pointing away from the surface; they need
        not be unit length and broadcast against each other. Directions below the horizon give 0.
        Returns (..., 3) linear RGB channels, or (..., len(wavelengths)) with `wavelengths` (nm). float32 when both
        inputs are float32, float64 otherwise. Units: 1/sr.

        Model options (keyword arguments; an unknown one is a TypeError):
        - every model: `distribution` 'ggx' | 'beckmann'; `g2` 'height_correlated' | 'separable' (Mitsuba 3) |
          'v_cavity'; `fresnel` 'exact' | 'schlick' | 'lazanyi'. Defaults: GGX, height-correlated Smith, exact;
          model="weidlich_wilkie" defaults to Beckmann with the V-cavity G (Torrance–Sparrow).
        - "belcour": `symmetric` (the reciprocal variant); where paper and reference code differ, `cosines`
          'frozen' (code: the transmission scale s at normal incidence) | 'real' (paper: s from the exact Jacobians
          at the lobe mean, |J_t(θi)| / |J_r(θt)|), `jacobian` 'j12' (code) | 'j21' (paper), `energy` 'fgd' | 'fresnel';
          the code's optional TIR step, `tir` 'off' (default) | 'transmittance' (the code's table, which repeats the
          Fresnel factor) | 'fraction' (only the totally reflected fraction);
          `tabulated` (default True) interpolates the adding-doubling from a table over cos θ (and the azimuth, for
          anisotropic stacks), built on the first call and kept for the next calls with the same stack and options.
        - "steinberg": `lut` 'tabulated' (default) | 'fitted' (the article's closed forms).
        - "steinberg" and "weidlich_wilkie": `clamp_roughness` (Elek's m₂ ≥ m₁, default True) and `eta2` (the
          radiance compression 1/η² through each coat, lamina's addition, default True); set both False for the
          published forms.
        - "weidlich_wilkie": `precomputed` (Elek's Fresnel and Beckmann tables); car paint: `flake_normal`
          (..., 3) flake vectors and `distance` (...) viewing distances, broadcast with the directions; the base is
          evaluated about normalize(flake + max(distance, 1) ẑ), which must point above the surface.
        Measured against the reference in docs/validation.md. model="reference" returns the mean of
        `Stack.reference` with `samples` paths per pair (exact Fresnel; `distribution` and `g2` apply)."""
        if model == "reference":
            if flake_normal is not None or distance is not None:
                raise ValueError("flake_normal: flakes are a feature of model 'weidlich_wilkie', got model 'reference'")
            unknown = set(options) - {"distribution", "g2"}
            if unknown:
                raise TypeError(f"model 'reference' takes the options distribution and g2, got {sorted(unknown)}")
            return self.reference(wi, wo, wavelengths=wavelengths, samples=samples, seed=seed, **options)[0]
        wl = _wavelengths(wavelengths)
        if (flake_normal is None) != (distance is None):
            raise ValueError("flake_normal and distance must be given together")
        if flake_normal is None:
            wi, wo = broadcast(wi=(wi, 3), wo=(wo, 3))
            return _lamina.eval_stack(self._resolve(wl), self.ext_ior, model, wi, wo, options)
        wi, wo, fl, d = broadcast(wi=(wi, 3), wo=(wo, 3), flake_normal=(flake_normal, 3), distance=(distance, 0))
        with np.errstate(invalid="ignore"):
            below = fl[..., 2] + np.maximum(d[..., 0], 1.0) <= 0
        if np.any(below):
            raise ValueError("flake_normal: flake + max(distance, 1) ẑ must point above the surface (z > 0)")
        return _lamina.eval_stack(self._resolve(wl), self.ext_ior, model, wi, wo, options, fl, d)

    def reference(self, wi, wo, *, wavelengths=None, samples: int = 100_000, seed: int = 0, progress=None,
                  distribution: str = "ggx", g2: str = "height_correlated"):
        """Monte Carlo ground truth for f(wi, wo): unbiased, with next-event estimation through the stack's delta
        interfaces (see src/reference.rs). wi, wo: (..., 3), broadcast. Returns (f, stderr), each (..., channels).
        Specular (Dirac) lobes are not part of f. Deterministic for a seed, whatever the thread count."""
        wl = _wavelengths(wavelengths)
        wi, wo = broadcast(wi=(wi, 3), wo=(wo, 3))
        from .reference import f_estimate

        mean, err = f_estimate(self._resolve(wl), self.ext_ior, _unit_rows("wi", wi), _unit_rows("wo", wo), samples,
                               seed, progress=progress, distribution=distribution, g2=g2)
        shape = wi.shape[:-1] + (mean.shape[-1],)
        return mean.reshape(shape), err.reshape(shape)

    def lobes(self, wi, model: str = "belcour", *, wavelengths=None) -> dict:
        """The lobes a statistical model builds for viewing direction(s) wi (..., 3), one GGX lobe per interface
        (L = interfaces down to the first opaque one), all centred on the mirror direction:
        {"energy": (..., L, channels), "covariance": (..., L, 2, 2) in the local tangent frame (Yamaguchi et al.
        2019; σI for isotropic stacks), "roughness": (..., L, 2) the GGX (alpha_x, alpha_y) along the covariance's
        eigenvectors, "angle": (..., L) the tangent angle (radians) of the alpha_x axis}. A lobe of roughness 0 is a
        specular (Dirac) reflection. Only model="belcour" has lobes."""
        if model != "belcour":
            raise ValueError(f"model must be 'belcour' for lobes, got {model!r}")
        wl = _wavelengths(wavelengths)
        (wi,) = broadcast(wi=(wi, 3))
        rows = _unit_rows("wi", wi)
        lead = wi.shape[:-1]
        energy, cov, rough = (np.asarray(a, dtype=np.float64).reshape(lead + np.shape(a)[1:])
                              for a in _lamina.belcour_lobes(self._resolve(wl), self.ext_ior, rows.tolist()))
        sigma = np.stack([cov[..., 0], cov[..., 1], cov[..., 1], cov[..., 2]], -1).reshape(cov.shape[:-1] + (2, 2))
        return {"energy": energy, "covariance": sigma, "roughness": rough[..., :2], "angle": rough[..., 2]}

    def albedo(self, wi, model: str = "microfacet", *, wavelengths=None, samples: int = 100_000, seed: int = 0,
               progress=None, **model_options):
        """Directional albedo ∫ f(wi, wo) cos θo dωo: the fraction of light from wi that the stack reflects.

        wi: (..., 3). Returns (..., channels). For an analytic model the integral is a midpoint quadrature
        (512 x 1024 in θo, φo) of `eval` with `model_options` (its smooth, Dirac parts are not included). With
        model="reference" it is
        the brute-force Monte Carlo walk with `samples` paths per direction (delta reflections included), and the
        result is a pair (albedo, standard error)."""
        wl = _wavelengths(wavelengths)
        (wi,) = broadcast(wi=(wi, 3))
        rows = _unit_rows("wi", wi)
        if model == "reference":
            from .reference import tally

            mean, err = tally(self._resolve(wl), self.ext_ior, rows, samples, seed, progress=progress,
                              **model_options)
            shape = wi.shape[:-1] + (mean.shape[1],)
            return mean[..., 0].reshape(shape), err[..., 0].reshape(shape)
        nt, npp = 512, 1024
        t = (np.arange(nt) + 0.5) * (np.pi / 2 / nt)
        p = (np.arange(npp) + 0.5) * (2 * np.pi / npp)
        wo = np.stack([np.outer(np.sin(t), np.cos(p)), np.outer(np.sin(t), np.sin(p)),
                       np.repeat(np.cos(t)[:, None], npp, axis=1)], axis=-1)
        weight = (np.cos(t) * np.sin(t))[:, None, None] * (np.pi / 2 / nt) * (2 * np.pi / npp)
        out = [np.sum(self.eval(w, wo, model, wavelengths=wl, **model_options)
                      * weight, axis=(0, 1)) for w in rows]
        return np.array(out).reshape(wi.shape[:-1] + (len(out[0]),))

    def reference_lobe(self, wi, bins=(18, 36), *, wavelengths=None, samples: int = 1_000_000, seed: int = 0,
                       progress=None, distribution: str = "ggx", g2: str = "height_correlated"):
        """Brute-force Monte Carlo lobe for light from one direction `wi` (3,): the reflected energy per steradian,
        i.e. f·cos θo averaged over each of n_theta x n_phi bins uniform in (θo, φo) (delta lobes included).

        Returns (f_cos, stderr, (theta_edges, phi_edges)) with f_cos and stderr of shape (n_theta, n_phi, channels)
        and edges in radians."""
        wl = _wavelengths(wavelengths)
        (wi,) = broadcast(wi=(wi, 3))
        if wi.shape != (3,):
            raise ValueError(f"wi must be a single direction of shape (3,), got {wi.shape}")
        n_theta, n_phi = (int(b) for b in bins)
        from .reference import tally

        mean, err = tally(self._resolve(wl), self.ext_ior, _unit_rows("wi", wi), samples, seed,
                          bins=(n_theta, n_phi), progress=progress, distribution=distribution, g2=g2)
        te = np.linspace(0, np.pi / 2, n_theta + 1)
        pe = np.linspace(0, 2 * np.pi, n_phi + 1)
        solid = np.outer(np.cos(te[:-1]) - np.cos(te[1:]), np.diff(pe))  # (n_theta, n_phi) steradians
        per_sr = lambda x: np.moveaxis(x[0].reshape(-1, n_theta, n_phi), 0, -1) / solid[..., None]  # noqa: E731
        return per_sr(mean), per_sr(err), (te, pe)


def _unit_rows(name: str, w: np.ndarray) -> np.ndarray:
    """Rows of w as unit float64 directions above the surface; ValueError otherwise."""
    rows = np.asarray(w, dtype=np.float64).reshape(-1, 3)
    norm = np.linalg.norm(rows, axis=-1, keepdims=True)
    if not np.all(np.isfinite(rows)) or np.any(norm == 0) or np.any(rows[:, 2] <= 0):
        raise ValueError(f"{name} must hold finite, non-zero directions above the surface (z > 0)")
    return rows / norm


def _wavelengths(wavelengths):
    if wavelengths is None:
        return None
    wl = np.atleast_1d(np.asarray(wavelengths, dtype=np.float64))
    if wl.ndim != 1 or not np.all(np.isfinite(wl)) or np.any(wl <= 0):
        raise ValueError(f"wavelengths must be a 1-D array of positive finite values in nm, got {wavelengths!r}")
    return wl
