"""The model catalogue: every model lamina evaluates, with its options (default, allowed values, doc), its
per-element inputs and the properties a user chooses by, as Rust's catalogue states them (src/models/): the analytic
models, then `reference`, the Monte Carlo ground truth. Rust checks every option given (an option a model does not
take is a TypeError from there). `Stack.eval`'s docstring and the README's model table are generated from here."""

from __future__ import annotations

from dataclasses import dataclass
from types import MappingProxyType
from typing import Any, Mapping, Optional

from . import _lamina


@dataclass(frozen=True)
class Option:
    """One option: `kind` is 'choice', 'flag', 'number' or 'channels' (a number per channel, or one for all);
    `choices` lists a choice's (or flag's) values, `range` a number's closed interval."""

    name: str
    kind: str
    default: Any
    doc: str
    choices: Optional[tuple] = None
    range: Optional[tuple] = None

    def allowed(self) -> str:
        """The allowed values as text."""
        if self.choices is not None:
            return " | ".join(repr(c) for c in self.choices)
        lo, hi = self.range
        return f"[{lo:g}, {hi:g}]" + (" per channel" if self.kind == "channels" else "")


@dataclass(frozen=True)
class Input:
    """A per-element input: `width` values per element (1: a map's values, 3: a vector), each in `range`."""

    name: str
    width: int
    range: tuple
    doc: str


@dataclass(frozen=True)
class Model:
    """A model of the catalogue and the properties a user chooses by."""

    name: str
    summary: str
    options: Mapping[str, Option]
    inputs: Mapping[str, Input]
    reciprocal: bool
    energy_conserving: bool
    anisotropic: bool
    spectral: bool
    #: Whether the model runs on the GPU: "yes", "yes, but not" the option values that stay on the CPU, or "no".
    gpu: str = "no"
    #: The layer fields whose gradients `Stack.eval_grad` returns, exact (forward mode): "ior", "k", "roughness_x",
    #: "roughness_y", "angle", "albedo", "diffuse_roughness" (a diffuse base's roughness).
    gradients: tuple = ()

    def __repr__(self) -> str:
        return f"<lamina model {self.name!r}: {self.summary}>"


def _from_rust(d: dict) -> Model:
    options = {
        o["name"]: Option(
            o["name"],
            o["kind"],
            o["default"],
            o["doc"],
            tuple(o["choices"]) if "choices" in o else None,
            tuple(o["range"]) if "range" in o else None,
        )
        for o in d["options"]
    }
    inputs = {i["name"]: Input(i["name"], i["width"], tuple(i["range"]), i["doc"]) for i in d["inputs"]}
    return Model(
        d["name"],
        d["summary"],
        MappingProxyType(options),
        MappingProxyType(inputs),
        **d["properties"],
        gpu=d["gpu"],
        gradients=tuple(d["gradients"]),
    )


_CATALOGUE = tuple(_from_rust(d) for d in _lamina.models())

#: Model names accepted by `model=`, the analytic ones first.
MODELS: tuple = tuple(m.name for m in _CATALOGUE)


def models() -> list:
    """The catalogue: one `Model` per model (`.name`, `.summary`, `.options`, `.inputs`, the properties
    `.reciprocal`, `.energy_conserving`, `.anisotropic`, `.spectral`, `.gpu`: whether it runs on the GPU, and
    `.gradients`: the layer fields `Stack.eval_grad` differentiates by)."""
    return list(_CATALOGUE)


def model(name) -> Model:
    """The catalogue entry of `name`; TypeError / ValueError listing every model otherwise."""
    if not isinstance(name, str):
        raise TypeError(f"model must be a string, one of {list(MODELS)}, got {name!r}")
    for m in _CATALOGUE:
        if m.name == name:
            return m
    raise ValueError(f"model must be one of {list(MODELS)}, got {name!r}")


def options_doc() -> str:
    """Every model's options and inputs as docstring text."""
    lines = []
    for m in _CATALOGUE:
        lines.append(f'- "{m.name}": {m.summary}.')
        for o in m.options.values():
            lines.append(f"    {o.name} = {o.default!r} ({o.allowed()}): {o.doc}")
        for i in m.inputs.values():
            shape = "(...)" if i.width == 1 else f"(..., {i.width})"
            hi = "inf" if i.range[1] >= 1e308 else f"{i.range[1]:g}"
            lines.append(f"    per element {i.name} {shape} in [{i.range[0]:g}, {hi}]: {i.doc}")
    return "\n".join(lines)


def markdown_table() -> str:
    """The README's model table."""
    yes = {True: "yes", False: "no"}
    rows = [
        "| model | what it is | options | per-element inputs | reciprocal | energy-conserving | anisotropic | GPU |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for m in _CATALOGUE:
        opts = ", ".join(f"`{o}`" for o in m.options) or "—"
        inputs = ", ".join(f"`{i}`" for i in m.inputs) or "—"
        rows.append(
            f"| `{m.name}` | {m.summary} | {opts} | {inputs} | {yes[m.reciprocal]} | "
            f"{yes[m.energy_conserving]} | {yes[m.anisotropic]} | {m.gpu} |"
        )
    return "\n".join(rows)


if __name__ == "__main__":
    print(markdown_table())
