"""Measuring models against the Monte Carlo reference, stack by stack: the data behind the speed/accuracy chart's
population rows, `lamina.choose`'s predictor and the failure atlas (scripts/population.py, scripts/atlas.py).

Every measurement uses the suite's direction grid (lamina.reference.suite_directions: θi ∈ SUITE_THETAS, 30
outgoing directions) and the cached reference (lamina.reference.cached_reference, GROUND_TRUTH_SAMPLES paths per
pair), so an interrupted run resumes where it stopped.
- lobe error at θi: Σ|f − f_ref| / Σ|f_ref| over the 30 outgoing directions and RGB;
- noise at θi: the reference's Σ SE / Σ|f_ref| (the floor under every lobe error);
- albedo error at θi: |a − a_ref| (green), a from ALBEDO_SAMPLES of the model's own importance sampling (its mean
  weight) and a_ref from the reference walk, less a smooth top's Dirac reflection, which the models leave out.
"""

from __future__ import annotations

import time

import numpy as np

from ._reference import lobe_errors
from .choose import CANDIDATES, MODEL_OF, features
from .layers import Dielectric
from .reference import SUITE_THETAS, cached_reference, reference_albedo, suite_directions

GROUND_TRUTH_SAMPLES = 8000
ALBEDO_SAMPLES = 20_000
#: A stack whose reference noise (Σ SE / Σ|f|) exceeds this at some θi ≤ 80° is not resolved by the reference: its
#: lobe errors are not measurements (a smooth clear coat over a near-mirror layer puts the lobes on a few grid
#: directions that the reference's paths do not resolve).
MAX_NOISE = 0.1


def resolved(row: dict) -> bool:
    """Whether a `measure`d stack's reference resolves its lobes at θi ≤ 80° (MAX_NOISE)."""
    return float(np.max(np.array(row["noise"])[np.array(SUITE_THETAS) <= 80.0])) <= MAX_NOISE


def model_albedo(stack, model: str, options: dict, samples: int = ALBEDO_SAMPLES, thetas=SUITE_THETAS) -> tuple:
    """The model's albedo seen from incident angles `thetas` (degrees, x–z plane) as the mean weight of its own
    importance sampling, and that mean's standard error: ((len(thetas), channels), (len(thetas), channels))."""
    t = np.radians(thetas)
    wo = np.stack([np.sin(t), np.zeros_like(t), np.cos(t)], -1)[:, None, :]
    u = np.random.default_rng(0).uniform(size=(1, samples, 3))
    with np.errstate(all="ignore"):
        weight = stack.sample(wo, u, model, **options)[1]
    return weight.mean(axis=1), weight.std(axis=1) / np.sqrt(samples)


def candidate_error(row: dict, label: str, model: str, options: dict, ground_truth_samples: int) -> float:
    """A candidate's error on a `measure`d stack, averaged over θi ≤ 80°: its lobe error (inf where it cannot
    represent the stack); for the reference at n = options["samples"] paths, the expected L1 error of its noise,
    √(2/π) Σ SE / Σ|f|, scaled from the ground truth's paths to n."""
    low = np.array(SUITE_THETAS) <= 80.0
    if model == "reference":
        scale = np.sqrt(ground_truth_samples / options["samples"])
        return float(np.sqrt(2 / np.pi) * np.mean(np.array(row["noise"])[low]) * scale)
    e = row["lobe_error"][label]
    return np.inf if e is None else float(np.mean(np.array(e)[low]))


