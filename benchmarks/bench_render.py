"""Rendering throughput: material balls per second at 256² under one directional light, and environment-lit samples
per second under the built-in sky, for each model; beside Mitsuba 3 `llvm_ad_rgb` rendering the same ball (a unit
sphere, orthographic camera, 256², one sample per pixel) with its `roughconductor` under a directional light, and
with an `envmap` of the same sky map through its `path` integrator (max depth 2), in the same run. lamina's CPU
renderer, and its GPU path (both lights, and a batch of BATCH balls in one call: one dispatch) on whatever adapter
wgpu finds. Writes the "render" section of
docs/benchmarks.md. Not a test: nothing is asserted.
Run: make bench"""

from __future__ import annotations

import platform

import lamina
import numpy as np
from bench_conductor import ETA, K, measure
from docs_section import write_section
from lamina import materials
from lamina import renderer as R

SIZE = 256
ENV_SPP = 16
BATCH = 16
LIGHT = R.DirectionalLight((-0.4, 0.5, 0.8), (2.0, 1.5, 1.0))
#: (label, stack, model)
CASES = [
    ("gold, 1 layer", "gold", "microfacet"),
    ("coated copper, 2 layers", "rough-coat-rough-copper", "belcour"),
    ("coated copper, 2 layers", "rough-coat-rough-copper", "steinberg"),
    ("coated copper, 2 layers", "rough-coat-rough-copper", "weidlich_wilkie"),
    ("coated copper, 2 layers", "rough-coat-rough-copper", "albedo_scaling"),
    ("coated copper, 2 layers", "rough-coat-rough-copper", "reference"),
]


def stack(name: str):
    return materials.preset(name) if name in materials.PRESETS else materials.suite(name)


def mitsuba_scene(env: np.ndarray | None):
    """The ball in Mitsuba 3: roughconductor (GGX α = 0.3, lamina's benchmark IOR) on the unit sphere, orthographic
    camera over [−1, 1]², one sample per pixel (box filter); the directional light or the sky map."""
    import mitsuba as mi

    mi.set_variant("llvm_ad_rgb")
    spp = 1 if env is None else ENV_SPP
    d = np.asarray(LIGHT.direction) / np.linalg.norm(LIGHT.direction)
    light = (
        {
            "type": "directional",
            "direction": (-d).tolist(),
            "irradiance": {"type": "rgb", "value": list(LIGHT.irradiance)},
        }
        if env is None
        else {"type": "envmap", "bitmap": mi.Bitmap(env.astype(np.float32))}
    )
    return mi.load_dict(
        {
            "type": "scene",
            "integrator": {"type": "direct"} if env is None else {"type": "path", "max_depth": 2},
            "sensor": {
                "type": "orthographic",
                "to_world": mi.ScalarTransform4f().look_at(origin=[0, 0, 10], target=[0, 0, 0], up=[0, 1, 0]),
                "film": {"type": "hdrfilm", "width": SIZE, "height": SIZE, "rfilter": {"type": "box"}},
                "sampler": {"type": "independent", "sample_count": spp},
            },
            "ball": {
                "type": "sphere",
                "bsdf": {
                    "type": "roughconductor",
                    "alpha": 0.3,
                    "eta": {"type": "rgb", "value": list(ETA)},
                    "k": {"type": "rgb", "value": list(K)},
                },
            },
            "light": light,
        }
    )


def main() -> None:
    import mitsuba as mi

    sky = R.sky()
    fns = {}
    for label, name, model in CASES:
        s = stack(name)
        key = f"lamina {model}: {label}"
        fns[key + ", directional"] = lambda s=s, m=model: R.render(s, m, width=SIZE, height=SIZE, lights=[LIGHT])
        fns[key + f", sky {ENV_SPP} spp"] = lambda s=s, m=model: R.render(
            s, m, width=SIZE, height=SIZE, lights=[sky], spp=ENV_SPP
        )
    adapter = lamina.gpu.adapter()
    for label, name, model in CASES:
        if adapter is not None and model in lamina.gpu.models():
            s = stack(name)
            key = f"lamina {model} on the GPU ({adapter['name']}): {label}"
            fns[key + ", directional"] = lambda s=s, m=model: R.render(
                s, m, width=SIZE, height=SIZE, lights=[LIGHT], device="gpu"
            )
            fns[key + f", sky {ENV_SPP} spp"] = lambda s=s, m=model: R.render(
                s, m, width=SIZE, height=SIZE, lights=[sky], spp=ENV_SPP, device="gpu"
            )
            fns[key.replace(": ", f": {BATCH} balls of ") + ", directional"] = lambda s=s, m=model: R.render(
                [s] * BATCH, m, width=SIZE, height=SIZE, lights=[LIGHT], device="gpu"
            )
    directional, envlit = mitsuba_scene(None), mitsuba_scene(sky.map)
    fns["Mitsuba 3 llvm_ad_rgb roughconductor, directional"] = lambda: np.array(mi.render(directional, seed=0))
    fns[f"Mitsuba 3 llvm_ad_rgb roughconductor, sky {ENV_SPP} spp"] = lambda: np.array(mi.render(envlit, seed=0))
    times = measure(fns)
    peer = {
        "directional": times["Mitsuba 3 llvm_ad_rgb roughconductor, directional"][0],
        "sky": times[f"Mitsuba 3 llvm_ad_rgb roughconductor, sky {ENV_SPP} spp"][0],
    }
    lines = [
        "## Rendering: material balls on the CPU",
        "",
        "Generated by `benchmarks/bench_render.py` (`make bench`); do not edit by hand. Not a test. "
        f"{SIZE}² balls, orthographic camera, one ray per pixel. Directional: one light, exact (no samples); "
        f"sky: the built-in sky and sun, {ENV_SPP} samples per pixel (each one light and one BSDF sample, MIS; the "
        "reference: one walk per channel). Mitsuba 3 renders the same ball with `roughconductor` (one lobe) through "
        "`direct` (directional, 1 spp) or `path` with max depth 2 (its `envmap` of the same sky map, "
        f"{ENV_SPP} spp), `np.array(mi.render(scene))` as its users call it. Median of the round-robin runs after a "
        "cold call (Mitsuba's includes compiling its kernels). GPU rows: `device='gpu'` on the adapter named, "
        "including the upload of the tables and the read-back of the image; the batch rows render a list of "
        f"{BATCH} stacks in one call (one dispatch).",
        "",
        "| renderer | light | median (s) | balls/s | samples/s | throughput ratio to Mitsuba (same light) |",
        "|---|---|---:|---:|---:|---:|",
    ]
    for name, (t, _cold) in times.items():
        kind = "directional" if name.endswith("directional") else "sky"
        ball, light = name.rsplit(", ", 1)
        balls = BATCH if f"{BATCH} balls of" in name else 1
        samples = balls * SIZE * SIZE * (1 if kind == "directional" else ENV_SPP)
        ratio = balls * peer[kind] / t
        lines.append(f"| {ball} | {light} | {t:.3f} | {balls / t:,.2f} | {samples / t:,.0f} | {ratio:.2f}x |")
    lines += [
        "",
        f"Mitsuba 3: {1 / peer['directional']:,.2f} balls/s directional, "
        f"{SIZE * SIZE * ENV_SPP / peer['sky']:,.0f} samples/s under the sky.",
        "",
        f"Machine: {platform.processor() or platform.machine()}, lamina {lamina.__version__}, "
        f"Mitsuba {mi.__version__}.",
    ]
    print("\n".join(lines))
    print(f"wrote {write_section('benchmarks.md', 'Benchmarks', 'render', lines)}")


if __name__ == "__main__":
    main()
