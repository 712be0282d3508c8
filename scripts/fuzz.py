"""Fuzzes every analytic model (not a test; `make fuzz`): evaluates at least 1e8 direction pairs per model over random
stacks that include the extremes (roughness 0, 1e-6 and 1; IORs near 1; thick and strongly scattering slabs) with
directions that include exactly normal and exactly grazing ones, wi == wo, mirror pairs and float32/float64
denormal z, under every model option, in float64 and float32 (half each: float32 directions take the models' float32
lanes where they have them), and counts NaN, Inf and negative values. Writes docs/fuzz.json, which
scripts/reliability.py renders into docs/reliability.md.

    python scripts/fuzz.py [--pairs 1e8] [--seed 0]
"""

from __future__ import annotations

import argparse
import itertools
import json
import time
from pathlib import Path

import lamina
import numpy as np
from lamina import Conductor, Dielectric, Diffuse, Stack

ROOT = Path(__file__).resolve().parents[1]
BATCH = 1 << 20

#: Option sets per model: every value of every option, one option changed at a time from the defaults.
OPTION_SETS = {
    "microfacet": [
        {},
        {"distribution": "beckmann"},
        {"g2": "separable"},
        {"g2": "v_cavity"},
        {"fresnel": "schlick"},
        {"fresnel": "lazanyi"},
    ],
    "belcour": [
        {},
        {"symmetric": True},
        {"tir": "transmittance"},
        {"tir": "fraction"},
        {"cosines": "real"},
        {"jacobian": "j21"},
        {"energy": "fresnel"},
        {"interpolated": False},
        {"g2": "separable"},
        {"variant": "improved"},
    ],
    "steinberg": [
        {},
        {"lut": "fitted"},
        {"fresnel": "lazanyi"},
        {"fresnel": "schlick"},
        {"clamp_roughness": False},
        {"eta2": False},
        {"g2": "v_cavity"},
        {"variant": "improved"},
    ],
    "weidlich_wilkie": [
        {},
        {"precomputed": True},
        {"fresnel": "lazanyi"},
        {"distribution": "ggx"},
        {"g2": "height_correlated"},
        {"clamp_roughness": False, "eta2": False},
        {"variant": "improved"},
    ],
    "albedo_scaling": [{}, {"scaling": "view"}, {"g2": "height_correlated"}],
    "tabulated": [{}, {"distribution": "beckmann"}],
}


def _pick(rng, *choices):
    return choices[rng.integers(len(choices))]


def _roughness(rng):
    a = _pick(rng, 0.0, 1e-6, 1.0, float(rng.random()), float(rng.random()) ** 3)
    return (a, a) if rng.random() < 0.6 else (a, float(_pick(rng, 0.0, 1e-6, 1.0, rng.random())))


def random_stack(rng) -> Stack:
    """A random stack of 0–3 dielectric layers over a conductor or diffuse base, extremes included."""
    layers = []
    for _ in range(rng.integers(0, 4)):
        layers.append(
            Dielectric(
                ior=float(_pick(rng, 1.0 + 1e-9, 1.0001, 1.0 + 2 * rng.random(), 0.8 + 0.4 * rng.random(), 3.0)),
                roughness=_roughness(rng),
                angle=float(rng.uniform(-4, 4)),
                thickness=float(_pick(rng, 0.0, 1e-6, 5 * rng.random(), 1e4)),
                sigma_a=float(_pick(rng, 0.0, 10 * rng.random(), 1e6)),
                sigma_s=float(_pick(rng, 0.0, 10 * rng.random(), 1e6)),
                g=float(_pick(rng, 0.0, 0.999, -0.999, rng.uniform(-0.9, 0.9))),
            )
        )
    if rng.random() < 0.6:
        layers.append(
            Conductor(
                ior=float(_pick(rng, 0.05, 1.0, 3 * rng.random() + 0.01)),
                k=float(_pick(rng, 0.0, 10 * rng.random(), 10.0)),
                roughness=_roughness(rng),
                angle=float(rng.uniform(-4, 4)),
            )
        )
    else:
        layers.append(
            Diffuse(
                albedo=float(_pick(rng, 0.0, 1.0, rng.random())), roughness=float(_pick(rng, 0.0, 1.0, rng.random()))
            )
        )
    return Stack(layers, ext_ior=float(_pick(rng, 1.0, 1.0, 1.33)))


