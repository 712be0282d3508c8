"""From measurements back to a stack: `fit` finds the free parameters (lamina.Param) of a template stack that explain
measured f under a model, by SciPy's trust-region least squares with lamina's exact Jacobian (Stack.eval_grad), from
several starts; standard errors come from the Jacobian at the optimum. `fit_models` fits every model that can and
tabulates how well each explains the data, at what cost. `lamina.models()` lists which models have gradients
(`.gradients`).
"""

from __future__ import annotations

import time
import warnings
from dataclasses import dataclass, field

import numpy as np

from .measured import Samples, _checked
from .stack import Stack

#: Bands of incidence (degrees) the residual is reported in.
BANDS = ((0.0, 60.0), (60.0, 80.0), (80.0, 90.0))
LOSSES = ("linear", "cosine", "log")


@dataclass(frozen=True)
class FitResult:
    """What `fit` found: `stack` (the template with its Params bound), `params` and `stderr` (name -> value; the
    standard errors from the Jacobian at the optimum: the larger of `stderr_noise`, which assumes independent noise
    of equal variance in the residuals, and the cluster-robust one, which also counts errors that neighbouring
    directions share, as a model's own error does), `residual` (band of incidence "0-60", "60-80", "80-90" ->
    relative L1 error Σ|f − measured| / Σ measured there, None where no sample falls), `cost` (½ Σ residual² of the
    best start), `converged` and the optimiser's `message`, `history` (the cost at each evaluation, per start) and
    `model`."""

    stack: Stack
    params: dict
    stderr: dict
    residual: dict
    cost: float
    converged: bool
    message: str
    model: str
    stderr_noise: dict
    history: list = field(repr=False)


def _residuals(f, grad, measured, weights, loss):
    """The residuals r and their Jacobian dr/dp (n·channels rows) of a loss: linear (f − m) w, cosine-weighted
    (f − m) cos θo w (what a renderer integrates), or log (log(1 + f) − log(1 + m)) w."""
    if loss == "log":
        r = (np.log1p(f) - np.log1p(measured)) * weights
        j = grad / (1.0 + f)[..., None] * weights[..., None]
    else:
        r = (f - measured) * weights
        j = grad * weights[..., None]
    return r.ravel(), j.reshape(-1, grad.shape[-1])


def _neighbourhoods(wi, wo, channels: int) -> np.ndarray:
    """The neighbourhood of directions of each residual (n·channels, as `_residuals` orders them): 6 × 6 cells of
    (cos θi, cos θo) × the two halves of the azimuth between wi and wo, every channel of a pair in its pair's."""
    cell = lambda w: np.minimum((np.clip(w[:, 2], 0.0, 1.0) * 6).astype(int), 5)  # noqa: E731
    back = wi[:, 0] * wo[:, 0] + wi[:, 1] * wo[:, 1] < 0.0
    return np.repeat((cell(wi) * 6 + cell(wo)) * 2 + back, channels)


def _stderrs(r, jac, groups) -> tuple:
    """Standard errors of least squares at its optimum (residuals r, Jacobian jac), as (noise, robust). Noise:
    s² (JᵀJ)⁻¹, s² the residual variance per degree of freedom, which assumes independent residuals. Robust: the
    cluster-robust sandwich (JᵀJ)⁻¹ (Σ_g u_g u_gᵀ) (JᵀJ)⁻¹ with u_g = J_gᵀ r_g over each neighbourhood g of
    directions (Liang and Zeger 1986; Cameron and Miller 2015, with their small-sample factor), which also counts
    residuals that neighbouring directions share: a model's own error, smooth over the hemisphere, which no number of
    samples averages away (lamina's tabulated against its reference: 0.1–1% of f, most at grazing angles). None
    where there are too few neighbourhoods to estimate it."""
    m, k = jac.shape
    inv = np.linalg.pinv(jac.T @ jac)
    noise = np.sqrt(np.maximum(np.diag(inv) * (r @ r) / max(m - k, 1), 0.0))
    labels, g = np.unique(groups, return_inverse=True)
    if len(labels) <= k + 1:
        return noise, None
    u = np.zeros((len(labels), k))
    np.add.at(u, g, jac * r[:, None])
    meat = u.T @ u * len(labels) / (len(labels) - 1) * (m - 1) / max(m - k, 1)
    return noise, np.sqrt(np.maximum(np.diag(inv @ meat @ inv), 0.0))


