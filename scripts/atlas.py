"""`make atlas`: the failure atlas. For every layered model, its lobe error against the reference over the parameter
planes of lamina.atlas.PLANES, with stability flags on the same grids. Writes docs/atlas.json, docs/atlas/<plane>.png
and docs/atlas.md (figures and a reading per model, generated from the data). Not a test; resumable (the references
are cached), and distributed with --scheduler.

Flags, per model and cell:
- E: energy > 1, the model's albedo (mean weight of its own sampling) above 1 by more than 4 standard errors;
- N: NaN or Inf in f; −: negative f;
- D: a discontinuity, found by finite differences: the model's albedo jumps between neighbouring cells by more than
  0.05 and by more than 3x the reference albedo's jump plus 4 standard errors there.
"""

from __future__ import annotations

import argparse
import json
import sys
import textwrap
from pathlib import Path

import numpy as np
from lamina import atlas

ROOT = Path(__file__).resolve().parents[1]
#: Lobe errors above FAIL count as failures in the readings.
FAIL = 0.3


def grids(name: str, cells: list) -> dict:
    """Per model: error, albedo, albedo SE, nonfinite and negative counts as (len(x), len(y)) arrays, and the
    reference's albedo and noise."""
    xlabel, xs, ylabel, ys, _ = atlas.PLANES[name]
    theta = ylabel == "θi"
    shape = (len(xs), len(atlas.ATLAS_THETAS) if theta else len(ys))

    def field(get):
        if theta:  # one cell per x, one value per θi
            return np.array([get(c) for c in cells], dtype=float).reshape(shape)
        w = np.array(atlas.PLANE_THETAS) <= 80.0
        return np.array([np.mean(np.asarray(get(c), dtype=float)[w]) for c in cells]).reshape(shape)

    out = {"ref_albedo": field(lambda c: c["ref_albedo"]), "noise": field(lambda c: c["noise"])}
    for m in atlas.ATLAS_MODELS:
        out[m] = {k: field(lambda c, k=k, m=m: c[m][k]) for k in ("error", "albedo", "albedo_se")}
        counts = lambda k, m=m: np.array([c[m][k] for c in cells], dtype=float)  # noqa: E731
        if theta:
            out[m]["nonfinite"] = np.repeat(counts("nonfinite")[:, None], shape[1], 1)
            out[m]["negative"] = np.repeat(counts("negative")[:, None], shape[1], 1)
        else:
            out[m]["nonfinite"] = counts("nonfinite").reshape(shape)
            out[m]["negative"] = counts("negative").reshape(shape)
    return out


def flags(g: dict, model: str) -> dict:
    """Boolean (x, y) maps of the stability flags of `model` on a plane's grids."""
    m = g[model]
    return atlas.stability_flags(m["albedo"], m["albedo_se"], g["ref_albedo"], m["nonfinite"], m["negative"])


