#!/usr/bin/env bash
# The GPU check for a machine with a hardware GPU, run from the repository root: builds lamina with its default
# features (`make develop test-deps`, which install what they need), runs the GPU parity tests (tests/test_gpu.py)
# and the two quick GPU benchmarks (LAMINA_BENCH_QUICK=1 benchmarks/bench_gpu.py and bench_render.py, which write
# their sections of docs/benchmarks.md with the adapter's name: "gpu-hardware" and "render-hardware" on a hardware
# GPU), and writes what it measured to one folder: $OUT, else ./device-check. Aimed at under 8 minutes on a 16-core
# machine with an NVIDIA GPU. Nothing in CI runs it, and no test depends on it.
# A machine that reaches no package registry and has no Rust (this project's lent GPU machines) takes what
# scripts/device_prepare.sh packed elsewhere: the extension built there (python/lamina/_lamina.abi3.so) and .device/
# (the Vulkan loader, a slim Mitsuba 3 for its Python), with its own python3's NumPy, pytest and Hypothesis; there
# the Mitsuba peers run on cuda_ad_rgb, the GPU they are measured against. Back on the developer's machine,
# `python benchmarks/docs_section.py import-device-check FOLDER` takes the figures into docs/benchmarks.md.
set -uo pipefail
OUT=${OUT:-device-check}
mkdir -p "$OUT"
: > "$OUT/steps.txt"
export PYTHONUNBUFFERED=1
start=$SECONDS
status=0
step() { echo "== $1 ($((SECONDS - start)) s)" | tee -a "$OUT/steps.txt"; }

step "the machine"
{ nvidia-smi || echo "nvidia-smi: not found"; uname -a; nproc; } > "$OUT/machine.txt" 2>&1

if ! command -v cargo > /dev/null && [ -e .device/site.tar.xz ] && [ -e python/lamina/_lamina.abi3.so ]; then
    step "prebuilt (scripts/device_prepare.sh's .device/)"
    for f in .device/gl/*.deb; do dpkg -x "$f" /; done
    ldconfig
    icd=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
    [ -e "$icd" ] && export VK_DRIVER_FILES=$icd
    mkdir -p /tmp/lamina-site && tar -xJf .device/site.tar.xz -C /tmp/lamina-site
    export PYTHONPATH=$PWD/python:/tmp/lamina-site
    PY=python3
    export LAMINA_BENCH_MITSUBA=cuda_ad_rgb LAMINA_BENCH_GPU_N=${LAMINA_BENCH_GPU_N:-16777216}
else
    step "build (default features, release)"
    if ! make develop test-deps > "$OUT/build.log" 2>&1; then
        tail -40 "$OUT/build.log"
        exit 1
    fi
    PY=.venv/bin/python
fi
llvm=$($PY tests/libllvm.py)
$PY -c 'import mitsuba, numpy; print("mitsuba", mitsuba.__version__, "numpy", numpy.__version__)' 2>&1 |
    tee -a "$OUT/machine.txt"

step "adapter"
$PY -c 'import json, lamina; print(json.dumps(lamina.gpu.adapter()))' | tee "$OUT/adapter.json"

step "GPU parity tests"
DRJIT_LIBLLVM_PATH="$llvm" $PY -m pytest -q -p no:cacheprovider tests/test_gpu.py > "$OUT/parity.log" 2>&1 ||
    status=1
tail -3 "$OUT/parity.log"

for bench in bench_gpu bench_render; do
    step "$bench (quick)"
    LAMINA_BENCH_QUICK=1 DRJIT_LIBLLVM_PATH="$llvm" $PY "benchmarks/$bench.py" > "$OUT/$bench.log" 2>&1 ||
        status=1
    tail -2 "$OUT/$bench.log"
done
cp docs/benchmarks.md "$OUT/benchmarks.md"
step "done (exit $status)"
exit $status
