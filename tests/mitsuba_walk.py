"""A layered-BSDF ground truth built from Mitsuba 3's own BSDFs, sharing no code with lamina's reference: a random
walk from the light through a `roughdielectric` coat (both sides of it), a Beer–Lambert slab, and a
`roughconductor` or `diffuse` base, with Mitsuba sampling every scattering event (`BSDF.sample`, importance
transport, in a JIT variant) and NumPy keeping the paths. Escaping paths give the directional albedo and the
binned lobe (reflected energy per steradian, f·cos θo averaged over bins uniform in (θo, φo)), with standard errors.
Used by tests/test_mitsuba_reference.py."""

from __future__ import annotations

import drjit as dr
import mitsuba as mi
import numpy as np


def _sample(bsdf, ctx, wi: np.ndarray, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Mitsuba's sample of `bsdf` for local directions wi (n, 3) pointing back along the path: (new direction of
    travel (n, 3), weight f·cos/pdf (n, 3))."""
    si = dr.zeros(mi.SurfaceInteraction3f, len(wi))
    si.wi = mi.Vector3f(np.ascontiguousarray(wi.T, dtype=np.float32))
    bs, weight = bsdf.sample(
        ctx, si, mi.Float(u[:, 0].astype(np.float32)), mi.Point2f(np.ascontiguousarray(u[:, 1:].T, dtype=np.float32))
    )
    return np.array(bs.wo, dtype=np.float64).T, np.array(weight, dtype=np.float64).T


def walk(
    coat: dict, base: dict, sigma_a, thickness: float, wi, paths: int, seed: int, bins=(9, 18), max_depth: int = 200
):
    """Light arriving from `wi` (towards the light, unit) on the stack coat / slab (σa per RGB channel, thickness) /
    base. Returns (albedo (3,), albedo SE (3,), lobe (n_theta, n_phi, 3), lobe SE (same)). Russian roulette after
    16 events keeps the estimate unbiased."""
    ctx = mi.BSDFContext(mi.TransportMode.Importance)
    coat, base = mi.load_dict(coat), mi.load_dict(base)
    sigma_a = np.broadcast_to(np.asarray(sigma_a, dtype=np.float64), (3,))
    rng = np.random.default_rng(seed)
    d = np.tile(-np.asarray(wi, dtype=np.float64), (paths, 1))
    throughput = np.ones((paths, 3))
    below = np.zeros(paths, dtype=bool)  # in the slab
    alive = np.ones(paths, dtype=bool)
    exits_d, exits_w = np.zeros((paths, 3)), np.zeros((paths, 3))
    slab = lambda dz: np.exp(-sigma_a * thickness / np.abs(dz)[:, None])  # noqa: E731
    for depth in range(max_depth):
        # At the coat: from above (first event) or from the slab below (going up).
        k = np.nonzero(alive & ((~below) | (d[:, 2] > 0)))[0]
        if len(k):
            new, w = _sample(coat, ctx, -d[k], rng.random((len(k), 3)))
            throughput[k] *= w
            d[k] = new
            dead = k[w.max(axis=1) <= 0]
            alive[dead] = False
            out = k[(new[:, 2] > 0) & (w.max(axis=1) > 0)]
            exits_d[out], exits_w[out] = d[out], throughput[out]
            alive[out] = False
            below[k[new[:, 2] < 0]] = True
        # Down through the slab to the base, and back up through the slab.
        k = np.nonzero(alive & below & (d[:, 2] < 0))[0]
        if len(k):
            throughput[k] *= slab(d[k, 2])
            new, w = _sample(base, ctx, -d[k], rng.random((len(k), 3)))
            throughput[k] *= w * np.where(new[:, 2:3] > 0, slab(np.maximum(new[:, 2], 1e-12)), 0.0)
            d[k] = new
            alive[k[w.max(axis=1) <= 0]] = False
        if depth >= 16:  # Russian roulette on the brightest channel
            k = np.nonzero(alive)[0]
            q = np.clip(throughput[k].max(axis=1), 0.05, 1.0)
            survive = rng.random(len(k)) < q
            alive[k[~survive]] = False
            throughput[k[survive]] /= q[survive, None]
        if not alive.any():
            break
    albedo = exits_w.mean(axis=0)
    albedo_se = exits_w.std(axis=0, ddof=1) / np.sqrt(paths)
    theta = np.arccos(np.clip(exits_d[:, 2], -1, 1))
    phi = np.mod(np.arctan2(exits_d[:, 1], exits_d[:, 0]), 2 * np.pi)
    te, pe = np.linspace(0, np.pi / 2, bins[0] + 1), np.linspace(0, 2 * np.pi, bins[1] + 1)
    solid = np.outer(np.cos(te[:-1]) - np.cos(te[1:]), np.diff(pe))
    escaped = exits_w.max(axis=1) > 0
    lobe, lobe_se = np.zeros(bins + (3,)), np.zeros(bins + (3,))
    for c in range(3):
        s1 = np.histogram2d(theta[escaped], phi[escaped], (te, pe), weights=exits_w[escaped, c])[0]
        s2 = np.histogram2d(theta[escaped], phi[escaped], (te, pe), weights=exits_w[escaped, c] ** 2)[0]
        mean = s1 / paths
        lobe[..., c] = mean / solid
        lobe_se[..., c] = np.sqrt(np.maximum(s2 / paths - mean**2, 0) / (paths - 1)) / solid
    return albedo, albedo_se, lobe, lobe_se
