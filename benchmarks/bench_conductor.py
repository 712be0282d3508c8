"""Throughput of lamina's rough conductor against Mitsuba 3 `llvm_ad_rgb` `roughconductor` and a NumPy
implementation of the same formula, on the same random (wi, wo) pairs, measured in one process, at 1 and 2 threads.

Each side is timed as its users call it. lamina: `Stack.eval` on NumPy arrays, everything included (broadcasting,
validation, gather, the output array). Mitsuba: `np.array(bsdf.eval(ctx, si, wo))` and nothing else, its inputs
built once as Dr.Jit arrays; it returns f·cos θ, lamina f: each its own natural quantity, nothing is charged to the
peer. The implementations alternate round-robin; each figure is the median of REPEATS runs after a cold call, with
the quartiles. Thread scaling: each thread count runs in a process of its own (RAYON_NUM_THREADS for lamina,
dr.set_thread_count for Mitsuba). Writes the "conductor" section of docs/benchmarks.md.
Run: make bench   (not a test: no timing is ever asserted)
"""

from __future__ import annotations

import json
import os
import platform
import subprocess
import sys
import time

import lamina
import numpy as np
from docs_section import write_section

N = int(os.environ.get("LAMINA_BENCH_N", 1_000_000))
REPEATS = 15
ETA, K, ALPHA = (0.2, 0.45, 1.4), (3.6, 2.5, 1.9), 0.3
MITSUBA = "Mitsuba 3 llvm_ad_rgb roughconductor (float32)"
ALONE = "lamina float32 in/out, before any Mitsuba call"
MEMCPY = "memcpy of the same bytes (36 per pair; the roofline)"
#: Seconds of untimed calls of an implementation before each of its timed calls. Dr.Jit's worker threads keep
#: spinning for about 20 ms after each of its calls (measured: 20 ms of CPU time on its "nt" threads in the second
#: after a call, none later); a call timed in that window shares the two cores with them and took 2x as long. Every
#: implementation gets the same settling, Mitsuba included (lamina's rayon workers spin too).
SETTLE = 0.03


def timed(fn) -> float:
    t0 = time.perf_counter()
    fn()
    return time.perf_counter() - t0


def settled(fn) -> float:
    """The time of one call of fn after SETTLE seconds of untimed calls of it."""
    t0 = time.perf_counter()
    while time.perf_counter() - t0 < SETTLE:
        fn()
    return timed(fn)


def measure_all(fns: dict, repeats: int = REPEATS) -> dict:
    """{name: (every time, first call)}: one cold call each, then `repeats` rounds that time every implementation
    in turn (round-robin, each call settled), so that machine noise falls on all of them alike."""
    cold = {name: timed(fn) for name, fn in fns.items()}
    times = {name: [] for name in fns}
    for _ in range(repeats):
        for name, fn in fns.items():
            times[name].append(settled(fn))
    return {name: (times[name], cold[name]) for name in fns}


def measure(fns: dict) -> dict:
    """{name: (median, first call)} of `measure_all`."""
    return {name: (float(np.median(t)), cold) for name, (t, cold) in measure_all(fns).items()}


def hemisphere(rng, n: int, min_cos: float = 0.05) -> np.ndarray:
    """n random directions above the surface (cos θ in [min_cos, 1])."""
    z = rng.uniform(min_cos, 1, n)
    p = rng.uniform(0, 2 * np.pi, n)
    s = np.sqrt(1 - z * z)
    return np.stack([s * np.cos(p), s * np.sin(p), z], -1)


def mitsuba_eval(bsdf, wi: np.ndarray, wo: np.ndarray):
    """Mitsuba's eval as its users call it: inputs built once as Dr.Jit arrays (wo as si.wi), then a closure that
    returns `np.array(bsdf.eval(ctx, si, wi))`: f·cos θi, shape (3, n)."""
    import drjit as dr
    import mitsuba as mi

    ctx = mi.BSDFContext()
    si = dr.zeros(mi.SurfaceInteraction3f, len(wo))
    si.wi = mi.Vector3f(np.ascontiguousarray(wo.T, dtype=np.float32))
    w = mi.Vector3f(np.ascontiguousarray(wi.T, dtype=np.float32))
    return lambda: np.array(bsdf.eval(ctx, si, w))