def plot(name: str, g: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.colors import LogNorm

    xlabel, xs, ylabel, ys, _ = atlas.PLANES[name]
    ys = atlas.ATLAS_THETAS if ylabel == "θi" else ys
    panels = [*atlas.ATLAS_MODELS, "reference noise"]
    cols = 4
    rows = -(-len(panels) // cols)
    fig, grid = plt.subplots(rows, cols, figsize=(4.2 * cols, 4.2 * rows + 0.3), constrained_layout=True, squeeze=False)
    axes = grid.ravel()[: len(panels)]
    for ax in grid.ravel()[len(panels) :]:
        ax.set_visible(False)
    norm = LogNorm(0.005, 2.0)
    for ax, p in zip(axes, panels):
        e = g["noise"] if p == "reference noise" else g[p]["error"]
        im = ax.imshow(np.clip(e.T, 0.005, 2.0), origin="lower", cmap="magma", norm=norm, aspect="auto")
        for i in range(e.shape[0]):
            for j in range(e.shape[1]):
                v = e[i, j]
                ax.text(
                    i,
                    j,
                    f"{v:.2f}" if v < 10 else f"{v:.0f}",
                    ha="center",
                    va="center",
                    fontsize=5.5,
                    color="white" if v < 0.3 else "black",
                )
        if p != "reference noise":
            marks = flags(g, p)
            for k, (sym, dy) in zip(marks, (("E", 0.3), ("N", 0.3), ("−", -0.3), ("D", -0.3))):
                for i, j in zip(*np.nonzero(marks[k])):
                    ax.text(
                        i + (0.3 if k in "EN" else -0.3),
                        j + dy,
                        sym,
                        ha="center",
                        va="center",
                        fontsize=6.5,
                        color="cyan",
                        fontweight="bold",
                    )
        ax.set_title(p)
        ax.set_xticks(range(len(xs)), [f"{x:g}" for x in xs], fontsize=7, rotation=45)
        ax.set_yticks(range(len(ys)), [f"{y:g}" for y in ys], fontsize=7)
        ax.set_xlabel(textwrap.fill(xlabel, 60), fontsize=7)
        ax.set_ylabel(ylabel + (" (°)" if ylabel == "θi" else ""), fontsize=8)
    fig.colorbar(im, ax=list(axes), shrink=0.8, label="relative L1 lobe error against the reference")
    fig.suptitle(f"Failure atlas: {name}. Flags: E energy > 1, N NaN/Inf, − negative, D discontinuity", fontsize=10)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def describe(name: str, mask: np.ndarray) -> str:
    """Where a boolean (x, y) map is true, in the plane's own values."""
    xlabel, xs, ylabel, ys, _ = atlas.PLANES[name]
    ys = atlas.ATLAS_THETAS if ylabel == "θi" else ys
    if not mask.any():
        return "nowhere"
    parts = []
    for i in np.nonzero(mask.any(axis=1))[0]:
        js = np.nonzero(mask[i])[0]
        span = f"{ys[js[0]]:g}" if len(js) == 1 else f"{ys[js[0]]:g}–{ys[js[-1]]:g}"
        parts.append(f"{xs[i]:g} ({span})")
    short = ylabel.split(" (")[0]
    return f"{mask.sum()} of {mask.size} cells; {xlabel.split(' (')[0]} ({short}): " + ", ".join(parts)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scheduler", help="address of a dask.distributed scheduler to run the cells on")
    parser.add_argument("--planes", nargs="*", default=list(atlas.PLANES), help="planes to compute (default: all)")
    args = parser.parse_args()
    client = None
    if args.scheduler:
        from distributed import Client

        client = Client(args.scheduler)
    data_path = ROOT / "docs" / "atlas.json"
    data = json.loads(data_path.read_text()) if data_path.exists() else {}
    for name in args.planes:
        data[name] = atlas.atlas_plane(name, client=client)
        data_path.write_text(json.dumps(data))
    (ROOT / "docs" / "atlas").mkdir(exist_ok=True)
    lines = [
        "# The failure atlas",
        "",
        "Generated by `make atlas` (scripts/atlas.py) from lamina.atlas. Do not edit.",
        "",
        f"Each cell is a stack measured against the reference ({atlas.ATLAS_SAMPLES} paths per pair, cached) on the "
        "suite's 30 outgoing directions: the relative L1 lobe error Σ|f − f_ref| / Σ|f_ref| over them and RGB, at "
        "the cell's θi, or averaged over θi ∈ {" + ", ".join(f"{t:g}" for t in atlas.PLANE_THETAS) + "}° on the "
        "parameter × parameter planes. The last panel of each figure is the reference's own noise, Σ SE / Σ|f_ref|, "
        "the floor under every error. Flags (cyan): "
        + " ".join(__doc__.split("Flags, per model and cell:")[1].split()),
        "",
    ]
    grids_ = {name: grids(name, data[name]) for name in atlas.PLANES if name in data}
    for name, g in grids_.items():
        plot(name, g, ROOT / "docs" / "atlas" / f"{name}.png")
        lines += [f"## {name}", "", f"![{name}](atlas/{name}.png)", ""]
    lines += [
        "## Readings",
        "",
        f"Generated from the grids above: where each model's lobe error exceeds {FAIL}, and "
        "where its flags are raised (per plane: x values, with the span of y values in brackets).",
        "",
    ]
    for m in atlas.ATLAS_MODELS:
        errors = np.concatenate([g[m]["error"].ravel() for g in grids_.values()])
        lines += [
            f"### {m}",
            "",
            f"Median lobe error over all {errors.size} cells {np.median(errors):.3f}; "
            f"{np.mean(errors > FAIL):.0%} of cells above {FAIL}.",
            "",
        ]
        for name, g in grids_.items():
            f = flags(g, m)
            worst = np.unravel_index(np.argmax(g[m]["error"]), g[m]["error"].shape)
            lines.append(
                f"- **{name}**: {m} fails (error > {FAIL}) at {describe(name, g[m]['error'] > FAIL)}. "
                f"Worst {g[m]['error'][worst]:.2f}."
            )
            for k, label in (("E", "energy > 1"), ("N", "NaN/Inf"), ("−", "negative values"), ("D", "discontinuities")):
                if f[k].any():
                    lines.append(f"  - {label}: {describe(name, f[k])}")
        lines.append("")
    (ROOT / "docs" / "atlas.md").write_text("\n".join(lines) + "\n")
    print(f"wrote docs/atlas.md and {len(grids_)} figures", file=sys.stderr)


if __name__ == "__main__":
    main()