def measure(
    stack, candidates=CANDIDATES, samples: int = GROUND_TRUTH_SAMPLES, seed: int = 0, albedo: bool = True
) -> dict:
    """One stack against the reference: its features, the reference's noise, and per candidate (label, model,
    options) the lobe and albedo errors at SUITE_THETAS (None where the model cannot represent the stack); without
    `albedo`, the lobe errors alone (the albedos' walks and sampling take 9% of the time on the population)."""
    wi, wo = suite_directions()
    f_ref, se = cached_reference(stack, wi, wo, samples=samples, seed=seed, progress=False)
    if albedo:
        a_ref, a_se = reference_albedo(stack, samples=ALBEDO_SAMPLES, seed=seed)
    lobe, albedo_error, flags = {}, {}, {}
    for label, model, options in candidates:
        try:
            f = stack.eval(wi, wo, model, **options)
        except ValueError:
            lobe[label] = albedo_error[label] = None
            continue
        lobe[label] = lobe_errors(f, f_ref).tolist()
        if albedo:
            albedo_error[label] = np.abs(model_albedo(stack, model, options)[0][:, 1] - a_ref[:, 1]).tolist()
        flags[label] = {"nonfinite": int((~np.isfinite(f)).sum()), "negative": int((f < 0).sum())}
    row = {
        "features": features(stack).tolist(),
        "noise": (se.sum(axis=(1, 2)) / np.abs(f_ref).sum(axis=(1, 2))).tolist(),
        "lobe_error": lobe,
        "flags": flags,
    }
    if albedo:
        row.update(albedo_se=a_se[:, 1].tolist(), albedo_error=albedo_error)
    return row


def measure_all(stacks, client=None, desc: str = "measuring", **kwargs) -> list:
    """[measure(s) for s in stacks] with a progress bar, or as one task per stack on a dask.distributed `client`."""
    if client is not None:
        return client.gather(client.map(lambda s: measure(s, **kwargs), list(stacks), pure=False))
    try:
        from tqdm.auto import tqdm
    except ImportError:
        tqdm = None
    items = tqdm(list(stacks), desc=desc, unit="stack") if tqdm else stacks
    return [measure(s, **kwargs) for s in items]


def cost(model: str, options: dict, n: int = 1_000_000, repeats: int = 5, device: str = "cpu") -> tuple:
    """(ns per evaluation, first-call ms): the median of `repeats` calls on n random float32 pairs of the suite's
    2-layer rough-coat-rough-copper (its copper base alone for
    microfacet, which takes single interfaces; RGB), after a first call that prepares the model (timed on its own)."""
    from .materials import suite

    rng = np.random.default_rng(0)
    w = rng.normal(size=(2, n, 3))
    w[..., 2] = np.abs(w[..., 2])
    wi, wo = w.astype(np.float32)
    stack = suite("rough-coat-rough-copper")
    if model == "microfacet":  # single interfaces only: the stack's rough copper base
        stack = type(stack)(stack.layers[1:])
    t0 = time.perf_counter()
    stack.eval(wi[:10], wo[:10], model, device=device, **options)
    first = time.perf_counter() - t0
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        stack.eval(wi, wo, model, device=device, **options)
        times.append(time.perf_counter() - t0)
    return float(np.median(times)) / n * 1e9, first * 1e3


def reference_cost(samples: int = 1000) -> float:
    """ns per (pair × path) of the reference's f estimate on the suite's rough-coat-rough-copper (RGB)."""
    from .materials import suite

    wi, wo = suite_directions()
    t0 = time.perf_counter()
    suite("rough-coat-rough-copper").reference(wi, wo, samples=samples, seed=7, progress=False)
    return (time.perf_counter() - t0) / (wi.shape[0] * wo.shape[1] * samples) * 1e9


# --- The failure atlas -------------------------------------------------------------------------------------------

#: The layered models the atlas maps: the published ones, lamina's near-exact `tabulated` and belcour's improved variant
#: (labels of CANDIDATES).
ATLAS_MODELS = ("belcour", "steinberg", "weidlich_wilkie", "albedo_scaling", "tabulated", "belcour improved")
#: Incident angles (degrees) of the θi axes.
ATLAS_THETAS = (0.0, 15.0, 30.0, 45.0, 60.0, 70.0, 75.0, 80.0, 85.0, 89.0)
#: Incident angles of the parameter × parameter planes, whose cells average the lobe error over them.
PLANE_THETAS = (0.0, 30.0, 60.0, 80.0)
#: Paths per pair of the atlas's references.
ATLAS_SAMPLES = 4000


