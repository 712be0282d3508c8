"""Model no more than a scene needs: `choose` picks the cheapest model whose predicted lobe error for a stack stays
within a tolerance, and `features` describes a stack for that prediction.

The prediction is a k-nearest-neighbour quantile over measured data (python/lamina/data/choose.json, written by
`make population` from the seed-1 population of lamina.materials.population): each stack is a point in the weighted,
standardized feature space of `features`, and a candidate's predicted error at θi is a quantile of its measured
errors on the k nearest measured stacks (linear in θi between the measured angles; `rank`). k and the quantiles are
fitted by leave-one-out on the seed-1 stacks. No reference runs inside `choose`.
docs/choose.md validates it on the seed-2 population, which the predictor never saw."""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path

import numpy as np

#: The analytic candidates, cheapest first by the measured costs in choose.json: (label, model, options).
CANDIDATES = (
    ("microfacet", "microfacet", {}),
    ("belcour", "belcour", {}),
    ("weidlich_wilkie", "weidlich_wilkie", {}),
    ("steinberg", "steinberg", {}),
    ("albedo_scaling", "albedo_scaling", {}),
)
#: Paths per pair of the reference candidates, the fallback when no analytic model is predicted within tolerance.
REFERENCE_SAMPLES = (64, 256, 1024, 4096, 16384, 65536)
#: Names of `features`' entries.
FEATURES = (
    "coat_alpha",
    "coat_eta",
    "anisotropy",
    "absorption_depth",
    "scattering_depth",
    "base_roughness",
    "diffuse_base",
    "dielectric_layers",
)
#: Weights of the standardized features in the neighbour distance: base kind and layer count dominate.
WEIGHTS = np.array([1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 3.0, 3.0])


def features(stack) -> np.ndarray:
    """The stack's descriptors for the predictor, in the order of FEATURES: the top interface's alpha (geometric
    mean of alpha_x, alpha_y) and relative IOR (mean of the RGB channels), the largest |ln(alpha_x/alpha_y)| of any
    layer, ln(1 + Σ thickness · mean σa) and ln(1 + Σ thickness · mean σs), the base's roughness (alpha, or
    Oren–Nayar σ), 1 for a diffuse base, and the number of dielectric layers."""
    layers = stack._resolve(None)
    coats = [x for x in layers if x["kind"] == "dielectric"]
    top, base = layers[0], layers[-1]
    alpha = lambda x: float(np.sqrt(np.prod(x["roughness"])))  # noqa: E731
    aniso = [
        abs(np.log(max(x["roughness"][0], 1e-4) / max(x["roughness"][1], 1e-4)))
        for x in layers
        if x["kind"] != "diffuse"
    ]
    diffuse = base["kind"] == "diffuse"
    return np.array(
        [
            1.0 if top["kind"] == "diffuse" else alpha(top),
            1.0 if top["kind"] == "diffuse" else float(np.mean(top["ior"])) / stack.ext_ior,
            max(aniso, default=0.0),
            np.log1p(sum(c["thickness"] * float(np.mean(c["sigma_a"])) for c in coats)),
            np.log1p(sum(c["thickness"] * float(np.mean(c["sigma_s"])) for c in coats)),
            base["roughness"] if diffuse else alpha(base),
            float(diffuse),
            float(len(coats)),
        ]
    )


@dataclass(frozen=True)
class Choice:
    """What `choose` picked: evaluate with `stack.eval(wi, wo, choice.model, **choice.options)`. `candidates` lists
    every candidate as (label, predicted error, cost in ns per evaluation), cheapest first."""

    model: str
    options: dict
    predicted_error: float
    cost_ns: float
    reason: str
    candidates: tuple = field(repr=False)


def prepare(d: dict) -> dict:
    """The predictor from choose.json's content: the training features, their scale, and per candidate the
    errors (inf where it cannot represent the stack) and the reference's noise for one path."""
    d = dict(d)
    x = np.array([r["features"] for r in d["train"]])
    d["x"] = x
    d["scale"] = np.where(x.std(axis=0) > 0, x.std(axis=0), 1.0) / WEIGHTS
    d["errors"] = {
        label: np.array(
            [r["lobe_error"][label] if r["lobe_error"][label] is not None else [np.inf] * 5 for r in d["train"]]
        )
        for label, _, _ in CANDIDATES
    }
    d["noise"] = np.array([r["noise"] for r in d["train"]]) * np.sqrt(d["ground_truth_samples"])
    # The population's reach: the largest distance from a training stack to its k-th nearest other one. A stack
    # farther than that from its own k-th nearest has no measured neighbours to predict from.
    dist = np.sqrt((((x[:, None] - x[None]) / d["scale"]) ** 2).sum(-1))
    np.fill_diagonal(dist, np.inf)
    k = min(d.get("k", 3), len(x) - 1)
    d["reach"] = float(np.sort(dist, axis=1)[:, k - 1].max())
    return d


@lru_cache(maxsize=1)
def _data() -> dict:
    return prepare(json.loads((Path(__file__).parent / "data" / "choose.json").read_text()))


