"""Type stubs of the Rust extension. Arrays arrive broadcast by python/lamina/_arrays.py; see docs/conventions.md."""

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float32] | NDArray[np.float64]

MODELS: list[str]
REFERENCE_MAX_DEPTH: int
__version__: str

def check_layer(layer: dict, name: str) -> None: ...
def check_stack(layers: list[dict], ext_ior: float, model: str | None = None) -> int: ...
def models() -> list[dict]: ...
def eval(
    layers: list[dict],
    ext_ior: float,
    model: str,
    wi: Array,
    wo: Array,
    options: dict | None = None,
    inputs: dict[str, Array] | None = None,
) -> Array: ...
def sample(
    layers: list[dict],
    ext_ior: float,
    model: str,
    wo: Array,
    u: Array,
    options: dict | None = None,
    inputs: dict[str, Array] | None = None,
) -> Array: ...
def pdf(layers: list[dict], ext_ior: float, model: str, wi: Array, wo: Array, options: dict | None = None) -> Array: ...
def specular(layers: list[dict], ext_ior: float, model: str, wo: Array, options: dict | None = None) -> Array: ...
def reference_sample(
    layers: list[dict],
    ext_ior: float,
    wo: Array,
    u: Array,
    distribution: str = "ggx",
    g2: str = "height_correlated",
) -> Array: ...
def steinberg_lut(mu: Array, alpha: Array, eta: Array, lut: str) -> Array: ...
def fresnel_dielectric(cos_i: Array, eta: Array) -> Array: ...
def fresnel_conductor(cos_i: Array, eta: Array, k: Array, form: str) -> Array: ...
def fresnel_schlick(cos_i: Array, f0: Array) -> Array: ...
def fresnel_diffuse_reflectance(eta: Array) -> Array: ...

#: (alpha_x, alpha_y, angle in radians, distribution 'ggx' | 'beckmann')
MicrofacetSpec = tuple[float, float, float, str]

def microfacet_d(m: Array, mf: MicrofacetSpec) -> Array: ...
def microfacet_lambda(w: Array, mf: MicrofacetSpec) -> Array: ...
def microfacet_g2(wi: Array, wo: Array, m: Array, mf: MicrofacetSpec, g2: str) -> Array: ...
def sample_visible(wi: Array, u: Array, mf: MicrofacetSpec) -> Array: ...
def pdf_visible(wi: Array, m: Array, mf: MicrofacetSpec) -> Array: ...
def interface_bsdf(
    kind: str, wi: Array, wo: Array, eta: list[float], k: list[float], mf: MicrofacetSpec, g2: str
) -> Array: ...
def reference_tally(
    layers: list[dict],
    ext_ior: float,
    wi: list[float],
    first: int,
    samples: int,
    seed: int,
    n_theta: int = 1,
    n_phi: int = 1,
    distribution: str = "ggx",
    g2: str = "height_correlated",
) -> tuple[list[list[float]], list[list[float]], list[int]]: ...
def reference_f(
    layers: list[dict],
    ext_ior: float,
    wi: list[list[float]],
    wo: list[list[float]],
    first: int,
    samples: int,
    seed: int,
    distribution: str = "ggx",
    g2: str = "height_correlated",
) -> tuple[list[list[float]], list[list[float]], list[int]]: ...
def belcour_lobes(
    layers: list[dict], ext_ior: float, wo: list[list[float]]
) -> tuple[list[list[list[float]]], list[list[list[float]]], list[list[list[float]]]]: ...
def jacobian(theta_i: Array, xh: Array, yh: Array, eta: Array | None = None, exact: bool = True) -> Array: ...
