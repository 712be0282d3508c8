# Two entry points on a fresh machine: `make demo` and `make test`. Each sets up what it needs.
SHELL := /bin/bash
PY ?= python3
VENV := .venv
VPY := $(VENV)/bin/python
# Mitsuba's llvm_ad_* variants need a system libLLVM: tests/libllvm.py picks the highest version >= 16 (3.9.1 aborts
# with LLVM 15); system-deps installs Debian's libllvm19 when root. Without one, the tests use scalar_* variants.
# The GPU parity tests need a Vulkan adapter: system-deps installs Mesa's lavapipe when root; tests/test_gpu.py
# fails without one unless LAMINA_SKIP_GPU=1 says to skip it.
LLVM = DRJIT_LIBLLVM_PATH="$$($(PY) tests/libllvm.py)"

.PHONY: demo test lint wheel-test develop venv test-deps system-deps rust-test py-test bench validation reference reliability fuzz readme chart population anisotropic atlas oat notebooks fit clean

$(VPY):
	$(PY) -m venv $(VENV)
	$(VPY) -m pip install -q --upgrade pip

venv: $(VPY)
	$(VPY) -m pip install -q "maturin>=1.7,<2" "numpy>=1.22" "matplotlib>=3.5" tqdm

# Builds the Rust extension in release mode into the venv (editable install of python/lamina); this project's venv
# even when another one is active in the calling shell.
develop: venv
	rm -f python/lamina/_lamina.cpython-*.so  # a pre-abi3 build would shadow the abi3 one
	VIRTUAL_ENV="$(abspath $(VENV))" $(VENV)/bin/maturin develop --release -q

# The main job: the gallery (every layered model beside the reference, error heatmaps; docs/gallery.png and
# docs/features.png), then a material ball and BRDF slices.
# The demo uses the GPU when there is one: with a GPU device node (/dev/dri/renderD*, /dev/nvidia0) it builds the
# default features, wgpu included, and the gallery renders its models there (device "auto"). Without one it builds
# without the wgpu path (DEMO_FEATURES), which would only add about 2.5 minutes to a fresh build on 2 cores, and
# renders on the CPU. `make DEMO_FEATURES= demo` forces the default features.
DEMO_FEATURES ?= $(if $(wildcard /dev/dri/renderD* /dev/nvidia0),,--no-default-features)
demo: venv
	rm -f python/lamina/_lamina.cpython-*.so
	VIRTUAL_ENV="$(abspath $(VENV))" $(VENV)/bin/maturin develop --release -q $(DEMO_FEATURES)
	$(VENV)/bin/lamina gallery --out out --docs docs
	$(VENV)/bin/lamina render --material car-paint --model weidlich_wilkie --out out
	$(VENV)/bin/lamina plot --material coated-copper --model belcour --out out

