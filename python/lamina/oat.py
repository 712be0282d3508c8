"""Oat 2006, "Rendering Gooey Materials with Multiple Layers" (SIGGRAPH 2006 course 26, ch. 4): a semi-transparent
outer layer over inner layers, rendered by `lamina.render(material=lamina.oat.Material(...))`. The chapter's
primitives are public (`parallax`, `poisson_filter`, `light_map`), and `radius_from_slab` derives a blur radius
from a scattering slab, which the chapter leaves as a free parameter. The Rust side is src/oat/.

Conventions (docs/conventions.md): textures are images (H, W, C) with row 0 at v = 0 and u along the columns,
texel (i, j) centred at ((i + ½)/W, (j + ½)/H); tangent space has x along +u, y along +v (down the image) and z out
of the surface; depths and radii are in texels, as in the chapter. The chapter's `a` in w = a · saturate(n · v)
lets the inner layer show where a = 1, so it is a transparency: lamina takes the outer layer's *opacity* α (1 hides
the inner layers) and uses a = 1 − α.
"""

from __future__ import annotations

from numbers import Real

import numpy as np

from . import _lamina
from .materials import patina_mask

#: The chapter's techniques (src/oat: Technique) and texture addressing (Border), as Rust names them.
VARIANTS = tuple(_lamina.OAT_VARIANTS)
BORDERS = tuple(_lamina.OAT_BORDERS)
#: The chapter's hard-coded texel size (a 1024-texel texture).
CHAPTER_TEXEL = 1.0 / 1024.0
#: The 12 unit-disc positions of the growable Poisson disc (Oat 2006, Listing 2), from src/oat/mod.rs.
POISSON_DISC = np.array(_lamina.OAT_POISSON_DISC)


def _image(name: str, a, channels=(1, 3), lo=None, hi=None) -> np.ndarray:
    """A texture as float64 (H, W, C), checked: finite, C in `channels`, values in [lo, hi]."""
    try:
        a = np.asarray(a, dtype=np.float64)
    except (TypeError, ValueError):
        raise TypeError(f"{name} must be an array (H, W) or (H, W, 3) of numbers") from None
    if a.ndim == 2:
        a = a[..., None]
    if a.ndim != 3 or a.shape[2] not in channels or min(a.shape[:2]) < 1:
        raise ValueError(f"{name} must have shape (H, W) or (H, W, {max(channels)}), got {a.shape}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{name} must be finite")
    if (lo is not None and a.min() < lo) or (hi is not None and a.max() > hi):
        raise ValueError(f"{name} must be in [{lo}, {hi}], got values in [{a.min():g}, {a.max():g}]")
    return np.ascontiguousarray(a)


def _texel(texel_size) -> tuple[float, float]:
    t = np.broadcast_to(np.asarray(texel_size, dtype=np.float64), (2,))
    if not np.all(np.isfinite(t)) or np.any(t <= 0):
        raise ValueError(f"texel_size must be a positive number or (u, v) pair, got {texel_size!r}")
    return float(t[0]), float(t[1])


def _depth(name: str, d) -> np.ndarray:
    if isinstance(d, Real) and not isinstance(d, bool):
        d = np.full((1, 1), float(d))
    return _image(name, d, channels=(1,), lo=0.0)


