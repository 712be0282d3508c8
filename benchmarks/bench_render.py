"""Rendering throughput: material balls per second at 256² under one directional light, and environment-lit samples
per second under the built-in sky, for each model; beside Mitsuba 3 rendering the same ball (a unit
sphere, orthographic camera, 256², one sample per pixel) with its `roughconductor` under a directional light, and
with an `envmap` of the same sky map through its `path` integrator (max depth 2), in the same run: `llvm_ad_rgb` by
default, `cuda_ad_rgb` with LAMINA_BENCH_MITSUBA=cuda_ad_rgb (scripts/device_check.sh, on an NVIDIA GPU). lamina's
CPU renderer, and its GPU path (both lights, and a batch of BATCH balls in one call: one dispatch) on whatever adapter
wgpu finds. Writes the "render" section of docs/benchmarks.md, or "render-hardware" on a hardware GPU. Not a test:
nothing is asserted. Oat 2006's full technique at 1024² (no peer implements it: lamina's CPU and GPU side by side,
against the chapter's real time).
Run: make bench   (LAMINA_BENCH_QUICK=1: one round, the GPU rows, the CPU's directional rows and no reference, for
scripts/device_check.sh)"""

from __future__ import annotations

import os
import platform

import lamina
import numpy as np
from bench_conductor import ETA, REPEATS, K, measure_all
from docs_section import write_section
from lamina import materials, oat
from lamina import renderer as R

QUICK = os.environ.get("LAMINA_BENCH_QUICK") == "1"
SIZE = 256
ENV_SPP = 16
BATCH = 16
#: A batch large enough to measure balls/s on a hardware GPU (the issue's goal: ≥ 1000 balls/s at 256², one dispatch).
BIG_BATCH = 256
OAT_SIZE = 1024
LIGHT = R.DirectionalLight((-0.4, 0.5, 0.8), (2.0, 1.5, 1.0))
#: The Mitsuba 3 variant of the peer.
MITSUBA = os.environ.get("LAMINA_BENCH_MITSUBA", "llvm_ad_rgb")
#: (label, stack, model, options)
CASES = [
    ("gold, 1 layer", "gold", "microfacet", {}),
    ("coated copper, 2 layers", "rough-coat-rough-copper", "belcour", {}),
    ("coated copper, 2 layers", "rough-coat-rough-copper", "steinberg", {}),
    ("coated copper, 2 layers", "rough-coat-rough-copper", "weidlich_wilkie", {}),
    ("coated copper, 2 layers", "rough-coat-rough-copper", "albedo_scaling", {}),
    ("coated copper, 2 layers", "rough-coat-rough-copper", "tabulated", {}),
    ("coated copper, 2 layers", "rough-coat-rough-copper", "steinberg", {"variant": "improved"}),
    ("coated copper, 2 layers", "rough-coat-rough-copper", "reference", {}),
]


def stack(name: str):
    return materials.preset(name) if name in materials.PRESETS else materials.suite(name)


