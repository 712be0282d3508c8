"""The faults lamina survives, each as a scenario that provokes it for real and measures what happens: damaged and
unwritable caches, concurrent writers, a Dask worker lost mid-sweep, Ctrl-C in long work, a GPU lost or asked for too
much. tests/test_faults.py asserts each outcome; scripts/reliability.py lists them in docs/reliability.md. Every
scenario works in its own temporary cache and, where a fault would touch the test process, in a child process."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import tempfile
import textwrap
import threading
import time
from pathlib import Path

import numpy as np

#: Stacks whose tabulated solve is quick (a smooth or rough coat over a rough conductor, grey: one solve per stack).
QUICK = """
import lamina
def quick(k):
    return lamina.Stack([lamina.Dielectric(1.3 + 0.1 * k, 0.1 * k), lamina.Conductor(0.5, 3.0, 0.3)])
"""

#: A stack whose tabulated solve takes seconds: three channels of different slabs, one scattering, two rough layers.
SLOW = """
import lamina
slow = lamina.Stack([
    lamina.Dielectric((1.3, 1.4, 1.5), 0.2, thickness=2.0, sigma_a=(0.1, 0.2, 0.3), sigma_s=(3.0, 2.0, 1.0), g=0.5),
    lamina.Dielectric(1.6, 0.3, thickness=1.0, sigma_a=0.2),
    lamina.Conductor((0.2, 0.9, 1.1), (3.6, 2.6, 2.3), 0.25),
])
"""


def _child(code: str, cache: Path, extra_env: dict | None = None, timeout: float = 600) -> dict:
    """Runs `code` in a child Python with LAMINA_CACHE = `cache`; it prints one JSON object last, which is returned
    (with the child's stderr as "stderr")."""
    env = {**os.environ, "LAMINA_CACHE": str(cache), **(extra_env or {})}
    p = subprocess.run(
        [sys.executable, "-c", textwrap.dedent(code)], env=env, capture_output=True, text=True, timeout=timeout
    )
    if p.returncode != 0:
        raise RuntimeError(f"child failed ({p.returncode}):\n{p.stderr[-3000:]}")
    out = json.loads(p.stdout.strip().splitlines()[-1])
    out["stderr"] = p.stderr
    return out


def _files(cache: Path, pattern: str) -> list:
    return sorted(p for p in cache.rglob(pattern) if p.is_file())


def _temporaries(cache: Path) -> list:
    return [p for p in cache.rglob("*") if p.is_file() and ".tmp-" in p.name]


#: The damage done to a cache file, by name: its bytes -> the damaged bytes.
DAMAGE = {
    "truncated": lambda b: b[: len(b) // 2],
    "zeroed": lambda b: bytes(len(b)),
    "garbage": lambda b: bytes((k * 7919) % 251 for k in range(len(b))),
    "one bit flipped": lambda b: b[:-9] + bytes([b[-9] ^ 1]) + b[-8:],
}


def cache_corruption() -> list:
    """A tabulated table and a reference result per kind of damage: cached by one process, damaged, then asked for by
    a fresh process. Rows: (what, damage, rebuilt bit-identical, entry intact again)."""
    code = (
        QUICK
        + """
import json, sys, numpy as np, lamina
from lamina.reference import cached_reference
wi, wo = np.array([0.3, 0.1, 0.9]), np.array([-0.4, 0.2, 0.85])
out = {}
for k in range(4):
    out[f"table {k}"] = quick(k).eval(wi, wo, "tabulated").tolist()
    out[f"reference {k}"] = cached_reference(quick(k), wi, wo, samples=2000 + k)[0].tolist()
print(json.dumps(out))
"""
    )
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        cache = Path(tmp)
        first = _child(code, cache)
        tables, references = _files(cache, "tabulated-*"), _files(cache, "*.ref")
        originals = {p: p.read_bytes() for p in tables + references}
        damaged = list(zip(tables, DAMAGE)) + list(zip(references, DAMAGE))
        for path, kind in damaged:
            path.write_bytes(DAMAGE[kind](originals[path]))
        second = _child(code, cache)
        for path, kind in damaged:
            what = "tabulated table" if path in tables else "reference result"
            same = all(first[k] == second[k] for k in first if k != "stderr")
            rows.append((what, kind, same, path.read_bytes() == originals[path]))
    return rows


def unwritable_cache() -> dict:
    """LAMINA_CACHE where nothing can be written (a path through a regular file: as a read-only or missing folder
    fails, whoever runs), then a cache that fills up (a file-size limit of 64 KiB, as a full disk stops a write):
    tables and references are computed in memory, equal a writable run, and one warning says so."""
    code = (
        QUICK
        + """
import json, os, resource, signal, warnings, numpy as np, lamina
from lamina.reference import cached_reference
if os.environ.get("LAMINA_TEST_FULL"):
    signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # a write past the limit fails (EFBIG) instead of killing us
    resource.setrlimit(resource.RLIMIT_FSIZE, (64 << 10, 64 << 10))
wi, wo = np.array([0.3, 0.1, 0.9]), np.array([-0.4, 0.2, 0.85])
with warnings.catch_warnings(record=True) as caught:
    warnings.simplefilter("always")
    f = [quick(k).eval(wi, wo, "tabulated").tolist() for k in range(2)]
    r = cached_reference(quick(0), wi, wo, samples=2000)[0].tolist()
print(json.dumps({"f": f, "r": r, "warnings": [str(w.message) for w in caught]}))
"""
    )
    out = {}
    with tempfile.TemporaryDirectory() as tmp:
        writable = _child(code, Path(tmp, "ok"))
        blocker = Path(tmp, "file")
        blocker.write_text("not a folder")
        for name, cache, env in (
            ("unwritable", blocker / "cache", {}),
            ("full", Path(tmp, "full"), {"LAMINA_TEST_FULL": "1"}),
        ):
            run = _child(code, cache, env)
            written = [p for p in cache.rglob("*") if p.is_file()] if cache.is_dir() else []
            out[name] = {
                "same": run["f"] == writable["f"] and run["r"] == writable["r"],
                "warnings": [w.replace(str(cache), "$LAMINA_CACHE") for w in run["warnings"]],
                "left behind": [p.name for p in written if ".tmp-" in p.name],
            }
    return out


def concurrent_writers() -> dict:
    """Two processes prepare the same table at once into one fresh cache, then two Dask workers do: the same bits
    everywhere, one intact file, no temporary file left."""
    code = (
        QUICK
        + """
import json, numpy as np, lamina
wi, wo = np.array([0.3, 0.1, 0.9]), np.array([-0.4, 0.2, 0.85])
print(json.dumps({"f": quick(3).eval(wi, wo, "tabulated").tolist()}))
"""
    )
    out = {}
    with tempfile.TemporaryDirectory() as tmp:
        cache = Path(tmp)
        env = {**os.environ, "LAMINA_CACHE": str(cache)}
        procs = [
            subprocess.Popen([sys.executable, "-c", code], env=env, stdout=subprocess.PIPE, text=True) for _ in "ab"
        ]
        results = [json.loads(p.communicate(timeout=600)[0].strip().splitlines()[-1])["f"] for p in procs]
        files = _files(cache, "tabulated-*")
        out["processes"] = {
            "same": results[0] == results[1],
            "files": len(files),
            "intact": _intact(files),
            "left behind": len(_temporaries(cache)),
        }
    with tempfile.TemporaryDirectory() as tmp:
        cache = Path(tmp)
        from dask.distributed import Client, LocalCluster

        os.environ["LAMINA_CACHE"] = str(cache)
        try:
            with LocalCluster(n_workers=2, threads_per_worker=1, processes=True) as cluster, Client(cluster) as client:
                exec(QUICK, namespace := {})
                stack = namespace["quick"](3)
                wi, wo = np.array([0.3, 0.1, 0.9]), np.array([-0.4, 0.2, 0.85])
                workers = list(client.scheduler_info()["workers"])
                futures = [client.submit(stack.eval, wi, wo, "tabulated", workers=[w], pure=False) for w in workers]
                results = client.gather(futures)
        finally:
            del os.environ["LAMINA_CACHE"]
        files = _files(cache, "tabulated-*")
        out["dask workers"] = {
            "same": bool(np.array_equal(results[0], results[1])),
            "files": len(files),
            "intact": _intact(files),
            "left behind": len(_temporaries(cache)),
        }
    return out


def _intact(files: list) -> bool:
    from lamina import _lamina

    return all(_lamina.cache_read(str(p)) is not None for p in files)


def lost_worker() -> dict:
    """lamina.dask.suite_reference over a two-worker cluster, one worker killed while it runs a task: the sweep
    completes on what remains and equals a local run bit for bit."""
    import lamina
    from dask.distributed import Client, LocalCluster

    names, samples = ["gold-clearcoat", "varnished-diffuse", "rough-coat-rough-copper"], 3000
    with tempfile.TemporaryDirectory() as local_cache:
        os.environ["LAMINA_CACHE"] = local_cache
        try:
            local = lamina.dask.suite_reference(names, samples=samples)
        finally:
            del os.environ["LAMINA_CACHE"]
    with tempfile.TemporaryDirectory() as tmp:
        os.environ["LAMINA_CACHE"] = tmp
        try:
            with LocalCluster(n_workers=2, threads_per_worker=1, processes=True) as cluster, Client(cluster) as client:
                pids = client.run(os.getpid)
                result, killed = {}, {}

                def sweep():
                    result.update(lamina.dask.suite_reference(names, samples=samples, client=client))

                t = threading.Thread(target=sweep)
                t.start()
                deadline = time.time() + 60
                while time.time() < deadline and not killed:
                    busy = [w for w, tasks in client.processing().items() if tasks]
                    if busy:
                        time.sleep(0.2)  # well inside the task
                        os.kill(pids[busy[0]], signal.SIGKILL)
                        killed["worker"] = busy[0]
                    time.sleep(0.02)
                t.join(timeout=600)
        finally:
            del os.environ["LAMINA_CACHE"]
    same = sorted(result) == sorted(local) and all(
        all(np.array_equal(a, b) for a, b in zip(result[n], local[n])) for n in names
    )
    return {"killed": bool(killed), "completed": len(result) == len(names), "same": same}


def _interrupt(setup: str, work: str, cache: Path, wait: float) -> dict:
    """A child that runs `setup`, prints "ready", then runs `work`; SIGINT `wait` seconds later: whether it raised
    KeyboardInterrupt, and how long after the signal (the child stamps the moment it catches it)."""
    code = (
        setup
        + f"""
import sys, time
print("ready", flush=True)
try:
{textwrap.indent(work, "    ")}
    print("finished", flush=True)
except KeyboardInterrupt:
    print(f"interrupted {{time.time()}}", flush=True)
"""
    )
    env = {**os.environ, "LAMINA_CACHE": str(cache)}
    # The child starts with SIGINT at its default: a background job ignores SIGINT, and a child would inherit that.
    p = subprocess.Popen(
        [sys.executable, "-c", code],
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )
    try:
        assert p.stdout.readline().strip() == "ready"
        time.sleep(wait)
        sent = time.time()
        p.send_signal(signal.SIGINT)
        out, err = p.communicate(timeout=60)
    finally:
        p.kill()
    line = out.strip().splitlines()[-1] if out.strip() else ""
    caught = line.startswith("interrupted")
    return {"raised": caught, "seconds": float(line.split()[1]) - sent if caught else None, "stderr": err[-500:]}


def interrupts() -> dict:
    """Ctrl-C during a tabulated precomputation (seconds of adding-doubling), during tabulated's gradient (its solve in
    Duals) and during a long render (the reference under the sky): KeyboardInterrupt within a second, and no cache
    entry or temporary file left."""
    out, solve = {}, "slow.eval([0, 0, 1], [0, 0, 1], 'tabulated')"
    with tempfile.TemporaryDirectory() as tmp:  # how long the solve takes, uninterrupted
        started = time.perf_counter()
        _child(SLOW + f"import json\n{solve}\nprint(json.dumps({{}}))", Path(tmp))
        seconds = time.perf_counter() - started
    with tempfile.TemporaryDirectory() as tmp:
        cache = Path(tmp)
        r = _interrupt(SLOW, solve, cache, wait=0.3 * seconds)
        r["solve seconds"] = seconds
        r["left behind"] = [p.name for p in cache.rglob("*") if p.is_file() and "tabulated" in p.name]
        out["tabulated precomputation"] = r
    # The gradient's own solve (in Duals), after the f64 solve that `eval` cached: Ctrl-C must reach it too.
    setup = (
        "import lamina\ngrad = lamina.Stack([lamina.Dielectric(1.5, thickness=2.0, sigma_a=0.1, "
        "sigma_s=(lamina.Param('s', 0.5, 5.0), 2.0, 1.0), g=0.5), lamina.Diffuse(0.5)])\n"
        "grad.bind(s=3.0).eval([0, 0, 1], [0, 0, 1], 'tabulated')\n"
    )
    work = "grad.eval_grad([0, 0, 1], [0, 0, 1], 'tabulated', s=3.0)"
    with tempfile.TemporaryDirectory() as tmp:  # how long the gradient takes, uninterrupted
        timed = (
            f"import json, time\nt = time.perf_counter()\n{work}\nprint(json.dumps({{'s': time.perf_counter() - t}}))"
        )
        seconds = _child(setup + timed, Path(tmp))["s"]
    with tempfile.TemporaryDirectory() as tmp:
        r = _interrupt(setup, work, Path(tmp), wait=0.3 * seconds)
        r["gradient seconds"] = seconds
        out["tabulated gradient"] = r
    with tempfile.TemporaryDirectory() as tmp:
        setup = "import lamina\nstack = lamina.materials.suite('three-layer')\n"
        work = "lamina.render(stack, 'reference', width=256, height=256, spp=256, device='cpu', progress=False)"
        out["render"] = _interrupt(setup, work, Path(tmp), wait=1.0)
    return out


def gpu_faults() -> dict:
    """On the GPU (lavapipe in CI): a render that needs more than the device holds, and a device lost in the middle
    of a batch (it destroys itself after one dispatch of three: lamina's fault injection): a RuntimeError that names
    the device and the size, then the next call works."""
    code = """
import json, numpy as np, lamina
from lamina import _lamina
stack, out = lamina.materials.suite("rough-coat-rough-copper"), {}
rng = np.random.default_rng(0)
w = rng.normal(size=(5_000_000, 3)); w[:, 2] = np.abs(w[:, 2]) + 0.1
w = (w / np.linalg.norm(w, axis=1, keepdims=True)).astype(np.float32)
def attempt(key, call):
    try:
        call()
        out[key] = None
    except RuntimeError as e:
        out[key] = str(e)
light = [lamina.DirectionalLight((0, 0, 1))]
attempt("too large", lambda: lamina.render(stack, "belcour", width=16384, height=16384, device="gpu", lights=light))
out["after too large"] = float(lamina.render(stack, "belcour", width=32, height=32, device="gpu", lights=light).mean())
_lamina._gpu_lose_after(1)
attempt("lost", lambda: stack.eval(w, w, "belcour", device="gpu"))
f = stack.eval(w[:1000], w[:1000], "belcour", device="gpu")
cpu = stack.eval(w[:1000].astype(np.float64), w[:1000].astype(np.float64), "belcour", device="cpu")
out["after lost"] = float(np.max(np.abs(f - cpu) / np.maximum(cpu, 1e-3 * cpu.max())))
out["adapter"] = lamina.gpu.adapter()["name"]
print(json.dumps(out))
"""
    with tempfile.TemporaryDirectory() as tmp:
        return _child(code, Path(tmp))