class Material:
    """Oat's gooey material: an outer layer (albedo, opacity, tangent-space normal map) over inner layers.

    outer_albedo: (H, W, 3) in [0, 1]; outer_opacity: (H, W) in [0, 1] (1 hides what is beneath); outer_normal:
    (H, W, 3) tangent-space vectors (normalized on lookup; see `normals_from_height`). inner_albedo: an (H', W', 3)
    texture, or a list of them, outermost first; thickness: each inner layer's depth below the outer surface in
    texels (the chapter's d), a number or an (H, W) map, or a list matching inner_albedo; inner_opacity: for every
    inner layer but the deepest, an opacity map (default opaque). variant: "full" (texture-space light map),
    "normal_filtered" or "vertex_normal" (the chapter's two optimizations). shadowing: weight light reaching the
    inner layers by the outer layer's transparency (the chapter's future work). border: "wrap" or "clamp" texture
    addressing. texel_size: a texel in uv, default (1/W, 1/H) of outer_albedo (the chapter hard-codes 1/1024)."""

    def __init__(
        self,
        outer_albedo,
        outer_opacity,
        outer_normal,
        inner_albedo,
        thickness,
        *,
        inner_opacity=(),
        variant: str = "full",
        shadowing: bool = False,
        border: str = "wrap",
        texel_size=None,
        dilate: int = 16,
    ):
        self.outer_albedo = _image("outer_albedo", outer_albedo, (3,), 0.0, 1.0)
        self.outer_opacity = _image("outer_opacity", outer_opacity, (1,), 0.0, 1.0)
        self.outer_normal = _image("outer_normal", outer_normal, (3,))
        if np.any(np.linalg.norm(self.outer_normal, axis=-1) == 0):
            raise ValueError("outer_normal must have no zero vectors")
        albedos = inner_albedo if isinstance(inner_albedo, (list, tuple)) else [inner_albedo]
        depths = thickness if isinstance(thickness, (list, tuple)) else [thickness]
        if not albedos or len(depths) != len(albedos):
            raise ValueError(f"thickness must give one depth per inner layer ({len(albedos)}), got {len(depths)}")
        if len(inner_opacity) not in (0, len(albedos) - 1):
            raise ValueError(f"inner_opacity must have one map per inner layer but the deepest ({len(albedos) - 1})")
        opacities = list(inner_opacity) or [np.ones((1, 1))] * (len(albedos) - 1)
        self.inner = [
            (
                _image(f"inner_albedo[{k}]", a, (3,), 0.0, 1.0),
                _image(f"inner_opacity[{k}]", opacities[k], (1,), 0.0, 1.0) if k < len(albedos) - 1 else None,
                _depth(f"thickness[{k}]", d),
            )
            for k, (a, d) in enumerate(zip(albedos, depths))
        ]
        if variant not in VARIANTS:
            raise ValueError(f"variant must be one of {VARIANTS}, got {variant!r}")
        if border not in BORDERS:
            raise ValueError(f"border must be one of {BORDERS}, got {border!r}")
        if not isinstance(dilate, int) or isinstance(dilate, bool) or not 0 <= dilate <= 1024:
            raise ValueError(f"dilate must be an integer in [0, 1024], got {dilate!r}")
        h, w = self.outer_albedo.shape[:2]
        self.texel = _texel((1.0 / w, 1.0 / h) if texel_size is None else texel_size)
        self.variant, self.shadowing, self.border, self.dilate = variant, bool(shadowing), border, dilate

    def __repr__(self) -> str:
        h, w = self.outer_albedo.shape[:2]
        return (
            f"oat.Material({w}x{h}, {len(self.inner)} inner layer(s), variant={self.variant!r}, "
            f"shadowing={self.shadowing}, border={self.border!r})"
        )

    def with_variant(self, variant: str) -> Material:
        """The same material with another variant."""
        m = object.__new__(Material)
        m.__dict__.update(self.__dict__)
        if variant not in VARIANTS:
            raise ValueError(f"variant must be one of {VARIANTS}, got {variant!r}")
        m.variant = variant
        return m

    def _prepared(self, shape, light_specs, light_map: bool = True) -> object:
        """The material for one render: with `light_map`, its light map (variant "full") for the shape and lights,
        computed on the CPU (the GPU computes its own)."""
        light = None
        if light_map and self.variant == "full":
            light = _lamina.oat_light_map(self.outer_normal, shape, light_specs, self.dilate)
        return _lamina.OatMaterial(
            self.outer_albedo,
            self.outer_opacity,
            self.outer_normal,
            self.inner,
            self.variant,
            self.shadowing,
            self.border,
            self.texel,
            self.dilate,
            light,
        )


