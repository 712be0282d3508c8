"""Rendering: material balls and swatches of layer stacks under directional, point and environment lights, shaded by
any model of the catalogue or by the Monte Carlo reference; tone mapping and image files. The renderer itself is
Rust (src/render): one call renders a band of rows for a batch of stacks in parallel, with the GIL released.

Camera contract (orthographic, the default; docs/conventions.md): the viewer looks along −z from +z and the image
spans [−1, 1]²; pixel (i, j) has its centre at x = (i + ½)/W·2 − 1, y = 1 − (j + ½)/H·2. On the unit sphere the
shading frame is n = the surface point, t = normalize(ŷ × n), so anisotropic layers streak horizontally. World +y is
up; the environment map's centre lies behind the object (direction −z)."""

from __future__ import annotations

from numbers import Integral, Real
from pathlib import Path

import numpy as np

from . import _lamina
from . import gpu as _gpu
from .catalogue import model as _model
from .materials import Patina
from .oat import Material as OatMaterial
from .stack import Stack

Vec3 = tuple[float, float, float]


def _vec(name: str, v, positive: bool = False, nonzero: bool = False) -> Vec3:
    a = np.asarray(v, dtype=np.float64)
    if a.ndim == 0:
        a = np.full(3, float(a))
    if a.shape != (3,) or not np.all(np.isfinite(a)):
        raise ValueError(f"{name} must be 3 finite numbers, got {v!r}")
    if positive and np.any(a < 0):
        raise ValueError(f"{name} must be in [0, inf) per channel, got {v!r}")
    if nonzero and not np.any(a):
        raise ValueError(f"{name} must not be the zero vector")
    return tuple(float(x) for x in a)


def _number(name: str, v, lo: float, hi: float) -> float:
    if not isinstance(v, Real) or isinstance(v, bool):
        raise TypeError(f"{name} must be a number in [{lo}, {hi}], got {v!r}")
    if not lo <= v <= hi:
        raise ValueError(f"{name} must be in [{lo}, {hi}], got {v!r}")
    return float(v)


class DirectionalLight:
    """A distant light: `direction` points towards the light (world frame, any length), `irradiance` is the RGB
    irradiance (W/m² per channel) on a surface facing it."""

    def __init__(self, direction, irradiance=(1.0, 1.0, 1.0)):
        self.direction = _vec("direction", direction, nonzero=True)
        self.irradiance = _vec("irradiance", irradiance, positive=True)

    def _spec(self):
        return ("directional", self.direction, self.irradiance)

    def __repr__(self) -> str:
        return f"DirectionalLight({self.direction}, {self.irradiance})"


class PointLight:
    """An isotropic point light at `position` with RGB radiant intensity `intensity` (W/sr): irradiance
    intensity·cos/r² at distance r."""

    def __init__(self, position, intensity=(1.0, 1.0, 1.0)):
        self.position = _vec("position", position)
        self.intensity = _vec("intensity", intensity, positive=True)

    def _spec(self):
        return ("point", self.position, self.intensity)

    def __repr__(self) -> str:
        return f"PointLight({self.position}, {self.intensity})"


class EnvironmentLight:
    """Light from every direction: an equirectangular RGB radiance map (an array (h, w, 3), or the path of a Radiance
    .hdr or OpenEXR file), or "sky": the built-in procedural sky with its sun (a directional light), so that nothing
    has to be downloaded. `scale` multiplies the radiance; `rotation` (radians) turns the map (and the sun) about +y.
    Importance-sampled and combined with BSDF sampling by multiple importance sampling."""

    SKY_WIDTH = 512

    def __init__(self, source="sky", scale: float = 1.0, rotation: float = 0.0):
        self.scale = _number("scale", scale, 0.0, float("inf"))
        self.rotation = _number("rotation", rotation, -1e6, 1e6)
        self.sun = None
        if isinstance(source, str) and source == "sky":
            self.name = "sky"
            self.map, sun, irradiance = _lamina.sky(self.SKY_WIDTH)
            c, s = np.cos(self.rotation), np.sin(self.rotation)
            # The map turns by +rotation in azimuth (φ from −z towards +x): so does the sun.
            sun = (c * sun[0] + s * sun[2], sun[1], -s * sun[0] + c * sun[2])
            self.sun = DirectionalLight(sun, tuple(self.scale * e for e in irradiance))
        elif isinstance(source, (str, Path)):
            self.name = str(source)
            if not Path(source).is_file():
                raise ValueError(f"source must be 'sky', an array or an image file; no file {str(source)!r}")
            self.map = np.asarray(_lamina.read_image(str(source)), dtype=np.float64)
        else:
            self.name = "array"
            self.map = np.asarray(source, dtype=np.float64)
        if self.map.ndim != 3 or self.map.shape[2] != 3 or min(self.map.shape[:2]) < 1:
            raise ValueError(f"source must be an (h, w, 3) RGB radiance map, got shape {self.map.shape}")
        if not np.all(np.isfinite(self.map)) or np.any(self.map < 0):
            raise ValueError("source must hold finite, non-negative radiance")
        self.map = np.ascontiguousarray(self.map)

    def __repr__(self) -> str:
        return f"EnvironmentLight({self.name!r}, scale={self.scale}, rotation={self.rotation})"


