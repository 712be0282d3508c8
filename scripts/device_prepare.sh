#!/usr/bin/env bash
# Packs, on a machine that reaches the package registries, what scripts/device_check.sh needs on a GPU machine that
# reaches none (this project's lent NVIDIA machines: Python 3.12 with NumPy, pytest and Hypothesis, no Rust, no
# Vulkan loader, no Mitsuba): the extension built here (`make develop`, default features: python/lamina/*.so), and
# in .device/ (git-ignored) the Debian packages of the Vulkan loader and glvnd, and a slim Mitsuba 3 + Dr.Jit for
# that Python (the variants scalar_rgb, llvm_ad_rgb and cuda_ad_rgb and the plugins the benchmarks' scenes load;
# the full wheels are 68 MB, over what travels). Then carry .device and python/lamina/_lamina.abi3.so and run
# scripts/device_check.sh there.
set -euo pipefail
PYVER=${PYVER:-3.12}
make develop
rm -rf .device && mkdir -p .device/gl /tmp/lamina-apt/partial
apt=(-oAPT::Architecture=amd64 -oAPT::Architectures=amd64 -oDir::State::Lists=/tmp/lamina-apt)
apt-get "${apt[@]}" update -qq
# The loader, and the glvnd libraries that NVIDIA's Vulkan driver (libGLX_nvidia) loads: without them, no adapter.
(cd .device/gl && apt-get "${apt[@]}" download libvulkan1 libglvnd0 libegl1 libgl1 libglx0 libgles2 libopengl0)

wheels=$(mktemp -d)
.venv/bin/python -m pip download -q --no-deps --only-binary=:all: --python-version "$PYVER" --implementation cp \
    --platform manylinux_2_28_x86_64 --platform manylinux_2_27_x86_64 --platform manylinux_2_17_x86_64 \
    -d "$wheels" "mitsuba==$(.venv/bin/python -c 'import mitsuba; print(mitsuba.__version__)')" \
    "drjit==$(.venv/bin/python -c 'import drjit; print(drjit.__version__)')"
site=$(mktemp -d)
for w in "$wheels"/*.whl; do .venv/bin/python -m zipfile -e "$w" "$site"; done
tag=cpython-${PYVER/./}
(cd "$site/mitsuba" && rm -rf include mitsuba_stubs ./*.pyi data/ior data/sunsky &&
    find . -maxdepth 1 -name "*_ad_*.so" ! -name "llvm_ad_rgb.$tag*" ! -name "cuda_ad_rgb.$tag*" -delete &&
    find . -maxdepth 1 -name "scalar_*.so" ! -name "scalar_rgb.$tag*" -delete &&
    keep='roughconductor|srgb|uniform|d65|direct|path|orthographic|hdrfilm|box|regular|independent|sphere'
    find plugins -name "*.so" | grep -Ev "/($keep|directional|envmap|bitmap|merge)\.so$" | xargs rm -f)
rm -rf "$site"/*.dist-info "$site/drjit/include"
tar -cJf .device/site.tar.xz -C "$site" .
rm -rf "$wheels" "$site"
du -sh .device/* python/lamina/_lamina.abi3.so
