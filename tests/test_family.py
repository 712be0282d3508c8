"""Families of stacks (lamina.family): a template stack with per-element values of its free parameters (lamina.Param),
interpolated on a grid of explicit stacks chosen by estimated error. Against the explicit stack at each element's
values: the issue's goal is 1% (relative L1 lobe error)."""

from __future__ import annotations

import time

import numpy as np
import pytest
from conftest import random_hemisphere
from lamina import Dielectric, Diffuse, Param, Stack, family
from lamina._reference import lobe_errors, suite_directions
from lamina.materials import metal


def _worst(fam: Stack, model: str, rng, draws: int = 10) -> float:
    """The largest lobe error (θi ≤ 80°, suite grid) of the family at random values against the explicit stacks."""
    wi, wo = suite_directions()
    worst = 0.0
    for _ in range(draws):
        v = {p.name: rng.uniform(p.low, p.high) for p in fam.params}
        per_element = {k: np.full(wi.shape[:-1], x) for k, x in v.items()}
        err = lobe_errors(fam.eval(wi, wo, model, **per_element), fam.bind(**v).eval(wi, wo, model))[:4].max()
        worst = max(worst, err)
    return worst


@pytest.mark.parametrize(
    "fam",
    [
        # varnish thickness, coat roughness, absorption (one channel), a diffuse base's albedo, two at once
        Stack([Dielectric(1.5, 0.1, thickness=Param("t", 0.1, 5.0), sigma_a=(0.2, 0.4, 0.8)), metal("Cu", 0.3)]),
        Stack([Dielectric(1.5, Param("r", 0.05, 0.6)), metal("Au", 0.2)]),
        Stack([Dielectric(1.5, 0.2, thickness=1.0, sigma_a=(Param("s", 0.0, 2.0), 0.3, 0.3)), Diffuse(0.8)]),
        Stack([Dielectric(1.4, 0.3), Diffuse((0.8, Param("g", 0.05, 0.95), 0.2))]),
        Stack([Dielectric(Param("n", 1.2, 2.0), Param("r", 0.05, 0.5)), metal("Cu", 0.4)]),
    ],
    ids=["thickness", "coat-roughness", "absorption", "albedo", "ior-and-roughness"],
)
def test_a_family_is_the_explicit_stack_at_each_element_s_values(fam, rng):
    # Measured (belcour): at most 0.59% over these families, 3 seeds of 10 draws each (grids of 7 to 44 nodes).
    assert _worst(fam, "belcour", rng) <= 0.01


def test_a_tabulated_family_within_its_budget(rng, tmp_path, monkeypatch):
    """The varnish-thickness family with tabulated: within 1% of the explicit stacks (measured 0.44% at most over
    20 values), its grid built in ≤ 30 s on 2 cores from an empty cache (measured 27 s, 20 nodes, 16 MB of tables)."""
    monkeypatch.setenv("LAMINA_CACHE", str(tmp_path))
    fam = Stack([Dielectric(1.5, 0.1, thickness=Param("t", 0.1, 5.0), sigma_a=(0.2, 0.4, 0.8)), metal("Cu", 0.3)])
    start = time.perf_counter()
    nodes = family.grid(fam, "tabulated")
    built = time.perf_counter() - start
    assert _worst(fam, "tabulated", rng, 20) <= 0.01
    # Not a timed assertion: the budget is the issue's, reported here with the grid.
    print(f"tabulated family grid: {len(nodes[0])} nodes in {built:.1f} s")


def test_per_element_values_broadcast_and_bad_ones_are_refused(rng):
    fam = Stack([Dielectric(1.5, Param("r", 0.05, 0.6)), metal("Au", 0.2)])
    wi, wo = random_hemisphere(rng, 64), random_hemisphere(rng, 64)
    r = rng.uniform(0.05, 0.6, 64)
    f = fam.eval(wi, wo, "belcour", r=r)
    assert f.shape == (64, 3)
    # A scalar value broadcasts: the family at one value is that stack, to the interpolation error.
    f_one = fam.eval(wi, wo, "belcour", r=0.3)
    assert lobe_errors(f_one[None], fam.bind(r=0.3).eval(wi, wo, "belcour")[None])[0] <= 0.01
    assert fam.eval(wi.astype(np.float32), wo.astype(np.float32), "belcour", r=r).dtype == np.float32
    with pytest.raises(ValueError, match=r"r must hold finite values in \[0.05, 0.6\]"):
        fam.eval(wi, wo, "belcour", r=r + 1.0)
    with pytest.raises(ValueError, match=r"family over \['r'\]"):
        fam.eval(wi, wo, "belcour")
    with pytest.raises(ValueError, match="takes an analytic model, not 'reference'"):
        fam.eval(wi, wo, "reference", r=r)
    with pytest.raises(ValueError, match="input shapes do not broadcast"):
        fam.eval(wi, wo, "belcour", r=r[:10])


def test_the_cell_lookup_is_a_binary_search(rng):
    """family._cells (a table over uniform bins and one comparison each way) finds the same cell as a binary search,
    on grids as the refinement makes them (nodes on a 1/256 lattice of the range, 2 to 65 of them), for random
    values, the nodes themselves and the floats just beside them."""
    for _ in range(100):
        lattice = np.unique(rng.integers(0, 257, rng.integers(0, 64)))
        nodes = 0.1 + 4.9 * np.unique(np.concatenate([[0, 256], lattice])) / 256
        v = np.concatenate(
            [rng.uniform(nodes[0], nodes[-1], 2000), nodes, np.nextafter(nodes, 0)[1:], np.nextafter(nodes, 9)[:-1]]
        )
        exact = np.clip(np.searchsorted(nodes, v, side="right") - 1, 0, len(nodes) - 2)
        assert np.array_equal(family._cells(nodes, v), exact)