class Mesh:
    """A triangle mesh to render: `vertices` (n, 3), `triangles` (m, 3) vertex indices, and per vertex `normals`
    (default: area-weighted face normals), `uvs` (n, 2) (default 0: textures then read their first texel) and
    `tangents` (n, 3) (default: normalize(ŷ × n), as on the sphere). World frame as for the sphere; the default
    orthographic camera sees [−1, 1]², so scale the mesh or pass a camera. `Mesh.from_obj(path)` reads a
    Wavefront OBJ file (triangulated)."""

    def __init__(self, vertices, triangles, normals=None, uvs=None, tangents=None):
        self.vertices = self._rows("vertices", vertices, 3)
        n = len(self.vertices)
        tris = np.asarray(triangles)
        if tris.ndim != 2 or tris.shape[1] != 3 or len(tris) == 0 or not np.issubdtype(tris.dtype, np.integer):
            raise ValueError(f"triangles must be a non-empty (m, 3) integer array, got shape {tris.shape}")
        if tris.min() < 0 or tris.max() >= n:
            raise ValueError(f"triangles must index vertices in [0, {n}), got indices in [{tris.min()}, {tris.max()}]")
        self.triangles = np.ascontiguousarray(tris, dtype=np.int64)
        self.normals = self._vertex_normals() if normals is None else self._rows("normals", normals, 3, n)
        self.uvs = np.zeros((n, 2)) if uvs is None else self._rows("uvs", uvs, 2, n)
        self.tangents = None if tangents is None else self._rows("tangents", tangents, 3, n)

    @staticmethod
    def _rows(name: str, a, k: int, n: int | None = None) -> np.ndarray:
        a = np.ascontiguousarray(a, dtype=np.float64)
        if a.ndim != 2 or a.shape[1] != k or (n is not None and len(a) != n) or len(a) == 0:
            want = f"({n if n is not None else 'n'}, {k})"
            raise ValueError(f"{name} must have shape {want}, got {a.shape}")
        if not np.all(np.isfinite(a)):
            raise ValueError(f"{name} must be finite")
        return a

    def _vertex_normals(self) -> np.ndarray:
        p = self.vertices[self.triangles]
        face = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])  # length = twice the area: area weighting
        normals = np.zeros_like(self.vertices)
        for k in range(3):
            np.add.at(normals, self.triangles[:, k], face)
        length = np.linalg.norm(normals, axis=-1, keepdims=True)
        return np.where(length > 0, normals / np.where(length > 0, length, 1), [0.0, 0.0, 1.0])

    @classmethod
    def from_obj(cls, path) -> Mesh:
        """Reads a Wavefront OBJ file through the `tobj` crate: every object merged, polygons triangulated."""
        if not Path(path).is_file():
            raise ValueError(f"path: no file {str(path)!r}")
        p, n, uv, tris = _lamina.read_obj(str(path))
        return cls(p, np.asarray(tris, dtype=np.int64), n if len(n) else None, uv if len(uv) else None)

    def _spec(self) -> tuple:
        return (self.vertices, self.normals, self.uvs, self.tangents, self.triangles.astype(np.float64))

    def __repr__(self) -> str:
        return f"Mesh({len(self.vertices)} vertices, {len(self.triangles)} triangles)"


