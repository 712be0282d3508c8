"""Gradients, fits and families against the evaluation they build on, in one process (2 threads on the CI machine):
`Stack.eval_grad` with k parameters against `Stack.eval` (the issue's goal: ≤ (1 + k)x), a family's per-element
evaluation against the single stack's (goal: ≤ 2x), and `lamina.fit` of 2000 samples. Medians of 5 alternating runs
on 1M random pairs. Writes the "fit" section of docs/benchmarks.md. Not a test.
"""

from __future__ import annotations

import os
import sys
import time

import numpy as np
from docs_section import write_section
from lamina import Conductor, Dielectric, Param, Stack, fit
from lamina.materials import metal

N = 1_000_000


def pairs(n: int, rng) -> tuple:
    w = rng.normal(size=(2, n, 3))
    w[..., 2] = np.abs(w[..., 2]) + 1e-3
    return tuple(w / np.linalg.norm(w, axis=-1, keepdims=True))


def medians(a, b, repeats: int = 5) -> tuple:
    """Median seconds of a() and b(), alternating, after one warm-up call each."""
    a(), b()
    ta, tb = [], []
    for _ in range(repeats):
        for f, t in ((a, ta), (b, tb)):
            start = time.perf_counter()
            f()
            t.append(time.perf_counter() - start)
    return float(np.median(ta)), float(np.median(tb))


def main() -> None:
    rng = np.random.default_rng(0)
    wi, wo = pairs(N, rng)
    lines = [
        "## Gradients, fits and families (python benchmarks/bench_fit.py)",
        "",
        f"Against the evaluation they build on, in one process ({os.cpu_count()} CPUs), medians of 5 alternating runs "
        "on 1M random pairs.",
        "",
        "| what | ns per evaluation | baseline | ns per evaluation | ratio | goal |",
        "|---|---:|---|---:|---:|---:|",
    ]
    conductor = Stack([Conductor(Param("eta", 0.1, 3.0), Param("k", 0.5, 6.0), roughness=Param("alpha", 0.02, 0.9))])
    at = dict(eta=0.2, k=3.0, alpha=0.3)
    g, e = medians(lambda: conductor.eval_grad(wi, wo, **at), lambda: conductor.bind(**at).eval(wi, wo))
    lines.append(
        f"| microfacet eval_grad, 3 parameters (float64) | {g / N * 1e9:.1f} | eval (float64) | {e / N * 1e9:.1f} "
        f"| {g / e:.2f} | ≤ 4 |"
    )
    coated = Stack(
        [
            Dielectric(Param("n", 1.2, 2.0), Param("r", 0.01, 1.0), thickness=1.0, sigma_a=Param("sa", 0.0, 3.0)),
            Conductor(0.2, 3.5, roughness=Param("rb", 0.01, 1.0)),
        ]
    )
    at4 = dict(n=1.5, r=0.2, sa=0.5, rb=0.3)
    # belcour's gradient runs the adding-doubling in Duals at its table's nodes (interpolated as `eval` interpolates
    # them), or per pair with interpolated=False (a tenth of the pairs): each against `eval` with the same options.
    for options, what, m in ((dict(interpolated=False), "interpolated=False", N // 10), ({}, "its table", N)):
        g, e = medians(
            lambda o=options, m=m: coated.eval_grad(wi[:m], wo[:m], "belcour", **at4, **o),
            lambda o=options, m=m: coated.bind(**at4).eval(wi[:m], wo[:m], "belcour", **o),
        )
        lines.append(
            f"| belcour eval_grad, 4 parameters, {what} (float64) | {g / m * 1e9:.1f} | eval, {what} (float64) "
            f"| {e / m * 1e9:.1f} | {g / e:.2f} | ≤ 5 |"
        )
    # The single-pass walks and albedo scaling in Duals, per pair, against their float64 evaluation.
    for model in ("steinberg", "weidlich_wilkie", "albedo_scaling"):
        g, e = medians(
            lambda m=model: coated.eval_grad(wi, wo, m, **at4), lambda m=model: coated.bind(**at4).eval(wi, wo, m)
        )
        lines.append(
            f"| {model} eval_grad, 4 parameters (float64) | {g / N * 1e9:.1f} | eval (float64) | {e / N * 1e9:.1f} "
            f"| {g / e:.2f} | ≤ 5 |"
        )
    # tabulated's gradient of a new stack is its solve in Duals alone (models::prepare_gradient: no f64 table), against
    # the f64 solve (the precomputation of `eval`'s first call on a new stack). Each call at new values, so that no
    # cache answers.
    slab = Stack(
        [
            Dielectric(
                1.5, thickness=Param("t", 0.1, 3.0), sigma_a=Param("sa", 0.0, 1.0), sigma_s=1.0, g=Param("g", -0.9, 0.9)
            ),
            Conductor(Param("e", 0.1, 3.0), 3.0, roughness=0.3),
        ]
    )
    calls = iter(range(1000))
    fresh = lambda: dict(t=1.0 + 1e-3 * next(calls), sa=0.3, g=0.4, e=0.5)  # noqa: E731
    g, e = medians(
        lambda: slab.eval_grad(wi[:10], wo[:10], "tabulated", **fresh()),
        lambda: slab.bind(**fresh()).eval(wi[:10], wo[:10], "tabulated"),
    )
    lines.append(
        f"| tabulated eval_grad of a new stack, 4 parameters (its solve in Duals) | "
        f"{g:.2f} s per call | eval of a new stack (its f64 solve) | {e:.2f} s per call | {g / e:.2f} | ≤ 5 |"
    )
    varnish = Stack([Dielectric(1.5, 0.1, thickness=Param("t", 0.1, 5.0), sigma_a=(0.2, 0.4, 0.8)), metal("Cu", 0.3)])
    t = rng.uniform(0.1, 5.0, N)
    for model in ("belcour", "tabulated"):
        for dtype in (np.float32, np.float64):
            a, b = wi.astype(dtype), wo.astype(dtype)
            one = varnish.bind(t=1.0)
            fam, single = medians(
                lambda a=a, b=b, m=model: varnish.eval(a, b, m, t=t), lambda a=a, b=b, m=model, s=one: s.eval(a, b, m)
            )
            lines.append(
                f"| {model} family over thickness ({np.dtype(dtype).name}) | {fam / N * 1e9:.1f} | the single stack "
                f"| {single / N * 1e9:.1f} | {fam / single:.2f} | ≤ 2 |"
            )
    samples = 2000
    truth = conductor.bind(**at)
    fw, fo = pairs(samples, rng)
    data = truth.eval(fw, fo)
    start = time.perf_counter()
    result = fit(conductor, fw, fo, data, starts=4)
    seconds = time.perf_counter() - start
    lines += [
        "",
        f"`lamina.fit` of {samples} samples, 3 parameters of a rough conductor (microfacet), 4 starts: {seconds:.2f} s "
        f"(found {', '.join(f'{k} = {v:.4f}' for k, v in result.params.items())}; truth 0.2, 3.0, 0.3).",
    ]
    print("\n".join(lines))
    path = write_section("benchmarks.md", "Benchmarks", "fit", lines)
    print(f"wrote {path}", file=sys.stderr)


if __name__ == "__main__":
    main()
