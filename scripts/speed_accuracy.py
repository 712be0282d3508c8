"""Speed against accuracy (`make chart`): one point per model and variant — the cost of one evaluation on the CPU
against its error relative to the Monte Carlo reference on the material suite — and the reference itself at several
sample counts. Writes docs/speed_accuracy.json and docs/speed_accuracy.png. Not a test.

- Cost: ns per evaluation, the median of 5 calls on 1M random float32 pairs of rough-coat-rough-copper (2 layers,
  RGB) after the first call, which prepares the model and is reported on its own (prepare_ms). The reference's cost
  is its time per NEE estimate of f at that sample count, per pair.
- Error, per band of incidence (0–60°, 60–80°, 80–89°; the suite grid's θi of 0/30/60, 80 and 87°), averaged over
  the suite: the relative L1 lobe error Σ|f − f_ref| / Σ|f_ref| over the grid's 30 outgoing directions and RGB, and
  the absolute albedo error (green) against the brute-force reference albedo. Error bars: the reference's own
  relative standard error, Σ SE / Σ|f_ref|.
- The Pareto front joins the points that no other point beats in both cost and error (0–60° band).
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

import lamina
import numpy as np
from lamina.reference import SUITE_THETAS, suite_reference, suite_reference_albedo

ROOT = Path(__file__).resolve().parents[1]
N = 1_000_000
BANDS = {"0-60": [0, 1, 2], "60-80": [3], "80-89": [4]}
#: (label, model, options): each model's published form and its variants.
VARIANTS = [
    ("belcour", "belcour", {}),
    ("belcour symmetric", "belcour", {"symmetric": True}),
    ("belcour TIR fraction", "belcour", {"tir": "fraction"}),
    ("steinberg (lamina defaults)", "steinberg", {}),
    ("steinberg published", "steinberg", {"clamp_roughness": False, "eta2": False}),
    ("steinberg fitted LUT", "steinberg", {"lut": "fitted"}),
    ("weidlich_wilkie (lamina defaults)", "weidlich_wilkie", {}),
    ("weidlich_wilkie published", "weidlich_wilkie", {"clamp_roughness": False, "eta2": False}),
    ("weidlich_wilkie precomputed", "weidlich_wilkie", {"precomputed": True}),
    ("weidlich_wilkie Lazányi", "weidlich_wilkie", {"fresnel": "lazanyi"}),
    ("albedo_scaling reciprocal", "albedo_scaling", {}),
    ("albedo_scaling view", "albedo_scaling", {"scaling": "view"}),
]
REFERENCE_SAMPLES = (100, 300, 1000, 3000)


def cost(model: str, options: dict) -> tuple:
    """(ns per evaluation, first-call ms) on 1M float32 pairs of the 2-layer stack."""
    rng = np.random.default_rng(0)
    w = rng.normal(size=(2, N, 3))
    w[..., 2] = np.abs(w[..., 2])
    wi, wo = w.astype(np.float32)
    stack = lamina.materials.suite("rough-coat-rough-copper")
    t0 = time.perf_counter()
    stack.eval(wi[:10], wo[:10], model, **options)
    first = time.perf_counter() - t0
    times = []
    for _ in range(5):
        t0 = time.perf_counter()
        stack.eval(wi, wo, model, **options)
        times.append(time.perf_counter() - t0)
    return float(np.median(times)) / N * 1e9, first * 1e3


def suite_errors(evaluate) -> dict:
    """Mean over the suite of the lobe error and |albedo error| per band; `evaluate(stack, wi, wo)` returns f, and
    None for a stack the model cannot represent (left out of the means, counted in `unsupported`)."""
    lobe = {b: [] for b in BANDS}
    albedo = {b: [] for b in BANDS}
    spread = {b: [] for b in BANDS}
    unsupported = 0
    for name in lamina.materials.SUITE:
        stack = lamina.materials.suite(name)
        wi, wo, f, se = suite_reference(name, samples=20_000)
        try:
            b, a = evaluate(stack, wi, wo)
        except ValueError:
            unsupported += 1
            continue
        err = np.abs(b - f).sum(axis=(1, 2)) / np.abs(f).sum(axis=(1, 2))
        rel_se = se.sum(axis=(1, 2)) / np.abs(f).sum(axis=(1, 2))
        a_err = np.abs(a - reference_albedo(name)) if a is not None else np.full(len(err), np.nan)
        for band, k in BANDS.items():
            lobe[band].append(err[k].mean())
            albedo[band].append(a_err[k].mean())
            spread[band].append(rel_se[k].mean())
    # None where a model has no albedo to compare (the reference's f estimates): JSON has no NaN.
    mean = lambda d: {b: (float(np.mean(v)) if np.all(np.isfinite(v)) else None) for b, v in d.items()}  # noqa: E731
    return {
        "lobe_error": mean(lobe),
        "albedo_error": mean(albedo),
        "reference_rel_se": mean(spread),
        "unsupported": unsupported,
    }


_ALBEDO: dict = {}


def reference_albedo(name: str) -> np.ndarray:
    """The suite's brute-force reference albedo at SUITE_THETAS, green channel (smooth tops' Dirac removed)."""
    if name not in _ALBEDO:
        _ALBEDO[name] = suite_reference_albedo(name)[1][:, 1]
    return _ALBEDO[name]


def model_rows() -> list:
    rows = []
    for label, model, options in VARIANTS:
        ns, prepare = cost(model, options)

        def evaluate(stack, wi, wo, m=model, o=options):
            return stack.eval(wi, wo, m, **o), stack.albedo(wi[:, 0, :], m, **o)[:, 1]

        rows.append(
            {
                "label": label,
                "model": model,
                "options": options,
                "ns_per_eval": ns,
                "prepare_ms": prepare,
                "set": "suite",
                **suite_errors(evaluate),
            }
        )
        print(f"{label:36s} {ns:8.1f} ns  lobe error {rows[-1]['lobe_error']}", file=sys.stderr)
    return rows


def reference_rows() -> list:
    rows = []
    for samples in REFERENCE_SAMPLES:
        clock = {"seconds": 0.0, "pairs": 0}

        def evaluate(stack, wi, wo, n=samples, clock=clock):
            t0 = time.perf_counter()
            f = stack.reference(wi, wo, samples=n, seed=1, progress=False)[0]
            clock["seconds"] += time.perf_counter() - t0
            clock["pairs"] += f.shape[0] * f.shape[1]
            return f, None

        errors = suite_errors(evaluate)
        rows.append(
            {
                "label": f"reference, {samples} paths",
                "model": "reference",
                "options": {"samples": samples},
                "ns_per_eval": clock["seconds"] / clock["pairs"] * 1e9,
                "prepare_ms": 0.0,
                "set": "suite",
                **errors,
            }
        )
        print(f"reference {samples:6d} {rows[-1]['ns_per_eval']:10.0f} ns  {rows[-1]['lobe_error']}", file=sys.stderr)
    return rows


def pareto(rows: list, band: str) -> list:
    """Rows that no other row beats in both cost and lobe error, by increasing cost."""
    front = [
        r
        for r in rows
        if not any(
            o["ns_per_eval"] <= r["ns_per_eval"] and o["lobe_error"][band] < r["lobe_error"][band]
            for o in rows
            if o is not r
        )
    ]
    return sorted(front, key=lambda r: r["ns_per_eval"])


def plot(rows: list, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    colours = {
        "belcour": "tab:blue",
        "steinberg": "tab:orange",
        "weidlich_wilkie": "tab:green",
        "albedo_scaling": "tab:purple",
        "reference": "black",
    }
    fig, axes = plt.subplots(1, 3, figsize=(18, 7), sharey=True, constrained_layout=True)
    for ax, band in zip(axes, BANDS):
        for i, r in enumerate(sorted(rows, key=lambda r: (r["ns_per_eval"], r["lobe_error"][band]))):
            y, se = r["lobe_error"][band], r["reference_rel_se"][band]
            marker = "s" if r["model"] == "reference" else "o"
            ax.errorbar(r["ns_per_eval"], y, yerr=se, fmt=marker, color=colours[r["model"]], ms=6, capsize=2)
            # Neighbours in cost get labels at staggered heights, so that clusters stay legible.
            ax.annotate(
                r["label"],
                (r["ns_per_eval"], y),
                fontsize=6.5,
                xytext=(5, 9 * (i % 4) - 12),
                textcoords="offset points",
                arrowprops={"arrowstyle": "-", "lw": 0.4, "color": "grey"},
            )
        front = pareto(rows, band)
        ax.plot(
            [r["ns_per_eval"] for r in front],
            [r["lobe_error"][band] for r in front],
            "--",
            color="grey",
            lw=1,
            label="Pareto front",
        )
        ax.set(
            xscale="log",
            yscale="log",
            xlabel="CPU cost per evaluation (ns, 1M pairs, 2 threads)",
            title=f"θi {band.replace('-', '–')}°",
        )
        ax.grid(True, which="both", alpha=0.3)
    axes[0].set_ylabel("mean relative L1 lobe error vs the reference (suite)")
    handles = [
        plt.Line2D([], [], marker="s" if m == "reference" else "o", ls="", color=c, label=m) for m, c in colours.items()
    ]
    axes[-1].legend(
        handles=handles + [plt.Line2D([], [], ls="--", color="grey", label="Pareto front")],
        loc="upper right",
        fontsize=8,
    )
    fig.suptitle(
        "lamina: speed against accuracy on the material suite (error bars: the reference's own standard error)"
    )
    fig.savefig(path, dpi=140)


def main() -> None:
    out = ROOT / "docs" / "speed_accuracy.json"
    if sys.argv[1:] == ["--plot"]:  # redraw the figure from the JSON
        plot(json.loads(out.read_text())["rows"], ROOT / "docs" / "speed_accuracy.png")
        return
    rows = model_rows() + reference_rows()
    out.write_text(
        json.dumps(
            {
                "generated_by": "scripts/speed_accuracy.py",
                "lamina": lamina.__version__,
                "bands_deg": list(BANDS),
                "suite_thetas_deg": list(SUITE_THETAS),
                "rows": rows,
            },
            indent=1,
        )
        + "\n"
    )
    plot(rows, ROOT / "docs" / "speed_accuracy.png")
    print(f"wrote {out} and docs/speed_accuracy.png", file=sys.stderr)


if __name__ == "__main__":
    main()
