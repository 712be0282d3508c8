"""Measured BRDFs in the formats researchers have: samples as NumPy arrays of (wi, wo, f), and the MERL 100 binary
tables (Matusik, Pfister, Brand and McMillan 2003, "A Data-Driven Reflectance Model"). Nothing is shipped (the
databases have their own licences): these read and write files the user has.

Conventions as lamina's (docs/conventions.md): local frame, z the normal, wi and wo pointing away from the surface,
f without the cosine, in 1/sr, one value per channel.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from ._arrays import as_real_array, broadcast


@dataclass(frozen=True)
class Samples:
    """Isotropic or anisotropic BRDF samples: f (n, channels) at direction pairs wi, wo (n, 3, unit, z > 0), and the
    wavelengths (nm) of the channels where they are spectral (None: linear RGB, or one channel)."""

    wi: np.ndarray
    wo: np.ndarray
    f: np.ndarray
    wavelengths: np.ndarray | None = None

    def __post_init__(self):
        wi, wo, f = _checked(self.wi, self.wo, self.f)
        object.__setattr__(self, "wi", wi)
        object.__setattr__(self, "wo", wo)
        object.__setattr__(self, "f", f)
        if self.wavelengths is not None:
            wl = np.atleast_1d(np.asarray(self.wavelengths, dtype=np.float64))
            if wl.shape != (f.shape[1],) or not np.all(np.isfinite(wl)) or np.any(wl <= 0):
                raise ValueError(
                    f"wavelengths must hold one positive wavelength (nm) per channel of f ({f.shape[1]}), got "
                    f"{np.shape(self.wavelengths)}"
                )
            object.__setattr__(self, "wavelengths", wl)

    def __len__(self) -> int:
        return len(self.f)


def _unit(name: str, w) -> np.ndarray:
    w = np.asarray(as_real_array(name, w), dtype=np.float64)
    if w.ndim != 2 or w.shape[1] != 3 or len(w) == 0:
        raise ValueError(f"{name} must have shape (n, 3) with n ≥ 1, got {w.shape}")
    norm = np.linalg.norm(w, axis=1, keepdims=True)
    if not np.all(np.isfinite(w)) or np.any(norm == 0) or np.any(w[:, 2] <= 0):
        raise ValueError(f"{name} must hold finite, non-zero directions above the surface (z > 0)")
    return w / np.where(np.abs(norm - 1.0) < 1e-15, 1.0, norm)  # unit rows stay as they are: a lookup sees its input


def _checked(wi, wo, f) -> tuple:
    """wi, wo as unit (n, 3) rows and f as (n, channels) finite values ≥ 0; ValueError naming what is wrong."""
    wi, wo = _unit("wi", wi), _unit("wo", wo)
    f = np.asarray(as_real_array("f", f), dtype=np.float64)
    if f.ndim == 1:
        f = f[:, None]
    if f.ndim != 2 or len(f) != len(wi) or len(wo) != len(wi):
        raise ValueError(
            f"wi, wo and f must have n rows each: (n, 3), (n, 3), (n, channels); got {wi.shape}, {wo.shape}, {f.shape}"
        )
    if not np.all(np.isfinite(f)) or np.any(f < 0):
        raise ValueError("f must hold finite values ≥ 0 (a BRDF, 1/sr): found NaN, Inf or negative values")
    return wi, wo, f


def save_samples(path, samples: Samples) -> None:
    """Writes `samples` to `path` as a NumPy .npz archive (wi, wo, f and, if spectral, wavelengths)."""
    arrays = {"wi": samples.wi, "wo": samples.wo, "f": samples.f}
    if samples.wavelengths is not None:
        arrays["wavelengths"] = samples.wavelengths
    with open(path, "wb") as out:
        np.savez(out, **arrays)


def load_samples(path) -> Samples:
    """Reads samples written by `save_samples` (or any .npz with arrays wi, wo, f and optionally wavelengths),
    checked as `Samples` checks them."""
    with np.load(path, allow_pickle=False) as z:
        missing = {"wi", "wo", "f"} - set(z.files)
        if missing:
            raise ValueError(f"{os.fspath(path)} lacks the arrays {sorted(missing)} (it needs wi, wo and f)")
        return Samples(z["wi"], z["wo"], z["f"], z["wavelengths"] if "wavelengths" in z.files else None)


#: MERL's table: θh (nonlinear), θd and φd bins, and its scale per channel (R, G, B).
MERL_SHAPE = (90, 90, 180)
MERL_SCALE = np.array([1.0 / 1500.0, 1.15 / 1500.0, 1.66 / 1500.0])


def half_difference(wi: np.ndarray, wo: np.ndarray) -> tuple:
    """Rusinkiewicz's (1998) half/difference angles of direction pairs (..., 3): (θh, θd, φd), φd in (−π, π]: h the
    half vector, d the incident direction in the frame where h is the normal (wi rotated by −φh about z, then by −θh
    about y)."""
    h = wi + wo
    h = h / np.linalg.norm(h, axis=-1, keepdims=True)
    theta_h = np.arccos(np.clip(h[..., 2], -1.0, 1.0))
    phi_h = np.arctan2(h[..., 1], h[..., 0])
    c, s = np.cos(-phi_h), np.sin(-phi_h)
    x, y = c * wi[..., 0] - s * wi[..., 1], s * wi[..., 0] + c * wi[..., 1]
    c, s = np.cos(-theta_h), np.sin(-theta_h)
    dx, dz = c * x + s * wi[..., 2], -s * x + c * wi[..., 2]
    return theta_h, np.arccos(np.clip(dz, -1.0, 1.0)), np.arctan2(y, dx)


def from_half_difference(theta_h, theta_d, phi_d, phi_h=0.0) -> tuple:
    """The direction pair (wi, wo) of half/difference angles (the inverse of `half_difference`, at azimuth φh of the
    half vector)."""
    theta_h, theta_d, phi_d, phi_h = np.broadcast_arrays(
        *(np.asarray(a, dtype=np.float64) for a in (theta_h, theta_d, phi_d, phi_h))
    )
    d = np.stack([np.sin(theta_d) * np.cos(phi_d), np.sin(theta_d) * np.sin(phi_d), np.cos(theta_d)], -1)

    def to_world(v):
        # Rotate by θh about y, then by φh about z.
        c, s = np.cos(theta_h), np.sin(theta_h)
        x, z = c * v[..., 0] + s * v[..., 2], -s * v[..., 0] + c * v[..., 2]
        c, s = np.cos(phi_h), np.sin(phi_h)
        return np.stack([c * x - s * v[..., 1], s * x + c * v[..., 1], z], -1)

    return to_world(d), to_world(d * [-1.0, -1.0, 1.0])


@dataclass(frozen=True)
class Merl:
    """A MERL isotropic BRDF: `table` (3, 90, 90, 180) of f per channel (R, G, B; scaled, 1/sr) over the θh, θd, φd
    bins, negative where the measurement left a bin empty."""

    table: np.ndarray

    def bins(self, wi, wo) -> tuple:
        """The table's bin of each direction pair: θh binned as √(θh / 90°) (dense at the peak), θd uniformly, φd
        uniformly over [0, π) (reciprocity folds φd + π onto φd), each clamped to the table."""
        theta_h, theta_d, phi_d = half_difference(wi, wo)
        n_h, n_d, n_p = MERL_SHAPE
        ih = np.sqrt(np.maximum(theta_h, 0.0) / (np.pi / 2)) * n_h
        id_ = theta_d / (np.pi / 2) * n_d
        ip = np.where(phi_d < 0.0, phi_d + np.pi, phi_d) / np.pi * n_p
        clip = lambda i, n: np.clip(i.astype(np.int64), 0, n - 1)  # noqa: E731
        return clip(ih, n_h), clip(id_, n_d), clip(ip, n_p)

    def eval(self, wi, wo) -> np.ndarray:
        """f (..., 3) at direction pairs wi, wo (..., 3; broadcast; above the surface): the value of the pair's bin,
        as the database's own lookup reads it. Empty bins read as 0 (`measured` says which)."""
        wi, wo = broadcast(wi=(wi, 3), wo=(wo, 3))
        shape = wi.shape[:-1]
        f = self.table[(slice(None), *self.bins(_unit("wi", wi.reshape(-1, 3)), _unit("wo", wo.reshape(-1, 3))))]
        return np.maximum(f.T, 0.0).reshape(shape + (3,))

    def measured(self, wi, wo) -> np.ndarray:
        """Whether the bin of each pair holds a measurement in every channel (...,)."""
        wi, wo = broadcast(wi=(wi, 3), wo=(wo, 3))
        bins = self.bins(_unit("wi", wi.reshape(-1, 3)), _unit("wo", wo.reshape(-1, 3)))
        return np.all(self.table[(slice(None), *bins)] >= 0.0, axis=0).reshape(wi.shape[:-1])

    def samples(self, n: int, seed: int = 0) -> Samples:
        """`n` samples of measured bins (`_samples`)."""
        return _samples(self, n, seed, self.measured)