def fit(
    template: Stack,
    wi,
    wo,
    measured,
    model: str = "microfacet",
    *,
    weights=None,
    loss: str = "linear",
    starts: int = 4,
    seed: int = 0,
    progress=None,
    **options,
) -> FitResult:
    """Fits every free parameter (lamina.Param) of `template` to `measured` f (n, channels; no cosine, 1/sr, like
    `Stack.eval`'s output) at direction pairs wi, wo (n, 3), under `model` with its `options`. `measured` may also be
    a `lamina.measured.Samples` (then wi and wo are None). `weights` (n,) or (n, channels) scale the residuals;
    `loss` is "linear", "cosine" (residuals × cos θo) or "log". Each Param bounds its parameter; the first start is
    the Params' starts, the others uniform in the bounds (seeded). `progress` shows a bar over the starts (default:
    with more than 4). A fit that does not converge says so (a RuntimeWarning with its last cost, and
    `converged` False). Needs SciPy (`pip install lamina[fit]`)."""
    from scipy.optimize import least_squares

    if not isinstance(template, Stack) or not template.params:
        raise ValueError("fit needs a template stack with at least one free parameter (lamina.Param)")
    if isinstance(measured, Samples):
        if wi is not None or wo is not None:
            raise ValueError("with measured given as Samples, wi and wo must be None (the samples carry them)")
        wi, wo, measured = measured.wi, measured.wo, measured.f
    wi, wo, measured = _checked(wi, wo, measured)
    if loss not in LOSSES:
        raise ValueError(f"loss must be one of {list(LOSSES)}, got {loss!r}")
    if not isinstance(starts, int) or starts < 1:
        raise ValueError(f"starts must be a positive integer, got {starts!r}")
    params = template.params
    lows, highs = np.array([p.low for p in params]), np.array([p.high for p in params])
    channels = template.bind(**{p.name: p.start for p in params}).eval(wi[:1], wo[:1], model, **options).shape[-1]
    if measured.shape[1] != channels:
        raise ValueError(f"measured must have {channels} channels (the stack's), got {measured.shape[1]}")
    w = np.ones_like(measured) if weights is None else np.asarray(weights, dtype=float)
    try:
        w = np.broadcast_to(w[:, None] if w.ndim == 1 else w, measured.shape)
    except (ValueError, IndexError):
        raise ValueError(f"weights must be (n,) or (n, channels) = {measured.shape}, got {np.shape(weights)}") from None
    if not np.all(np.isfinite(w)) or np.any(w < 0):
        raise ValueError("weights must be finite and ≥ 0")
    if loss == "cosine":
        w = w * wo[:, 2:3]

    history = []

    def evaluate(x):
        f, grad = template.eval_grad(wi, wo, model, **dict(zip((p.name for p in params), x)), **options)
        return _residuals(f, grad, measured, w, loss)

    def run(x0):
        costs = []
        cache = {}

        def at(x):
            key = x.tobytes()
            if key not in cache:
                cache.clear()
                cache[key] = evaluate(x)
                costs.append(0.5 * float(cache[key][0] @ cache[key][0]))
            return cache[key]

        result = least_squares(
            lambda x: at(x)[0], x0, jac=lambda x: at(x)[1], bounds=(lows, highs), x_scale="jac", method="trf"
        )
        history.append(costs)
        return result

    rng = np.random.default_rng(seed)
    x0s = [np.array([p.start for p in params])] + [rng.uniform(lows, highs) for _ in range(starts - 1)]
    show = starts > 4 if progress is None else bool(progress)
    if show:
        from tqdm.auto import tqdm

        x0s = tqdm(x0s, desc="fit starts", unit="start")
    best = min((run(x0) for x0 in x0s), key=lambda r: r.cost)
    values = {p.name: float(v) for p, v in zip(params, best.x)}
    noise, robust = _stderrs(best.fun, best.jac, _neighbourhoods(wi, wo, channels))
    stderr_noise = {p.name: float(noise[i]) for i, p in enumerate(params)}
    larger = noise if robust is None else np.maximum(noise, robust)
    stderr = {p.name: float(larger[i]) for i, p in enumerate(params)}
    stack = template.bind(**values)
    f, _ = template.eval_grad(wi, wo, model, **values, **options)  # the f that was fitted
    theta = np.degrees(np.arccos(np.clip(wi[:, 2], -1.0, 1.0)))
    residual = {}
    for lo, hi in BANDS:
        band = (theta >= lo) & (theta < hi)
        total = measured[band].sum()
        residual[f"{lo:.0f}-{hi:.0f}"] = float(np.abs(f[band] - measured[band]).sum() / total) if total > 0 else None
    converged = bool(best.success) and best.status > 0
    if not converged:
        warnings.warn(f"fit did not converge ({best.message}); last cost {best.cost:.6g}", RuntimeWarning, stacklevel=2)
    return FitResult(
        stack, values, stderr, residual, float(best.cost), converged, str(best.message), model, stderr_noise, history
    )


