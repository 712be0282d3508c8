"""Monte Carlo ground truth (brute-force random walk in Rust): directional albedo and binned lobes of any stack.

Paths run in fixed chunks of CHUNK, so a long run shows a progress bar (tqdm, if installed) and stops cleanly on
Ctrl-C between chunks; results depend only on (seed, samples), never on the thread count or the chunking.
"""

from __future__ import annotations

import warnings

import numpy as np

from . import _lamina

#: Paths per direction and call into Rust (fixed: the order of the partial sums is part of what makes results
#: reproducible), and the most (pair x path) estimates per call, which bounds how long Ctrl-C waits.
CHUNK = 1 << 18
WORK_PER_CALL = 1 << 20


#: Incident zenith angles (degrees) of the suite's reference grid.
SUITE_THETAS = (0.0, 30.0, 60.0, 80.0, 87.0)


def suite_directions() -> tuple[np.ndarray, np.ndarray]:
    """The fixed grid of the suite's reference values: wi (5, 1, 3) at SUITE_THETAS in the x–z plane (φ = 0) and
    wo (1, 30, 3) at θo ∈ {0, 20, 40, 60, 75, 85}° x φo ∈ {0, 45, 90, 135, 180}° (φo = 180° holds the mirror
    direction); they broadcast to (5, 30, 3)."""
    ti = np.radians(SUITE_THETAS)
    wi = np.stack([np.sin(ti), np.zeros_like(ti), np.cos(ti)], -1)[:, None, :]
    to, po = np.meshgrid(np.radians([0, 20, 40, 60, 75, 85]), np.radians([0, 45, 90, 135, 180]), indexing="ij")
    wo = np.stack([np.sin(to) * np.cos(po), np.sin(to) * np.sin(po), np.cos(to)], -1).reshape(1, -1, 3)
    return wi, wo


def lobe_errors(f: np.ndarray, f_ref: np.ndarray) -> np.ndarray:
    """Relative L1 lobe error per θi row: Σ|f − f_ref| / Σ|f_ref| over directions and channels."""
    return np.abs(f - f_ref).sum(axis=(1, 2)) / np.maximum(np.abs(f_ref).sum(axis=(1, 2)), 1e-300)


def lobe_noise(se: np.ndarray, f_ref: np.ndarray) -> np.ndarray:
    """The reference's own expected lobe error per θi row (what a perfect model shows against it): √(2/π) Σ SE /
    Σ|f_ref| over directions and channels (the mean absolute value of a normal error is √(2/π) σ)."""
    return np.sqrt(2 / np.pi) * se.sum(axis=(1, 2)) / np.maximum(np.abs(f_ref).sum(axis=(1, 2)), 1e-300)


def _progress(total: int, progress):
    if progress is False or (progress is None and total < 4 * CHUNK):
        return None
    try:
        from tqdm.auto import tqdm
    except ImportError:
        return None
    return tqdm(total=total, unit="path", unit_scale=True, desc="lamina reference")


def _finish(truncated: int, stacklevel: int):
    """Warns, at the user's call `stacklevel` frames up, of paths dropped at the depth limit."""
    if truncated:
        warnings.warn(
            f"{truncated} reference paths reached the depth limit ({_lamina.REFERENCE_MAX_DEPTH} events) "
            "and were dropped; the estimate is biased low by at most their share",
            stacklevel=stacklevel,
        )


def _mean_stderr(s, s2, samples: int):
    """Mean of `samples` estimates and its standard error from their sum and sum of squares."""
    mean = s / samples
    return mean, np.sqrt(np.maximum(s2 / samples - mean**2, 0.0) / (samples - 1))


def _check(samples, seed):
    if isinstance(samples, bool) or not isinstance(samples, (int, np.integer)):
        raise TypeError(f"samples must be an integer >= 2, got {samples!r}")
    if samples < 2:
        raise ValueError(f"samples must be an integer >= 2, got {samples!r}")
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)):
        raise TypeError(f"seed must be an integer in [0, 2**64), got {seed!r}")
    if not 0 <= seed < 2**64:
        raise ValueError(f"seed must be an integer in [0, 2**64), got {seed!r}")


def f_estimate(layers, ext_ior, wi_rows, wo_rows, samples: int, seed: int, progress=None, options=None):
    """NEE estimate of f for each (wi, wo) row pair: mean and standard error, (pairs, channels) each. `options`: the
    reference's (distribution, g2), checked by Rust."""
    _check(samples, seed)
    bar = _progress(len(wi_rows) * samples, progress)
    wi_list, wo_list = wi_rows.tolist(), wo_rows.tolist()
    pairs_per_call = max(1, WORK_PER_CALL // min(samples, CHUNK))
    sums = []
    truncated = 0
    try:
        for lo in range(0, len(wi_list), pairs_per_call):
            hi = min(lo + pairs_per_call, len(wi_list))
            s = s2 = 0.0
            for first in range(0, samples, CHUNK):
                n = min(CHUNK, samples - first)
                a, b, t = _lamina.reference_f(
                    layers, ext_ior, wi_list[lo:hi], wo_list[lo:hi], first, n, int(seed), options or {}
                )
                s, s2 = s + np.asarray(a), s2 + np.asarray(b)
                truncated += int(np.sum(t))
                if bar is not None:
                    bar.update(n * (hi - lo))
            sums.append((s, s2))
    finally:
        if bar is not None:
            bar.close()
    _finish(truncated, stacklevel=5)  # the user's call -> Stack.reference -> _reference_f -> f_estimate -> _finish
    s, s2 = np.concatenate([a for a, _ in sums]), np.concatenate([b for _, b in sums])
    return _mean_stderr(s, s2, samples)


def tally(layers, ext_ior, wi_rows: np.ndarray, samples: int, seed: int, bins=(1, 1), progress=None, options=None):
    """Mean escaping energy per path and its standard error, shape (rows, channels, n_theta * n_phi) each.
    `options`: the reference's (distribution, g2), checked by Rust."""
    _check(samples, seed)
    n_theta, n_phi = bins
    bar = _progress(len(wi_rows) * samples, progress)
    means, errors, truncated = [], [], 0
    try:
        for wi in wi_rows:
            s = s2 = None
            for first in range(0, samples, CHUNK):
                n = min(CHUNK, samples - first)
                a, b, t = _lamina.reference_tally(
                    layers, ext_ior, [float(x) for x in wi], first, n, int(seed), n_theta, n_phi, options or {}
                )
                a, b = np.asarray(a), np.asarray(b)
                s, s2 = (a, b) if s is None else (s + a, s2 + b)
                truncated += int(np.sum(t))
                if bar is not None:
                    bar.update(n)
            mean, err = _mean_stderr(s, s2, samples)
            means.append(mean)
            errors.append(err)
    finally:
        if bar is not None:
            bar.close()
    _finish(truncated, stacklevel=4)  # the user's call -> Stack.albedo or reference_lobe -> tally -> _finish
    return np.array(means), np.array(errors)