def rank(
    d: dict, x: np.ndarray, microfacet_exact: bool, w: np.ndarray, k: int, quantile: float, noise_quantile: float
) -> list:
    """Every candidate as (label, model, options, predicted error, cost ns), cheapest first: the `quantile` of the
    errors of the `k` training stacks nearest to features `x`, averaged over the angles with weights `w`; 0 for
    model "microfacet" where it is exact (it refuses other stacks); for the reference at n paths, √(2/π) times the
    `noise_quantile` of the neighbours' noise for one path, over √n. Beyond the population's reach (`prepare`) the
    approximate models get no prediction (inf), so that only exact answers remain."""
    dist = np.sqrt((((d["x"] - x) / d["scale"]) ** 2).sum(axis=1))
    near = np.argsort(dist, kind="stable")[:k]
    inside = dist[near[-1]] <= d["reach"]
    rows = []
    for label, model, options in CANDIDATES:
        if model == "microfacet":
            err = 0.0 if microfacet_exact else np.inf
        elif not inside:  # no measured stack like this one: no prediction for the approximate models
            err = np.inf
        else:
            err = float(np.quantile(d["errors"][label][near], quantile, axis=0) @ w)
        rows.append((label, model, options, err, d["costs"][label]["ns_per_eval"]))
    noise = float(np.quantile(d["noise"][near], noise_quantile, axis=0) @ w)
    for n in d["reference_samples"]:
        err = np.sqrt(2 / np.pi) * noise / np.sqrt(n)
        rows.append(
            (f"reference, {n} paths", "reference", {"samples": n}, err, n * d["costs"]["reference"]["ns_per_path"])
        )
    return sorted(rows, key=lambda r: r[4])


def _weights(thetas, wi) -> np.ndarray:
    """Weights over the measured angles that average a per-angle error over the directions `wi` (linear
    interpolation in θi), or over θi ≤ 80° when wi is None."""
    thetas = np.asarray(thetas)
    if wi is None:
        w = (thetas <= 80.0).astype(float)
        return w / w.sum()
    wi = np.asarray(wi, dtype=float).reshape(-1, 3)
    if not len(wi) or not np.all(np.isfinite(wi)):
        raise ValueError("wi must be a non-empty array (..., 3) of finite directions, or None")
    theta = np.degrees(np.arccos(np.clip(wi[:, 2] / np.maximum(np.linalg.norm(wi, axis=1), 1e-300), 0.0, 1.0)))
    eye = np.eye(len(thetas))
    return np.mean([[np.interp(t, thetas, eye[k]) for k in range(len(thetas))] for t in theta], axis=0)


def _single_interface_exact(stack) -> bool:
    """Whether model 'microfacet' evaluates the stack exactly (it refuses others)."""
    try:
        stack.eval([0.0, 0.0, 1.0], [0.0, 0.0, 1.0], "microfacet")
    except ValueError:
        return False
    return True


def choose(stack, tolerance: float = 0.05, wi=None) -> Choice:
    """The cheapest model (by measured cost per evaluation) whose predicted relative L1 lobe error for `stack` stays
    within `tolerance`, averaged over the incident directions `wi` (..., 3), or over θi ≤ 80° when wi is None.
    Falls back to the reference with enough paths per pair when no analytic model is predicted within tolerance.
    The prediction: see the module docstring; docs/choose.md measures how often it holds."""
    if isinstance(tolerance, bool) or not isinstance(tolerance, (int, float)) or not 0.0 < tolerance < 1e3:
        raise ValueError(f"tolerance must be a relative L1 lobe error > 0, got {tolerance!r}")
    d = _data()
    w = _weights(d["thetas"], wi)
    rows = rank(d, features(stack), _single_interface_exact(stack), w, d["k"], d["quantile"], d["noise_quantile"])
    table = tuple((r[0], r[3], r[4]) for r in rows)
    fits = [r for r in rows if r[3] <= tolerance]
    x = features(stack)
    nearest = np.sort(np.sqrt((((d["x"] - x) / d["scale"]) ** 2).sum(axis=1)))[d["k"] - 1]
    outside = (
        f"outside the measured population (its {d['k']} nearest measured stacks are within {nearest:.2f}, farther "
        f"than the population's own reach {d['reach']:.2f}): no prediction for the approximate models; "
        if nearest > d["reach"]
        else ""
    )
    if not fits:
        label, model, options, err, cost = rows[-1]
        reason = f"{outside}no candidate is predicted within {tolerance}; the most accurate is {label}"
    else:
        label, model, options, err, cost = fits[0]

        def predicted(r) -> str:
            if not np.isinf(r[3]):
                return f"{r[3]:.3g}"
            return "no prediction" if outside and r[1] != "microfacet" else "cannot represent this stack"

        cheaper = [f"{r[0]} ({predicted(r)})" for r in rows if r[4] < cost]
        reason = (
            f"{outside}{label} is the cheapest candidate predicted within tolerance {tolerance} "
            f"({err:.3g} at {cost:.3g} ns)"
        )
        if cheaper:
            reason += "; cheaper ones are predicted above it: " + ", ".join(cheaper)
    return Choice(model, dict(options), err, cost, reason, table)
