"""Speed against accuracy (`make chart`, after `make population`): one point per model and variant — the cost of
one evaluation against its error relative to the Monte Carlo reference — on two sets: the material suite and the
held-out population (lamina.materials.population(200, seed=1), whose references `make population` caches); the
reference itself at several path counts (suite only); and the GPU path for the models it has, on the adapter lamina
finds (labelled with it). Writes docs/speed_accuracy.json and docs/speed_accuracy.png. Not a test.

- Cost: lamina.atlas.cost: ns per evaluation, the median of 5 calls on 1M random float32 pairs of
  rough-coat-rough-copper (2 layers, RGB) after the first call, which prepares the model and is reported on its own
  (prepare_ms). The reference's cost is its time per NEE estimate of f at that path count, per pair.
- Error, per band of incidence (0–60°, 60–80°, 80–89°; the suite grid's θi of 0/30/60, 80 and 87°), averaged over
  the set: the relative L1 lobe error Σ|f − f_ref| / Σ|f_ref| over the grid's 30 outgoing directions and RGB, and
  the absolute albedo error (green) of the model's albedo (mean weight of its own sampling, lamina.atlas.model_albedo)
  against the brute-force reference albedo. Error bars: the reference's own relative standard error, Σ SE / Σ|f_ref|.
- The Pareto front joins the points that no other point beats in both cost and error, per set and band.
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

import lamina
import lamina.mitsuba
import numpy as np
from lamina import atlas
from lamina.reference import SUITE_THETAS, cached_reference, suite_directions, suite_reference, suite_reference_albedo
from tqdm import tqdm

ROOT = Path(__file__).resolve().parents[1]
POPULATION = 200
BANDS = {"0-60": [0, 1, 2], "60-80": [3], "80-89": [4]}
#: (label, model, options): each model's published form and its variants.
VARIANTS = [
    ("belcour", "belcour", {}),
    ("belcour symmetric", "belcour", {"symmetric": True}),
    ("belcour TIR fraction", "belcour", {"tir": "fraction"}),
    ("belcour improved", "belcour", {"variant": "improved"}),
    ("steinberg (lamina defaults)", "steinberg", {}),
    ("steinberg published", "steinberg", {"clamp_roughness": False, "eta2": False}),
    ("steinberg fitted LUT", "steinberg", {"lut": "fitted"}),
    ("steinberg + interreflection", "steinberg", {"interreflection": True}),
    ("steinberg improved", "steinberg", {"variant": "improved"}),
    ("weidlich_wilkie (lamina defaults)", "weidlich_wilkie", {}),
    ("weidlich_wilkie published", "weidlich_wilkie", {"clamp_roughness": False, "eta2": False}),
    ("weidlich_wilkie precomputed", "weidlich_wilkie", {"precomputed": True}),
    ("weidlich_wilkie Lazányi", "weidlich_wilkie", {"fresnel": "lazanyi"}),
    ("weidlich_wilkie improved", "weidlich_wilkie", {"variant": "improved"}),
    ("albedo_scaling reciprocal", "albedo_scaling", {}),
    ("albedo_scaling view", "albedo_scaling", {"scaling": "view"}),
    ("tabulated (precomputed)", "tabulated", {}),
]
REFERENCE_SAMPLES = (100, 300, 1000, 3000)


def suite_set() -> list:
    """The suite as (stack, f_ref, se, reference albedo (green)) items on the suite grid."""
    items = []
    for name in lamina.materials.SUITE:
        _, _, f, se = suite_reference(name, samples=20_000)
        items.append((lamina.materials.suite(name), f, se, suite_reference_albedo(name)[1][:, 1]))
    return items


def population_set() -> list:
    """The held-out population (lamina.materials.population(POPULATION, seed=1)) as suite_set's items, from the
    references `make population` computed and cached."""
    wi, wo = suite_directions()
    items = []
    for _, stack in tqdm(lamina.materials.population(POPULATION, 1), desc="population references", unit="stack"):
        f, se = cached_reference(stack, wi, wo, samples=atlas.GROUND_TRUTH_SAMPLES, seed=0, progress=False)
        items.append((stack, f, se, atlas.reference_albedo(stack, samples=atlas.ALBEDO_SAMPLES)[0][:, 1]))
    return items


def errors(items: list, evaluate) -> dict:
    """Means over `items` of the lobe error and |albedo error| per band; `evaluate(stack, wi, wo)` returns
    (f, green albedo or None), and raises ValueError for a stack the model cannot represent (left out of the means,
    counted in `unsupported`). Stacks whose reference noise exceeds lamina.atlas.MAX_NOISE at some angle count in
    `unresolved` and are left out of the lobe error: a smooth clear coat over a near-mirror layer puts lobes on grid
    directions that the reference's paths do not resolve."""
    wi, wo = suite_directions()
    lobe = {b: [] for b in BANDS}
    albedo = {b: [] for b in BANDS}
    spread = {b: [] for b in BANDS}
    unresolved = {b: 0 for b in BANDS}
    unsupported = 0
    for stack, f, se, a_ref in items:
        try:
            b, a = evaluate(stack, wi, wo)
        except ValueError:
            unsupported += 1
            continue
        err = atlas.lobe_errors(b, f)
        rel_se = se.sum(axis=(1, 2)) / np.abs(f).sum(axis=(1, 2))
        a_err = np.abs(a - a_ref) if a is not None else np.full(len(err), np.nan)
        for band, k in BANDS.items():
            albedo[band].append(a_err[k].mean())
            if rel_se.max() > atlas.MAX_NOISE:  # the reference does not resolve this stack's lobes: nothing to measure
                unresolved[band] += 1
                continue
            lobe[band].append(err[k].mean())
            spread[band].append(rel_se[k].mean())
    # None where a model has no albedo to compare (the reference's f estimates): JSON has no NaN.
    mean = lambda d: {b: (float(np.mean(v)) if np.all(np.isfinite(v)) else None) for b, v in d.items()}  # noqa: E731
    return {
        "lobe_error": mean(lobe),
        "albedo_error": mean(albedo),
        "reference_rel_se": mean(spread),
        "unsupported": unsupported,
        "unresolved": unresolved,
    }


