"""`make population`: measures every candidate model of lamina.choose against the Monte Carlo reference on two
random populations of lamina.materials.population — seed 1 (TRAIN stacks: the speed/accuracy chart's held-out
population, and the data `choose` predicts from) and seed 2 (HELD_OUT stacks, which only validate `choose`) — on
stacks drawn from another distribution (`out_of_distribution`: OOD stacks, which validate `choose` where its
neighbours say nothing), and the candidates' costs. Writes docs/population.json (every measurement),
python/lamina/data/choose.json (the predictor's data: seed 1 only, and the costs) and docs/choose.md (the
validation). Not a test; resumable, since the references are cached.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
from pathlib import Path

import lamina
import numpy as np
from lamina import Conductor, Dielectric, Diffuse, Stack, atlas
from lamina.choose import (
    CANDIDATES,
    FEATURES,
    REFERENCE_SAMPLES,
    START_WEIGHTS,
    check,
    choose_with,
    covered,
    distances,
    prepare,
    rank,
    represents,
)
from lamina.materials import metal

ROOT = Path(__file__).resolve().parents[1]
TRAIN, HELD_OUT, OOD = 200, 100, 40
#: Tolerances (relative L1 lobe error) at which `choose` is fitted and validated.
TOLERANCES = (0.05, 0.1, 0.2, 0.3)
#: The predictor's settings tried by leave-one-out on the training set: neighbours and quantiles; the feature weights
#: are fitted by coordinate ascent from START_WEIGHTS, one weight at a time scaled by FACTORS, on the smaller grid
#: ASCENT_GRID of the other settings.
KS = (3, 5, 7, 9)
QUANTILES = (0.6, 0.7, 0.8, 0.9)
NOISE_QUANTILES = (0.5, 0.7, 0.9)
FACTORS = (0.25, 0.5, 2.0, 4.0)
ASCENT_GRID = [(k, q, qn) for k in (3, 5) for q in (0.6, 0.7, 0.8) for qn in (0.5, 0.7, 0.9)]
#: θi ≤ 80° of the suite grid: the angles a wi=None choice is about.
LOW = np.array(lamina.reference.SUITE_THETAS) <= 80.0


def truth(d: dict, rows: list, leave_one_out: bool, stacks: dict | None = None) -> list:
    """Per stack: its features, whether each candidate represents it, every candidate's measured error (as `rank`
    labels them), whether it lies inside the training population (`covered`; with leave_one_out, `rows` is the
    training set and each stack is judged without itself), and for a stack outside it whose Stack `stacks` holds (by
    repr) `choose`'s check against the tabulated solve (else None). None of it depends on the predictor's settings
    but the check's bound, tabulated's error quantile over d's training stacks."""
    gt = d["ground_truth_samples"]
    train = np.array([r["features"] for r in d["train"]])
    out = []
    for i, r in enumerate(rows):
        can = {label: r["lobe_error"][label] is not None for label, _, _ in CANDIDATES}
        err = {label: atlas.candidate_error(r, label, model, options, gt) for label, model, options in CANDIDATES}
        for n in d["reference_samples"]:
            label = f"reference, {n} paths"
            err[label] = atlas.candidate_error(r, label, "reference", {"samples": n}, gt)
        x = np.array(r["features"])
        inside = covered(np.delete(train, i, axis=0) if leave_one_out else train, x)
        stack = (stacks or {}).get(r.get("stack"))
        checked = None if inside or stack is None else check(stack, d["tabulated_bound"], represents(stack))
        out.append((x, can, err, inside, checked))
    return out


def outcomes(d: dict, known: list, leave_one_out: bool) -> dict:
    """Per tolerance, per stack of `known` (from `truth`): (chosen label, its error within tol, its cost within
    1.25x the cheapest candidate within tol; None when no candidate is within tol). With leave_one_out, `known` is
    d's own training set and each stack is predicted without itself."""
    w = LOW / LOW.sum()
    dist = distances(d, np.array([k[0] for k in known]))
    if leave_one_out:
        np.fill_diagonal(dist, np.inf)
    out = {tol: [] for tol in TOLERANCES}
    for i, (_, can, err, inside, checked) in enumerate(known):
        ranked = rank(d, dist[i], can, w, inside, checked=checked)
        for tol in TOLERANCES:
            fits = [c for c in ranked if c[3] <= tol]
            label, _, _, _, cost = fits[0] if fits else ranked[-1]
            within = [c[4] for c in ranked if err[c[0]] <= tol]
            out[tol].append((label, err[label] <= tol, cost <= 1.25 * min(within) if within else None))
    return out