def _samples(brdf, n: int, seed: int, keep=None) -> Samples:
    """`n` samples of `brdf` at direction pairs drawn over the projected hemispheres (both cosine-distributed,
    random azimuths), only those where `keep(wi, wo)` holds if given."""
    if not isinstance(n, (int, np.integer)) or n < 1:
        raise ValueError(f"n must be a positive integer, got {n!r}")
    rng = np.random.default_rng(seed)
    wi, wo = np.empty((0, 3)), np.empty((0, 3))
    while len(wi) < n:
        u = rng.random((2 * n, 4))
        a, b = _cosine(u[:, :2]), _cosine(u[:, 2:])
        mask = keep(a, b) if keep is not None else slice(None)
        wi, wo = np.concatenate([wi, a[mask]]), np.concatenate([wo, b[mask]])
    return Samples(wi[:n], wo[:n], brdf.eval(wi[:n], wo[:n]))


def _cosine(u: np.ndarray) -> np.ndarray:
    """Cosine-distributed directions from uniform pairs u (n, 2), strictly above the horizon."""
    r, phi = np.sqrt(u[:, 0]), 2 * np.pi * u[:, 1]
    z = np.sqrt(np.maximum(1.0 - r * r, 1e-12))
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], -1)


def read_merl(path) -> Merl:
    """Reads a MERL .binary file: three int32 (the table's dimensions 90, 90, 180), then the float64 table of each
    channel (R, G, B) in turn, φd fastest, then θd, then θh, little-endian; the channels are multiplied by the
    database's scales (MERL_SCALE) into f. ValueError if the file is not such a table."""
    data = open(path, "rb").read()
    n = int(np.prod(MERL_SHAPE))
    dims = tuple(int(d) for d in np.frombuffer(data[:12], dtype="<i4")) if len(data) >= 12 else ()
    if dims != MERL_SHAPE:
        raise ValueError(f"{os.fspath(path)} is not a MERL BRDF: its header gives dimensions {dims}, not {MERL_SHAPE}")
    if len(data) != 12 + 3 * n * 8:
        raise ValueError(f"{os.fspath(path)} is not a MERL BRDF: {len(data)} bytes, not {12 + 3 * n * 8} (truncated?)")
    table = np.frombuffer(data, dtype="<f8", offset=12).reshape((3,) + MERL_SHAPE)
    if not np.all(np.isfinite(table)):
        raise ValueError(f"{os.fspath(path)} holds NaN or Inf values")
    return Merl(table * MERL_SCALE[:, None, None, None])