# Debian's libLLVM for Mitsuba's llvm_ad_* variants, installed when running as root (CI and dev machines).
system-deps:
	@if [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null && [ -z "$$($(PY) tests/libllvm.py)" ]; then \
		echo "installing libllvm19 for Mitsuba's llvm variants"; \
		apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq libllvm19 >/dev/null; \
	fi
	@if [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null && ! ls /usr/share/vulkan/icd.d/lvp_icd.*.json >/dev/null 2>&1; then \
		echo "installing Mesa's lavapipe (Vulkan on the CPU) for the GPU parity tests"; \
		apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq mesa-vulkan-drivers libvulkan1 >/dev/null; \
	fi

test-deps: venv system-deps
	$(VPY) -m pip install -q "pytest>=7" "hypothesis>=6" "colour-science>=0.4.4" scipy "mitsuba>=3.9,<3.10" "ruff==0.17.6" "dask[distributed]>=2024.1" "iadpython>=0.5" mypy nbclient nbformat ipykernel

# The unit tests (src/, `--lib`: there are no doctests, and lint's clippy compiles the examples) in the rust-test
# profile of Cargo.toml.
rust-test:
	cargo test --profile rust-test --lib

# Formatting and lints of both languages (clippy over every target, the Python bindings included), and the
# extension's type stubs against the built module (mypy's stubtest).
lint: develop test-deps
	cargo fmt --check
	cargo clippy --release --all-targets --features python -- -D warnings
	$(VENV)/bin/ruff check python tests scripts benchmarks
	$(VENV)/bin/ruff format --check python tests scripts benchmarks
	$(VPY) -m mypy.stubtest lamina._lamina

# The abi3 wheel as a user installs it: built, installed into a throwaway venv, imported and used from another
# directory; it must carry py.typed and the stubs.
wheel-test: venv
	rm -rf target/wheels
	VIRTUAL_ENV="$(abspath $(VENV))" $(VENV)/bin/maturin build --release -q -o target/wheels
	tmp=$$(mktemp -d) && $(PY) -m venv $$tmp/venv && $$tmp/venv/bin/pip install -q target/wheels/*.whl && \
		cd $$tmp && $$tmp/venv/bin/python $(abspath tests/wheel_smoke.py)

py-test: develop test-deps
	$(LLVM) $(VPY) -m pytest tests

test: rust-test lint py-test wheel-test

# OPENBLAS_NUM_THREADS=1: NumPy's BLAS threads would otherwise spin on the cores both sides are measured on.
bench: export OPENBLAS_NUM_THREADS = 1
bench: develop test-deps
	@if [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null && ! command -v perf >/dev/null; then \
		apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq linux-perf >/dev/null; \
	fi
	$(LLVM) $(VPY) benchmarks/bench_conductor.py
	$(VPY) benchmarks/bench_float32.py
	$(LLVM) $(VPY) benchmarks/bench_layered.py
	$(LLVM) $(VPY) benchmarks/bench_sampling.py
	$(VPY) benchmarks/bench_reference.py
	$(LLVM) $(VPY) benchmarks/bench_render.py
	$(LLVM) $(VPY) benchmarks/bench_gpu.py
	$(VPY) benchmarks/bench_memory.py
	$(VPY) benchmarks/profile.py

# Regenerates docs/validation.md from measurements against Mitsuba 3 and colour-science.
validation: develop test-deps
	$(LLVM) $(VPY) scripts/validation_report.py

# docs/reliability.md: the bad-input table (and the fuzz counts of docs/fuzz.json, written by `make fuzz`).
reliability: develop
	$(VPY) scripts/reliability.py

# Fuzzes every model with 1e8 direction pairs (several minutes), then regenerates docs/reliability.md.
fuzz: develop
	$(VPY) scripts/fuzz.py
	$(VPY) scripts/reliability.py

# lamina.choose's data and its validation: every candidate model against the reference on 300 random stacks of
# lamina.materials.population (about 15 minutes on 2 cores; the references are cached, so it resumes). Writes
# docs/population.json, python/lamina/data/choose.json and docs/choose.md.
population: develop
	$(VPY) scripts/population.py

# `tabulated` on 50 anisotropic stacks against the reference: docs/anisotropic.md and .png (about 12 minutes on 2
# cores the first time; references and tables cached).
anisotropic: develop
	$(VPY) scripts/anisotropic_population.py

# The failure atlas: docs/atlas.md, docs/atlas/*.png and docs/atlas.json (about 10 minutes on 2 cores; resumes).
atlas: develop
	$(VPY) scripts/atlas.py

# Executes every notebook on a kernel and writes it back with its outputs (figures), for readers.
notebooks: develop test-deps
	$(LLVM) $(VPY) scripts/run_notebooks.py

# docs/oat.md, docs/oat.png and docs/oat_slab.png: Oat 2006's variants (frame time, difference) and blur radii.
oat: develop
	$(VPY) scripts/oat_report.py

# docs/speed_accuracy.json and .png: every model's cost against its error on the suite and on the held-out
# population (whose references `make population` caches), the reference's, and the GPU path's.
chart: develop
	$(VPY) scripts/speed_accuracy.py

# docs/fit.md and docs/fit.png: fit_models on Mitsuba 3's roughplastic and plastic, recovery of known parameters,
# and a fit's speed (about 13 minutes on 2 cores: tabulated solves the stack at every step).
fit: develop test-deps
	$(LLVM) $(VPY) scripts/fit_report.py

# Regenerates the README's model table from the catalogue (lamina.models()).
readme: develop
	$(VPY) scripts/readme_tables.py

# Computes (or loads from ~/.cache/lamina) the suite's reference values on its fixed direction grid.
reference: develop
	$(VPY) -c "import lamina.reference as r, lamina.materials as m; [print(n, r.suite_reference(n, progress=True)[2].mean()) for n in m.SUITE]"

clean:
	rm -rf $(VENV) target out