def light_map(material: Material, lights, shape="sphere") -> np.ndarray:
    """Step 2 of the chapter: the texture-space light map (H, W, 3) of `material`'s outer normal map on `shape`
    ("sphere", "plane" or a lamina.Mesh) for `lights` (DirectionalLight, PointLight): each texel the shape covers in
    uv, lit by Σ E max(0, N·l)/π at its world position, then `material.dilate` passes of dilation over the rest."""
    spec = shape._spec() if hasattr(shape, "_spec") else shape
    return _lamina.oat_light_map(material.outer_normal, spec, [light._spec() for light in lights], material.dilate)


def parallax(uv, view, normal, thickness, texel_size=CHAPTER_TEXEL):
    """Oat 2006 Listing 1 for arrays: uv (..., 2), view and normal (..., 3) unit vectors in tangent space (view
    from the surface towards the eye), thickness (...) in texels; they broadcast. r = reflect(−v, n),
    t = (r.x, r.y, −r.z), s = thickness / |t.z|, uv_inner = uv + texel_size · s · t.xy. Returns (uv_inner (..., 2),
    s (...))."""
    uv, view, normal = (np.asarray(x, dtype=np.float64) for x in (uv, view, normal))
    if uv.shape[-1:] != (2,) or view.shape[-1:] != (3,) or normal.shape[-1:] != (3,):
        raise ValueError("uv must be (..., 2), view and normal (..., 3)")
    d = np.asarray(thickness, dtype=np.float64)
    if not np.all(np.isfinite(d)) or np.any(d < 0):
        raise ValueError("thickness must be finite and >= 0")
    lead = np.broadcast_shapes(uv.shape[:-1], view.shape[:-1], normal.shape[:-1], d.shape)
    rows = lambda a, k: np.ascontiguousarray(np.broadcast_to(a, lead + (k,)).reshape(-1, k))  # noqa: E731
    out = _lamina.oat_parallax(
        rows(uv, 2),
        rows(view, 3),
        rows(normal, 3),
        np.ascontiguousarray(np.broadcast_to(d, lead).ravel()),
        _texel(texel_size),
    )
    return out[:, :2].reshape(lead + (2,)), out[:, 2].reshape(lead)


def poisson_filter(image, uv, radius, texel_size=None, border: str = "clamp"):
    """Oat 2006 Listing 2 for arrays: the mean of 13 equally weighted bilinear taps of `image` ((H, W) or (H, W, C)),
    at uv (..., 2) and at uv + texel_size · p_k · radius for the chapter's 12 unit-disc positions p_k; radius (...)
    in texels, broadcast with uv. texel_size defaults to (1/W, 1/H). Returns (..., C), or (...) for an (H, W) image."""
    a = np.asarray(image, dtype=np.float64)
    flat = a.ndim == 2
    img = _image("image", a, (1, 2, 3, 4))
    if border not in BORDERS:
        raise ValueError(f"border must be one of {BORDERS}, got {border!r}")
    uv = np.asarray(uv, dtype=np.float64)
    if uv.shape[-1:] != (2,):
        raise ValueError(f"uv must be (..., 2), got {uv.shape}")
    r = np.asarray(radius, dtype=np.float64)
    if not np.all(np.isfinite(r)) or np.any(r < 0):
        raise ValueError("radius must be finite and >= 0")
    lead = np.broadcast_shapes(uv.shape[:-1], r.shape)
    texel = _texel((1.0 / img.shape[1], 1.0 / img.shape[0]) if texel_size is None else texel_size)
    out = np.concatenate(
        [
            _lamina.oat_poisson_filter(
                np.ascontiguousarray(img[..., c : c + 3]),
                np.ascontiguousarray(np.broadcast_to(uv, lead + (2,)).reshape(-1, 2)),
                np.ascontiguousarray(np.broadcast_to(r, lead).ravel()),
                texel,
                border,
            )
            for c in range(0, img.shape[2], 3)
        ],
        axis=-1,
    )
    out = out.reshape(lead + (img.shape[2],))
    return out[..., 0] if flat else out