def numpy_conductor(wi, wo):
    """GGX rough conductor with exact Fresnel and separable Smith, written with NumPy (the NumPy peer)."""
    h = wi + wo
    h /= np.linalg.norm(h, axis=-1, keepdims=True)
    a2 = ALPHA * ALPHA
    d = 1 / (np.pi * a2 * ((h[:, 0] ** 2 + h[:, 1] ** 2) / a2 + h[:, 2] ** 2) ** 2)

    def g1(w):
        t2 = a2 * (w[:, 0] ** 2 + w[:, 1] ** 2) / w[:, 2] ** 2
        return 2 / (1 + np.sqrt(1 + t2))

    geo = d * g1(wi) * g1(wo) / (4 * wi[:, 2] * wo[:, 2])
    c = np.sum(wi * h, axis=-1)[:, None]
    eta, k = np.array(ETA), np.array(K)
    c2, s2 = c * c, 1 - c * c
    t0 = eta * eta - k * k - s2
    a2b2 = np.sqrt(t0 * t0 + 4 * eta * eta * k * k)
    a = np.sqrt(0.5 * (a2b2 + t0))
    rs = (a2b2 - 2 * a * c + c2) / (a2b2 + 2 * a * c + c2)
    rp = rs * (c2 * a2b2 - 2 * a * c * s2 + s2 * s2) / (c2 * a2b2 + 2 * a * c * s2 + s2 * s2)
    return geo[:, None] * 0.5 * (rs + rp)


def mitsuba_conductor(variant: str = "llvm_ad_rgb"):
    """Mitsuba 3's `roughconductor` (GGX, α = ALPHA, the RGB complex IOR ETA + iK) on `variant`: the peer."""
    import mitsuba as mi

    mi.set_variant(variant)
    return mi.load_dict(
        {
            "type": "roughconductor",
            "distribution": "ggx",
            "alpha": ALPHA,
            "eta": {"type": "rgb", "value": list(ETA)},
            "k": {"type": "rgb", "value": list(K)},
        }
    )


def worker(threads: int) -> dict:
    """Every implementation's times in this process, at `threads` threads."""
    import drjit as dr

    dr.set_thread_count(threads)
    rng = np.random.default_rng(1)
    wi64, wo64 = hemisphere(rng, N), hemisphere(rng, N)
    wi32, wo32 = wi64.astype(np.float32), wo64.astype(np.float32)
    stack = lamina.Stack([lamina.Conductor(ETA, K, ALPHA)])
    # lamina alone first, before Mitsuba has run in this process (its thread pool then shares the cores).
    alone = measure_all({ALONE: lambda: stack.eval(wi32, wo32, g2="separable")})
    # The memory roofline: a copy of the bytes an evaluation moves (two float32 directions in, three values out).
    src, dst = np.ones(9 * N, np.float32), np.empty(9 * N, np.float32)
    fns = {
        "lamina float32 in/out": lambda: stack.eval(wi32, wo32, g2="separable"),
        "lamina float64 in/out": lambda: stack.eval(wi64, wo64, g2="separable"),
        "lamina float32, fresnel='schlick'": lambda: stack.eval(wi32, wo32, g2="separable", fresnel="schlick"),
        MITSUBA: mitsuba_eval(mitsuba_conductor(), wi32, wo32),
        MEMCPY: lambda: np.copyto(dst, src),
    }
    if threads == 1:
        fns["NumPy float64 (one thread)"] = lambda: numpy_conductor(wi64, wo64)
    rows = {**alone, **measure_all(fns)}
    # Same answers before any figure is reported: Mitsuba's f·cos θi divided by cos θi here, outside its timing.
    a, b = stack.eval(wi64, wo64, g2="separable"), fns[MITSUBA]().T / wi32[:, 2:3]
    big = a > 1e-3 * a.max()
    schlick = stack.eval(wi64, wo64, g2="separable", fresnel="schlick")
    return {
        "rows": {name: {"times": t, "cold": cold} for name, (t, cold) in rows.items()},
        "agreement": float(np.max(np.abs(a[big] - b[big]) / a[big])),
        "schlick": float(np.max(np.abs(schlick[big] - a[big]) / a[big])),
    }


