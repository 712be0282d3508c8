"""Vectorized optics primitives, exposed for plotting, teaching and cross-checks. Every function broadcasts its
array arguments, accepts float32/float64 with any strides and evaluates in Rust in parallel.
Directions are (..., 3) in the local frame (z = normal) pointing away from the surface."""

from __future__ import annotations

import numpy as np

from . import _lamina
from ._arrays import broadcast
from .layers import _roughness


def _scalar(fn, **inputs) -> np.ndarray:
    return fn(*broadcast(**{k: (v, 0) for k, v in inputs.items()}))[..., 0]


def fresnel_dielectric(cos_i, eta) -> np.ndarray:
    """Exact unpolarized dielectric reflectance; `eta` = η_inside/η_outside, negative `cos_i` = from inside."""
    return _scalar(_lamina.fresnel_dielectric, cos_i=cos_i, eta=eta)


def fresnel_conductor(cos_i, eta, k) -> np.ndarray:
    """Exact unpolarized conductor reflectance of the relative complex IOR eta + ik, cos_i in [0, 1]."""
    return _scalar(lambda *a: _lamina.fresnel_conductor(*a, "exact"), cos_i=cos_i, eta=eta, k=k)


def fresnel_schlick(cos_i, f0) -> np.ndarray:
    """Schlick's approximation f0 + (1 - f0)(1 - cos_i)^5."""
    return _scalar(_lamina.fresnel_schlick, cos_i=cos_i, f0=f0)


def fresnel_lazanyi(cos_i, eta, k) -> np.ndarray:
    """Lazányi & Szirmay-Kalos 2005 approximation [(η-1)² + 4η(1-cos)^5 + k²] / [(η+1)² + k²]."""
    return _scalar(lambda *a: _lamina.fresnel_conductor(*a, "lazanyi"), cos_i=cos_i, eta=eta, k=k)


def fresnel_diffuse_reflectance(eta) -> np.ndarray:
    """Cosine-weighted hemispherical average of the dielectric Fresnel reflectance (exact quadrature)."""
    return _scalar(_lamina.fresnel_diffuse_reflectance, eta=eta)


def _mf(roughness, angle, distribution) -> tuple:
    """The (alpha_x, alpha_y, angle, distribution) spec the Rust bindings take."""
    ax, ay = _roughness(roughness)
    return ax, ay, float(angle), str(distribution)


def ndf(m, roughness, angle=0.0, distribution="ggx") -> np.ndarray:
    """Microfacet normal distribution D(m) (1/sr); roughness in (0, 1], scalar or (alpha_x, alpha_y)."""
    (m,) = broadcast(m=(m, 3))
    return _lamina.microfacet_d(m, _mf(roughness, angle, distribution))[..., 0]


def smith_lambda(w, roughness, angle=0.0, distribution="ggx") -> np.ndarray:
    """Smith Λ(w) of the distribution."""
    (w,) = broadcast(w=(w, 3))
    return _lamina.microfacet_lambda(w, _mf(roughness, angle, distribution))[..., 0]


def masking_shadowing(wi, wo, m, roughness, angle=0.0, distribution="ggx", g2="height_correlated") -> np.ndarray:
    """G2(wi, wo, m): 'separable', 'height_correlated' or 'v_cavity'."""
    wi, wo, m = broadcast(wi=(wi, 3), wo=(wo, 3), m=(m, 3))
    return _lamina.microfacet_g2(wi, wo, m, _mf(roughness, angle, distribution), g2)[..., 0]


def sample_visible_normal(wi, u, roughness, angle=0.0, distribution="ggx") -> np.ndarray:
    """Samples microfacet normals m (..., 3) visible from wi given uniform numbers u (..., 2) in [0, 1)
    (Heitz 2018 for GGX, Heitz & d'Eon 2014 for Beckmann); zero vectors where wi is below the horizon."""
    wi, u = broadcast(wi=(wi, 3), u=(u, 2))
    return _lamina.sample_visible(wi, u, _mf(roughness, angle, distribution))


def visible_normal_pdf(wi, m, roughness, angle=0.0, distribution="ggx") -> np.ndarray:
    """Density (1/sr) of `sample_visible_normal`: G1(wi, m) max(0, wi·m) D(m) / cos θi."""
    wi, m = broadcast(wi=(wi, 3), m=(m, 3))
    return _lamina.pdf_visible(wi, m, _mf(roughness, angle, distribution))[..., 0]