def normals_from_height(height, strength: float = 1.0) -> np.ndarray:
    """Tangent-space normals (H, W, 3) of a height field (H, W) given in texels times `strength`: normalize(−∂h/∂u,
    −∂h/∂v, 1) by central differences with wrapping, x along +u (columns) and y along +v (rows)."""
    h = _image("height", height, (1,))[..., 0] * float(strength)
    du = 0.5 * (np.roll(h, -1, axis=1) - np.roll(h, 1, axis=1))
    dv = 0.5 * (np.roll(h, -1, axis=0) - np.roll(h, 1, axis=0))
    n = np.stack([-du, -dv, np.ones_like(h)], -1)
    return n / np.linalg.norm(n, axis=-1, keepdims=True)


def organic_textures(size: int = 512, seed: int = 0) -> dict:
    """Procedural textures of a gooey organic surface, generated by lamina's own seeded noise (no downloaded
    assets): a membrane-like outer layer (noise albedo, normals from a height field, an opacity map that thins in
    patches) and an inner layer of veins (a network of dark red lines where fractal noise crosses its median)."""
    n1, n2, n3, n4 = (patina_mask(size, scale, seed + k) for k, scale in enumerate((4.0, 9.0, 3.0, 6.0)))
    outer = np.stack([0.75 + 0.2 * n1, 0.45 + 0.25 * n1 * n2, 0.4 + 0.2 * n2], -1)
    opacity = np.clip(0.3 + 1.4 * (n3 - 0.5), 0.05, 0.95)
    normal = normals_from_height(n2 * 6.0 + n1 * 3.0)
    veins = np.exp(-((np.abs(n4 - 0.5) / 0.035) ** 2)) + 0.6 * np.exp(-((np.abs(n2 - 0.5) / 0.02) ** 2))
    veins = np.clip(veins, 0.0, 1.0)[..., None]
    base = np.array([0.85, 0.55, 0.45])
    inner = base * (1 - veins) + np.array([0.45, 0.03, 0.05]) * veins
    return {
        "outer_albedo": np.clip(outer, 0.0, 1.0),
        "outer_opacity": opacity,
        "outer_normal": normal,
        "inner_albedo": np.clip(inner, 0.0, 1.0),
    }


def radius_from_slab(layer, texel_size: float, samples: int = 200_000, seed: int = 0) -> dict:
    """Oat's blur radius from physics: light entering a `lamina.Dielectric` slab (thickness, σs, σa, g; RGB means)
    at normal incidence is followed by a random walk that tracks positions (src/oat/mod.rs, `slab_exit`), and
    the radial profile of where it leaves the bottom gives the sideways spread. Returns {"rms": the profile's RMS
    radius in texels (texel_size: scene units per texel), "radius": the 13-tap disc radius with the same RMS,
    "radii" and "weights": the transmitted paths' exit radii (texels) and throughputs, "transmittance": their
    mean}. The interfaces are index-matched: only the medium spreads the light."""
    from .layers import Dielectric

    if not isinstance(layer, Dielectric):
        raise TypeError(f"layer must be a lamina.Dielectric, got {type(layer).__name__}")
    if not isinstance(texel_size, Real) or not texel_size > 0:
        raise ValueError(f"texel_size must be a positive number (scene units per texel), got {texel_size!r}")
    if layer.thickness <= 0:
        raise ValueError("layer must have a slab: thickness > 0")
    sigma_s, sigma_a = float(np.mean(layer.sigma_s)), float(np.mean(layer.sigma_a))
    exits = _lamina.oat_slab_exit(layer.thickness, sigma_s, sigma_a, layer.g, samples, seed)
    radii, weights = exits[:, 0] / texel_size, exits[:, 1]
    total = weights.sum()
    rms = float(np.sqrt((weights * radii**2).sum() / total)) if total > 0 else 0.0
    disc = float(np.sqrt((POISSON_DISC**2).sum() / 13.0))
    return {"rms": rms, "radius": rms / disc, "radii": radii, "weights": weights, "transmittance": total / samples}
