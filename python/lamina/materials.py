"""Material presets built from the shipped measured data."""

from __future__ import annotations

from numbers import Integral, Real

import numpy as np

from .layers import Colour, Conductor, Dielectric, Diffuse, Roughness, _channels
from .spectrum import IOR_MATERIALS, RGB_WAVELENGTHS, ior
from .stack import Stack


def metal(material: str, roughness: Roughness = 0.1, angle: float = 0.0) -> Conductor:
    """A conductor with the measured spectral complex IOR of `material` (one of IOR_MATERIALS)."""
    n, k = ior(material)
    return Conductor(ior=n, k=k, roughness=roughness, angle=angle)


def measured_rgb(material: str) -> tuple[tuple[float, float, float], tuple[float, float, float]]:
    """RGB complex IOR (n, k) sampled from the shipped measured table of `material` (one of IOR_MATERIALS; sources
    in python/lamina/data/ior/) at Elek 2010's wavelengths 690/550/450 nm, rounded to 4 decimals."""
    n, k = ior(material)
    return tuple(n(RGB_WAVELENGTHS).round(4).tolist()), tuple(k(RGB_WAVELENGTHS).round(4).tolist())


#: Elek 2010's published RGB optical constants (Appendix A, "Selected coefficients"): absolute n and κ at 690, 550
#: and 450 nm of copper, chromium and cuprite, exactly as printed. car_paint() and Patina use them.
ELEK2010 = {
    "Cu": ((0.213, 1.04, 1.17), (4.05, 2.59, 2.36)),
    "Cr": ((3.84, 3.18, 1.99), (4.37, 4.41, 4.22)),
    "Cu2O": ((2.83, 3.10, 3.06), (0.083, 0.19, 0.6)),
}

#: The same three materials sampled from lamina's measured tables at Elek's wavelengths (`measured_rgb`);
#: docs/validation.md compares them with ELEK2010.
MEASURED_RGB = {m: measured_rgb(m) for m in ELEK2010}


def plastic(albedo=(0.6, 0.1, 0.08), ior: float = 1.5, roughness: Roughness = 0.0) -> Stack:
    """A dielectric coat over a Lambertian base (with roughness 0: Mitsuba's `plastic`)."""
    return Stack([Dielectric(ior, roughness), Diffuse(albedo)])


def preset(name: str) -> Stack:
    """A named material for demos and plots (single interfaces, and layered stacks for the layered models); see
    PRESETS."""
    if not isinstance(name, str):
        raise TypeError(f"name must be a string, one of {sorted(PRESETS)}, got {name!r}")
    try:
        return PRESETS[name]()
    except KeyError:
        raise ValueError(f"name must be one of {sorted(PRESETS)}, got {name!r}") from None


class _Factories(dict):
    """Material factories by name; prints as the names it holds."""

    def __repr__(self) -> str:
        return f"{type(self).__name__.lstrip('_')}({list(self)})"


PRESETS = _Factories(
    {
        "gold": lambda: Stack([metal("Au", 0.15)]),
        "silver": lambda: Stack([metal("Ag", 0.1)]),
        "copper": lambda: Stack([metal("Cu", 0.2)]),
        "aluminium": lambda: Stack([metal("Al", 0.25)]),
        "chromium": lambda: Stack([metal("Cr", 0.1)]),
        "brushed-aluminium": lambda: Stack([metal("Al", (0.05, 0.35), angle=np.pi / 4)]),
        "red-plastic": lambda: plastic(),
        "clay": lambda: Stack([Diffuse((0.55, 0.35, 0.25), roughness=0.6)]),
        # Layered: evaluate with model="belcour", "steinberg" or "weidlich_wilkie".
        "coated-copper": lambda: Stack([Dielectric(1.5, 0.2), metal("Cu", 0.35)]),
        "car-paint": lambda: car_paint(),
        "varnished-wood": lambda: Stack(
            [Dielectric(1.5, 0.05, thickness=1.0, sigma_a=(0.1, 0.35, 0.9)), Diffuse((0.45, 0.25, 0.12), roughness=0.3)]
        ),
    }
)

