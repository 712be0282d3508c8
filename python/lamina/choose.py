"""Model no more than a scene needs: `choose` picks the cheapest model whose predicted lobe error for a stack stays
within a tolerance, and `features` describes a stack for that prediction.

The candidates are every analytic model, the improved variants, `tabulated` and the reference at several path
counts; a candidate's cost is its measured time per evaluation plus its precomputation spread over the evaluations
the user will make (`evaluations`).

Inside the measured population the prediction is a k-nearest-neighbour quantile over measured data
(python/lamina/data/choose.json, written by `make population` from the seed-1 population of
lamina.materials.population): each stack is a point in the weighted, standardized feature space of `features`, and a
candidate's predicted error at θi is a quantile of its measured errors on the k nearest measured stacks that the
model represents (linear in θi between the measured angles; `rank`). The feature weights, k and the quantiles are
fitted by leave-one-out on the seed-1 stacks (scripts/population.py).

Outside it (`covered`) the neighbours say nothing, so `choose` checks instead of guessing (`check`): where
`tabulated` represents the stack and resolves its lobes, every candidate is evaluated on the suite's direction grid
against the tabulated solve (seconds, once per stack), and its predicted error is that distance plus tabulated's own
error bound (the triangle inequality; `TABULATED_QUANTILE` of tabulated's measured errors); elsewhere only exact
answers remain (the reference, `microfacet` where it applies), with the reference's noise taken at its largest over
the training stacks. No reference runs inside `choose`. docs/choose.md validates it on the seed-2 population, which
the predictor never saw, and on stacks drawn from other distributions."""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path

import numpy as np

from ._reference import lobe_errors, suite_directions

#: The analytic candidates: (label, model, options).
CANDIDATES = (
    ("microfacet", "microfacet", {}),
    ("belcour", "belcour", {}),
    ("weidlich_wilkie", "weidlich_wilkie", {}),
    ("steinberg", "steinberg", {}),
    ("albedo_scaling", "albedo_scaling", {}),
    ("belcour improved", "belcour", {"variant": "improved"}),
    ("steinberg improved", "steinberg", {"variant": "improved"}),
    ("weidlich_wilkie improved", "weidlich_wilkie", {"variant": "improved"}),
    ("tabulated", "tabulated", {}),
)
#: Each candidate label's (model, options).
MODEL_OF = {label: (model, options) for label, model, options in CANDIDATES}
#: The evaluations a choice's precomputation is spread over when the caller does not say (a 1024² image at about 10
#: samples per pixel).
EVALUATIONS = 10_000_000
#: The quantile of tabulated's measured errors on the training stacks that bounds its error in a `check`.
TABULATED_QUANTILE = 0.95
#: Roughness below which a lobe is narrower than tabulated's grid resolves (docs/validation.md: its population errors
#: of 4.5–9.4% are all of lobes with α ≤ 0.06 seen through a smooth coat); a `check` does not trust tabulated there.
SHARP_ALPHA = 0.07
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
#: The feature weights `make population` starts its fit from: base kind and layer count dominate.
START_WEIGHTS = (1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 3.0, 3.0)


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
    every candidate as (label, predicted error, cost in ns per evaluation with its precomputation spread over the
    evaluations), cheapest first; `checked` says whether the errors were checked against the tabulated solve."""

    model: str
    options: dict
    predicted_error: float
    cost_ns: float
    reason: str
    candidates: tuple = field(repr=False)
    checked: bool = False


def prepare(d: dict) -> dict:
    """The predictor from choose.json's content: the training features and their weighted scale, per candidate the
    errors (inf where it cannot represent the stack) and the reference's noise for one path."""
    d = dict(d)
    x = np.array([r["features"] for r in d["train"]])
    d["x"] = x
    d["scale"] = np.where(x.std(axis=0) > 0, x.std(axis=0), 1.0) / np.asarray(d["weights"])
    d["errors"] = {
        label: np.array(
            [r["lobe_error"][label] if r["lobe_error"][label] is not None else [np.inf] * 5 for r in d["train"]]
        )
        for label, _, _ in CANDIDATES
    }
    d["noise"] = np.array([r["noise"] for r in d["train"]]) * np.sqrt(d["ground_truth_samples"])
    tab = d["errors"]["tabulated"]
    d["tabulated_bound"] = np.quantile(tab[np.isfinite(tab[:, 0])], TABULATED_QUANTILE, axis=0)
    return d