def model_rows(sets: dict) -> list:
    """A row per variant and set, and per GPU-capable variant a GPU row (float32, on the adapter lamina finds)."""
    rows = []
    gpu = lamina.gpu.adapter() if hasattr(lamina, "gpu") else None
    for label, model, options in VARIANTS:
        ns, prepare = atlas.cost(model, options)
        for device in ("cpu", "gpu") if gpu and model in lamina.gpu.models() and not options else ("cpu",):

            def evaluate(stack, wi, wo, m=model, o=options, device=device):
                f = stack.eval(wi, wo, m, device=device, **o)
                return f, atlas.model_albedo(stack, m, o)[0][:, 1]

            if device == "gpu":
                ns, prepare = atlas.cost(model, options, device="gpu")
            for name, items in sets.items():
                rows.append(
                    {
                        "label": label if device == "cpu" else f"{label} GPU ({gpu['name']})",
                        "model": model,
                        "options": options,
                        "device": device,
                        "ns_per_eval": ns,
                        "prepare_ms": prepare,
                        "set": name,
                        **errors(items, evaluate),
                    }
                )
                print(f"{rows[-1]['label']:36s} {name:10s} {ns:8.1f} ns  {rows[-1]['lobe_error']}", file=sys.stderr)
    return rows


def principled_cost(n: int = 1_000_000, repeats: int = 5) -> tuple:
    """Mitsuba principled's ns per evaluation as its users call it, np.array(bsdf.eval(ctx, si, wo)) on n random
    float32 pairs (llvm_ad_rgb), of rough-coat-rough-copper's closest principled; and its first call in ms."""
    import drjit as dr
    import mitsuba as mi

    if lamina.mitsuba.variant() != "llvm_ad_rgb":
        raise SystemExit("the principled row needs Mitsuba's llvm_ad_rgb (a libLLVM >= 16: see tests/libllvm.py)")
    rng = np.random.default_rng(0)
    w = rng.normal(size=(2, n, 3))
    w[..., 2] = np.abs(w[..., 2])
    b = mi.load_dict(lamina.mitsuba.principled(lamina.materials.suite("rough-coat-rough-copper")))
    si = dr.zeros(mi.SurfaceInteraction3f, n)
    si.wi = mi.Vector3f(np.ascontiguousarray(w[1].T, dtype=np.float32))
    wo, ctx = mi.Vector3f(np.ascontiguousarray(w[0].T, dtype=np.float32)), mi.BSDFContext()
    t0 = time.perf_counter()
    np.array(b.eval(ctx, si, wo))
    first = time.perf_counter() - t0
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        np.array(b.eval(ctx, si, wo))
        times.append(time.perf_counter() - t0)
    return float(np.median(times)) / n * 1e9, first * 1e3


