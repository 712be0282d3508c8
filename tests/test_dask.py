"""lamina.dask on a LocalCluster of 2 worker processes: block-wise eval on dask arrays and distributed Monte Carlo
sweeps, each bit-identical to the local computation."""

from __future__ import annotations

import dask.array as da
import lamina
import lamina.dask as ldask
import numpy as np
import pytest
from distributed import Client, LocalCluster


@pytest.fixture(scope="module")
def client():
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
        with Client(cluster) as c:
            yield c


def directions(rng, n):
    w = rng.normal(size=(n, 3))
    w[:, 2] = np.abs(w[:, 2]) + 0.01
    return w


def test_eval_on_dask_arrays_is_bit_identical(client, rng):
    stack = lamina.materials.suite("rough-coat-rough-copper")
    state = da.random.RandomState(5)
    wi, wo = (state.normal(size=(2_500_000, 3), chunks=(700_000, 3)) + [0, 0, 3.0] for _ in range(2))
    lazy = ldask.eval(stack, wi, wo, "belcour")
    assert lazy.chunks[0][0] >= ldask.MIN_CHUNK and lazy.shape == (2_500_000, 3)
    f = client.compute(lazy).result()
    wi, wo = wi.compute(), wo.compute()
    assert np.array_equal(f, stack.eval(wi, wo, "belcour"))
    wi, wo = wi[:100_000].astype(np.float32), wo[:100_000].astype(np.float32)  # NumPy inputs travel in the graph
    f32 = ldask.eval(stack, wi, wo, "steinberg", lut="fitted").compute()
    assert f32.dtype == np.float32
    assert np.array_equal(f32, stack.eval(wi, wo, "steinberg", lut="fitted"))
    with pytest.raises(TypeError, match="per-element inputs"):
        ldask.eval(lamina.materials.car_paint(), wi, wo, "weidlich_wilkie", flake_normal=wi)


def test_distributed_sweeps_equal_local_runs(client, rng):
    stack = lamina.materials.suite("three-layer")
    wi, wo = directions(rng, 4), directions(rng, 4)
    f, se = ldask.reference(stack, wi, wo, samples=4000, seed=3, client=client)
    local = stack.reference(wi, wo, samples=4000, seed=3)
    assert np.array_equal(f, local[0]) and np.array_equal(se, local[1])
    a, a_se = ldask.albedo(stack, wi, client=client, samples=4000, seed=2)
    local = stack.albedo(wi, "reference", samples=4000, seed=2)
    assert np.array_equal(a, local[0]) and np.array_equal(a_se, local[1])
    assert np.array_equal(ldask.albedo(stack, wi[:2], "belcour", client=client), stack.albedo(wi[:2], "belcour"))
    suite = ldask.suite_reference(["gold-clearcoat", "varnished-diffuse"], samples=500, client=client)
    for name, (_, _, f_s, se_s) in suite.items():
        ref = lamina.reference.suite_reference(name, samples=500)
        assert np.array_equal(f_s, ref[2]) and np.array_equal(se_s, ref[3])


def test_atlas_plane_over_a_client_equals_a_local_run(client, tmp_path, monkeypatch):
    """The failure atlas's cells as one task per stack: the same numbers as a local run in a fresh cache (a published
    model, and `tabulated`, whose tables the workers solve)."""
    models = ("belcour", "tabulated")
    remote = lamina.atlas.atlas_plane("theta-coat-ior", client=client, samples=200, models=models)
    monkeypatch.setenv("LAMINA_CACHE", str(tmp_path))
    local = lamina.atlas.atlas_plane("theta-coat-ior", samples=200, models=models)
    assert remote == local