def _coat_metal(alpha=0.1, eta=1.5, base_alpha=0.3, thickness=0.0, sigma_a=0.0, sigma_s=0.0, angle=0.0):
    from .materials import metal
    from .stack import Stack

    coat = Dielectric(eta, alpha, angle, thickness=thickness, sigma_a=sigma_a, sigma_s=sigma_s, g=0.5)
    return Stack([coat, metal("Cu", base_alpha)])


def _coat_diffuse(thickness=1.0, sigma_a=0.0, sigma_s=0.0):
    from .layers import Diffuse
    from .stack import Stack

    return Stack([Dielectric(1.5, 0.1, thickness=thickness, sigma_a=sigma_a, sigma_s=sigma_s, g=0.5), Diffuse(0.6)])


#: The atlas's planes: name → (x label, x values, y label, y values, stack(x, y)). A y of "θi" is the incident angle
#: (ATLAS_THETAS); otherwise each cell is one stack, measured at PLANE_THETAS.
PLANES = {
    "theta-coat-roughness": (
        "coat alpha (coat η 1.5 over Cu α 0.3)",
        (0.0, 0.02, 0.05, 0.1, 0.15, 0.2, 0.3, 0.45, 0.65, 1.0),
        "θi",
        ATLAS_THETAS,
        lambda a, _: _coat_metal(alpha=a),
    ),
    "theta-coat-ior": (
        "coat IOR (α 0.1 over Cu α 0.3; η < 1: total internal reflection inside the coat)",
        (0.5, 0.67, 0.8, 0.9, 1.05, 1.2, 1.5, 1.8, 2.3, 3.0),
        "θi",
        ATLAS_THETAS,
        lambda eta, _: _coat_metal(eta=eta),
    ),
    "theta-optical-depth": (
        "absorbing optical depth σa·d (α 0.1 coat, d = 1, over Lambert 0.6)",
        (0.0, 0.03, 0.1, 0.2, 0.4, 0.7, 1.0, 2.0, 4.0, 8.0),
        "θi",
        ATLAS_THETAS,
        lambda tau, _: _coat_diffuse(sigma_a=tau),
    ),
    "coat-base-roughness": (
        "coat alpha (η 1.5)",
        (0.0, 0.03, 0.08, 0.15, 0.25, 0.4, 0.65),
        "base alpha (Cu)",
        (0.03, 0.08, 0.15, 0.25, 0.4, 0.65, 1.0),
        lambda a, b: _coat_metal(alpha=a, base_alpha=b),
    ),
    "thickness-scattering": (
        "slab thickness d (σa 0.1, g 0.5, α 0.1 coat over Lambert 0.6)",
        (0.1, 0.25, 0.5, 1.0, 2.0, 4.0, 8.0),
        "σs",
        (0.0, 0.1, 0.3, 0.6, 1.0, 2.0, 4.0),
        lambda d, s: _coat_diffuse(thickness=d, sigma_a=0.1, sigma_s=s),
    ),
    "anisotropy": (
        "coat anisotropy α_y/α_x (α_x 0.3, η 1.5 over Cu α 0.3)",
        (1.0, 0.7, 0.5, 0.35, 0.25, 0.15, 0.1),
        "tangent angle (degrees)",
        (0.0, 15.0, 30.0, 45.0, 60.0, 75.0, 90.0),
        lambda r, phi: _coat_metal(alpha=(0.3, 0.3 * r), angle=np.radians(phi)),
    ),
}