def principled_rows(sets: dict) -> list:
    """Mitsuba's principled, on the closest principled of each stack (lamina.mitsuba.principled)."""
    ns, prepare = principled_cost()
    t = np.radians(SUITE_THETAS)
    rows = []

    def evaluate(stack, wi, wo):
        d = lamina.mitsuba.principled(stack)
        wi_b, wo_b = np.broadcast_arrays(wi, wo)
        f = lamina.mitsuba.eval_f(d, wi_b.reshape(-1, 3), wo_b.reshape(-1, 3)).reshape(wi_b.shape)
        a = lamina.mitsuba.albedo(d, np.stack([np.sin(t), np.zeros_like(t), np.cos(t)], -1))[:, 1]
        return f, a

    for name, items in sets.items():
        rows.append(
            {
                "label": "Mitsuba principled",
                "model": "principled",
                "options": {},
                "device": "cpu",
                "ns_per_eval": ns,
                "prepare_ms": prepare,
                "set": name,
                **errors(items, evaluate),
            }
        )
        print(f"Mitsuba principled {name:10s} {ns:8.1f} ns  {rows[-1]['lobe_error']}", file=sys.stderr)
    return rows


def reference_rows(items: list) -> list:
    rows = []
    for samples in REFERENCE_SAMPLES:
        clock = {"seconds": 0.0, "pairs": 0}

        def evaluate(stack, wi, wo, n=samples, clock=clock):
            t0 = time.perf_counter()
            f = stack.reference(wi, wo, samples=n, seed=1, progress=False)[0]
            clock["seconds"] += time.perf_counter() - t0
            clock["pairs"] += f.shape[0] * f.shape[1]
            return f, None

        errs = errors(items, evaluate)
        rows.append(
            {
                "label": f"reference, {samples} paths",
                "model": "reference",
                "options": {"samples": samples},
                "ns_per_eval": clock["seconds"] / clock["pairs"] * 1e9,
                "prepare_ms": 0.0,
                "device": "cpu",
                "set": "suite",
                **errs,
            }
        )
        print(f"reference {samples:6d} {rows[-1]['ns_per_eval']:10.0f} ns  {rows[-1]['lobe_error']}", file=sys.stderr)
    return rows


def pareto(rows: list, band: str) -> list:
    """Rows that no other row beats in both cost and lobe error, by increasing cost."""
    rows = [r for r in rows if r["lobe_error"][band] is not None]
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


#: Each model's colour, and each variant's marker (the label less the model's name; GPU points are hollow).
COLOURS = {
    "belcour": "tab:blue",
    "steinberg": "tab:orange",
    "weidlich_wilkie": "tab:green",
    "albedo_scaling": "tab:purple",
    "tabulated": "tab:cyan",
    "principled": "tab:red",
    "reference": "black",
}
MARKERS = {
    "default": "o",
    "published": "v",
    "improved": "*",
    "symmetric": "<",
    "TIR fraction": ">",
    "fitted LUT": "P",
    "+ interreflection": "X",
    "precomputed": "p",
    "Lazányi": "h",
    "view": "d",
    "paths": "s",
}


def variant(r: dict) -> str:
    """The variant of row r, a key of MARKERS: what its label says beyond the model's name."""
    rest = r["label"].split(" GPU")[0].removeprefix(r["model"]).strip()
    if r["model"] == "reference":
        return "paths"
    if r["model"] == "belcour" and not rest:
        return "published"
    return rest if rest in MARKERS else "default"


def short(r: dict) -> str:
    """Row r's label in a panel: the GPU's adapter name left to the JSON and the legend."""
    return r["label"].split(" GPU")[0] + (" GPU" if r.get("device") == "gpu" else "")


def place_labels(ax, items: list) -> None:
    """Writes each (text, (x, y)) of `items` beside its point, moving it down (then up) by whole lines until it
    overlaps no label already placed, with a thin leader to the point."""
    from matplotlib.text import Text

    fig = ax.figure
    renderer = fig.canvas.get_renderer()
    placed = []
    for text, xy in items:
        for dy in [0, -10, 10, -20, 20, -30, 30, -40, 40, -50, 50, -60, 60]:
            t = ax.annotate(
                text,
                xy,
                xytext=(24 if dy else 6, dy - 3),
                textcoords="offset points",
                fontsize=7,
                arrowprops={"arrowstyle": "-", "lw": 0.6, "color": "dimgrey"} if dy else None,
            )
            t.update_positions(renderer)
            box = Text.get_window_extent(t, renderer).expanded(1.02, 1.1)  # the text's, without its leader
            if not any(box.overlaps(b) for b in placed):
                break
            t.remove()
        else:
            print(f"no free place for the label {text!r}", file=sys.stderr)
            ax.annotate(text, xy, xytext=(6, -3), textcoords="offset points", fontsize=7)
        placed.append(box)