def rates(o: list) -> tuple:
    """(share of choices within tolerance, share of cost-efficient choices among the stacks some candidate meets,
    number of stacks no candidate meets)."""
    efficient = [x[2] for x in o if x[2] is not None]
    return np.mean([x[1] for x in o]), np.mean(efficient), len(o) - len(efficient)


def margin(d: dict, known: list, weights, k: int, q: float, qn: float) -> float:
    """The worst, over TOLERANCES, of leave-one-out coverage over 0.9 and cost efficiency over 0.8."""
    dd = prepare({**d, "weights": list(weights), "k": k, "quantile": q, "noise_quantile": qn})
    o = outcomes(dd, known, leave_one_out=True)
    return min(min(within - 0.9, efficient - 0.8) for within, efficient, _ in map(rates, o.values()))


def fit(d: dict) -> tuple:
    """(weights, k, quantile, noise quantile) maximizing the leave-one-out `margin` on the training set, and the
    table of every (k, q, qn)'s margin at the fitted weights."""
    known = truth(d, d["train"], leave_one_out=True)
    best = lambda wts: max((margin(d, known, wts, *s), s) for s in ASCENT_GRID)  # noqa: E731
    weights = list(START_WEIGHTS)
    current, _ = best(weights)
    for _ in range(2):
        for i in range(len(weights)):
            for factor in FACTORS:
                trial = weights[:i] + [weights[i] * factor] + weights[i + 1 :]
                score, _ = best(trial)
                if score > current + 1e-9:
                    current, weights = score, trial
                    print(f"fit: {FEATURES[i]} weight x{factor:g}: margin {score:+.3f}", file=sys.stderr)
    table = [(k, q, qn, margin(d, known, weights, k, q, qn)) for k in KS for q in QUANTILES for qn in NOISE_QUANTILES]
    k, q, qn, _ = max(table, key=lambda t: t[3])
    return weights, k, q, qn, table


def measure_set(seed: int, n: int, client=None) -> list:
    stacks = lamina.materials.population(n, seed)
    rows = atlas.measure_all([s for _, s in stacks], client=client, desc=f"population seed {seed}")
    for (kind, stack), row in zip(stacks, rows):
        row["class"] = kind
        row["stack"] = repr(stack)
    return rows


def costs() -> dict:
    """Per candidate its ns per evaluation and its first call's ms (lamina.atlas.cost). Each first call runs in an
    empty cache of its own, after every candidate has run on another stack: what it times is the precomputation a
    user pays per stack (tabulated's solve, the improved variants' solve and fit), not the tables built once per
    installation."""
    for _, model, options in CANDIDATES:
        stack = Stack([metal("Au", 0.2)]) if model == "microfacet" else lamina.materials.suite("gold-clearcoat")
        stack.eval([0.0, 0.0, 1.0], [0.0, 0.0, 1.0], model, **options)
    out = {}
    old = os.environ.get("LAMINA_CACHE")
    try:
        for label, model, options in CANDIDATES:
            with tempfile.TemporaryDirectory() as empty:
                os.environ["LAMINA_CACHE"] = empty
                ns, prepare_ms = atlas.cost(model, options)
            out[label] = {"ns_per_eval": ns, "prepare_ms": prepare_ms}
            print(f"{label:26s} {ns:8.1f} ns/eval, first call {prepare_ms:.1f} ms", file=sys.stderr)
    finally:
        if old is None:
            del os.environ["LAMINA_CACHE"]
        else:
            os.environ["LAMINA_CACHE"] = old
    out["reference"] = {"ns_per_path": atlas.reference_cost()}
    print(f"reference {out['reference']['ns_per_path']:.1f} ns per pair and path", file=sys.stderr)
    return out