def stability_flags(albedo, albedo_se, ref_albedo, nonfinite, negative) -> dict:
    """Boolean maps of a model's stability flags on a 2D parameter grid, from its albedo (and standard error), the
    reference's albedo and the counts of non-finite and negative values of f per cell:
    "E" energy > 1 (albedo above 1 by more than 4 SE + 1e-3); "N" NaN or Inf; "−" negative values; "D" a
    discontinuity: by finite differences along either axis, the model's albedo jumps by more than 0.05 and by more
    than 3x the reference's jump plus 4 SE (flagged on the cell after the jump)."""
    albedo, albedo_se, ref_albedo = (np.asarray(a, dtype=float) for a in (albedo, albedo_se, ref_albedo))
    jump = np.zeros(albedo.shape, dtype=bool)
    for axis in (0, 1):
        dm = np.abs(np.diff(albedo, axis=axis))
        dr = np.abs(np.diff(ref_albedo, axis=axis))
        se = np.maximum(np.delete(albedo_se, 0, axis), np.delete(albedo_se, -1, axis))
        pad = [(0, 0), (0, 0)]
        pad[axis] = (1, 0)
        jump |= np.pad((dm > 0.05) & (dm > 3.0 * dr + 4.0 * se), pad)
    return {
        "E": albedo > 1.0 + 4.0 * albedo_se + 1e-3,
        "N": np.asarray(nonfinite) > 0,
        "−": np.asarray(negative) > 0,
        "D": jump,
    }


def _directions(thetas) -> tuple:
    t = np.radians(np.asarray(thetas))
    wi = np.stack([np.sin(t), np.zeros_like(t), np.cos(t)], -1)[:, None, :]
    return wi, suite_directions()[1]


def atlas_cell(stack, thetas, samples: int = ATLAS_SAMPLES, models=ATLAS_MODELS) -> dict:
    """One stack of the atlas at incident angles `thetas`: per model (labels of CANDIDATES), the lobe error at each
    angle, its albedo (mean weight of its own sampling) and that albedo's standard error, and counts of non-finite
    and negative values of f; the reference's noise and albedo at each angle. The reference is cached."""
    wi, wo = _directions(thetas)
    f_ref, se = cached_reference(stack, wi, wo, samples=samples, seed=0, progress=False)
    a_ref, _ = reference_albedo(stack, ALBEDO_SAMPLES, 0, thetas)
    out = {"noise": (se.sum(axis=(1, 2)) / np.abs(f_ref).sum(axis=(1, 2))).tolist(), "ref_albedo": a_ref[:, 1].tolist()}
    for label in models:
        model, options = MODEL_OF[label]
        with np.errstate(all="ignore"):
            f = stack.eval(wi, wo, model, **options)
        albedo, albedo_se = model_albedo(stack, model, options, thetas=thetas)
        out[label] = {
            "error": lobe_errors(np.nan_to_num(f, nan=0.0, posinf=0.0, neginf=0.0), f_ref).tolist(),
            "albedo": albedo[:, 1].tolist(),
            "albedo_se": albedo_se[:, 1].tolist(),
            "nonfinite": int((~np.isfinite(f)).sum()),
            "negative": int((f < 0).sum()),
        }
    return out


def atlas_plane(name: str, client=None, samples: int = ATLAS_SAMPLES, models=ATLAS_MODELS) -> list:
    """Every cell of plane `name` (PLANES), as atlas_cell dicts in x-major order: one per x for a θi plane, one per
    (x, y) otherwise; with a progress bar, or one task per stack on a dask.distributed `client`."""
    _, xs, ylabel, ys, make = PLANES[name]
    if ylabel == "θi":
        jobs = [(make(x, None), ATLAS_THETAS) for x in xs]
    else:
        jobs = [(make(x, y), PLANE_THETAS) for x in xs for y in ys]
    if client is not None:
        return client.gather(client.map(lambda j: atlas_cell(*j, samples=samples, models=models), jobs, pure=False))
    try:
        from tqdm.auto import tqdm

        jobs = tqdm(jobs, desc=f"atlas {name}", unit="stack")
    except ImportError:
        pass
    return [atlas_cell(*j, samples=samples, models=models) for j in jobs]