def plot(rows: list, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    sets = {"suite": "the material suite (8 stacks)", "population": f"the held-out population ({POPULATION} stacks)"}
    fig, axes = plt.subplots(2, 3, figsize=(18, 13), sharey=True, constrained_layout=True)
    for row_axes, (name, title) in zip(axes, sets.items()):
        subset = [r for r in rows if r["set"] == name]
        for ax, band in zip(row_axes, BANDS):
            ax.set(
                xscale="log",
                yscale="log",
                xlabel="cost per evaluation (ns, 1M pairs; CPU: 2 threads)",
                title=f"{title}, θi {band.replace('-', '–')}°",
            )
            for r in subset:
                y, se = r["lobe_error"][band], r["reference_rel_se"][band]
                if y is None:
                    continue
                colour, marker = COLOURS[r["model"]], MARKERS[variant(r)]
                face = "none" if r.get("device") == "gpu" else colour
                ms = 11 if marker == "*" else 6
                ax.errorbar(r["ns_per_eval"], y, yerr=se, fmt=marker, color=colour, mfc=face, ms=ms, capsize=2)
            front = pareto(subset, band)
            ax.plot([r["ns_per_eval"] for r in front], [r["lobe_error"][band] for r in front], "--", color="grey", lw=1)
            # Published → improved: an arrow from each published model to its improved variant.
            labelled = {id(r) for r in front}
            for r in subset:
                if variant(r) != "improved" or r["lobe_error"][band] is None:
                    continue
                start = next(
                    (
                        o
                        for o in subset
                        if o["model"] == r["model"] and variant(o) == "published" and o["device"] == "cpu"
                    ),
                    None,
                )
                if start is not None and start["lobe_error"][band] is not None:
                    ax.annotate(
                        "",
                        (r["ns_per_eval"], r["lobe_error"][band]),
                        (start["ns_per_eval"], start["lobe_error"][band]),
                        arrowprops={"arrowstyle": "->", "color": COLOURS[r["model"]], "lw": 1.2, "alpha": 0.7},
                    )
                    labelled |= {id(r), id(start)}
            ax.grid(True, which="both", alpha=0.3)
            fig.canvas.draw()  # the labels' extents need the axes' final scales
            chosen = sorted((r for r in subset if id(r) in labelled), key=lambda r: -r["lobe_error"][band])
            items = [(short(r), (r["ns_per_eval"], r["lobe_error"][band])) for r in chosen]
            # The reference's points say only their path count.
            items += [
                (f"{r['options']['samples']} paths", (r["ns_per_eval"], r["lobe_error"][band]))
                for r in subset
                if r["model"] == "reference" and id(r) not in labelled
            ]
            place_labels(ax, items)
        row_axes[0].set_ylabel(f"mean relative L1 lobe error vs the reference ({name})")
    # An error bar as wide as its point (the tabulated model sits at the reference's noise) would reach zero.
    axes[0, 0].set_ylim(bottom=2e-3)
    # The tabulated model's cost is per evaluation after a precomputation of its own per stack (docs/validation.md);
    # so are the improved variants': their fit starts from the same adding-doubling solution (transport_fit).
    names = {"tabulated": "tabulated (after a per-stack precomputation, 0.1–2 s)", "reference": "reference (paths)"}
    handles = [plt.Line2D([], [], marker="o", ls="", color=c, label=names.get(m, m)) for m, c in COLOURS.items()]
    variants = {
        "published": "published",
        "default": "lamina's defaults",
        "improved": "improved (tabulated's precomputation + a fit < 0.1 s)",
    }
    handles += [
        plt.Line2D(
            [], [], marker=MARKERS[v], ls="", color="grey", ms=10 if v == "improved" else 6, label=variants.get(v, v)
        )
        for v in MARKERS
        if v != "paths"
    ]
    gpus = sorted({r["label"].split(" GPU ")[1].strip("()") for r in rows if r.get("device") == "gpu"})
    handles += [
        plt.Line2D([], [], marker="o", ls="", color="grey", mfc="none", label=f"hollow: GPU ({', '.join(gpus)})"),
        plt.Line2D([], [], ls="--", color="grey", label="Pareto front (labelled)"),
        plt.Line2D([], [], ls="-", marker=">", color="grey", label="published → improved (labelled)"),
    ]
    fig.legend(handles=handles, loc="outside lower center", ncol=7, fontsize=8)
    fig.suptitle(
        "lamina: speed against accuracy (colour: model; marker: variant. Error bars: the reference's own relative "
        "standard error; the reference at several path counts on the suite only)"
    )
    fig.savefig(path, dpi=120)


def main() -> None:
    out = ROOT / "docs" / "speed_accuracy.json"
    if sys.argv[1:] == ["--plot"]:  # redraw the figure from the JSON
        plot(json.loads(out.read_text())["rows"], ROOT / "docs" / "speed_accuracy.png")
        return
    sets = {"suite": suite_set(), "population": population_set()}
    rows = model_rows(sets) + principled_rows(sets) + reference_rows(sets["suite"])
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