#: The six stacks made outside lamina's population on which `choose` was found overconfident (issue "Near-exact").
NAMED_OOD = {
    "clear coat over gold": lambda: Stack([Dielectric(1.5), metal("Au", 0.15)]),
    "rough coat over a near-mirror metal": lambda: Stack([Dielectric(1.5, roughness=0.3), metal("Ag", 0.02)]),
    "rough over rough": lambda: Stack([Dielectric(1.6, roughness=0.4), metal("Cu", 0.5)]),
    "varnish over diffuse": lambda: Stack(
        [Dielectric(1.5, roughness=0.05, thickness=1.0, sigma_a=(0.1, 0.3, 0.8)), Diffuse((0.6, 0.35, 0.15))]
    ),
    "anisotropic coat": lambda: Stack([Dielectric(1.5, roughness=(0.05, 0.4), angle=0.6), metal("Al", 0.2)]),
    "thick absorbing slab": lambda: Stack(
        [Dielectric(1.45, roughness=0.2, thickness=5.0, sigma_a=(0.6, 0.3, 0.1)), metal("Cr", 0.3)]
    ),
}


def ood_stack(rng) -> Stack:
    """A stack of another distribution than lamina.materials.population's real-material ranges: one to three
    dielectric layers (IOR U[1.1, 2.4]; smooth with probability 0.3, else alpha log-uniform in [0.005, 1], anisotropic
    (ratio U[0.1, 1], angle U[0, π)) with probability 0.3; thickness U[0, 8], σa ~ U[0, 2]³ with probability 0.5,
    σs U[0, 4] with g U[−0.3, 0.9] with probability 0.3) over a synthetic conductor (η U[0.1, 3], κ U[0.5, 8]
    per channel, alpha log-uniform in [0.005, 1]) or a diffuse base (albedo U[0, 1]³, Oren–Nayar σ U[0, 1] half
    the time)."""
    log_alpha = lambda: float(np.exp(rng.uniform(np.log(0.005), 0.0)))  # noqa: E731

    def roughness():
        if rng.uniform() < 0.3:
            return 0.0
        a = log_alpha()
        return (a, a * rng.uniform(0.1, 1.0)) if rng.uniform() < 0.3 else a

    layers = []
    for _ in range(int(rng.integers(1, 4))):
        scatter = rng.uniform() < 0.3
        layers.append(
            Dielectric(
                float(rng.uniform(1.1, 2.4)),
                roughness=roughness(),
                angle=float(rng.uniform(0, np.pi)),
                thickness=float(rng.uniform(0, 8)),
                sigma_a=tuple(rng.uniform(0, 2, 3)) if rng.uniform() < 0.5 else 0.0,
                sigma_s=float(rng.uniform(0, 4)) if scatter else 0.0,
                g=float(rng.uniform(-0.3, 0.9)) if scatter else 0.0,
            )
        )
    if rng.uniform() < 0.5:
        layers.append(Conductor(tuple(rng.uniform(0.1, 3, 3)), tuple(rng.uniform(0.5, 8, 3)), log_alpha()))
    else:
        layers.append(Diffuse(tuple(rng.uniform(0, 1, 3)), float(rng.uniform(0, 1)) if rng.uniform() < 0.5 else 0.0))
    return Stack(layers)


def ood_stacks(n: int = OOD) -> list:
    """(name, stack): NAMED_OOD, then n stacks of `ood_stack` (seed 3)."""
    rng = np.random.default_rng([3, 0x00D])
    return [(name, make()) for name, make in NAMED_OOD.items()] + [(f"ood {i}", ood_stack(rng)) for i in range(n)]


def measure_ood(client=None) -> list:
    stacks = ood_stacks()
    rows = atlas.measure_all([s for _, s in stacks], client=client, desc="out of distribution")
    for (name, stack), row in zip(stacks, rows):
        row["class"] = name
        row["stack"] = repr(stack)
    return rows


def ood_outcomes(d: dict, rows: list) -> dict:
    """Per tolerance, per resolved OOD stack: (chosen label, its measured error within 1.25x tol, whether the choice
    was checked against the tabulated solve, whether the stack lies inside the training population)."""
    gt = d["ground_truth_samples"]
    out = {tol: [] for tol in TOLERANCES}
    for (_, stack), r in zip(ood_stacks(), rows):
        if not atlas.resolved(r):
            continue
        for tol in TOLERANCES:
            c = choose_with(d, stack, tol)
            if c.model == "reference":
                label = f"reference, {c.options['samples']} paths"
            else:
                label = next(lb for lb, m, o in CANDIDATES if (m, o) == (c.model, c.options))
            err = atlas.candidate_error(r, label, c.model, c.options, gt)
            out[tol].append((label, err <= 1.25 * tol, c.checked, covered(d["x"], np.array(r["features"]))))
    return out