def covered(train: np.ndarray, x: np.ndarray) -> bool:
    """Whether features x lie inside the measured population `train` (n, n_features): some training stack shares
    its base kind and number of dielectric layers, and each continuous feature lies within the range those stacks
    span, widened by a quarter of the feature's standard deviation over all of them. Elsewhere the neighbours'
    errors say nothing about the stack (a scattering slab over a diffuse base, when only patinas scatter)."""
    same = train[(train[:, 6] == x[6]) & (train[:, 7] == x[7])]
    if not len(same):
        return False
    margin = 0.25 * train[:, :6].std(axis=0)
    return bool(np.all(x[:6] >= same[:, :6].min(axis=0) - margin) and np.all(x[:6] <= same[:, :6].max(axis=0) + margin))


@lru_cache(maxsize=1)
def _data() -> dict:
    return prepare(json.loads((Path(__file__).parent / "data" / "choose.json").read_text()))


def distances(d: dict, x: np.ndarray) -> np.ndarray:
    """Distances in the weighted, standardized feature space from features x (..., n_features) to every training
    stack (..., n_train)."""
    return np.sqrt((((x[..., None, :] - d["x"]) / d["scale"]) ** 2).sum(axis=-1))


def cost(d: dict, label: str, evaluations: float) -> float:
    """A candidate's cost in ns per evaluation: its measured time per evaluation and its first call (the
    precomputation: tables, the adding-doubling solve) spread over `evaluations`."""
    c = d["costs"][label]
    return c["ns_per_eval"] + 1e6 * c["prepare_ms"] / evaluations


def rank(
    d: dict,
    dist: np.ndarray,
    represents: dict,
    w: np.ndarray,
    inside: bool,
    evaluations: float = EVALUATIONS,
    checked: dict | None = None,
) -> list:
    """Every candidate as (label, model, options, predicted error, cost ns), cheapest first, for a stack at
    distances `dist` from the training stacks: inf where the model cannot represent it (`represents[label]` false);
    0 for "microfacet" where it can (it is exact there); the per-angle errors `checked[label]` (`check`) averaged
    with weights `w` where given; else, `inside` the measured population (`covered`), the d["quantile"] of the errors
    of the d["k"] nearest training stacks the model represents, averaged over the angles with weights `w`; else no
    prediction (inf). The reference at n paths: √(2/π) times the d["noise_quantile"] of the k nearest stacks' noise
    for one path (outside the population: the largest over the training stacks), over √n."""
    k = d["k"]
    near = np.argsort(dist, kind="stable")[:k]
    rows = []
    for label, model, options in CANDIDATES:
        known = np.isfinite(d["errors"][label][:, 0])
        if not represents[label]:
            err = np.inf
        elif model == "microfacet":
            err = 0.0
        elif checked is not None:
            err = float(np.asarray(checked[label]) @ w)
        elif not inside or not known.any():
            err = np.inf
        else:
            mine = np.argsort(np.where(known, dist, np.inf), kind="stable")[: min(k, known.sum())]
            err = float(np.quantile(d["errors"][label][mine], d["quantile"], axis=0) @ w)
        rows.append((label, model, options, err, cost(d, label, evaluations)))
    noise_one_path = np.quantile(d["noise"][near], d["noise_quantile"], axis=0) if inside else d["noise"].max(axis=0)
    noise = float(noise_one_path @ w)
    for n in d["reference_samples"]:
        err = np.sqrt(2 / np.pi) * noise / np.sqrt(n)
        rows.append(
            (f"reference, {n} paths", "reference", {"samples": n}, err, n * d["costs"]["reference"]["ns_per_path"])
        )
    return sorted(rows, key=lambda r: r[4])


def resolves(stack) -> bool:
    """Whether tabulated represents the stack (isotropic) and its grid resolves the stack's lobes
    (no rough interface sharper than SHARP_ALPHA)."""
    layers = stack._resolve(None)
    sharp = any(0 < x["roughness"][0] < SHARP_ALPHA for x in layers if x["kind"] != "diffuse")
    return _isotropic(stack) and not sharp


def check(stack, bound: np.ndarray, represents: dict) -> dict | None:
    """Per candidate label, the per-angle error bound of a quick check against the tabulated solve (None where
    tabulated does not `resolves` the stack): the candidate's lobe error against tabulated on the suite's direction
    grid (the measured population's grid) plus `bound`, tabulated's own error per angle; `bound` alone for tabulated;
    inf where the candidate cannot represent the stack."""
    if not resolves(stack):
        return None
    return _check(repr(stack), stack, tuple(bound), tuple(sorted(represents.items())))