#: The material suite used for validation and benchmarks: layered stacks covering coats over metals, absorbing and
#: scattering slabs, anisotropy with rotated tangent frames and three layers. Thicknesses in arbitrary units, with
#: sigma_a / sigma_s in their inverse.
SUITE = _Factories(
    {
        "gold-clearcoat": lambda: Stack([Dielectric(1.5), metal("Au", 0.15)]),
        "frosted-metal": lambda: Stack([Dielectric(1.5, 0.35), metal("Al", 0.02)]),
        "rough-coat-rough-copper": lambda: Stack([Dielectric(1.5, 0.2), metal("Cu", 0.35)]),
        "varnished-diffuse": lambda: Stack(
            [Dielectric(1.5, thickness=1.0, sigma_a=(0.1, 0.35, 0.9)), Diffuse((0.6, 0.35, 0.15))]
        ),
        "anisotropic-coat-metal": lambda: Stack(
            [Dielectric(1.5, (0.1, 0.4), angle=0.5), metal("Al", (0.35, 0.08), angle=-0.4)]
        ),
        "thick-absorbing-slab": lambda: Stack(
            [Dielectric(1.5, 0.1, thickness=5.0, sigma_a=(0.05, 0.15, 0.4)), Diffuse(0.8)]
        ),
        "three-layer": lambda: Stack(
            [Dielectric(1.3, 0.1), Dielectric(1.6, 0.25, thickness=0.5, sigma_a=0.2), metal("Cu", 0.2)]
        ),
        "scattering-slab": lambda: Stack(
            [Dielectric(1.4, thickness=1.0, sigma_a=0.05, sigma_s=2.0, g=0.7), Diffuse((0.5, 0.4, 0.3))]
        ),
    }
)


def car_paint(
    coat_absorption: Colour = (0.1, 1.2, 1.5),
    coat_thickness: float = 1.0,
    coat_roughness: Roughness = 0.03,
    flake_roughness: Roughness = 0.25,
    ior: float = 1.5,
) -> Stack:
    """Elek 2010's metallic car paint: a tinted clear coat (absorption 1/scene unit over `coat_thickness`) over a
    chromium flake base with Elek's RGB complex IOR of Cr (ELEK2010). Evaluate with model="weidlich_wilkie" and
    per-sample `flake_normal` / `distance` (see `flake_normals`)."""
    n, k = ELEK2010["Cr"]
    return Stack(
        [
            Dielectric(ior, coat_roughness, thickness=coat_thickness, sigma_a=coat_absorption),
            Conductor(n, k, flake_roughness),
        ]
    )


