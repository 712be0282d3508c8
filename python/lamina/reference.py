"""Monte Carlo ground truth (brute-force random walk in Rust): directional albedo and binned lobes of any stack.

Paths run in fixed chunks of CHUNK, so a long run shows a progress bar (tqdm, if installed) and stops cleanly on
Ctrl-C between chunks; results depend only on (seed, samples), never on the thread count or the chunking.
"""

from __future__ import annotations

import warnings

import numpy as np

from . import _lamina

#: Paths per call into Rust (fixed: it is part of what makes results reproducible).
CHUNK = 1 << 18


def _progress(total: int, progress):
    if progress is False or (progress is None and total < 4 * CHUNK):
        return None
    try:
        from tqdm.auto import tqdm
    except ImportError:
        return None
    return tqdm(total=total, unit="path", unit_scale=True, desc="lamina reference")


def tally(layers, ext_ior, wi_rows: np.ndarray, samples: int, seed: int, bins=(1, 1), progress=None, **options):
    """Mean escaping energy per path and its standard error, shape (rows, channels, n_theta * n_phi) each."""
    if not isinstance(samples, (int, np.integer)) or samples < 2:
        raise ValueError(f"samples must be an integer >= 2, got {samples!r}")
    if not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"seed must be a non-negative integer, got {seed!r}")
    n_theta, n_phi = bins
    bar = _progress(len(wi_rows) * samples, progress)
    means, errors, truncated = [], [], 0
    try:
        for wi in wi_rows:
            s = s2 = None
            for first in range(0, samples, CHUNK):
                n = min(CHUNK, samples - first)
                a, b, t = _lamina.reference_tally(layers, ext_ior, [float(x) for x in wi], first, n, int(seed),
                                                  n_theta, n_phi, **options)
                a, b = np.asarray(a), np.asarray(b)
                s, s2 = (a, b) if s is None else (s + a, s2 + b)
                truncated += int(np.sum(t))
                if bar is not None:
                    bar.update(n)
            mean = s / samples
            means.append(mean)
            errors.append(np.sqrt(np.maximum(s2 / samples - mean**2, 0.0) / (samples - 1)))
    finally:
        if bar is not None:
            bar.close()
    if truncated:
        warnings.warn(f"{truncated} reference paths reached the depth limit ({_lamina.REFERENCE_MAX_DEPTH} events) "
                      "and were dropped; the estimate is biased low by at most their share", stacklevel=3)
    return np.array(means), np.array(errors)
