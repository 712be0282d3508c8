#!/usr/bin/env bash
# The GPU check for a machine with a hardware GPU, run from the repository root: builds lamina with its default
# features (`make develop test-deps`, which install what they need), runs the GPU parity tests (tests/test_gpu.py)
# and the two quick GPU benchmarks (LAMINA_BENCH_QUICK=1 benchmarks/bench_gpu.py and bench_render.py, which write
# their sections of docs/benchmarks.md with the adapter's name), and writes what it measured to one folder: $OUT,
# else ./device-check. Aimed at under 8 minutes on a 16-core machine with an NVIDIA GPU. Nothing in CI runs it, and
# no test depends on it.
set -uo pipefail
OUT=${OUT:-device-check}
mkdir -p "$OUT"
export PYTHONUNBUFFERED=1
start=$SECONDS
status=0
step() { echo "== $1 ($((SECONDS - start)) s)" | tee -a "$OUT/steps.txt"; }

step "the machine"
{ nvidia-smi || echo "nvidia-smi: not found"; uname -a; nproc; } > "$OUT/machine.txt" 2>&1

step "build (default features, release)"
if ! make develop test-deps > "$OUT/build.log" 2>&1; then
    tail -40 "$OUT/build.log"
    exit 1
fi
llvm=$(.venv/bin/python tests/libllvm.py)

step "adapter"
.venv/bin/python -c 'import json, lamina; print(json.dumps(lamina.gpu.adapter()))' | tee "$OUT/adapter.json"

step "GPU parity tests"
DRJIT_LIBLLVM_PATH="$llvm" .venv/bin/python -m pytest -q -p no:cacheprovider tests/test_gpu.py > "$OUT/parity.log" 2>&1 ||
    status=1
tail -3 "$OUT/parity.log"

for bench in bench_gpu bench_render; do
    step "$bench (quick)"
    LAMINA_BENCH_QUICK=1 DRJIT_LIBLLVM_PATH="$llvm" .venv/bin/python "benchmarks/$bench.py" > "$OUT/$bench.log" 2>&1 ||
        status=1
    tail -2 "$OUT/$bench.log"
done
cp docs/benchmarks.md "$OUT/benchmarks.md"
step "done (exit $status)"
exit $status
