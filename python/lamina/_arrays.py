"""Array plumbing shared by every vectorized call: dtype checks and zero-copy NumPy broadcasting.

Only whole-array NumPy operations happen here; per-element work (and the NaN/Inf and shape checks) is in Rust.
"""

from __future__ import annotations

import numpy as np


def as_real_array(name: str, x) -> np.ndarray:
    """`x` as a float32 or float64 array (integers are promoted to float64); TypeError for anything else."""
    try:
        a = np.asarray(x)
    except ValueError as e:  # ragged nested sequences
        raise ValueError(f"{name} must be a rectangular array: {e}") from None
    if a.dtype.kind in "iu":
        return a.astype(np.float64)
    if a.dtype not in (np.float32, np.float64):
        raise TypeError(f"{name} must be a real float32 or float64 array, got dtype {a.dtype}")
    return a


def broadcast(**inputs: tuple[object, int]) -> list[np.ndarray]:
    """Broadcasts named inputs against each other. Each value is (array, k): k > 0 means a trailing vector axis of
    length k ((..., k) arrays, e.g. directions with k = 3), k = 0 a plain per-element scalar, which is given a
    trailing axis of length 1 for the Rust kernels. Returns read-only strided views; nothing is copied."""
    arrays = {}
    for name, (x, k) in inputs.items():
        a = as_real_array(name, x)
        if k == 0:
            a = a[..., None]
        elif a.ndim == 0 or a.shape[-1] != k:
            raise ValueError(f"{name} must have shape (..., {k}), got {a.shape}")
        arrays[name] = a
    try:
        batch = np.broadcast_shapes(*(a.shape[:-1] for a in arrays.values()))
    except ValueError:
        shapes = ", ".join(f"{n}: {a.shape}" for n, a in arrays.items())
        raise ValueError(f"input shapes do not broadcast ({shapes})") from None
    return [np.broadcast_to(a, batch + a.shape[-1:]) for a in arrays.values()]
