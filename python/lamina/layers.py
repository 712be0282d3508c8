"""Layer descriptions (validated when constructed). Conventions: docs/conventions.md."""

from __future__ import annotations

import math
from dataclasses import dataclass, fields, replace
from numbers import Real
from typing import Sequence, Union

from . import _lamina
from .spectrum import RGB_WAVELENGTHS, Spectrum

#: A colour quantity: a scalar (grey), an RGB triple, or a Spectrum.
Colour = Union[float, Sequence[float], Spectrum]
#: A GGX/Beckmann roughness alpha in [0, 1]: isotropic scalar or (alpha_x, alpha_y) along the layer's tangent.
Roughness = Union[float, Sequence[float]]


@dataclass(frozen=True)
class Param:
    """A free parameter of a layer: a number between `low` and `high` that `lamina.fit` finds (starting at `init`,
    default the middle) and `Stack.eval_grad` differentiates by. In place of a layer's number, or of one entry of
    an RGB triple or a roughness pair: `lamina.Conductor(Param("eta", 0.1, 3.0), k=3.0, roughness=Param("r", 0.01,
    1.0))`. A stack holding Params is a template; `Stack.bind(eta=..., r=...)` makes it a stack. One name is one
    parameter wherever it appears."""

    name: str
    low: float
    high: float
    init: float | None = None

    def __post_init__(self):
        if not isinstance(self.name, str) or not self.name.isidentifier():
            raise TypeError(f"Param name must be a Python identifier, got {self.name!r}")
        for k in ("low", "high") + (("init",) if self.init is not None else ()):
            v = getattr(self, k)
            if not isinstance(v, Real) or isinstance(v, bool) or not math.isfinite(v):
                raise ValueError(f"Param {self.name!r}: {k} must be a finite number, got {v!r}")
        if not self.low < self.high:
            raise ValueError(f"Param {self.name!r}: low must be below high, got [{self.low}, {self.high}]")
        if self.init is not None and not self.low <= self.init <= self.high:
            raise ValueError(f"Param {self.name!r}: init must lie in [{self.low}, {self.high}], got {self.init}")

    @property
    def start(self) -> float:
        """Where a fit starts: `init`, else the middle of [low, high]."""
        return 0.5 * (self.low + self.high) if self.init is None else float(self.init)


def _params_in(value) -> list:
    """The Params in a field's value (a Param, or a tuple or list holding some)."""
    if isinstance(value, Param):
        return [value]
    if isinstance(value, (tuple, list)):
        return [v for v in value if isinstance(v, Param)]
    return []


def _bound(value, values: dict):
    """A field's value with each Param replaced by values[name]."""
    if isinstance(value, Param):
        return float(values[value.name])
    if isinstance(value, (tuple, list)) and any(isinstance(v, Param) for v in value):
        return tuple(float(values[v.name]) if isinstance(v, Param) else v for v in value)
    return value


def layer_params(layer) -> list:
    """The Params of a layer, field by field: (field name, Param, entry index or None)."""
    out = []
    for f in fields(layer):
        v = getattr(layer, f.name)
        if isinstance(v, Param):
            out.append((f.name, v, None))
        elif isinstance(v, (tuple, list)):
            out += [(f.name, x, i) for i, x in enumerate(v) if isinstance(x, Param)]
    return out


def bind_layer(layer, values: dict):
    """`layer` with its Params replaced by `values` (name -> number), validated as any layer."""
    return replace(layer, **{f.name: _bound(getattr(layer, f.name), values) for f in fields(layer)})


def _validate_template(layer) -> None:
    """A layer holding Params is valid when it is at both ends of their ranges (each field's range is an
    interval): a ValueError names the Param whose range leaves the layer's."""
    params = [p for _, p, _ in layer_params(layer)]
    for end in ("low", "high"):
        try:
            bind_layer(layer, {p.name: getattr(p, end) for p in params})
        except (ValueError, TypeError) as e:
            names = ", ".join(f"{p.name!r} [{p.low}, {p.high}]" for p in params)
            raise ValueError(f"{type(layer).__name__}: the range of Param {names} leaves the layer's: {e}") from None


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


