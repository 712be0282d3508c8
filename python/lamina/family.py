"""Families of stacks: a template stack (one holding lamina.Param) evaluated with per-element values of its free
parameters, a texture of varnish thickness, a roughness map, a patina mask. The family is tabulated over its free
parameters on a grid chosen by measured interpolation error, each node a stack the model prepares once (and caches),
and interpolated per element: multilinear, 2^k evaluations per element for k free parameters.

The grid: each parameter's nodes start at 5 uniform ones and an interval is halved while its linear interpolation's
error, estimated at its middle against the quadratic through a neighbouring node, exceeds `TOLERANCE` (relative L1
lobe error, on the suite's direction grid at θi ≤ 80°), the other parameters at their starts; at most `MAX_NODES`
per parameter; with several free parameters, each one's grid is refined with the others at their lows, starts and
highs. tests/test_family.py measures the real error against the explicit stacks.
"""

from __future__ import annotations

import itertools
from functools import lru_cache

import numpy as np

from ._arrays import broadcast
from ._reference import lobe_errors, suite_directions

#: The interpolation error a grid is refined to (relative L1 lobe error at the intervals' middles).
TOLERANCE = 0.004
#: The most nodes of one parameter's grid.
MAX_NODES = 65


def _f(template, model: str, options: tuple, values: dict) -> np.ndarray:
    """f of the explicit stack at `values` on the suite's direction grid."""
    wi, wo = suite_directions()
    return template.bind(**values).eval(wi, wo, model, **dict(options))


def _lagrange(x: float, xa: float, xb: float, xc: float) -> float:
    """The Lagrange basis polynomial of node xa among (xa, xb, xc), at x."""
    return (x - xb) * (x - xc) / ((xa - xb) * (xa - xc))


@lru_cache(maxsize=32)
def grid(template, model: str, options: tuple = ()) -> tuple:
    """Per free parameter of `template`, its nodes (a sorted array): from 5 uniform nodes, an interval is halved while
    the linear interpolation of its ends differs at its middle from the quadratic through them and a neighbouring node
    by more than TOLERANCE (relative L1 lobe error at θi ≤ 80°): an estimate of the linear interpolation's error that
    needs no solve beyond the nodes'. The other parameters at their lows, starts and highs (the largest estimate)."""
    out = []
    for p in template.params:
        others = [q for q in template.params if q is not p]
        settings = [{q.name: q.start for q in others}]
        if others:
            settings += [{q.name: q.low for q in others}, {q.name: q.high for q in others}]
        f = lambda x: np.stack([_f(template, model, options, {**o, p.name: x}) for o in settings])  # noqa: E731, B023
        nodes = [(x, f(x)) for x in np.linspace(p.low, p.high, 5)]
        i = 0
        while i < len(nodes) - 1:
            (x0, f0), (x1, f1) = nodes[i], nodes[i + 1]
            # The neighbour on the side with one (the next interval's end at the first interval).
            x2, f2 = nodes[i + 2] if i + 2 < len(nodes) else nodes[i - 1]
            mid = 0.5 * (x0 + x1)
            quadratic = sum(
                fa * _lagrange(mid, xa, xb, xc)
                for fa, xa, xb, xc in ((f0, x0, x1, x2), (f1, x1, x0, x2), (f2, x2, x0, x1))
            )
            linear = 0.5 * (f0 + f1)
            error = max(float(np.max(lobe_errors(a, b)[:4])) for a, b in zip(linear, quadratic))
            if error > TOLERANCE and len(nodes) < MAX_NODES:
                nodes.insert(i + 1, (mid, f(mid)))
            else:
                i += 1
        out.append(np.array([x for x, _ in nodes]))
    return tuple(out)


#: Uniform bins of a parameter's range in the lookup table that finds a value's grid cell (finer than the closest
#: nodes, MAX_NODES from halvings of 4 intervals: at most one node falls inside a bin).
_BINS = 4096


