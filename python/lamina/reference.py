"""The Monte Carlo reference as a tool: the suite's cached reference values on a fixed direction grid, and an on-disk
cache for any reference run (the estimators themselves are in _reference.py; Stack.reference calls them). Entries
go through lamina's checked cache (src/cache.rs): read back only when intact, written atomically, recomputed in
memory (with one warning) when the cache cannot be written."""

from __future__ import annotations

import hashlib
import io
import json
import zipfile
from pathlib import Path

import numpy as np

from . import _lamina, optics
from ._reference import CHUNK, SUITE_THETAS, WORK_PER_CALL, f_estimate, suite_directions, tally
from .layers import Dielectric
from .materials import suite

__all__ = [
    "CHUNK",
    "WORK_PER_CALL",
    "SUITE_THETAS",
    "cache_dir",
    "cache_key",
    "cached_reference",
    "f_estimate",
    "suite_directions",
    "suite_reference",
    "suite_reference_albedo",
    "reference_albedo",
    "tally",
]


def cache_dir() -> Path:
    """Where reference results are cached: the reference/ folder of lamina's cache root ($LAMINA_CACHE, else
    ~/.cache/lamina; src/cache.rs)."""
    root = _lamina.cache_root()
    return (Path(root) if root is not None else Path.home() / ".cache" / "lamina") / "reference"


def cache_key(stack, wi, wo, samples: int, seed: int, **options) -> str:
    """Hash of everything a reference result depends on: the resolved stack, directions, sample count, seed,
    options and the build's source fingerprint (_lamina.SOURCE_HASH: a cache written by another build is not read)."""
    h = hashlib.sha256()
    h.update(
        json.dumps(
            [
                stack._resolve(options.get("wavelengths")),
                stack.ext_ior,
                samples,
                seed,
                {
                    k: (np.asarray(v).tolist() if k == "wavelengths" and v is not None else v)
                    for k, v in sorted(options.items())
                },
                _lamina.SOURCE_HASH,
            ]
        ).encode()
    )
    for a in (wi, wo):
        h.update(np.ascontiguousarray(a, dtype=np.float64).tobytes())
        h.update(str(np.shape(a)).encode())
    return h.hexdigest()[:32]


def load(path: Path, *names: str) -> tuple | None:
    """The arrays `names` of the cache entry at `path`, or None when it is missing or damaged (lamina's cache checks
    its header, length and checksum; the arrays must then be there, finite)."""
    payload = _lamina.cache_read(str(path))
    if payload is None:
        return None
    try:
        with np.load(io.BytesIO(payload)) as z:
            arrays = tuple(np.asarray(z[n]) for n in names)
    except (ValueError, OSError, KeyError, zipfile.BadZipFile):
        return None
    return arrays if all(np.all(np.isfinite(a)) for a in arrays) else None


def store(path: Path, **arrays) -> None:
    """Writes the arrays as the cache entry at `path` (atomically; a cache that cannot be written warns once)."""
    buffer = io.BytesIO()
    np.savez(buffer, **arrays)
    _lamina.cache_write(str(path), buffer.getvalue())


def cached_reference(stack, wi, wo, samples: int = 100_000, seed: int = 0, progress=None, **options):
    """Stack.reference(wi, wo, ...) through the on-disk cache: (f, stderr), computed once per key."""
    path = cache_dir() / f"{cache_key(stack, wi, wo, samples, seed, **options)}.ref"
    found = load(path, "f", "stderr")
    if found is not None:
        return found
    f, se = stack.reference(wi, wo, samples=samples, seed=seed, progress=progress, **options)
    store(path, f=f, stderr=se)
    return f, se


def suite_reference(name: str, samples: int = 100_000, seed: int = 0, progress=None):
    """Reference f and standard error of suite material `name` on the suite grid (cached): (wi, wo, f, stderr)
    with f and stderr of shape (5, 30, 3)."""
    wi, wo = suite_directions()
    f, se = cached_reference(suite(name), wi, wo, samples=samples, seed=seed, progress=progress)
    return wi, wo, f, se


def reference_albedo(stack, samples: int = 200_000, seed: int = 0, thetas=SUITE_THETAS) -> tuple:
    """Brute-force reference albedo of `stack` at incident angles `thetas` (degrees; light in the x–z plane),
    cached, with a smooth top's specular delta removed (the analytic models do not return Dirac lobes):
    (albedo (len(thetas), channels), stderr (len(thetas), channels))."""
    t = np.radians(thetas)
    wi = np.stack([np.sin(t), np.zeros_like(t), np.cos(t)], -1)
    path = cache_dir() / f"albedo-{cache_key(stack, wi, wi, samples, seed)}.ref"
    found = load(path, "a", "se")
    if found is not None:
        albedo, se = found
    else:
        albedo, se = stack.albedo(wi, "reference", samples=samples, seed=seed, progress=False)
        store(path, a=albedo, se=se)
    top = stack.layers[0]
    if isinstance(top, Dielectric) and max(np.ravel(top.roughness)) == 0.0:
        albedo = albedo - optics.fresnel_dielectric(wi[:, 2], float(np.mean(top.ior)) / stack.ext_ior)[:, None]
    return albedo, se


def suite_reference_albedo(name: str, samples: int = 200_000, seed: int = 0):
    """reference_albedo of suite material `name`: (wi (5, 3), albedo (5, channels), stderr (5, channels))."""
    t = np.radians(SUITE_THETAS)
    return (np.stack([np.sin(t), np.zeros_like(t), np.cos(t)], -1), *reference_albedo(suite(name), samples, seed))