def sky(scale: float = 1.0, rotation: float = 0.0) -> EnvironmentLight:
    """The built-in sky and sun."""
    return EnvironmentLight("sky", scale, rotation)


def _stacks(stacks) -> tuple[list, dict, bool]:
    """(stacks, options they bring (a Patina's), whether one was given)."""
    single = isinstance(stacks, (Stack, Patina))
    items = [stacks] if single else list(stacks)
    if not items:
        raise ValueError("stacks must be a Stack or a non-empty list of them")
    options: dict = {}
    out = []
    for i, s in enumerate(items):
        if isinstance(s, Patina):
            if options and options != s.params:
                raise ValueError("stacks: patinas of one render call must share extent, transition and tint")
            options = dict(s.params)
            s = s.stack
        if not isinstance(s, Stack):
            raise TypeError(f"stacks[{i}] must be a lamina.Stack or materials.Patina, got {type(s).__name__}")
        out.append(s)
    return out, options, single


def _texture(name: str, value, width: int) -> np.ndarray:
    """A per-element input as a texture (h, w, width) looked up by uv; a constant becomes 1 x 1."""
    a = np.asarray(value, dtype=np.float64)
    if a.ndim <= 1 and a.size in (1, width):
        a = np.broadcast_to(a, (width,)).reshape(1, 1, width)
    elif a.ndim == 2 and width == 1:
        a = a[..., None]
    if a.ndim != 3 or a.shape[-1] != width or min(a.shape[:2]) < 1:
        shape = "(h, w)" if width == 1 else f"(h, w, {width})"
        raise ValueError(f"{name} must be a constant or a texture of shape {shape}, got shape {a.shape}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{name} must be finite")
    return np.ascontiguousarray(a)


def _progress(total: int, progress):
    if progress is False or (progress is None and total < 2_000_000):
        return None
    try:
        from tqdm.auto import tqdm
    except ImportError:
        return None
    return tqdm(total=total, unit="sample", unit_scale=True, desc="lamina render")


def _scene(shape, width: int, height: int, camera):
    """Checked shape spec, size and camera (origin, target, fov in radians) or None."""
    for name, v in (("width", width), ("height", height)):
        if not isinstance(v, Integral) or isinstance(v, bool):
            raise TypeError(f"{name} must be an integer, got {v!r}")
        if not 1 <= v <= 16384:
            raise ValueError(f"{name} must be in [1, 16384], got {v}")
    if isinstance(shape, Mesh):
        shape = shape._spec()
    elif not isinstance(shape, str) or shape not in ("sphere", "plane"):
        raise ValueError(f"shape must be 'sphere', 'plane' or a lamina.Mesh, got {shape!r}")
    if camera is not None:
        try:
            origin, target, fov = camera
        except (TypeError, ValueError):
            raise TypeError("camera must be None or (origin, target, fov_degrees)") from None
        camera = (_vec("camera origin", origin), _vec("camera target", target), np.radians(_number("fov", fov, 1, 179)))
        if np.allclose(camera[0], camera[1]):
            raise ValueError("camera origin and target must differ")
    return shape, camera