def write_merl(path, merl: Merl) -> None:
    """Writes `merl` in the MERL .binary format (`read_merl` reads it back)."""
    table = np.asarray(merl.table, dtype=np.float64)
    if table.shape != (3,) + MERL_SHAPE:
        raise ValueError(f"a MERL table has shape {(3,) + MERL_SHAPE}, got {table.shape}")
    with open(path, "wb") as out:
        out.write(np.array(MERL_SHAPE, dtype="<i4").tobytes())
        out.write((table / MERL_SCALE[:, None, None, None]).astype("<f8").tobytes())


def merl_table(f) -> Merl:
    """A MERL table of the BRDF `f(wi, wo) -> (..., 3)` at each bin's centre (φh = 0): to write lamina's models in
    the database's format, or to compare them at its resolution."""
    n_h, n_d, n_p = MERL_SHAPE
    theta_h = ((np.arange(n_h) + 0.5) / n_h) ** 2 * (np.pi / 2)
    theta_d = (np.arange(n_d) + 0.5) / n_d * (np.pi / 2)
    phi_d = (np.arange(n_p) + 0.5) / n_p * np.pi
    wi, wo = from_half_difference(*np.meshgrid(theta_h, theta_d, phi_d, indexing="ij"))
    above = (wi[..., 2] > 1e-6) & (wo[..., 2] > 1e-6)
    table = np.full((3,) + MERL_SHAPE, -1.0)
    table[:, above] = np.moveaxis(np.asarray(f(wi[above], wo[above])), -1, 0)
    return Merl(table)


