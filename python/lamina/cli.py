"""Command line: `lamina plot` writes BRDF slices of a preset material as a PNG; `lamina presets` lists them;
`lamina models` lists the models and their options."""

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
    p = sub.add_parser("plot", help="write in-plane BRDF slices of a preset material to a PNG")
    p.add_argument(
        "--material",
        default="gold",
        choices=sorted(materials.PRESETS),
        help="preset material (default: gold; `lamina presets` lists them)",
    )
    p.add_argument(
        "--model",
        default="microfacet",
        choices=MODELS,
        help="model to evaluate (default: microfacet; `lamina models` lists them)",
    )
    p.add_argument("--out", default="out", help="output directory (default: out)")
    p.add_argument(
        "--thetas",
        default="0,30,60,80",
        help="incident zenith angles in degrees, comma separated (default: 0,30,60,80)",
    )
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
    stack = materials.preset(args.material)
    fig = brdf_slices(stack, thetas, model=args.model, title=f"lamina {args.model}: {args.material}")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    path = out / f"{args.material}_{args.model}_slices.png"
    fig.savefig(path, dpi=130)
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
        else:
            print(_plot(args))
    except (ValueError, TypeError) as e:  # bad input: one clear line, no traceback
        print(f"lamina: error: {e}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