@dataclass(frozen=True)
class ModelFits:
    """What `fit_models` found: `fits` (model -> FitResult, best first), `costs` (model -> ns per evaluation of
    the fitted stack by `Stack.eval`, measured on the data's directions), and `skipped` (model -> why it could not
    fit this template). `rows()` is the table; `plot()` draws it."""

    fits: dict
    costs: dict
    skipped: dict

    def rows(self) -> list:
        """One dict per fitted model, best first: model, residual per band, cost (½ Σ r²), ns per evaluation, the
        parameters and their standard errors."""
        return [
            dict(
                model=m,
                **{f"residual {k}": v for k, v in r.residual.items()},
                cost=r.cost,
                ns=self.costs[m],
                params=r.params,
                stderr=r.stderr,
                converged=r.converged,
            )
            for m, r in self.fits.items()
        ]

    def table(self) -> str:
        """The table in Markdown."""
        bands = [f"{lo:.0f}-{hi:.0f}" for lo, hi in BANDS]
        head = "| model | " + " | ".join(f"residual θi {b}°" for b in bands) + " | ns/eval | parameters (± 1 SE) |"
        lines = [head, "|" + "---|" * (len(bands) + 3)]
        for m, r in self.fits.items():
            res = " | ".join("–" if r.residual[b] is None else f"{r.residual[b]:.2%}" for b in bands)
            ps = ", ".join(f"{k} {v:.4g} ± {r.stderr[k]:.2g}" for k, v in r.params.items())
            lines.append(f"| {m} | {res} | {self.costs[m]:.0f} | {ps} |")
        lines += [f"| {m} | not fitted: {why} | | | |" for m, why in self.skipped.items()]
        return "\n".join(lines)

    def _repr_markdown_(self) -> str:
        return self.table()

    def __repr__(self) -> str:
        return self.table()

    def plot(self, ax=None):
        """Residual per band of incidence against the cost per evaluation, one point per model (matplotlib)."""
        import matplotlib.pyplot as plt

        if ax is None:
            _, ax = plt.subplots(figsize=(5.5, 3.6))
        bands = [f"{lo:.0f}-{hi:.0f}" for lo, hi in BANDS]
        for b, marker in zip(bands, "osD"):
            pts = [(self.costs[m], r.residual[b], m) for m, r in self.fits.items() if r.residual[b] is not None]
            if pts:
                ax.scatter([p[0] for p in pts], [p[1] for p in pts], marker=marker, label=f"θi {b}°")
        for m, r in self.fits.items():
            ax.annotate(m, (self.costs[m], r.residual[bands[0]] or 0.0), textcoords="offset points", xytext=(5, 5))
        ax.set(xscale="log", yscale="log", xlabel="ns per evaluation", ylabel="relative L1 residual")
        ax.set_title("which model explains the measurement")
        ax.legend(fontsize=8)
        return ax


def fit_models(template: Stack, wi, wo, measured, *, models=None, progress=None, **kwargs) -> ModelFits:
    """Fits `template` under every model that has gradients for its free parameters (or those named in `models`)
    with `fit` (the keyword arguments are fit's), and measures each fitted stack's cost per evaluation: the answer to
    "which model explains my measurement, and at what cost". Models that cannot fit the template (no gradient by one
    of its parameters, a stack they do not take) are listed in `skipped` with the reason."""
    from .catalogue import models as catalogue

    if isinstance(measured, Samples):
        wi, wo, measured = measured.wi, measured.wo, measured.f
    wi, wo, measured = _checked(wi, wo, measured)
    names = [m.name for m in catalogue() if m.gradients] if models is None else list(models)
    fits, costs, skipped = {}, {}, {}
    show = len(names) > 1 if progress is None else bool(progress)
    if show:
        from tqdm.auto import tqdm

        names = tqdm(names, desc="fit_models", unit="model")
    for name in names:
        try:
            template.eval_grad(wi[:1], wo[:1], name)
        except ValueError as e:
            skipped[name] = str(e)
            continue
        fits[name] = fit(template, wi, wo, measured, name, **kwargs)
        stack = fits[name].stack
        stack.eval(wi, wo, name)  # prepared once, outside the timing
        times = []
        for _ in range(3):
            t0 = time.perf_counter()
            stack.eval(wi, wo, name)
            times.append(time.perf_counter() - t0)
        costs[name] = 1e9 * min(times) / len(wi)
    order = sorted(fits, key=lambda m: fits[m].cost)
    return ModelFits({m: fits[m] for m in order}, {m: costs[m] for m in order}, skipped)
