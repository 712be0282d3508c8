"""Type stubs of the Rust extension. Arrays arrive broadcast by python/lamina/_arrays.py; see docs/conventions.md."""

from typing import final

import numpy as np
from numpy.typing import NDArray

_Array = NDArray[np.float32] | NDArray[np.float64]

__all__ = [
    "DEVICES",
    "MODELS",
    "REFERENCE_MAX_DEPTH",
    "OAT_POISSON_DISC",
    "OAT_VARIANTS",
    "OAT_BORDERS",
    "SOURCE_HASH",
    "__version__",
    "belcour_lobes",
    "cache_read",
    "cache_root",
    "cache_write",
    "check_layer",
    "check_stack",
    "eval",
    "eval_gpu",
    "sample_gpu",
    "pdf_gpu",
    "fresnel_conductor",
    "fresnel_dielectric",
    "fresnel_diffuse_reflectance",
    "fresnel_schlick",
    "gpu_adapter",
    "_gpu_lose_after",
    "gpu_models",
    "gpu_resident_seconds",
    "gpu_readback_seconds",
    "interface_bsdf",
    "use_gpu",
    "jacobian",
    "microfacet_d",
    "microfacet_g2",
    "microfacet_lambda",
    "models",
    "pdf",
    "pdf_visible",
    "reference_f",
    "reference_sample",
    "read_image",
    "read_obj",
    "reference_tally",
    "render",
    "render_oat",
    "oat_parallax",
    "oat_poisson_filter",
    "oat_light_map",
    "oat_slab_exit",
    "OatMaterial",
    "render_gpu",
    "render_oat_gpu",
    "sample",
    "sample_visible",
    "sky",
    "specular",
    "eval_grad",
    "steinberg_lut",
    "write_exr",
    "write_png",
]

MODELS: list[str]
DEVICES: list[str]
REFERENCE_MAX_DEPTH: int
OAT_POISSON_DISC: list[list[float]]
OAT_VARIANTS: list[str]
OAT_BORDERS: list[str]
__version__: str
SOURCE_HASH: str

def check_layer(layer: dict, name: str) -> None: ...
def check_stack(layers: list[dict], ext_ior: float, model: str | None = None) -> int: ...
def models() -> list[dict]: ...
def use_gpu(device: str, model: str | None = None, options: dict | None = None, float32: bool = True) -> bool: ...
def cache_read(path: str) -> bytes | None: ...
def cache_write(path: str, payload: bytes) -> None: ...
def cache_root() -> str | None: ...
def eval(
    layers: list[dict],
    ext_ior: float,
    model: str,
    wi: _Array,
    wo: _Array,
    options: dict | None = None,
    inputs: dict[str, _Array] | None = None,
) -> _Array: ...
def sample(
    layers: list[dict],
    ext_ior: float,
    model: str,
    wo: _Array,
    u: _Array,
    options: dict | None = None,
    inputs: dict[str, _Array] | None = None,
) -> _Array: ...
def pdf(
    layers: list[dict], ext_ior: float, model: str, wi: _Array, wo: _Array, options: dict | None = None
) -> _Array: ...
def specular(layers: list[dict], ext_ior: float, model: str, wo: _Array, options: dict | None = None) -> _Array: ...
def eval_grad(
    layers: list[dict],
    ext_ior: float,
    model: str,
    wi: _Array,
    wo: _Array,
    seeds: list[tuple[int, int, str, int, float]],
    n_params: int,
    options: dict | None = None,
) -> _Array: ...
def reference_sample(
    layers: list[dict],
    ext_ior: float,
    wo: _Array,
    u: _Array,
    options: dict | None = None,
) -> _Array: ...
def steinberg_lut(mu: _Array, alpha: _Array, eta: _Array, lut: str) -> _Array: ...
def fresnel_dielectric(cos_i: _Array, eta: _Array) -> _Array: ...
def fresnel_conductor(cos_i: _Array, eta: _Array, k: _Array, form: str) -> _Array: ...
def fresnel_schlick(cos_i: _Array, f0: _Array) -> _Array: ...
def fresnel_diffuse_reflectance(eta: _Array) -> _Array: ...

#: (alpha_x, alpha_y, angle in radians, distribution 'ggx' | 'beckmann')
_MicrofacetSpec = tuple[float, float, float, str]

