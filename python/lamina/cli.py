"""Command line: `lamina render` renders a material ball (PNG and EXR); `lamina gallery` renders every layered model
beside the reference with error heatmaps; `lamina plot` writes BRDF slices of a preset material as a PNG;
`lamina presets` lists them; `lamina models` lists the models and their options."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from . import __version__, materials
from .catalogue import MODELS, models


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="lamina", description=__doc__)
    parser.add_argument("--version", action="version", version=f"lamina {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)
    p = sub.add_parser("plot", help="write BRDF slices of a preset material (PNG, PDF or SVG)")
    p.add_argument(
        "--material",
        default="gold",
        choices=sorted(materials.PRESETS),
        help="preset material (default: gold; `lamina presets` lists them)",
    )
    p.add_argument(
        "--model",
        default="microfacet",
        help="model to evaluate, or several separated by commas, overlaid (default: microfacet; `lamina models`)",
    )
    p.add_argument(
        "--reference", type=int, default=None, help="overlay the reference with this many paths per direction (±2 SE)"
    )
    p.add_argument("--plane", default="incidence", choices=("incidence", "perpendicular"), help="plane of wo")
    p.add_argument("--format", default="png", choices=("png", "pdf", "svg"), help="file format (default: png)")
    p.add_argument("--out", default="out", help="output directory (default: out)")
    p.add_argument(
        "--thetas",
        default="0,30,60,80",
        help="incident zenith angles in degrees, comma separated (default: 0,30,60,80)",
    )
    r = sub.add_parser("render", help="render a material ball under the built-in sky and sun (PNG and EXR)")
    r.add_argument("--material", default="car-paint", choices=sorted(materials.PRESETS), help="preset material")
    r.add_argument("--model", default="belcour", choices=MODELS, help="model, or reference (default: belcour)")
    r.add_argument("--size", type=int, default=256, help="image width and height in pixels (default: 256)")
    r.add_argument("--spp", type=int, default=64, help="environment samples per pixel (default: 64)")
    r.add_argument("--seed", type=int, default=0, help="random seed (default: 0)")
    r.add_argument("--exposure", type=float, default=0.0, help="exposure of the PNG in stops (default: 0)")
    r.add_argument("--out", default="out", help="output directory (default: out)")
    g = sub.add_parser("gallery", help="render every layered model beside the reference, with error heatmaps")
    g.add_argument("--out", default="out", help="output directory (default: out)")
    g.add_argument("--size", type=int, default=128, help="ball size in pixels (default: 128)")
    g.add_argument("--spp", type=int, default=32, help="environment samples per pixel of the models (default: 32)")
    g.add_argument("--reference-spp", type=int, default=64, help="reference walks per pixel and channel (default: 64)")
    g.add_argument("--docs", default=None, help="also write the PNGs into this folder (make demo: docs)")
    sub.add_parser("presets", help="list the preset materials")
    sub.add_parser("models", help="list the models, their options and per-element inputs")
    return parser


def _plot(args) -> str:
    try:
        from .plot import brdf_slices
    except ImportError:
        raise SystemExit("lamina plot needs matplotlib: pip install lamina[plot]") from None
    try:
        thetas = [float(t) for t in args.thetas.split(",")]
    except ValueError:
        raise ValueError(f"--thetas must be comma-separated numbers in degrees, got {args.thetas!r}") from None
    models = args.model.split(",")
    unknown = [m for m in models if m not in MODELS]
    if unknown:
        raise ValueError(f"--model must be among {list(MODELS)}, got {unknown[0]!r}")
    stack = materials.preset(args.material)
    fig = brdf_slices(
        stack, thetas, model=models, title=f"lamina: {args.material}", plane=args.plane, reference=args.reference
    )
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    path = out / f"{args.material}_{'+'.join(models)}_slices.{args.format}"
    fig.savefig(path, dpi=130)
    return f"wrote {path}"


def _render(args) -> str:
    import time

    from .renderer import render, save_image

    stack = materials.preset(args.material)
    # Car paint's sparkle: per-element flake normals, which weidlich_wilkie takes.
    flakes = args.material == "car-paint" and args.model == "weidlich_wilkie"
    inputs = {"flake_normal": materials.flake_texture()} if flakes else {}
    start = time.perf_counter()
    image = render(stack, args.model, width=args.size, height=args.size, spp=args.spp, seed=args.seed, **inputs)
    seconds = time.perf_counter() - start
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    stem = out / f"{args.material}_{args.model}"
    save_image(stem.with_suffix(".png"), image, exposure=args.exposure)
    save_image(stem.with_suffix(".exr"), image)
    return f"rendered on the CPU in {seconds:.2f} s: wrote {stem}.png and {stem}.exr"


def _gallery(args) -> str:
    try:
        import matplotlib  # noqa: F401

        from .pictures import write_gallery
    except ImportError:
        raise SystemExit("lamina gallery needs matplotlib: pip install lamina[plot]") from None
    path = write_gallery(args.out, size=args.size, spp=args.spp, reference_spp=args.reference_spp, docs=args.docs)
    return f"wrote {path}"


def main(argv=None) -> int:
    args = _parser().parse_args(argv)
    try:
        if args.command == "presets":
            print("\n".join(f"{name:20s} {materials.preset(name)!r}" for name in sorted(materials.PRESETS)))
        elif args.command == "models":
            for m in models():
                print(f"{m.name}: {m.summary}")
                for o in m.options.values():
                    print(f"    {o.name} = {o.default!r} ({o.allowed()}): {o.doc}")
                for i in m.inputs.values():
                    print(f"    per element {i.name}: {i.doc}")
        elif args.command == "render":
            print(_render(args))
        elif args.command == "gallery":
            print(_gallery(args))
        else:
            print(_plot(args))
    except (ValueError, TypeError) as e:  # bad input: one clear line, no traceback
        print(f"lamina: error: {e}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