def main() -> None:
    if len(sys.argv) == 3 and sys.argv[1] == "--worker":
        print(json.dumps(worker(int(sys.argv[2]))))
        return
    runs = {}
    for threads in (1, 2):
        env = {**os.environ, "RAYON_NUM_THREADS": str(threads), "OPENBLAS_NUM_THREADS": "1"}
        out = subprocess.run(
            [sys.executable, __file__, "--worker", str(threads)], env=env, capture_output=True, text=True, check=True
        )
        runs[threads] = json.loads(out.stdout.strip().splitlines()[-1])
    import mitsuba as mi

    cpu = next((ln.split(":", 1)[1].strip() for ln in open("/proc/cpuinfo") if ln.startswith("model name")), "?")
    two = runs[2]
    lines = [
        "## Rough conductor: lamina vs Mitsuba 3 `roughconductor` and NumPy",
        "",
        "Generated by `benchmarks/bench_conductor.py` (`make bench`); do not edit by hand. Ratios > 1 mean lamina is "
        "faster. No benchmark is a test: timings are never asserted.",
        "",
        f"{N:,} random (wi, wo) pairs, GGX alpha = {ALPHA}, RGB complex IOR, separable Smith (Mitsuba's formula). "
        "lamina: `Stack.eval` on NumPy arrays, every conversion included. Mitsuba: `np.array(bsdf.eval(ctx, si, wo))` "
        "and nothing else (inputs built once as Dr.Jit arrays); it returns f·cos θ, lamina f, each its own quantity. "
        f"Median of {REPEATS} round-robin runs after a cold call, with the quartiles, each timed call after "
        f"{1000 * SETTLE:.0f} ms of untimed calls of the same implementation (Dr.Jit's worker threads spin for "
        "about 20 ms after its calls, and a lamina call timed in that window took twice as long); each thread count "
        "in a process of its own, with OPENBLAS_NUM_THREADS=1 (NumPy's BLAS threads otherwise spin on the same two "
        "cores). "
        "lamina's float32 inputs run in its float32 lane engine (src/engine). Largest relative difference lamina vs "
        "Mitsuba on these pairs (values above 1e-3 of the peak): "
        f"{two['agreement']:.1e}. Schlick's Fresnel instead of the exact conductor Fresnel changes f by up to "
        f"{two['schlick']:.1%} on the same pairs.",
        "",
        "| implementation | threads | median time (s) | quartiles (s) | first call (s) | evaluations/s | "
        "ratio to Mitsuba |",
        "|---|---:|---:|---|---:|---:|---:|",
    ]
    for threads, run in runs.items():
        mitsuba_t = float(np.median(run["rows"][MITSUBA]["times"]))
        for name, r in run["rows"].items():
            t = float(np.median(r["times"]))
            q1, q3 = np.percentile(r["times"], [25, 75])
            lines.append(
                f"| {name} | {threads} | {t:.4f} | {q1:.4f}–{q3:.4f} | {r['cold']:.4f} | {N / t:,.0f} | "
                f"{mitsuba_t / t:.2f}x |"
            )
    ratio = {
        th: float(np.median(run["rows"][MITSUBA]["times"]) / np.median(run["rows"]["lamina float32 in/out"]["times"]))
        for th, run in runs.items()
    }
    rate = {th: {name: N / float(np.median(r["times"])) for name, r in run["rows"].items()} for th, run in runs.items()}
    lamina32 = "lamina float32 in/out"
    lines += [
        "",
        f"**lamina (float32) / Mitsuba 3 llvm_ad_rgb throughput ratio: {ratio[2]:.2f}x at 2 threads, {ratio[1]:.2f}x "
        f"at 1 thread** (Mitsuba: {N / np.median(two['rows'][MITSUBA]['times']):,.0f} evaluations/s at 2 threads).",
        "",
        "The first row times lamina before Mitsuba has run in the process, the second in the round-robin with it.",
        "",
        f"Thread scaling 1 → 2 threads: lamina {rate[2][lamina32] / rate[1][lamina32]:.2f}x (measured alone: "
        f"{rate[2][ALONE] / rate[1][ALONE]:.2f}x), Mitsuba {rate[2][MITSUBA] / rate[1][MITSUBA]:.2f}x. Roofline at 2 "
        f"threads: lamina moves {36 * rate[2][lamina32] / 1e9:.2f} GB/s of the {36 * rate[2][MEMCPY] / 1e9:.2f} GB/s "
        f"a copy of the same bytes reaches ({rate[2][lamina32] / rate[2][MEMCPY]:.0%}; Mitsuba "
        f"{rate[2][MITSUBA] / rate[2][MEMCPY]:.0%}).",
        "",
        f"Machine: {cpu}, {os.cpu_count()} logical cores, Python {platform.python_version()}, NumPy {np.__version__}, "
        f"Mitsuba {mi.__version__}, lamina {lamina.__version__}. "
        "Mitsuba's first call includes compiling its LLVM kernel. Where the time goes: the profile section below.",
        "",
    ]
    out = write_section("benchmarks.md", "Benchmarks", "conductor", lines)
    print("\n".join(lines))
    print(f"wrote {out}", file=sys.stderr)


if __name__ == "__main__":
    main()