def directions(rng, n: int, dtype) -> tuple[np.ndarray, np.ndarray]:
    """n pairs mixing random hemisphere directions with the special ones."""
    tiny = np.finfo(dtype).smallest_subnormal * 4
    wi = rng.normal(size=(n, 3))
    wo = rng.normal(size=(n, 3))
    wi[:, 2], wo[:, 2] = np.abs(wi[:, 2]), np.abs(wo[:, 2])
    kind = rng.integers(0, 8, size=n)
    wi[kind == 1] = (0.0, 0.0, 1.0)  # exactly normal
    wo[kind == 2, 2] = 0.0  # exactly grazing
    wo[kind == 3] = wi[kind == 3]  # wi == wo
    m = kind == 4
    wo[m] = wi[m] * (-1.0, -1.0, 1.0)  # mirror pair
    wi[kind == 5, 2] = tiny  # denormal z
    m = kind == 6
    wi[m, 2], wo[m] = tiny, wi[m] * (-1.0, -1.0, 1.0)  # grazing mirror pair with denormal z
    wi[kind == 7, 2] = -np.abs(wi[kind == 7, 2])  # below the horizon
    return wi.astype(dtype), wo.astype(dtype)


def fuzz_model(model: str, pairs: float, seed: int) -> list[dict]:
    rows = []
    variants = OPTION_SETS[model]
    per_variant = int(pairs) // len(variants)
    for v, opts in enumerate(variants):
        rng = np.random.default_rng([seed, v, len(model)])
        counts = dict(evaluations=0, float32=0, nan=0, inf=0, negative=0, stacks=0, rejected=0)
        start = time.perf_counter()
        while counts["evaluations"] < per_variant:
            stack = random_stack(rng)
            if model == "microfacet" and not (len(stack.layers) == 1):
                stack = Stack(stack.layers[-1:])
            try:
                stack.eval([0, 0, 1.0], [0, 0, 1.0], model, **opts)
            except ValueError:
                counts["rejected"] += 1  # the model cannot represent this stack, and says so
                continue
            counts["stacks"] += 1
            for dtype in (np.float64, np.float32):
                wi, wo = directions(rng, BATCH // 2, dtype)
                f = stack.eval(wi, wo, model, **opts)
                counts["evaluations"] += len(wi)
                counts["float32"] += len(wi) if dtype == np.float32 else 0
                counts["nan"] += int(np.isnan(f).any(axis=-1).sum())
                counts["inf"] += int(np.isinf(f).any(axis=-1).sum())
                counts["negative"] += int((f < 0).any(axis=-1).sum())
                bad = ~np.isfinite(f).all(axis=-1) | (f < 0).any(axis=-1)
                if bad.any() and "example" not in counts:  # the first failure, to reproduce it
                    k = int(np.argmax(bad))
                    counts["example"] = dict(
                        stack=repr(stack),
                        dtype=np.dtype(dtype).name,
                        wi=wi[k].tolist(),
                        wo=wo[k].tolist(),
                        f=f[k].tolist(),
                    )
        options = ", ".join(f"{k}={v!r}" for k, v in opts.items()) or "defaults"
        rows.append(dict(model=model, options=options, seconds=round(time.perf_counter() - start, 1), **counts))
        print(f"{model:16s} {options:40s} {counts}", flush=True)
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--pairs", type=float, default=1e8, help="direction pairs per model (default 1e8)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", type=Path, default=ROOT / "docs" / "fuzz.json")
    args = ap.parse_args()
    rows = list(
        itertools.chain.from_iterable(fuzz_model(m, args.pairs, args.seed) for m in lamina.MODELS if m != "reference")
    )
    args.out.write_text(
        json.dumps(
            {"pairs_per_model": args.pairs, "seed": args.seed, "lamina": lamina.__version__, "rows": rows}, indent=1
        )
        + "\n"
    )
    bad = sum(r["nan"] + r["inf"] + r["negative"] for r in rows)
    print(f"wrote {args.out}: {sum(r['evaluations'] for r in rows):.3g} evaluations, {bad} NaN/Inf/negative")


if __name__ == "__main__":
    main()