def _cells(nodes: np.ndarray, v: np.ndarray) -> np.ndarray:
    """The grid cell of each value v (index of the node at or below it, at most len(nodes) − 2): a table over
    uniform bins gives the cell at the bin's start, and one comparison the node inside the bin (a binary search per
    value costs more)."""
    lo, hi = nodes[0], nodes[-1]
    starts = lo + (hi - lo) * np.arange(_BINS) / _BINS
    table = np.clip(np.searchsorted(nodes, starts, side="right") - 1, 0, len(nodes) - 2).astype(np.intp)
    i = table[np.clip(((v - lo) * (_BINS / (hi - lo))).astype(np.intp), 0, _BINS - 1)]
    i = np.maximum(i - (v < nodes[i]), 0)  # a value just below a node that starts its bin (rounding)
    return np.minimum(i + (v >= nodes[i + 1]), len(nodes) - 2)


def eval_family(template, wi, wo, model: str, values: dict, options: dict) -> np.ndarray:
    """f (..., channels) of `template` at direction pairs wi, wo with its free parameters' values per element
    (`values`: name -> array broadcast with the directions), interpolated on `grid`. ValueError for a missing or
    unknown parameter, or a value outside its Param's range."""
    names = [p.name for p in template.params]
    if set(values) != set(names):
        raise ValueError(
            f"the stack is a family over {names}: give each one's values per element (eval(..., {names[0]}=...)); "
            f"got {sorted(values)}"
        )
    arrays = broadcast(wi=(wi, 3), wo=(wo, 3), **{n: (values[n], 0) for n in names})
    shape = arrays[0].shape[:-1]
    wi, wo = arrays[0].reshape(-1, 3), arrays[1].reshape(-1, 3)
    nodes = grid(template, model, tuple(sorted(options.items())))
    index, weight = [], []
    for p, a, grid_p in zip(template.params, arrays[2:], nodes):
        v = a.reshape(-1).astype(np.float64)
        if not np.all(np.isfinite(v)) or v.min() < p.low or v.max() > p.high:
            raise ValueError(f"{p.name} must hold finite values in [{p.low}, {p.high}] per element")
        i = _cells(grid_p, v)
        index.append(i)
        weight.append((v - grid_p[i]) / (grid_p[i + 1] - grid_p[i]))
    # Rows sorted by the grid cell they fall in (one sort, one gather): each cell's rows, a contiguous slice, are
    # evaluated at its 2^k corners. Keys of 16 bits sort by radix.
    cells = tuple(len(g) - 1 for g in nodes)
    key = np.ravel_multi_index(index, cells).astype(np.uint16 if np.prod(cells) < 2**16 else np.int64)
    order = np.argsort(key, kind="stable")
    ends = np.concatenate([[0], np.cumsum(np.bincount(key, minlength=int(np.prod(cells))))])
    wi, wo, weight = wi[order], wo[order], [t[order] for t in weight]
    stacks = {}  # each node's stack, bound once (a node is the corner of up to 2^k cells)
    out = None
    for cell in np.flatnonzero(ends[1:] > ends[:-1]):
        rows = slice(ends[cell], ends[cell + 1])
        base = np.unravel_index(cell, cells)
        for corner in itertools.product((0, 1), repeat=len(names)):
            node = tuple(int(j + c) for j, c in zip(base, corner))
            if node not in stacks:
                stacks[node] = template.bind(**{n: float(g[j]) for n, g, j in zip(names, nodes, node)})
            f = stacks[node].eval(wi[rows], wo[rows], model, **options)
            w = np.prod([t[rows] if c else 1.0 - t[rows] for t, c in zip(weight, corner)], axis=0).astype(f.dtype)
            if out is None:
                out = np.zeros((len(wi), f.shape[-1]), dtype=f.dtype)
            out[rows] += w[:, None] * f
    unsorted = np.empty_like(out)
    unsorted[order] = out
    out = unsorted
    return out.reshape(shape + (out.shape[-1],))