def report(data: dict, table: list, everything: dict) -> None:
    """docs/choose.md: the fitted setting and the validation on the held-out population."""
    k, q, qn = data["k"], data["quantile"], data["noise_quantile"]
    d = prepare(data)
    lines = [
        "# `lamina.choose`: validation on held-out stacks",
        "",
        "Generated by `make population` (scripts/population.py). Do not edit.",
        "",
        f"The predictor is built from the {len(everything['train'])} stacks of `lamina.materials.population(seed=1)`, "
        f"and validated here on the {len(everything['held_out'])} stacks of seed 2, which it never saw. Stacks whose "
        f"reference noise exceeds {atlas.MAX_NOISE} at some θi ≤ 80° (`lamina.atlas.resolved`) have no measured lobe "
        f"error and are left out of both: {len(everything['train']) - len(data['train'])} and "
        f"{len(everything['held_out']) - len(data['held_out'])} of them. Each stack is "
        f"measured against the reference ({data['ground_truth_samples']} paths per pair) on the suite's direction "
        "grid; a model's error is its relative L1 lobe error averaged over θi ∈ {0, 30, 60, 80}°. The reference "
        "candidate at n paths is credited with the expected L1 error of its noise, √(2/π) Σ SE / Σ|f| scaled "
        "from the measured ground truth's standard errors to n paths. `microfacet` is exact where it applies.",
        "",
        f"Predictor (`lamina.choose.rank`): the {q:g} quantile of the errors of the k = {k} nearest training stacks "
        "that the model represents, in the weighted, standardized feature space of `lamina.choose.features`, and "
        f"for the reference the {qn:g} quantile of the k nearest stacks' noise. The feature weights, k and the "
        "quantiles maximize, by leave-one-out on the training stacks, the worst margin of coverage over 90% and of "
        "cost efficiency over 80% (table below). The weights, fitted by coordinate ascent from "
        f"{list(START_WEIGHTS)} (x{', x'.join(f'{f:g}' for f in FACTORS)} one at a time): "
        + ", ".join(f"{name} {wt:g}" for name, wt in zip(FEATURES, data["weights"]))
        + ".",
        "",
        "Costs (ns per evaluation, 1M float32 pairs, this machine): "
        + ", ".join(f"{c[0]} {data['costs'][c[0]]['ns_per_eval']:.1f}" for c in CANDIDATES)
        + f"; the reference {data['costs']['reference']['ns_per_path']:.0f} per pair and path.",
        "",
        "Cost efficiency counts the stacks where some candidate meets the tolerance; the last column counts those "
        "where none does (not even the reference at the most paths offered), where `choose` returns the most accurate "
        "candidate and says so in its reason.",
        "",
        "| tolerance | error ≤ tolerance (goal ≥ 90%) | cost ≤ 1.25x the cheapest candidate within tolerance "
        "(goal ≥ 80%) | no candidate within tolerance | choices |",
        "|---:|---:|---:|---:|---|",
    ]
    stacks = {repr(s): s for _, s in lamina.materials.population(HELD_OUT, 2)}
    held_out = outcomes(d, truth(d, data["held_out"], leave_one_out=False, stacks=stacks), leave_one_out=False)
    for tol in TOLERANCES:
        o = held_out[tol]
        within, efficient, none = rates(o)
        picks = {}
        for label, _, _ in o:
            picks[label] = picks.get(label, 0) + 1
        lines.append(
            f"| {tol:g} | {within:.0%} | {efficient:.0%} | {none} | "
            + ", ".join(f"{n} {label}" for label, n in sorted(picks.items(), key=lambda t: -t[1]))
            + " |"
        )
    ood = ood_outcomes(d, everything["out_of_distribution"])
    n_ood = len(ood[TOLERANCES[0]])
    lines += [
        "",
        "## Stacks from another distribution",
        "",
        f"{len(NAMED_OOD)} stacks made outside the population ({', '.join(NAMED_OOD)}) and {OOD} stacks of "
        "`scripts/population.py`'s `ood_stack` (one to three coats of IOR up to 2.4, roughness down to 0.005, "
        "anisotropic, scattering, over synthetic conductors or diffuse bases), each measured like the "
        f"populations; {n_ood} of the {len(NAMED_OOD) + OOD} are resolved by the reference. The goal: the chosen "
        "model's measured error within 1.25x the tolerance in ≥ 90% of them. Outside the measured population "
        "(`lamina.choose.covered`) `choose` checks every candidate against the tabulated solve where tabulated "
        "resolves the stack, and otherwise keeps only exact answers.",
        "",
        "| tolerance | error ≤ 1.25x tolerance (goal ≥ 90%) | outside the population | checked | choices |",
        "|---:|---:|---:|---:|---|",
    ]
    for tol in TOLERANCES:
        o = ood[tol]
        picks = {}
        for label, *_ in o:
            picks[label] = picks.get(label, 0) + 1
        lines.append(
            f"| {tol:g} | {np.mean([x[1] for x in o]):.0%} | {sum(not x[3] for x in o)} | {sum(x[2] for x in o)} | "
            + ", ".join(f"{n} {label}" for label, n in sorted(picks.items(), key=lambda t: -t[1]))
            + " |"
        )
    counts = {label: [0, 0] for label, _, _ in CANDIDATES}
    for r in everything["train"] + everything["held_out"]:
        for label, f in r["flags"].items():
            counts[label] = [counts[label][0] + f["nonfinite"], counts[label][1] + f["negative"]]
    lines += [
        "",
        f"Stability on all {len(everything['train']) + len(everything['held_out'])} stacks of both populations "
        "(values on the suite's direction grid that are NaN or Inf, and negative): "
        + ", ".join(f"{label} {n} and {neg}" for label, (n, neg) in counts.items())
        + ".",
    ]
    lines += [
        "",
        "Leave-one-out margins on the training set at the fitted weights, min over the tolerances of "
        "min(coverage − 0.9, efficiency − 0.8):",
        "",
        "| k | quantile | " + " | ".join(f"noise q = {x:g}" for x in NOISE_QUANTILES) + " |",
        "|---:|---:|" + "---:|" * len(NOISE_QUANTILES),
    ]
    for k_ in KS:
        for q_ in QUANTILES:
            cells = [m for kk, qq, _, m in table if kk == k_ and qq == q_]
            lines.append(f"| {k_} | {q_:g} | " + " | ".join(f"{m:+.2f}" for m in cells) + " |")
    (ROOT / "docs" / "choose.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines), file=sys.stderr)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--report-only", action="store_true", help="refit and report from docs/population.json")
    parser.add_argument(
        "--costs", action="store_true", help="with --report-only: measure the candidates' costs again (a faster build)"
    )
    parser.add_argument("--scheduler", help="address of a dask.distributed scheduler to run the references on")
    args = parser.parse_args()
    client = None
    if args.scheduler:
        from distributed import Client

        client = Client(args.scheduler)
    if args.report_only:
        data = json.loads((ROOT / "docs" / "population.json").read_text())
        if args.costs:
            data["costs"] = costs()
            (ROOT / "docs" / "population.json").write_text(json.dumps(data, indent=1))
    else:
        data = {
            "features": list(FEATURES),
            "thetas": list(lamina.reference.SUITE_THETAS),
            "ground_truth_samples": atlas.GROUND_TRUTH_SAMPLES,
            "reference_samples": list(REFERENCE_SAMPLES),
            "costs": costs(),
            "train": measure_set(1, TRAIN, client),
            "held_out": measure_set(2, HELD_OUT, client),
            "out_of_distribution": measure_ood(client),
        }
        (ROOT / "docs" / "population.json").write_text(json.dumps(data, indent=1))
    resolved = {**data, "train": [r for r in data["train"] if atlas.resolved(r)]}
    resolved["held_out"] = [r for r in data["held_out"] if atlas.resolved(r)]
    data["weights"], data["k"], data["quantile"], data["noise_quantile"], table = fit(resolved)
    predictor = {k: v for k, v in data.items() if k not in ("held_out", "out_of_distribution")}
    predictor["train"] = [
        {k: r[k] for k in ("features", "noise", "lobe_error")} for r in data["train"] if atlas.resolved(r)
    ]
    (ROOT / "python" / "lamina" / "data" / "choose.json").write_text(json.dumps(predictor))
    report({**resolved, **{k: data[k] for k in ("weights", "k", "quantile", "noise_quantile")}}, table, data)
    print(
        f"wrote docs/population.json, python/lamina/data/choose.json and docs/choose.md "
        f"({len(data['train'])} + {len(data['held_out'])} stacks)",
        file=sys.stderr,
    )


if __name__ == "__main__":
    np.seterr(all="ignore")
    main()
