"""Model no more than a scene needs: lamina.choose and model="auto" validated on held-out stacks, Stack.simplify,
the random population and the atlas's stability flags.

The held-out stacks are lamina.materials.population(100, seed=2): the predictor (python/lamina/data/choose.json,
written by `make population`) is built from seed 1 only. Their references (8000 paths per pair on the suite grid)
are computed afresh in this session, in a temporary cache, so that the check does not trust a stale one."""

from __future__ import annotations

import collections
import os
import sys
from pathlib import Path

import lamina
import numpy as np
import pytest
from lamina import Dielectric, Diffuse, Stack, atlas
from lamina.choose import EVALUATIONS, MODEL_OF, REFERENCE_SAMPLES, _data
from lamina.materials import metal
from lamina.reference import cached_reference, suite_directions

HELD_OUT = 100
#: Stacks of scripts/population.py's out-of-distribution set measured here (its named six first).
OOD_TESTED = 20


@pytest.fixture(scope="module")
def held_out(tmp_path_factory):
    """[(stack, measure(stack))] for the held-out population, references computed in a fresh cache."""
    old = os.environ.get("LAMINA_CACHE")
    os.environ["LAMINA_CACHE"] = str(tmp_path_factory.mktemp("held-out-cache"))
    try:
        stacks = [s for _, s in lamina.materials.population(HELD_OUT, seed=2)]
        return list(zip(stacks, [atlas.measure(s, albedo=False) for s in stacks]))  # choose needs lobes only
    finally:
        if old is None:
            del os.environ["LAMINA_CACHE"]
        else:
            os.environ["LAMINA_CACHE"] = old


@pytest.mark.parametrize("tolerance", [0.05, 0.1, 0.2, 0.3])
def test_choose_on_held_out_stacks(held_out, tolerance):
    """The issue's goals: the chosen model's measured error is within tolerance in >= 90% of the held-out stacks,
    and its cost within 1.25x the cheapest candidate that meets the tolerance (known by measuring all) in >= 80% of
    the stacks where one does. Stacks the reference does not resolve (lamina.atlas.resolved) have no measured error."""
    gt = _data()["ground_truth_samples"]
    resolved = [(stack, row) for stack, row in held_out if atlas.resolved(row)]
    assert len(resolved) >= 90  # the stacks whose lobes the reference resolves (docs/choose.md)
    within, efficient = [], []
    for stack, row in resolved:
        c = lamina.choose(stack, tolerance)
        errors = {
            label: (atlas.candidate_error(row, label, model, options, gt), cost)
            for label, model, options, cost in _candidates(c)
        }
        chosen = next(label for label, _, _, _ in _candidates(c) if _same(label, c))
        within.append(errors[chosen][0] <= tolerance)
        cheapest = min((cost for e, cost in errors.values() if e <= tolerance), default=None)
        if cheapest is not None:  # else no candidate meets the tolerance, and there is no cheapest one
            efficient.append(c.cost_ns <= 1.25 * cheapest)
    assert np.mean(within) >= 0.9, f"error within {tolerance} in {np.mean(within):.0%} of held-out stacks"
    assert np.mean(efficient) >= 0.8, f"cost within 1.25x the cheapest in {np.mean(efficient):.0%}"


def _candidates(choice):
    """(label, model, options, cost) of every candidate in the choice's table."""
    out = []
    for label, _, cost in choice.candidates:
        if label.startswith("reference"):
            out.append((label, "reference", {"samples": int(label.split()[1])}, cost))
        else:
            out.append((label, *MODEL_OF[label], cost))
    return out


def _same(label: str, choice) -> bool:
    if choice.model == "reference":
        return label == f"reference, {choice.options['samples']} paths"
    return label in MODEL_OF and MODEL_OF[label] == (choice.model, choice.options)


@pytest.fixture(scope="module")
def out_of_distribution(tmp_path_factory):
    """[(name, stack, lobe error of each model choice, noise per θi)] of the first OOD_TESTED stacks of
    scripts/population.py's out-of-distribution set, their references (8000 paths per pair on the suite grid)
    computed afresh in a temporary cache."""
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "scripts"))
    import population

    old = os.environ.get("LAMINA_CACHE")
    os.environ["LAMINA_CACHE"] = str(tmp_path_factory.mktemp("ood-cache"))
    try:
        wi, wo = suite_directions()
        out = []
        for name, stack in population.ood_stacks()[:OOD_TESTED]:
            f_ref, se = cached_reference(stack, wi, wo, samples=atlas.GROUND_TRUTH_SAMPLES, seed=0, progress=False)
            out.append((name, stack, f_ref, se.sum(axis=(1, 2)) / np.abs(f_ref).sum(axis=(1, 2))))
        return out
    finally:
        if old is None:
            del os.environ["LAMINA_CACHE"]
        else:
            os.environ["LAMINA_CACHE"] = old