def mitsuba_scene(env: np.ndarray | None):
    """The ball in Mitsuba 3: roughconductor (GGX α = 0.3, lamina's benchmark IOR) on the unit sphere, orthographic
    camera over [−1, 1]², one sample per pixel (box filter); the directional light or the sky map."""
    import mitsuba as mi

    mi.set_variant(MITSUBA)
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
    sky = R.sky()
    fns, balls = {}, {}
    for label, name, model, options in CASES:
        if QUICK and model == "reference":
            continue
        s = stack(name)
        s.eval([0, 0, 1], [0, 0, 1], model, **options)  # the tables (tabulated's, the fit) before any timing
        key = f"lamina {model}{''.join(f' {k}={v!r}' for k, v in options.items())}: {label}"
        fns[key + ", directional"] = lambda s=s, m=model, o=options: R.render(
            s, m, width=SIZE, height=SIZE, lights=[LIGHT], **o
        )
        if not QUICK:
            fns[key + f", sky {ENV_SPP} spp"] = lambda s=s, m=model, o=options: R.render(
                s, m, width=SIZE, height=SIZE, lights=[sky], spp=ENV_SPP, **o
            )
    adapter = lamina.gpu.adapter()
    for label, name, model, options in CASES:
        if adapter is not None and model in lamina.gpu.models():
            s = stack(name)
            extra = "".join(f" {k}={v!r}" for k, v in options.items())
            key = f"lamina {model}{extra} on the GPU ({adapter['name']}): {label}"
            fns[key + ", directional"] = lambda s=s, m=model, o=options: R.render(
                s, m, width=SIZE, height=SIZE, lights=[LIGHT], device="gpu", **o
            )
            fns[key + f", sky {ENV_SPP} spp"] = lambda s=s, m=model, o=options: R.render(
                s, m, width=SIZE, height=SIZE, lights=[sky], spp=ENV_SPP, device="gpu", **o
            )
            for n in (BATCH, BIG_BATCH):
                batch = key.replace(": ", f": {n} balls of ") + ", directional"
                balls[batch] = n
                fns[batch] = lambda s=s, m=model, o=options, n=n: R.render(
                    [s] * n, m, width=SIZE, height=SIZE, lights=[LIGHT], device="gpu", **o
                )
    try:
        import mitsuba as mi

        directional, envlit = mitsuba_scene(None), mitsuba_scene(sky.map)
        fns[f"Mitsuba 3 {MITSUBA} roughconductor, directional"] = lambda: np.array(mi.render(directional, seed=0))
        fns[f"Mitsuba 3 {MITSUBA} roughconductor, sky {ENV_SPP} spp"] = lambda: np.array(mi.render(envlit, seed=0))
        missing = None
    except Exception as error:  # noqa: BLE001 (no Mitsuba on the device check's machine: the page says so)
        missing = f"{type(error).__name__}: {error}"
    times = {k: (float(np.median(t)), cold) for k, (t, cold) in measure_all(fns, 1 if QUICK else REPEATS).items()}
    peer = (
        {
            "directional": times[f"Mitsuba 3 {MITSUBA} roughconductor, directional"][0],
            "sky": times[f"Mitsuba 3 {MITSUBA} roughconductor, sky {ENV_SPP} spp"][0],
        }
        if missing is None
        else None
    )
    hardware = adapter is not None and adapter["device_type"] != "Cpu"
    lines = [
        "## Rendering: material balls" + (" on a hardware GPU" if hardware else " on the CPU"),
        "",
        "Generated by `benchmarks/bench_render.py` (`make bench`); do not edit by hand. Not a test. "
        f"{SIZE}² balls, orthographic camera, one ray per pixel. Directional: one light, exact (no samples); "
        f"sky: the built-in sky and sun, {ENV_SPP} samples per pixel (each one light and one BSDF sample, MIS; the "
        "reference: one walk per channel). Mitsuba 3 renders the same ball with `roughconductor` (one lobe) through "
        "`direct` (directional, 1 spp) or `path` with max depth 2 (its `envmap` of the same sky map, "
        f"{ENV_SPP} spp), `np.array(mi.render(scene))` as its users call it. Median of the round-robin runs after a "
        "cold call (Mitsuba's includes compiling its kernels). GPU rows: `device='gpu'` on the adapter named, "
        "including the upload of the tables and the read-back of the images, which the last column reports on its "
        "own (`lamina.gpu.readback_seconds` of the same bytes); the batch rows render a list of stacks in one call "
        f"(one dispatch).{' Quick run (LAMINA_BENCH_QUICK=1): one round.' if QUICK else ''}",
        "",
        "| renderer | light | median (s) | balls/s | samples/s | throughput ratio to Mitsuba (same light) | "
        "of which read-back (s) |",
        "|---|---|---:|---:|---:|---:|---:|",
    ]
    for key, (t, _cold) in times.items():
        kind = "directional" if key.endswith("directional") else "sky"
        ball, light = key.rsplit(", ", 1)
        n = balls.get(key, 1)
        samples = n * SIZE * SIZE * (1 if kind == "directional" else ENV_SPP)
        ratio = f"{n * peer[kind] / t:.2f}x" if peer else "—"
        back = f"{lamina.gpu.readback_seconds(12 * n * SIZE * SIZE):.4f}" if "on the GPU" in key else "—"
        lines.append(f"| {ball} | {light} | {t:.3f} | {n / t:,.2f} | {samples / t:,.0f} | {ratio} | {back} |")
    lines += ["", *oat_rows(adapter)]
    lines += [
        "",
        f"Mitsuba 3 {MITSUBA}: {1 / peer['directional']:,.2f} balls/s directional, "
        f"{SIZE * SIZE * ENV_SPP / peer['sky']:,.0f} samples/s under the sky."
        if peer
        else f"Mitsuba 3 {MITSUBA} did not run here ({missing}): no ratios.",
        "",
        f"Machine: {platform.processor() or platform.machine()}, {os.cpu_count()} logical CPUs, "
        f"lamina {lamina.__version__}" + (f", Mitsuba {mi.__version__}." if peer else "."),
    ]
    print("\n".join(lines))
    print(f"wrote {write_section('benchmarks.md', 'Benchmarks', 'render-hardware' if hardware else 'render', lines)}")


def oat_rows(adapter) -> list[str]:
    """Oat 2006's gooey ball, variant "full" (texture-space light map, blurred; parallax) at OAT_SIZE², one
    directional light: lamina's CPU and GPU (with the read-back of the frame on its own), against the chapter's real
    time, which the issue puts at < 2 ms per frame on a hardware GPU."""
    m = oat.Material(**oat.organic_textures(512, seed=1), thickness=3.0)
    light = [R.DirectionalLight((-0.5, 0.6, 0.8), (3.0, 3.0, 3.0))]
    fns = {"CPU": lambda: R.render(material=m, width=OAT_SIZE, height=OAT_SIZE, lights=light, progress=False)}
    if adapter is not None:
        fns[f"GPU ({adapter['name']})"] = lambda: R.render(
            material=m, width=OAT_SIZE, height=OAT_SIZE, lights=light, device="gpu"
        )
    times = measure_all(fns, 1 if QUICK else 3)
    rows = [
        f"Oat 2006's full technique (light map, blur, parallax), {OAT_SIZE}², one directional light, lamina's own "
        "CPU and GPU (no peer implements the chapter); the goal on a hardware GPU is < 2 ms per frame.",
        "",
        "| device | median (ms per frame) | of which read-back (ms) |",
        "|---|---:|---:|",
    ]
    for key, (t, _cold) in times.items():
        back = f"{1e3 * lamina.gpu.readback_seconds(12 * OAT_SIZE**2):.2f}" if key != "CPU" else "—"
        rows.append(f"| {key} | {1e3 * float(np.median(t)):.1f} | {back} |")
    return rows


if __name__ == "__main__":
    main()