def flake_normals(uv, density: float = 200.0, spread: float = 0.5, seed: int = 0) -> np.ndarray:
    """Deterministic procedural flake vectors for `uv` (..., 2): one flake per cell of a `density` x `density` grid
    per unit of uv, each a tangential vector (x, y, 0) of length spread·√u in a uniformly random direction (u
    uniform in [0, 1)), hashed from the cell and `seed` (SplitMix64). Returns (..., 3) float64: the `flake_normal`
    of car-paint evaluation, which tilts the base normal to normalize(flake + max(distance, 1) ẑ)."""
    uv = np.asarray(uv, dtype=np.float64)
    if uv.ndim == 0 or uv.shape[-1] != 2 or not np.all(np.isfinite(uv)):
        raise ValueError(f"uv must be a finite array of shape (..., 2), got shape {uv.shape}")
    if not isinstance(density, Real) or isinstance(density, bool):
        raise TypeError(f"density must be a number, got {density!r}")
    if not isinstance(spread, Real) or isinstance(spread, bool):
        raise TypeError(f"spread must be a number, got {spread!r}")
    if not (isinstance(seed, (int, np.integer)) and not isinstance(seed, bool)):
        raise TypeError(f"seed must be an integer in [0, 2**64), got {seed!r}")
    if not (density > 0 and np.isfinite(density)):
        raise ValueError(f"density must be in (0, inf), got {density}")
    if not (0 <= spread <= 10):
        raise ValueError(f"spread must be in [0, 10], got {spread}")
    if not (isinstance(seed, (int, np.integer)) and 0 <= seed < 2**64):
        raise ValueError(f"seed must be an integer in [0, 2**64), got {seed!r}")
    cell = np.floor(uv * density).astype(np.int64).view(np.uint64)

    def mix(x):
        x = (x + np.uint64(0x9E3779B97F4A7C15)) & np.uint64(0xFFFFFFFFFFFFFFFF)
        x = (x ^ (x >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
        x = (x ^ (x >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
        return x ^ (x >> np.uint64(31))

    with np.errstate(over="ignore"):
        h = mix(mix(cell[..., 0] ^ np.uint64(seed)) ^ cell[..., 1])
        u1 = (h >> np.uint64(11)).astype(np.float64) / 2.0**53
        u2 = (mix(h) >> np.uint64(11)).astype(np.float64) / 2.0**53
    r, phi = spread * np.sqrt(u1), 2 * np.pi * u2
    return np.stack([r * np.cos(phi), r * np.sin(phi), np.zeros_like(r)], -1)


def flake_texture(size: int = 2048, density: float = 600.0, spread: float = 0.3, seed: int = 0) -> np.ndarray:
    """`flake_normals` sampled at the texel centres of a `size` x `size` texture over uv ∈ [0, 1)²: the
    `flake_normal` input of car paint for `lamina.render` ((size, size, 3))."""
    if not isinstance(size, Integral) or isinstance(size, bool) or not 1 <= size <= 16384:
        raise ValueError(f"size must be an integer in [1, 16384], got {size!r}")
    t = (np.arange(size) + 0.5) / size
    return flake_normals(np.stack(np.meshgrid(t, t), -1), density, spread, seed)


def patina_mask(size: int = 512, scale: float = 6.0, seed: int = 0) -> np.ndarray:
    """A grayscale mask (size, size) in [0, 1] for `Patina`: fractal value noise (four octaves of a random grid
    interpolated by smoothstep, wrapping in u), so that the patina gathers in blotches."""
    if not isinstance(size, Integral) or isinstance(size, bool) or not 1 <= size <= 16384:
        raise ValueError(f"size must be an integer in [1, 16384], got {size!r}")
    if not (isinstance(scale, Real) and 1 <= scale <= 1024):
        raise ValueError(f"scale must be in [1, 1024], got {scale!r}")
    rng = np.random.default_rng(seed)
    t = (np.arange(size) + 0.5) / size
    total, weight = np.zeros((size, size)), 0.0
    for octave in range(4):
        cells = int(round(scale * 2**octave))
        grid = rng.random((cells + 1, cells))
        x, y = t * cells, t * cells
        i, j = np.floor(x).astype(int), np.floor(y).astype(int)
        fx, fy = x - i, y - j
        sx, sy = fx * fx * (3 - 2 * fx), fy * fy * (3 - 2 * fy)
        rows = [grid[np.minimum(j + k, cells)] for k in (0, 1)]  # rows of the grid above and below each texel row
        top = rows[0][:, i % cells] * (1 - sx) + rows[0][:, (i + 1) % cells] * sx
        bottom = rows[1][:, i % cells] * (1 - sx) + rows[1][:, (i + 1) % cells] * sx
        total += 0.5**octave * (top * (1 - sy)[:, None] + bottom * sy[:, None])
        weight += 0.5**octave
    return total / weight


#: Light wavelengths of Elek's RGB channels in µm, for absorption coefficients 4πκ/λ.
_RGB_UM = np.asarray(RGB_WAVELENGTHS) / 1000.0


class Patina:
    """Elek 2010's copper patina for model="weidlich_wilkie" (Elek's RGB n, κ of Cu and Cu2O: ELEK2010): a cuprite
    (Cu2O) layer of `thickness` µm over copper, where a grayscale `mask` covers it. Per element, coverage
    w = 1 − smoothstep(extent − transition, extent + transition, mask); f = (1 − w) f_bare + w f_patina, the patina
    layer's roughness and IOR going from the bare copper surface's (no layer) to the patina's with w, and the copper
    under it tarnished by lerp(1, tint, w). The cuprite absorbs σa = 4πκ/λ (Elek's RGB κ) and scatters `scattering`
    per µm, which gives the diffuse patina term T₁₂ T₂₁ (1 − a) σs/(σa + σs) / (π η²): the light the layer does not
    transmit, a its transmittance (1/η² with the default `eta2`).

    `stack` is the patina stack; `eval` evaluates it with the per-element input `mask` and the options `extent`,
    `transition` and `tint` of model "weidlich_wilkie"."""

    def __init__(
        self,
        extent: float = 0.5,
        transition: float = 0.1,
        thickness: float = 0.5,
        roughness: Roughness = 0.35,
        scattering: float = 2.0,
        copper_roughness: Roughness = 0.15,
        tint: Colour = (0.75, 0.45, 0.3),
    ):
        n_cu, k_cu = ELEK2010["Cu"]
        n_p, k_p = ELEK2010["Cu2O"]
        sigma_a = tuple((4 * np.pi * np.asarray(k_p) / _RGB_UM).tolist())
        self.stack = Stack(
            [
                Dielectric(n_p, roughness, thickness=thickness, sigma_a=sigma_a, sigma_s=scattering),
                Conductor(n_cu, k_cu, copper_roughness),
            ]
        )
        self.bare = Stack(self.stack.layers[1:])
        self.params = dict(extent=extent, transition=transition, tint=tuple(_channels("tint", tint, None)))
        self.eval([0, 0, 1.0], [0, 0, 1.0], 0.0)  # validates the parameters

    def __repr__(self) -> str:
        p = self.params
        return (
            f"Patina(extent={p['extent']!r}, transition={p['transition']!r}, tint={p['tint']!r}, stack={self.stack!r})"
        )

    def eval(self, wi, wo, mask, **options) -> np.ndarray:
        """f(wi, wo) where the grayscale map has value `mask` (in [0, 1]); wi, wo (..., 3) and mask (...) broadcast.
        Returns (..., 3) RGB. Options as for Stack.eval with model="weidlich_wilkie"."""
        return self.stack.eval(wi, wo, "weidlich_wilkie", mask=mask, **{**self.params, **options})


def patina(extent: float = 0.5, transition: float = 0.1, **params) -> Patina:
    """Elek 2010's copper patina preset (see `Patina` for `params`); evaluate with `.eval(wi, wo, mask)`."""
    return Patina(extent, transition, **params)


#: Material classes of `population` and their shares.
POPULATION_CLASSES = {
    "metal": 0.10,
    "coated-metal": 0.25,
    "plastic": 0.20,
    "varnish": 0.15,
    "car-paint": 0.15,
    "patina": 0.15,
}


def _log_uniform(rng, lo: float, hi: float) -> float:
    return float(np.exp(rng.uniform(np.log(lo), np.log(hi))))


def _random_roughness(rng, lo: float, hi: float, smooth: float = 0.0, anisotropic: float = 0.0):
    """0 with probability `smooth`, else log-uniform in [lo, hi], anisotropic (alpha_y = alpha_x · U[0.15, 1],
    axes swapped half the time) with probability `anisotropic`."""
    if rng.uniform() < smooth:
        return 0.0
    a = _log_uniform(rng, lo, hi)
    if rng.uniform() >= anisotropic:
        return a
    pair = (a, max(a * rng.uniform(0.15, 1.0), 1e-3))
    return pair if rng.uniform() < 0.5 else pair[::-1]


def random_stack(rng: np.random.Generator) -> tuple[str, Stack]:
    """One stack drawn from `population`'s distribution: (class name, stack)."""
    names = list(POPULATION_CLASSES)
    kind = names[rng.choice(len(names), p=list(POPULATION_CLASSES.values()))]
    angle = float(rng.uniform(0.0, np.pi))
    if kind == "metal":
        return kind, Stack(
            [metal(str(rng.choice(["Au", "Ag", "Cu", "Al", "Cr"])), _random_roughness(rng, 0.03, 0.6, 0, 0.3), angle)]
        )
    if kind == "coated-metal":
        thick = rng.uniform() < 0.3
        coat = Dielectric(
            float(rng.uniform(1.3, 1.8)),
            _random_roughness(rng, 0.02, 0.5, smooth=0.4, anisotropic=0.25),
            angle,
            thickness=float(rng.uniform(0.1, 2.0)) if thick else 0.0,
            sigma_a=tuple(rng.uniform(0.0, 1.0, 3).tolist()) if thick else 0.0,
        )
        base = metal(
            str(rng.choice(["Au", "Ag", "Cu", "Al", "Cr"])), _random_roughness(rng, 0.03, 0.6, 0, 0.25), -angle
        )
        return kind, Stack([coat, base])
    if kind == "plastic":
        coat = Dielectric(float(rng.uniform(1.3, 1.7)), _random_roughness(rng, 0.02, 0.5, smooth=0.4))
        base = Diffuse(
            tuple(rng.uniform(0.05, 0.9, 3).tolist()), float(rng.uniform(0, 0.6)) if rng.uniform() < 0.5 else 0.0
        )
        return kind, Stack([coat, base])
    if kind == "varnish":
        tint = np.array([0.1, 0.35, 0.9]) * rng.uniform(0.0, 1.5)
        coat = Dielectric(
            float(rng.uniform(1.4, 1.6)),
            _random_roughness(rng, 0.02, 0.2, smooth=0.5),
            thickness=float(rng.uniform(0.2, 3.0)),
            sigma_a=tuple(tint.tolist()),
        )
        wood = np.array([0.6, 0.35, 0.15]) * rng.uniform(0.3, 1.4)
        return kind, Stack([coat, Diffuse(tuple(np.clip(wood, 0.0, 1.0).tolist()))])
    if kind == "car-paint":
        n, k = ELEK2010["Cr"]
        layers = [
            Dielectric(
                float(rng.uniform(1.45, 1.55)),
                _log_uniform(rng, 0.01, 0.08),
                thickness=float(rng.uniform(0.5, 2.0)),
                sigma_a=tuple(rng.uniform(0.0, 1.5, 3).tolist()),
            ),
            Conductor(n, k, float(rng.uniform(0.15, 0.5))),
        ]
        if rng.uniform() < 0.3:  # a clear coat over the tinted base coat
            layers.insert(0, Dielectric(float(rng.uniform(1.45, 1.55)), _random_roughness(rng, 0.01, 0.1, smooth=0.5)))
        return kind, Stack(layers)
    n_cu, k_cu = ELEK2010["Cu"]
    n_p, k_p = ELEK2010["Cu2O"]
    return kind, Stack(
        [
            Dielectric(
                n_p,
                float(rng.uniform(0.1, 0.5)),
                thickness=float(rng.uniform(0.05, 1.0)),
                sigma_a=tuple((4 * np.pi * np.asarray(k_p) / _RGB_UM).tolist()),
                sigma_s=float(rng.uniform(0.0, 4.0)) if rng.uniform() < 0.6 else 0.0,
            ),
            Conductor(n_cu, k_cu, float(rng.uniform(0.05, 0.4))),
        ]
    )


def population(n: int = 200, seed: int = 1) -> list[tuple[str, Stack]]:
    """`n` random stacks of real-material ranges, deterministic for `seed`: (class name, stack) pairs. The classes
    and their shares are POPULATION_CLASSES; within a class, every parameter is drawn independently:

    - metal: a bare measured conductor (Au, Ag, Cu, Al, Cr), alpha log-uniform in [0.03, 0.6], anisotropic (ratio
      U[0.15, 1], tangent angle U[0, π)) with probability 0.3;
    - coated-metal: a clear coat (IOR U[1.3, 1.8]; smooth with probability 0.4, else alpha log-uniform in
      [0.02, 0.5], anisotropic with probability 0.25; with probability 0.3 a slab of thickness U[0.1, 2] absorbing
      σa ~ U[0, 1]³) over a measured metal as above (anisotropic with probability 0.25);
    - plastic: a coat (IOR U[1.3, 1.7], smooth with probability 0.4, else alpha log-uniform in [0.02, 0.5]) over a
      diffuse base of albedo U[0.05, 0.9]³, Oren–Nayar σ U[0, 0.6] half the time;
    - varnish: a wood varnish (IOR U[1.4, 1.6], smooth half the time, else alpha log-uniform in [0.02, 0.2];
      thickness U[0.2, 3]; σa = (0.1, 0.35, 0.9)·U[0, 1.5]) over a wood-coloured diffuse base
      (0.6, 0.35, 0.15)·U[0.3, 1.4];
    - car-paint: Elek's tinted coat (IOR U[1.45, 1.55], alpha log-uniform in [0.01, 0.08], thickness U[0.5, 2],
      σa ~ U[0, 1.5]³) over chromium flakes (ELEK2010, alpha U[0.15, 0.5]); with probability 0.3 a clear coat on top;
    - patina: Elek's cuprite (ELEK2010; alpha U[0.1, 0.5], thickness U[0.05, 1] µm, σa = 4πκ/λ, σs U[0, 4] per µm
      with probability 0.6) over copper (alpha U[0.05, 0.4]).

    The chart (make chart) uses seed 1; `lamina.choose` is built from seed 1 and validated on seed 2."""
    if isinstance(n, bool) or not isinstance(n, Integral) or n < 1:
        raise ValueError(f"n must be a positive integer, got {n!r}")
    rng = np.random.default_rng([seed, 0x1A317A])
    return [random_stack(rng) for _ in range(n)]


def suite(name: str) -> Stack:
    """A material of the validation suite (see SUITE)."""
    if not isinstance(name, str):
        raise TypeError(f"name must be a string, one of {sorted(SUITE)}, got {name!r}")
    try:
        return SUITE[name]()
    except KeyError:
        raise ValueError(f"name must be one of {sorted(SUITE)}, got {name!r}") from None


__all__ = [
    "population",
    "random_stack",
    "POPULATION_CLASSES",
    "SUITE",
    "suite",
    "car_paint",
    "flake_normals",
    "flake_texture",
    "patina_mask",
    "Patina",
    "patina",
    "metal",
    "measured_rgb",
    "MEASURED_RGB",
    "ELEK2010",
    "plastic",
    "preset",
    "PRESETS",
    "IOR_MATERIALS",
]