@lru_cache(maxsize=64)
def _check(key: str, stack, bound: tuple, represents: tuple) -> dict:
    wi, wo = suite_directions()
    f_tab = stack.eval(wi, wo, "tabulated")
    can = dict(represents)
    out = {}
    for label, model, options in CANDIDATES:
        if not can[label]:
            out[label] = np.full(len(bound), np.inf)
        elif label == "tabulated":
            out[label] = np.array(bound)
        else:
            out[label] = lobe_errors(stack.eval(wi, wo, model, **options), f_tab) + np.array(bound)
    return out


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


def represents(stack) -> dict:
    """Per candidate label, whether its model accepts the stack (the published models refuse what they cannot
    represent: tried on one pair). Without preparing what takes seconds: an improved variant represents what its
    published model does, and tabulated every isotropic stack (its one refusal)."""
    out = {}
    for label, model, options in CANDIDATES:
        if label == "tabulated":
            out[label] = _isotropic(stack)
        elif options.get("variant") == "improved":
            out[label] = out[model]
        else:
            try:
                stack.eval([0.0, 0.0, 1.0], [0.0, 0.0, 1.0], model, **options)
                out[label] = True
            except ValueError:
                out[label] = False
    return out


def _isotropic(stack) -> bool:
    """Whether every rough layer of the stack has one roughness (αx = αy)."""
    return all(x["roughness"][0] == x["roughness"][1] for x in stack._resolve(None) if x["kind"] != "diffuse")


def choose(stack, tolerance: float = 0.05, wi=None, evaluations: float = EVALUATIONS) -> Choice:
    """The cheapest model whose predicted relative L1 lobe error for `stack` stays within `tolerance`, averaged over
    the incident directions `wi` (..., 3), or over θi ≤ 80° when wi is None. The cost of a candidate is its measured
    time per evaluation plus its precomputation spread over `evaluations` (default EVALUATIONS). Falls back to the
    reference with enough paths per pair when no analytic model is predicted within tolerance. The prediction: see
    the module docstring (a stack outside the measured population is checked against the tabulated solve, which
    takes seconds once per stack); docs/choose.md measures how often it holds."""
    if isinstance(tolerance, bool) or not isinstance(tolerance, (int, float)) or not 0.0 < tolerance < 1e3:
        raise ValueError(f"tolerance must be a relative L1 lobe error > 0, got {tolerance!r}")
    if isinstance(evaluations, bool) or not isinstance(evaluations, (int, float)) or not evaluations >= 1:
        raise ValueError(f"evaluations must be a number of evaluations >= 1, got {evaluations!r}")
    return choose_with(_data(), stack, tolerance, wi, evaluations)


def choose_with(d: dict, stack, tolerance: float, wi=None, evaluations: float = EVALUATIONS) -> Choice:
    """`choose` from the predictor `d` (`prepare` of choose.json's content)."""
    x = features(stack)
    inside, can = covered(d["x"], x), represents(stack)
    checked = None if inside else check(stack, d["tabulated_bound"], can)
    rows = rank(d, distances(d, x), can, _weights(d["thetas"], wi), inside, evaluations, checked)
    table = tuple((r[0], r[3], r[4]) for r in rows)
    fits = [r for r in rows if r[3] <= tolerance]
    if inside:
        outside = ""
    elif checked is not None:
        outside = (
            "outside the measured population (lamina.choose.covered): every candidate checked against the tabulated "
            "solve on the suite's grid, plus tabulated's own error bound; "
        )
    else:
        outside = (
            "outside the measured population (no measured stack of its base kind and layer count spans its features; "
            "lamina.choose.covered), where tabulated does not resolve it: no prediction for the approximate models; "
        )
    if not fits:
        label, model, options, err, ns = rows[-1]
        reason = f"{outside}no candidate is predicted within {tolerance}; the most accurate is {label}"
    else:
        label, model, options, err, ns = fits[0]

        def predicted(r) -> str:
            if not np.isinf(r[3]):
                return f"{r[3]:.3g}"
            return "no prediction" if can.get(r[0], True) else "cannot represent this stack"

        cheaper = [f"{r[0]} ({predicted(r)})" for r in rows if r[4] < ns]
        reason = (
            f"{outside}{label} is the cheapest candidate predicted within tolerance {tolerance} "
            f"({err:.3g} at {ns:.3g} ns)"
        )
        if cheaper:
            reason += "; cheaper ones are predicted above it: " + ", ".join(cheaper)
    return Choice(model, dict(options), err, ns, reason, table, checked is not None)