def _render_oat(material, shape, width, height, lights, device, camera, progress) -> np.ndarray:
    """lamina.render for Oat materials: each one prepared (light map) once, then rendered in bands of rows."""
    single = isinstance(material, OatMaterial)
    materials = [material] if single else list(material)
    for i, m in enumerate(materials):
        if not isinstance(m, OatMaterial):
            raise TypeError(f"material[{i}] must be a lamina.oat.Material, got {type(m).__name__}")
    shape, camera = _scene(shape, width, height, camera)
    lights = [DirectionalLight((0.5, 0.6, 1.0), (3.0, 3.0, 3.0))] if lights is None else list(lights)
    for i, light in enumerate(lights):
        if not isinstance(light, (DirectionalLight, PointLight)):
            raise TypeError(f"lights[{i}]: Oat materials take DirectionalLight and PointLight, got {light!r}")
    specs = [light._spec() for light in lights]
    if _gpu.use_gpu(device, None):  # the GPU lights its own light maps
        prepared = [m._prepared(shape, specs, light_map=False) for m in materials]
        out = _lamina.render_oat_gpu(prepared, shape, camera, specs, width, height)
        return out[0] if single else out
    prepared = [m._prepared(shape, specs) for m in materials]
    out = np.empty((len(materials), height, width, 3), dtype=np.float32)
    band = max(1, 4096 // width)
    bar = _progress(len(materials) * width * height, progress)
    for first in range(0, height, band):
        rows = min(band, height - first)
        out[:, first : first + rows] = _lamina.render_oat(prepared, shape, camera, specs, width, height, first, rows)
        if bar is not None:
            bar.update(len(materials) * width * rows)
    if bar is not None:
        bar.close()
    return out[0] if single else out


def render(
    stacks=None,
    model: str = "microfacet",
    *,
    material=None,
    shape: str = "sphere",
    width: int = 256,
    height: int = 256,
    lights=None,
    spp: int = 16,
    device: str = "auto",
    seed: int = 0,
    camera=None,
    progress=None,
    **kwargs,
) -> np.ndarray:
    """Renders one stack or a list of stacks with `model` ("reference" for the Monte Carlo truth) and returns linear
    HDR radiance, float32: (height, width, 3) for one stack, (N, height, width, 3) for N.

    shape: "sphere" (the unit sphere at the origin), "plane" (the square [−1, 1]² at z = 0 facing +z) or a Mesh. camera:
    None for the orthographic contract of this module, or (origin, target, fov_degrees) for a pinhole with +y up.
    lights: DirectionalLight, PointLight and EnvironmentLight objects; default [sky()], the built-in sky and sun.
    Directional and point lights are exact (no noise); an environment adds `spp` samples per pixel, deterministic
    for `seed`; every stack sees the same samples. The reference estimates f per light and the environment by random
    walks, `spp` per pixel and channel. Keyword arguments are the model's options, and its per-element inputs as
    textures over the surface's uv ((h, w) or (h, w, 3) arrays, or constants), e.g. flake_normal for car paint.
    device: "auto" (default), "cpu" or "gpu", by the rule of Stack.eval (docs/conventions.md): "gpu" renders with the
    models that run on the GPU (lamina.gpu.models(), wgpu, float32, one dispatch for a list of stacks, split only
    where the adapter's storage-buffer limit requires; a mesh is rasterized through the camera first; an environment
    is sampled as on the CPU, with other random numbers: the images agree statistically; the reference raises
    ValueError); "auto" takes a hardware GPU for such scenes (a render is float32 anyway), else the
    CPU.

    material: instead of stacks, a lamina.oat.Material or a list of them (Oat 2006's gooey layers, lit by the
    directional and point lights; on the GPU for every shape)."""
    if material is not None:
        if stacks is not None:
            raise TypeError("render takes stacks or material=, not both")
        return _render_oat(material, shape, width, height, lights, device, camera, progress)
    items, brought, single = _stacks(stacks)
    m = _model(model)
    for name, v in (("spp", spp), ("seed", seed)):
        if not isinstance(v, Integral) or isinstance(v, bool):
            raise TypeError(f"{name} must be an integer, got {v!r}")
    if not 1 <= spp <= 1 << 20:
        raise ValueError(f"spp must be in [1, {1 << 20}], got {spp}")
    if not 0 <= seed < 2**64:
        raise ValueError(f"seed must be in [0, 2**64), got {seed}")
    shape, camera = _scene(shape, width, height, camera)
    lights = [sky()] if lights is None else list(lights)
    env, specs = None, []
    for i, light in enumerate(lights):
        if isinstance(light, EnvironmentLight):
            if env is not None:
                raise ValueError("lights: at most one EnvironmentLight")
            env = (light.map, light.scale, light.rotation)
            if light.sun is not None:
                specs.append(light.sun._spec())
        elif isinstance(light, (DirectionalLight, PointLight)):
            specs.append(light._spec())
        else:
            raise TypeError(f"lights[{i}] must be a DirectionalLight, PointLight or EnvironmentLight, got {light!r}")
    kwargs = {**brought, **kwargs}
    textures = {k: _texture(k, v, m.inputs[k].width) for k, v in kwargs.items() if k in m.inputs}
    options = {k: v for k, v in kwargs.items() if k not in textures}  # checked by Rust against the model's table
    layers = [(s._resolve(None), s.ext_ior) for s in items]
    if _gpu.use_gpu(device, m.name, options):
        out = _lamina.render_gpu(layers, m.name, options, textures, shape, camera, specs, width, height, env, spp, seed)
        return out[0] if single else out
    out = np.empty((len(items), height, width, 3), dtype=np.float32)
    band = max(1, 4096 // width)
    bar = _progress(len(items) * width * height * (1 + spp * (env is not None)), progress)
    for first in range(0, height, band):
        rows = min(band, height - first)
        out[:, first : first + rows] = _lamina.render(
            layers, m.name, options, textures, shape, camera, specs, env, width, height, spp, seed, first, rows
        )
        if bar is not None:
            bar.update(len(items) * width * rows * (1 + spp * (env is not None)))
    if bar is not None:
        bar.close()
    return out[0] if single else out


def relative_error(image: np.ndarray, reference: np.ndarray, floor: float = 0.02) -> np.ndarray:
    """Per-pixel relative error of luminance against a reference image (..., H, W, 3): |Y − Y_ref| / max(Y_ref, floor
    · mean Y_ref), the floor keeping black pixels of the reference from dominating."""
    y, y_ref = _luminance(image), _luminance(reference)
    if y.shape != y_ref.shape:
        raise ValueError(f"image {image.shape} and reference {reference.shape} must have the same shape")
    scale = np.maximum(y_ref, floor * y_ref.mean(axis=(-2, -1), keepdims=True))
    return np.abs(y - y_ref) / np.where(scale > 0, scale, 1.0)


def _luminance(rgb) -> np.ndarray:
    rgb = np.asarray(rgb, dtype=np.float64)
    if rgb.ndim < 3 or rgb.shape[-1] != 3:
        raise ValueError(f"image must be (..., H, W, 3), got shape {rgb.shape}")
    return rgb @ np.array([0.2126, 0.7152, 0.0722])


def _aces(x: np.ndarray) -> np.ndarray:
    """Narkowicz 2015's fit of the ACES filmic curve."""
    return np.clip((x * (2.51 * x + 0.03)) / (x * (2.43 * x + 0.59) + 0.14), 0.0, 1.0)


def _srgb(x: np.ndarray) -> np.ndarray:
    """The sRGB transfer function (IEC 61966-2-1)."""
    x = np.clip(x, 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)


TONEMAPS = ("aces", "clamp")


def to_srgb8(image, exposure: float = 0.0, tonemap: str = "aces") -> np.ndarray:
    """Linear HDR (..., 3) to 8-bit sRGB: scaled by 2^exposure, tone mapped ("aces": Narkowicz's ACES fit;
    "clamp": none) and encoded."""
    if tonemap not in TONEMAPS:
        raise ValueError(f"tonemap must be one of {TONEMAPS}, got {tonemap!r}")
    x = np.asarray(image, dtype=np.float64) * 2.0 ** _number("exposure", exposure, -64, 64)
    x = np.nan_to_num(x, nan=0.0, posinf=1e30)
    x = _aces(x) if tonemap == "aces" else x
    return np.round(_srgb(x) * 255).astype(np.uint8)


def save_image(path, image, exposure: float = 0.0, tonemap: str = "aces") -> Path:
    """Writes (H, W, 3) linear radiance: `.png` as 8-bit sRGB after `tonemap` (see `to_srgb8`), `.exr` as linear
    float32 OpenEXR. Returns the path."""
    path = Path(path)
    image = np.asarray(image)
    if image.ndim != 3 or image.shape[2] != 3:
        raise ValueError(f"image must be (H, W, 3), got shape {image.shape}")
    suffix = path.suffix.lower()
    if suffix == ".png":
        _lamina.write_png(str(path), np.ascontiguousarray(to_srgb8(image, exposure, tonemap)))
    elif suffix == ".exr":
        _lamina.write_exr(str(path), np.ascontiguousarray(image, dtype=np.float32))
    else:
        raise ValueError(f"path must end in .png or .exr, got {str(path)!r}")
    return path


def read_image(path) -> np.ndarray:
    """Reads a Radiance .hdr, OpenEXR or PNG file as float32 (H, W, 3) (PNG values / 255, not linearised)."""
    if not Path(path).is_file():
        raise ValueError(f"path: no file {str(path)!r}")
    return _lamina.read_image(str(path))
