"""Command line: `lamina plot` writes BRDF slices of a preset material as a PNG; `lamina presets` lists them."""

from __future__ import annotations

import argparse
from pathlib import Path

from . import materials
from .catalogue import MODELS


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="lamina", description=__doc__)
    sub = parser.add_subparsers(dest="command", required=True)
    p = sub.add_parser("plot", help="write in-plane BRDF slices of a preset material to a PNG")
    p.add_argument("--material", default="gold", choices=sorted(materials.PRESETS))
    p.add_argument("--model", default="microfacet", choices=MODELS)
    p.add_argument("--out", default="out", help="output directory (default: out)")
    p.add_argument("--thetas", default="0,30,60,80", help="incident zenith angles in degrees (comma separated)")
    sub.add_parser("presets", help="list the preset materials")
    args = parser.parse_args(argv)

    if args.command == "presets":
        for name in sorted(materials.PRESETS):
            print(f"{name:20s} {materials.preset(name)!r}")
        return 0

    from .plot import brdf_slices

    thetas = [float(t) for t in args.thetas.split(",")]
    fig = brdf_slices(
        materials.preset(args.material), thetas, model=args.model, title=f"lamina {args.model}: {args.material}"
    )
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    path = out / f"{args.material}_{args.model}_slices.png"
    fig.savefig(path, dpi=130)
    print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