def _channel_list(name, x) -> list[float]:
    try:
        return [float(v) for v in np.atleast_1d(np.asarray(x, dtype=np.float64)).ravel()]
    except (TypeError, ValueError):
        raise TypeError(f"{name} must be a number or one number per channel, got {x!r}") from None


def rough_conductor(wi, wo, eta, k, roughness, angle=0.0, distribution="ggx", g2="height_correlated") -> np.ndarray:
    """Rough conductor BRDF F D G2 / (4 cos θi cos θo), one output channel per entry of eta/k (relative IOR)."""
    eta, k = _channel_list("eta", eta), _channel_list("k", k)
    if len(eta) != len(k):
        raise ValueError(f"eta and k must have the same number of channels, got {len(eta)} and {len(k)}")
    wi, wo = broadcast(wi=(wi, 3), wo=(wo, 3))
    return _lamina.interface_bsdf("conductor", wi, wo, eta, k, _mf(roughness, angle, distribution), g2)


def rough_dielectric(wi, wo, eta, roughness, angle=0.0, distribution="ggx", g2="height_correlated") -> np.ndarray:
    """Rough dielectric BSDF (Walter et al. 2007) for radiance, reflection and transmission, from either side;
    `eta` = η_below/η_above (one output channel per entry), light arriving along wi and leaving along wo."""
    eta = _channel_list("eta", eta)
    wi, wo = broadcast(wi=(wi, 3), wo=(wo, 3))
    return _lamina.interface_bsdf("dielectric", wi, wo, eta, [0.0] * len(eta), _mf(roughness, angle, distribution), g2)


def _jacobian(theta_i, xh, yh, eta, exact: bool) -> np.ndarray:
    inputs = dict(theta_i=theta_i, xh=xh, yh=yh) if eta is None else dict(theta_i=theta_i, xh=xh, yh=yh, eta=eta)
    arrays = broadcast(**{k: (v, 0) for k, v in inputs.items()})
    t, x, y = (a[..., 0] for a in arrays[:3])
    if np.any((t < 0) | (t >= np.pi / 2)):
        raise ValueError("theta_i must be in [0, pi/2) radians")
    if np.any(x * x + y * y >= 1):
        raise ValueError("(xh, yh) must lie inside the unit disc (a projected normal above the surface)")
    if eta is not None and np.any(arrays[3] <= 0):
        raise ValueError("eta must be in (0, inf)")
    out = _lamina.jacobian(*arrays[:3], eta=arrays[3] if eta is not None else None, exact=exact)
    if np.isnan(out).any():
        raise ValueError("eta: total internal reflection (sin θ at the microfacet exceeds eta) for some elements")
    return out.reshape(out.shape[:-1] + (2, 2))


def jacobian_reflect(theta_i, xh=0.0, yh=0.0, exact: bool = True) -> np.ndarray:
    """J_r = ∂(xo, yo)/∂(xh, yh), (..., 2, 2): how the projected reflected direction moves with the projected
    microfacet normal, light from wi = (sin θi, 0, cos θi). exact=False: Belcour's first order 2 cos θi I."""
    return _jacobian(theta_i, xh, yh, None, exact)


def jacobian_refract(theta_i, eta, xh=0.0, yh=0.0, exact: bool = True) -> np.ndarray:
    """J_t = ∂(xt, yt)/∂(xh, yh), (..., 2, 2), for refraction with relative IOR eta. exact=False: Belcour's first
    order ((cos θi − η cos θt)/η) I. ValueError under total internal reflection."""
    return _jacobian(theta_i, xh, yh, eta, exact)


def steinberg_lut(mu, alpha, eta, lut: str = "tabulated") -> np.ndarray:
    """Steinberg's tables for one GGX dielectric interface seen from above at cosine `mu` ((0, 1]), roughness `alpha`
    ([0, 1]) and relative IOR `eta` ([0.25, 4], below / above): (..., 2) with t, the mean Fresnel transmission over
    the visible microfacets, and s, the sine of the mean refracted direction. `lut` 'tabulated' | 'fitted'."""
    mu, alpha, eta = broadcast(mu=(mu, 0), alpha=(alpha, 0), eta=(eta, 0))
    for name, x, lo, hi, lo_open in (
        ("mu", mu, 0.0, 1.0, True),
        ("alpha", alpha, 0.0, 1.0, False),
        ("eta", eta, 0.25, 4.0, False),
    ):
        if not np.all(np.isfinite(x)) or np.any(x > hi) or np.any(x <= lo if lo_open else x < lo):
            raise ValueError(f"{name} must be in {'(' if lo_open else '['}{lo}, {hi}]")
    return _lamina.steinberg_lut(mu, alpha, eta, lut)