# RGL material database (Dupuy and Jakob 2018, "An Adaptive Parameterization for Efficient Material Acquisition and
# Rendering"): .bsdf files are "tensor files" of named arrays; f is tabulated per incident direction over the unit
# square that the visible normals' distribution warps onto the half vectors.

#: The tensor file's dtype codes.
TENSOR_DTYPES = {
    1: "u1",
    2: "i1",
    3: "<u2",
    4: "<i2",
    5: "<u4",
    6: "<i4",
    7: "<u8",
    8: "<i8",
    9: "<f2",
    10: "<f4",
    11: "<f8",
}
TENSOR_MAGIC = b"tensor_file\0"


def read_tensor_file(path) -> dict:
    """The named arrays of a tensor file: the magic `tensor_file\\0`, version (1, 0), a uint32 count, then per field
    its name (uint16 length, UTF-8), ndim (uint16), dtype code (uint8), the absolute offset of its data (uint64) and
    its shape (uint64 each); little-endian, C order. ValueError if the file is not one."""
    data = open(path, "rb").read()
    where = os.fspath(path)
    if data[:12] != TENSOR_MAGIC or data[12:14] != b"\1\0" or len(data) < 18:
        raise ValueError(f"{where} is not a tensor file (RGL .bsdf): wrong magic or version")
    fields, p = {}, 18
    try:
        for _ in range(int(np.frombuffer(data, "<u4", 1, 14)[0])):
            n = int(np.frombuffer(data, "<u2", 1, p)[0])
            name = data[p + 2 : p + 2 + n].decode()
            p += 2 + n
            ndim, code = int(np.frombuffer(data, "<u2", 1, p)[0]), data[p + 2]
            offset = int(np.frombuffer(data, "<u8", 1, p + 3)[0])
            shape = tuple(int(s) for s in np.frombuffer(data, "<u8", ndim, p + 11))
            p += 11 + 8 * ndim
            if code not in TENSOR_DTYPES:
                raise ValueError(f"{where}: field {name!r} has dtype code {code}, not one of 1-11")
            fields[name] = np.frombuffer(data, TENSOR_DTYPES[code], int(np.prod(shape)), offset).reshape(shape)
    except (ValueError, IndexError, UnicodeDecodeError) as e:
        raise ValueError(f"{where} is not a valid tensor file: {e}") from None
    return fields