def _colour(value: Colour):
    """A colour quantity in a hashable form: a number, a tuple of floats, or a Spectrum."""
    if isinstance(value, Spectrum) or (isinstance(value, Real) and not isinstance(value, bool)):
        return value
    if isinstance(value, (str, bytes, bool)) or value is None:
        raise TypeError(f"a colour must be a number, an RGB triple or a lamina.Spectrum, got {value!r}")
    try:
        return tuple(float(v) for v in value)
    except (TypeError, ValueError):
        raise TypeError(f"a colour must be a number, an RGB triple or a lamina.Spectrum, got {value!r}") from None


def _validate(layer, colours: tuple, scalars: tuple) -> None:
    """Normalises a frozen layer's fields (colours to tuples, roughness to a pair) and checks its ranges in Rust; a
    layer holding Params is checked at both ends of their ranges (`_validate_template`)."""
    if layer_params(layer):
        for f in fields(layer):
            if isinstance(getattr(layer, f.name), list):
                object.__setattr__(layer, f.name, tuple(getattr(layer, f.name)))
        _validate_template(layer)
        return
    for name in colours:
        try:
            object.__setattr__(layer, name, _colour(getattr(layer, name)))
        except TypeError:
            raise TypeError(
                f"{type(layer).__name__}: {name} must be a number, an RGB triple or a lamina.Spectrum, "
                f"got {getattr(layer, name)!r}"
            ) from None
    for name in scalars:
        v = getattr(layer, name)
        if name == "roughness" and not isinstance(layer, Diffuse):
            object.__setattr__(layer, name, v if isinstance(v, Real) and not isinstance(v, bool) else _roughness(v))
        elif not isinstance(v, Real) or isinstance(v, bool):
            raise TypeError(f"{type(layer).__name__}: {name} must be a number, got {v!r}")
    _lamina.check_layer(layer._resolve(None), type(layer).__name__)


def _roughness(value: Roughness) -> tuple[float, float]:
    if isinstance(value, Real) and not isinstance(value, bool):
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

    def __post_init__(self):
        _validate(self, ("ior", "sigma_a", "sigma_s"), ("roughness", "angle", "thickness", "g"))

    def _resolve(self, wavelengths) -> dict:
        return dict(
            kind="dielectric",
            ior=_channels("ior", self.ior, wavelengths),
            roughness=_roughness(self.roughness),
            angle=float(self.angle),
            thickness=float(self.thickness),
            sigma_a=_channels("sigma_a", self.sigma_a, wavelengths),
            sigma_s=_channels("sigma_s", self.sigma_s, wavelengths),
            g=float(self.g),
        )


@dataclass(frozen=True)
class Conductor:
    """An opaque conductor of absolute complex IOR `ior` + i`k` with GGX/Beckmann `roughness` and tangent `angle`."""

    ior: Colour
    k: Colour
    roughness: Roughness = 0.0
    angle: float = 0.0

    def __post_init__(self):
        _validate(self, ("ior", "k"), ("roughness", "angle"))

    def _resolve(self, wavelengths) -> dict:
        return dict(
            kind="conductor",
            ior=_channels("ior", self.ior, wavelengths),
            k=_channels("k", self.k, wavelengths),
            roughness=_roughness(self.roughness),
            angle=float(self.angle),
        )


@dataclass(frozen=True)
class Diffuse:
    """An opaque diffuse base of `albedo` in [0, 1]: Lambertian when `roughness` = 0, otherwise Oren–Nayar with
    facet-slope standard deviation sigma = `roughness` radians (in [0, 1])."""

    albedo: Colour
    roughness: float = 0.0

    def __post_init__(self):
        _validate(self, ("albedo",), ("roughness",))

    def _resolve(self, wavelengths) -> dict:
        return dict(
            kind="diffuse", albedo=_channels("albedo", self.albedo, wavelengths), roughness=float(self.roughness)
        )


Layer = Union[Dielectric, Conductor, Diffuse]
