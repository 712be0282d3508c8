"""Smoke test of an installed lamina wheel (run by `make wheel-test` from outside the source tree): it imports from
site-packages, carries py.typed and the extension's stubs, and evaluates, samples, chooses a model and lists its
models."""

from pathlib import Path

import lamina
import numpy as np

package = Path(lamina.__file__).parent
assert "site-packages" in str(package), f"lamina imported from {package}, not from the installed wheel"
assert (package / "py.typed").is_file() and (package / "_lamina.pyi").is_file(), sorted(
    p.name for p in package.iterdir()
)
assert Path(lamina._lamina.__file__).name.endswith(".abi3.so"), lamina._lamina.__file__
stack = lamina.materials.suite("rough-coat-rough-copper")
wo = np.array([0.3, 0.1, 0.9])
f = stack.eval(wo * [-1, -1, 1], wo, "belcour")
wi, weight, pdf = stack.sample(wo, np.full(3, 0.4), "steinberg")
assert np.all(np.isfinite(f)) and f.shape == (3,) and pdf > 0
choice = lamina.choose(stack, 0.2)  # its measured data (data/choose.json) ships in the wheel
assert choice.model in lamina.MODELS and choice.cost_ns > 0, choice
print(f"lamina {lamina.__version__} wheel OK: {len(lamina.models())} models, f = {np.round(f, 4).tolist()}")