def write_tensor_file(path, fields: dict) -> None:
    """Writes named arrays as a tensor file (`read_tensor_file`), each array's data at an offset that is a multiple
    of 8, as the reference writers place them."""
    arrays = {k: np.ascontiguousarray(v) for k, v in fields.items()}
    codes = {np.dtype(t).str: c for c, t in TENSOR_DTYPES.items()}
    for k, a in arrays.items():
        if a.dtype.newbyteorder("<").str not in codes:
            raise TypeError(f"field {k!r}: dtype {a.dtype} has no tensor file code")
    head = 18 + sum(13 + len(k.encode()) + 8 * a.ndim for k, a in arrays.items())
    offset, descriptors, blobs = -(-head // 8) * 8, b"", b""
    for k, a in arrays.items():
        name = k.encode()
        a = a.astype(a.dtype.newbyteorder("<"))
        descriptors += np.array([len(name)], "<u2").tobytes() + name + np.array([a.ndim], "<u2").tobytes()
        descriptors += bytes([codes[a.dtype.str]]) + np.array([offset, *a.shape], "<u8").tobytes()
        blob = a.tobytes() + b"\0" * (-a.nbytes % 8)
        blobs, offset = blobs + blob, offset + len(blob)
    header = TENSOR_MAGIC + b"\1\0" + np.array([len(arrays)], "<u4").tobytes() + descriptors
    with open(path, "wb") as out:
        out.write(header + b"\0" * (-(-head // 8) * 8 - len(header)) + blobs)


def _node_weights(grid: np.ndarray, x: np.ndarray) -> tuple:
    """Linear interpolation in a sorted grid, clamped at its ends: (lower node, weight of the upper) per value."""
    if len(grid) == 1:
        return np.zeros(x.shape, np.int64), np.zeros(x.shape)
    i = np.clip(np.searchsorted(grid, x, side="right") - 1, 0, len(grid) - 2)
    return i, np.clip((x - grid[i]) / (grid[i + 1] - grid[i]), 0.0, 1.0)


def _cell(u: np.ndarray, n: int) -> tuple:
    """The grid cell of u ∈ [0, 1] on n nodes (both ends included): (index, fraction)."""
    x = np.clip(u, 0.0, 1.0) * (n - 1)
    i = np.minimum(np.floor(x).astype(np.int64), n - 2)
    return i, x - i


def _bilinear(table: np.ndarray, u: np.ndarray) -> np.ndarray:
    """Bilinear interpolation at u (n, 2) ∈ [0, 1]² (columns: u[:, 0], rows: u[:, 1]) of one table (H, W), or of
    one table per row (n, C, H, W): (n,) or (n, C)."""
    (i, fx), (j, fy) = _cell(u[:, 0], table.shape[-1]), _cell(u[:, 1], table.shape[-2])
    if table.ndim == 2:
        at = lambda jj, ii: table[jj, ii]  # noqa: E731
    else:
        rows = np.arange(len(u))
        at = lambda jj, ii: table[rows, :, jj, ii]  # noqa: E731
        fx, fy = fx[:, None], fy[:, None]
    return (1 - fy) * ((1 - fx) * at(j, i) + fx * at(j, i + 1)) + fy * ((1 - fx) * at(j + 1, i) + fx * at(j + 1, i + 1))


@dataclass(frozen=True)
class Rgl:
    """An RGL material database BSDF (`read_rgl`): its fields, and the visible normals' warp of each incident node
    normalised (`_warp`)."""

    fields: dict
    description: str

    @property
    def isotropic(self) -> bool:
        return len(self.fields["phi_i"]) <= 2

    def _invert(self, u_m: np.ndarray, corners: list) -> np.ndarray:
        """The visible normals' warp inverted (Marginal2D: the conditional CDF in x, the marginal in y, of the
        bilinear density), the incident nodes' normalised tables blended with `corners` [(φ node, θ node, weight)]:
        the unit-square coordinate s of each half vector u_m."""
        d, c, m = self._warp
        h, w = d.shape[-2:]
        (i, fx), (j, fy) = _cell(u_m[:, 0], w), _cell(u_m[:, 1], h)
        blend = lambda t, *idx: sum(wt * t[(p, q, *idx)] for p, q, wt in corners)  # noqa: E731
        v00, v10, v01, v11 = blend(d, j, i), blend(d, j, i + 1), blend(d, j + 1, i), blend(d, j + 1, i + 1)
        c0, c1 = v00 + fy * (v01 - v00), v10 + fy * (v11 - v10)
        r0, r1 = blend(c, j, w - 1), blend(c, j + 1, w - 1)
        start = blend(c, j, i) + fy * (blend(c, j + 1, i) - blend(c, j, i))
        x = (fx * (c0 + 0.5 * fx * (c1 - c0)) + start) / np.maximum(r0 + fy * (r1 - r0), 1e-300)
        y = fy * (r0 + 0.5 * fy * (r1 - r0)) + blend(m, j)
        return np.stack([x, y], -1)

    @property
    def _warp(self) -> tuple:
        """Per incident node, the visible normals' density normalised over the unit square's index space, its
        conditional CDFs along x (trapezoids, a leading 0) and its marginal CDF along y: (d̂, Ĉ, M̂)."""
        cached = self.__dict__.get("_warp_cache")
        if cached is None:
            d = np.asarray(self.fields["vndf"], np.float64)
            c = np.concatenate([np.zeros(d.shape[:-1] + (1,)), np.cumsum(0.5 * (d[..., 1:] + d[..., :-1]), -1)], -1)
            rows = c[..., -1]
            m = np.concatenate(
                [np.zeros(d.shape[:-2] + (1,)), np.cumsum(0.5 * (rows[..., 1:] + rows[..., :-1]), -1)], -1
            )
            scale = 1.0 / m[..., -1]
            cached = (d * scale[..., None, None], c * scale[..., None, None], m * scale[..., None])
            object.__setattr__(self, "_warp_cache", cached)
        return cached

    def eval(self, wi, wo) -> np.ndarray:
        """f (..., channels) at direction pairs wi, wo (..., 3; broadcast; above the surface), without the cosine,
        as the authors' evaluator (powitacq) reads it: the half vector's warp coordinate s at wi's node, the table's
        ratio R there (interpolated over θi, φi and s, negative values clipped), times D(ωm) / (4 σ(wi)) / cos θo.
        wi, the light's direction, indexes the tables, as the acquisition's incident direction; Mitsuba's `measured`
        plugin indexes them by its si.wi (towards the camera), the same for a reciprocal material."""
        wi, wo = broadcast(wi=(wi, 3), wo=(wo, 3))
        shape = wi.shape[:-1]
        wi, wo = _unit("wi", wi.reshape(-1, 3)), _unit("wo", wo.reshape(-1, 3))
        wm = wi + wo
        wm /= np.linalg.norm(wm, axis=-1, keepdims=True)
        theta2u = lambda t: np.sqrt(2.0 * t / np.pi)  # noqa: E731
        elevation = lambda v: 2.0 * np.arcsin(np.clip(0.5 * np.linalg.norm(v - [0.0, 0.0, 1.0], axis=-1), 0, 1))  # noqa: E731
        theta_i, phi_i = elevation(wi), np.arctan2(wi[:, 1], wi[:, 0])
        theta_m, phi_m = elevation(wm), np.arctan2(wm[:, 1], wm[:, 0])
        u_wi = np.stack([theta2u(theta_i), (phi_i + np.pi) / (2 * np.pi)], -1)
        u_m = np.stack([theta2u(theta_m), (np.where(self.isotropic, phi_m - phi_i, phi_m) + np.pi) / (2 * np.pi)], -1)
        u_m[:, 1] -= np.floor(u_m[:, 1])
        p, wp = _node_weights(np.asarray(self.fields["phi_i"], np.float64), phi_i)
        t, wt = _node_weights(np.asarray(self.fields["theta_i"], np.float64), theta_i)
        one = len(self.fields["phi_i"]) == 1
        corners = [
            (p + a, t + b, (1 - wp if a == 0 else wp) * (1 - wt if b == 0 else wt)) for a in (0, 1) for b in (0, 1)
        ]
        corners = [(pp if not one else pp * 0, tt, w) for pp, tt, w in corners]
        s = self._invert(u_m, corners)
        table = np.asarray(self.fields["rgb"], np.float64)
        r = sum(w[:, None] * _bilinear(table[pp, tt], s) for pp, tt, w in corners)
        ndf = _bilinear(np.asarray(self.fields["ndf"], np.float64), u_m)
        sigma = _bilinear(np.asarray(self.fields["sigma"], np.float64), u_wi)
        f = np.maximum(r, 0.0) * (ndf / (4.0 * sigma) / wo[:, 2])[:, None]
        return f.reshape(shape + (f.shape[-1],))

    def samples(self, n: int, seed: int = 0) -> Samples:
        """`n` samples (`_samples`)."""
        return _samples(self, n, seed)


def read_rgl(path) -> Rgl:
    """Reads an RGL material database .bsdf file (RGB: the fields theta_i, phi_i, ndf, sigma, vndf, luminance, rgb
    and description). Spectral files (`spectra`, `wavelengths`) and anisotropic files whose φi does not cover the
    full circle are refused with a ValueError, as are inconsistent shapes."""
    fields = read_tensor_file(path)
    where = os.fspath(path)
    if "spectra" in fields:
        raise ValueError(f"{where} is a spectral RGL file; lamina reads the RGB ones (field 'rgb')")
    missing = {"theta_i", "phi_i", "ndf", "sigma", "vndf", "rgb"} - set(fields)
    if missing:
        raise ValueError(f"{where} is not an RGL BSDF: it lacks the fields {sorted(missing)}")
    n_phi, n_theta = len(fields["phi_i"]), len(fields["theta_i"])
    vndf, rgb = fields["vndf"], fields["rgb"]
    if vndf.ndim != 4 or vndf.shape[:2] != (n_phi, n_theta) or rgb.ndim != 5 or rgb.shape[:3] != (n_phi, n_theta, 3):
        raise ValueError(
            f"{where}: vndf must be (φi {n_phi}, θi {n_theta}, H, W) and rgb (φi, θi, 3, N, N); got {vndf.shape} and "
            f"{rgb.shape}"
        )
    if fields["ndf"].ndim != 2 or fields["sigma"].ndim != 2 or min(vndf.shape[2:] + rgb.shape[3:]) < 2:
        raise ValueError(f"{where}: ndf and sigma must be 2-D tables, and every table at least 2 × 2")
    phi = np.asarray(fields["phi_i"], np.float64)
    if n_phi > 2 and abs(phi[-1] - phi[0] - 2 * np.pi) > 1e-3:
        raise ValueError(f"{where}: φi covers {phi[-1] - phi[0]:.3f} rad; lamina reads files that cover 2π")
    description = bytes(fields.get("description", np.zeros(0, np.uint8))).decode(errors="replace")
    return Rgl(fields, description)
