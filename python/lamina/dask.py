"""Scale-out with Dask (optional: `pip install lamina[dask]`).

- `eval(stack, wi, wo, model, **options)` evaluates dask arrays block by block (`map_blocks`), rows in chunks of at
  least 1M: the result is a dask array, bit-identical to `stack.eval` on the same NumPy arrays.
- `reference(stack, wi, wo, ...)`, `albedo(stack, wi, ...)` and `suite_reference(names, ...)` run Monte Carlo sweeps
  over a `dask.distributed.Client`: one task per direction (pair) or material, each a plain lamina call, so the
  results are bit-identical to running them locally (the reference's random streams depend only on the seed, the
  directions and the path index).

Stacks and model options pickle, so they travel to the workers as they are. Without a client, the local scheduler
runs the tasks.
"""

from __future__ import annotations

import numpy as np

from . import materials
from . import reference as _reference
from .catalogue import model as model_info
from .stack import Stack

#: Rows per block of `eval` (at least this many, unless the input is smaller).
MIN_CHUNK = 1 << 20


def _dask():
    try:
        import dask.array as da
    except ImportError:
        raise ImportError("lamina.dask needs dask: pip install lamina[dask]") from None
    return da


def _rows(da, x, name: str):
    """`x` as a dask array of rows (n, 3), chunked by at least MIN_CHUNK rows."""
    x = x if isinstance(x, da.Array) else da.from_array(np.asarray(x), chunks=-1)
    if x.ndim != 2 or x.shape[1] != 3:
        raise ValueError(f"{name} must be a dask or NumPy array of shape (n, 3), got {x.shape}")
    return x.rechunk({0: max(MIN_CHUNK, x.chunks[0][0]), 1: 3})


def eval(stack: Stack, wi, wo, model: str = "microfacet", **options):
    """f(wi, wo) of `stack` under `model` for (n, 3) dask (or NumPy) arrays of directions: a lazy (n, channels) dask
    array, computed block by block with `Stack.eval` (bit-identical to it)."""
    if not isinstance(stack, Stack):
        raise TypeError(f"stack must be a lamina.Stack, got {type(stack).__name__}")
    inputs = [k for k in options if k in model_info(model).inputs]
    if inputs:
        raise TypeError(f"lamina.dask.eval takes model options only, not per-element inputs ({inputs})")
    da = _dask()
    wi, wo = _rows(da, wi, "wi"), _rows(da, wo, "wo")
    if wi.shape[0] != wo.shape[0]:
        raise ValueError(f"wi and wo need the same number of rows, got {wi.shape[0]} and {wo.shape[0]}")
    wo = wo.rechunk(wi.chunks)
    channels = stack.eval(np.zeros(3) + [0, 0, 1], np.zeros(3) + [0, 0, 1], model, **options).shape[-1]
    dtype = np.result_type(wi.dtype, wo.dtype, np.float32)

    def block(a, b):
        return stack.eval(a, b, model, **options)

    return da.map_blocks(block, wi, wo, dtype=dtype, chunks=(wi.chunks[0], (channels,)))


def _gather(client, fn, items):
    """[fn(item) for item in items], as one task each on `client` (or locally without one)."""
    if client is None:
        return [fn(item) for item in items]
    return client.gather(client.map(fn, items, pure=False))


def reference(stack: Stack, wi, wo, samples: int = 100_000, seed: int = 0, client=None, **options):
    """`Stack.reference` for (n, 3) wi and wo, one task per pair: (f, stderr), each (n, channels)."""
    wi, wo = np.asarray(wi, dtype=np.float64).reshape(-1, 3), np.asarray(wo, dtype=np.float64).reshape(-1, 3)
    if wi.shape != wo.shape:
        raise ValueError(f"wi and wo must have the same shape (n, 3), got {wi.shape} and {wo.shape}")
    pairs = list(zip(wi, wo))

    def task(pair):
        return stack.reference(pair[0], pair[1], samples=samples, seed=seed, progress=False, **options)

    out = _gather(client, task, pairs)
    return np.array([f for f, _ in out]), np.array([se for _, se in out])


def albedo(stack: Stack, wi, model: str = "reference", client=None, **options):
    """`Stack.albedo` for (n, 3) wi, one task per direction: (albedo, stderr) for the reference, albedo otherwise."""
    rows = np.asarray(wi, dtype=np.float64).reshape(-1, 3)

    def task(w):
        return stack.albedo(w, model, **({"progress": False} if model == "reference" else {}), **options)

    out = _gather(client, task, list(rows))
    if model == "reference":
        return np.array([a for a, _ in out]), np.array([se for _, se in out])
    return np.array(out)


def suite_reference(names=None, samples: int = 100_000, seed: int = 0, client=None) -> dict:
    """`lamina.reference.suite_reference` for the suite's materials (all by default), one task per material:
    {name: (wi, wo, f, stderr)}. Each worker caches its results like a local run."""
    names = list(materials.SUITE if names is None else names)

    def task(name):
        return _reference.suite_reference(name, samples=samples, seed=seed)

    return dict(zip(names, _gather(client, task, names)))