@pytest.mark.parametrize("tolerance", [0.05, 0.1, 0.2])
def test_choose_on_stacks_from_another_distribution(out_of_distribution, tolerance):
    """The issue's goal on stacks drawn from another distribution than the training one (the six stacks on which
    `choose` was overconfident, and random ones of wider ranges): the chosen model's measured error within 1.25x
    the tolerance in >= 90% of those the reference resolves. Outside the population `choose` checks against the
    tabulated solve or keeps to exact answers; docs/choose.md measures the whole set."""
    wi, wo = suite_directions()
    low = np.array(lamina.reference.SUITE_THETAS) <= 80.0
    met, checked = [], 0
    for name, stack, f_ref, noise in out_of_distribution:
        if noise[low].max() > atlas.MAX_NOISE:
            continue  # the reference does not resolve its lobes: no measurement
        c = lamina.choose(stack, tolerance)
        checked += c.checked
        if c.model == "reference":
            scale = np.sqrt(atlas.GROUND_TRUTH_SAMPLES / c.options["samples"])
            err = np.sqrt(2 / np.pi) * noise[low].mean() * scale
        else:
            err = atlas.lobe_errors(stack.eval(wi, wo, c.model, **c.options), f_ref)[low].mean()
        met.append((name, c.model, err, err <= 1.25 * tolerance))
    assert len(met) >= 14 and checked >= 2  # measured: 18 resolved, 2 of them outside the population and checked
    share = np.mean([m[3] for m in met])
    assert share >= 0.9, f"within 1.25x {tolerance} on {share:.0%} of {len(met)}: {[m for m in met if not m[3]]}"


def test_choose_picks_the_exact_model_for_a_single_interface():
    c = lamina.choose(Stack([metal("Au", 0.2)]), 0.05)
    assert c.model == "microfacet" and c.options == {}
    assert c.predicted_error < 0.05 and "microfacet" in c.reason


def test_a_scattering_slab_gets_the_tabulated_solve_or_the_reference():
    """A scattering slab: every single-pass model's lobe error is about 0.9 (docs/validation.md); the tabulated solve
    (1.1%) meets 0.05 where its precomputation (1.35 s measured) is spread over many evaluations, and the reference
    (4096 paths: 6 ms per evaluation) where it is spread over a hundred."""
    slab = lamina.materials.suite("scattering-slab")
    c = lamina.choose(slab, 0.05)
    assert c.model == "tabulated" and c.predicted_error <= 0.05
    assert all(err > 0.05 for label, err, cost in c.candidates if cost < c.cost_ns)
    few = lamina.choose(slab, 0.05, evaluations=100)
    assert few.model == "reference" and few.options["samples"] in REFERENCE_SAMPLES
    costs = _data()["costs"]["tabulated"]
    tabulated = {label: cost for label, _, cost in few.candidates}["tabulated"]
    assert tabulated == pytest.approx(costs["ns_per_eval"] + 1e6 * costs["prepare_ms"] / 100)
    assert tabulated > few.cost_ns
    assert c.cost_ns == pytest.approx(costs["ns_per_eval"] + 1e6 * costs["prepare_ms"] / EVALUATIONS)


def test_choose_accounts_for_the_directions():
    """Belcour degrades at grazing angles: its predicted error for grazing light exceeds that for normal light."""
    stack = lamina.materials.suite("rough-coat-rough-copper")
    normal = dict((label, err) for label, err, _ in lamina.choose(stack, 0.1, wi=[0.0, 0.0, 1.0]).candidates)
    t = np.radians(85.0)
    grazing = dict((label, err) for label, err, _ in lamina.choose(stack, 0.1, wi=[np.sin(t), 0, np.cos(t)]).candidates)
    assert grazing["belcour"] > normal["belcour"]


def test_eval_auto_is_the_chosen_model():
    stack = lamina.materials.suite("rough-coat-rough-copper")
    rng = np.random.default_rng(3)
    wi, wo = rng.normal(size=(2, 50, 3))
    wi[:, 2], wo[:, 2] = np.abs(wi[:, 2]), np.abs(wo[:, 2])
    c = lamina.choose(stack, 0.3, wi)
    assert c.model != "reference"
    np.testing.assert_array_equal(stack.eval(wi, wo, "auto", tolerance=0.3), stack.eval(wi, wo, c.model, **c.options))


def test_choose_rejects_bad_input():
    stack = lamina.materials.suite("rough-coat-rough-copper")
    for bad in (0.0, -1.0, np.inf, "0.1", True):
        with pytest.raises(ValueError, match="tolerance"):
            lamina.choose(stack, bad)
    with pytest.raises(ValueError, match="wi"):
        lamina.choose(stack, 0.1, wi=[np.nan, 0.0, 1.0])
    for bad in (0, -5, np.nan, "many", True):
        with pytest.raises(ValueError, match="evaluations"):
            lamina.choose(stack, 0.1, evaluations=bad)
    with pytest.raises(TypeError, match="tolerance"):
        stack.eval([0, 0, 1.0], [0, 0, 1.0], "belcour", tolerance=0.1)


