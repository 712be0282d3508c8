"""The GPU: which adapter lamina uses, and how a `device=` argument resolves. The wgpu path evaluates BRDFs as WGSL
compute shaders in float32 (src/gpu); it finds a GPU through Vulkan, or Mesa's lavapipe on machines without one."""

from __future__ import annotations

import os
import sys
import tempfile
from functools import lru_cache

import numpy as np

from . import _lamina

#: The values of every `device=` argument.
DEVICES = tuple(_lamina.DEVICES)


def _headless() -> None:
    """Mesa's Vulkan drivers print an error at exit on headless Linux machines without XDG_RUNTIME_DIR: one is made
    before the adapter is."""
    if sys.platform.startswith("linux") and "XDG_RUNTIME_DIR" not in os.environ:
        os.environ["XDG_RUNTIME_DIR"] = tempfile.mkdtemp(prefix="lamina-xdg-")


@lru_cache(maxsize=1)
def _adapter() -> tuple[dict | None, str]:
    if not hasattr(_lamina, "gpu_adapter"):
        return None, "this build of lamina has no GPU path (built without the 'gpu' feature)"
    _headless()
    try:
        return dict(_lamina.gpu_adapter()), ""
    except RuntimeError as e:
        return None, str(e)


def adapter() -> dict | None:
    """The adapter lamina evaluates on with device="gpu": {"name", "device_type" (DiscreteGpu, IntegratedGpu,
    VirtualGpu or Cpu for lavapipe), "backend", "driver"}, or None when there is none."""
    return _adapter()[0]


def models() -> list[str]:
    """The models with a GPU implementation."""
    return list(_lamina.gpu_models()) if hasattr(_lamina, "gpu_models") else []


def use_gpu(device: str, model: str | None, options: dict | None = None, float32: bool = True) -> bool:
    """Whether `device` means the GPU for `model` (None: Oat's materials, which always run there) with `options`,
    for a result that is float32 anyway when `float32`. Rust decides
    (src/device.rs): "cpu" never; "gpu" always, or a ValueError saying why the model does not run there (RuntimeError
    without an adapter, saying how to get one); "auto" when there is a hardware GPU (not lavapipe), the model runs there
    with these options and the result is float32 anyway."""
    _headless()
    return _lamina.use_gpu(device, model, options or {}, float32)


def resident_throughput(stack, wi, wo, model: str = "microfacet", repeats: int = 5, **options) -> float:
    """Evaluations per second on the GPU with the pairs (wi, wo broadcast to n) and the results resident on the device:
    uploaded once, dispatched `repeats` times, nothing read back. For benchmarks; `Stack.eval(device="gpu")` is the
    same evaluation with transfers."""
    from ._arrays import broadcast

    wi, wo = broadcast(wi=(wi, 3), wo=(wo, 3))
    n = int(np.prod(wi.shape[:-1]))
    seconds = _lamina.gpu_resident_seconds(stack._resolve(None), stack.ext_ior, model, wi, wo, repeats, options)
    return n / seconds


def readback_seconds(nbytes: int, repeats: int = 10) -> float:
    """Seconds to copy `nbytes` of results on the device into mappable memory and map them for the CPU: the read-back
    that every `device="gpu"` call pays on top of its work (an image: 12 bytes per pixel). For benchmarks."""
    return _lamina.gpu_readback_seconds(int(nbytes), int(repeats))