def microfacet_d(m: _Array, mf: _MicrofacetSpec) -> _Array: ...
def microfacet_lambda(w: _Array, mf: _MicrofacetSpec) -> _Array: ...
def microfacet_g2(wi: _Array, wo: _Array, m: _Array, mf: _MicrofacetSpec, g2: str) -> _Array: ...
def sample_visible(wi: _Array, u: _Array, mf: _MicrofacetSpec) -> _Array: ...
def pdf_visible(wi: _Array, m: _Array, mf: _MicrofacetSpec) -> _Array: ...
def interface_bsdf(
    kind: str, wi: _Array, wo: _Array, eta: list[float], k: list[float], mf: _MicrofacetSpec, g2: str
) -> _Array: ...
def reference_tally(
    layers: list[dict],
    ext_ior: float,
    wi: list[float],
    first: int,
    samples: int,
    seed: int,
    n_theta: int = 1,
    n_phi: int = 1,
    options: dict | None = None,
) -> tuple[list[list[float]], list[list[float]], list[int]]: ...
def reference_f(
    layers: list[dict],
    ext_ior: float,
    wi: list[list[float]],
    wo: list[list[float]],
    first: int,
    samples: int,
    seed: int,
    options: dict | None = None,
) -> tuple[list[list[float]], list[list[float]], list[int]]: ...
def belcour_lobes(
    layers: list[dict], ext_ior: float, wo: list[list[float]]
) -> tuple[list[list[list[float]]], list[list[list[float]]], list[list[list[float]]]]: ...
def jacobian(theta_i: _Array, xh: _Array, yh: _Array, eta: _Array | None = None, exact: bool = True) -> _Array: ...
def render(
    stacks: list[tuple[list[dict], float]],
    model: str,
    options: dict | None,
    textures: dict[str, _Array] | None,
    shape: str | tuple,
    camera: tuple[tuple[float, float, float], tuple[float, float, float], float] | None,
    lights: list[tuple[str, tuple[float, float, float], tuple[float, float, float]]],
    env: tuple[_Array, float, float] | None,
    width: int,
    height: int,
    spp: int,
    seed: int,
    first: int,
    rows: int,
) -> _Array: ...
def oat_parallax(uv: _Array, view: _Array, normal: _Array, thickness: _Array, texel: tuple[float, float]) -> _Array: ...
def oat_poisson_filter(
    image: _Array, uv: _Array, radius: _Array, texel: tuple[float, float], border: str
) -> _Array: ...
def oat_light_map(
    normal_map: _Array,
    shape: str | tuple,
    lights: list[tuple[str, tuple[float, float, float], tuple[float, float, float]]],
    dilate_passes: int,
) -> _Array: ...
def oat_slab_exit(thickness: float, sigma_s: float, sigma_a: float, g: float, samples: int, seed: int) -> _Array: ...

@final
class OatMaterial:
    def __new__(
        cls,
        outer_albedo: _Array,
        outer_opacity: _Array,
        outer_normal: _Array,
        inner: list[tuple[_Array, _Array | None, _Array]],
        variant: str,
        shadowing: bool,
        border: str,
        texel: tuple[float, float],
        dilate: int,
        light_map: _Array | None,
    ) -> OatMaterial: ...

def render_oat(
    materials: list[OatMaterial],
    shape: str | tuple,
    camera: tuple[tuple[float, float, float], tuple[float, float, float], float] | None,
    lights: list[tuple[str, tuple[float, float, float], tuple[float, float, float]]],
    width: int,
    height: int,
    first: int,
    rows: int,
) -> _Array: ...
def sky(width: int) -> tuple[_Array, list[float], list[float]]: ...
def read_image(path: str) -> _Array: ...
def read_obj(path: str) -> tuple[list[list[float]], list[list[float]], list[list[float]], list[list[int]]]: ...
def write_png(path: str, image: _Array) -> None: ...
def write_exr(path: str, image: _Array) -> None: ...
def gpu_adapter() -> dict[str, str]: ...
def gpu_models() -> list[str]: ...
def _gpu_lose_after(dispatches: int) -> None: ...
def eval_gpu(
    layers: list[dict],
    ext_ior: float,
    model: str,
    wi: _Array,
    wo: _Array,
    options: dict | None = None,
    inputs: dict[str, _Array] | None = None,
) -> _Array: ...
def sample_gpu(
    layers: list[dict],
    ext_ior: float,
    model: str,
    wo: _Array,
    u: _Array,
    options: dict | None = None,
    inputs: dict[str, _Array] | None = None,
) -> _Array: ...
def pdf_gpu(
    layers: list[dict], ext_ior: float, model: str, wi: _Array, wo: _Array, options: dict | None = None
) -> _Array: ...
def gpu_resident_seconds(
    layers: list[dict],
    ext_ior: float,
    model: str,
    wi: _Array,
    wo: _Array,
    repeats: int,
    options: dict | None = None,
) -> float: ...
def gpu_readback_seconds(bytes: int, repeats: int) -> float: ...
def render_gpu(
    stacks: list[tuple[list[dict], float]],
    model: str,
    options: dict | None,
    textures: dict[str, _Array] | None,
    shape: str | tuple,
    camera: tuple[tuple[float, float, float], tuple[float, float, float], float] | None,
    lights: list[tuple[str, tuple[float, float, float], tuple[float, float, float]]],
    width: int,
    height: int,
    env: tuple[_Array, float, float] | None = None,
    spp: int = 1,
    seed: int = 0,
) -> _Array: ...
def render_oat_gpu(
    materials: list[OatMaterial],
    shape: str | tuple,
    camera: tuple[tuple[float, float, float], tuple[float, float, float], float] | None,
    lights: list[tuple[str, tuple[float, float, float], tuple[float, float, float]]],
    width: int,
    height: int,
) -> _Array: ...