# --- Stack.simplify -------------------------------------------------------------------------------------------------


def _reference_agrees(a: Stack, b: Stack, samples: int = 20_000):
    """The two stacks' reference f agree within 4 joint standard errors (+1e-4 relative) on a few pairs."""
    t = np.radians([0.0, 40.0, 70.0])
    wi = np.stack([np.sin(t), np.zeros(3), np.cos(t)], -1)[:, None]
    wo = np.array([[0.0, 0.0, 1.0], [-0.5, 0.1, 0.86], [0.6, -0.3, 0.74]])[None]
    fa, sa = a.reference(wi, wo, samples=samples, seed=1, progress=False)
    fb, sb = b.reference(wi, wo, samples=samples, seed=2, progress=False)
    assert np.all(np.abs(fa - fb) <= 4 * np.hypot(sa, sb) + 1e-4 * np.abs(fa))


def test_simplify_removes_an_index_matched_smooth_interface_exactly():
    """A smooth interface between equal IORs does nothing; its slab joins the empty one above it."""
    stack = Stack([Dielectric(1.5, 0.2), Dielectric(1.5, thickness=1.0, sigma_a=0.3), metal("Au", 0.2)])
    s = stack.simplify(0.01)
    assert s.stack == Stack([Dielectric(1.5, 0.2, thickness=1.0, sigma_a=0.3), metal("Au", 0.2)])
    assert len(s.steps) == 1 and "index-matched" in s.steps[0]
    _reference_agrees(stack, s.stack)


def test_simplify_merges_adjacent_dielectrics_of_equal_ior_and_medium():
    stack = Stack(
        [Dielectric(1.5, 0.1, thickness=1.0, sigma_a=0.2), Dielectric(1.5, thickness=2.0, sigma_a=0.2), Diffuse(0.5)]
    )
    s = stack.simplify(0.01)
    assert s.stack == Stack([Dielectric(1.5, 0.1, thickness=3.0, sigma_a=0.2), Diffuse(0.5)])
    _reference_agrees(stack, s.stack)


def test_simplify_drops_a_slab_of_negligible_optical_depth():
    stack = Stack([Dielectric(1.5, 0.2, thickness=1e-3, sigma_a=1.0), metal("Cu", 0.3)])
    s = stack.simplify(0.01)
    assert s.stack == Stack([Dielectric(1.5, 0.2), metal("Cu", 0.3)])
    assert 0.0 < s.error <= 0.01  # the round trip's attenuation, 2e-3 at normal incidence, bounds it


def test_simplify_prunes_lobes_under_an_opaque_slab():
    stack = Stack([Dielectric(1.5, 0.2, thickness=10.0, sigma_a=2.0), metal("Cu", 0.3)])
    s = stack.simplify(0.01)
    assert s.stack == Stack([Dielectric(1.5, 0.2, thickness=10.0, sigma_a=2.0), Diffuse(0.0)])
    assert s.error <= 0.01
    _reference_agrees(stack, s.stack)


def test_simplify_leaves_a_stack_that_needs_every_layer():
    stack = lamina.materials.suite("three-layer")
    s = stack.simplify(0.01)
    assert s.stack is stack and s.error == 0.0 and s.steps == ()
    with pytest.raises(ValueError, match="tolerance"):
        stack.simplify(0.0)


# --- The population and the atlas ----------------------------------------------------------------------------------


def test_population_is_deterministic_and_follows_its_shares():
    a, b = lamina.materials.population(400, seed=5), lamina.materials.population(400, seed=5)
    assert a == b and a != lamina.materials.population(400, seed=6)
    counts = collections.Counter(kind for kind, _ in a)
    for kind, share in lamina.materials.POPULATION_CLASSES.items():
        sigma = np.sqrt(400 * share * (1 - share))
        assert abs(counts[kind] - 400 * share) <= 4 * sigma, kind


def test_stability_flags_find_what_they_claim():
    albedo = np.full((4, 4), 0.5)
    albedo[2:, :] += 0.2  # a jump of the model alone along x
    albedo[0, 0] = 1.2  # energy > 1
    ref = np.full((4, 4), 0.5)
    ref[2:, 3] += 0.2  # ... which the reference shares in the last column
    se = np.full((4, 4), 1e-3)
    nonfinite, negative = np.zeros((4, 4)), np.zeros((4, 4))
    negative[1, 1] = 2
    f = atlas.stability_flags(albedo, se, ref, nonfinite, negative)
    assert f["E"].sum() == 1 and f["E"][0, 0]
    assert f["−"].sum() == 1 and f["−"][1, 1] and not f["N"].any()
    assert f["D"][2, :3].all() and not f["D"][2, 3] and f["D"][1, 0]  # the 1.2 cell's neighbour jumps too
