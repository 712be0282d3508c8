"""The layer stack and its one evaluation interface: eval, sample, pdf and the Dirac reflection under any model of
the catalogue (lamina.models), the Monte Carlo reference, albedo and lobes. Conventions: docs/conventions.md."""

from __future__ import annotations

from dataclasses import replace
from numbers import Integral, Real
from typing import NamedTuple, Sequence

import numpy as np

from . import _lamina, _reference
from . import gpu as _gpu
from ._arrays import broadcast
from .catalogue import model as _model
from .catalogue import options_doc
from .choose import choose
from .family import eval_family
from .layers import Conductor, Dielectric, Diffuse, Layer, bind_layer, layer_params

_LAYERS = (Dielectric, Conductor, Diffuse)


class Simplified(NamedTuple):
    """What `Stack.simplify` returns: the simpler stack, the relative L1 difference of f it introduces under the
    model it was measured with, and a line per change made."""

    stack: Stack
    error: float
    steps: tuple


class Stack:
    """Layers from top to bottom, ending in one opaque base (Conductor or Diffuse), under a medium of absolute
    IOR `ext_ior` (air = 1.0). Validated at construction: bad parameters raise ValueError / TypeError. Stacks are
    values: equal layers and ext_ior compare equal and hash alike, and they pickle."""

    def __init__(self, layers: Sequence[Layer], ext_ior: float = 1.0):
        if isinstance(layers, _LAYERS):
            layers = [layers]
        if isinstance(layers, (str, bytes)) or not isinstance(layers, Sequence):
            raise TypeError(f"layers must be a list of lamina.Dielectric, Conductor or Diffuse, got {layers!r}")
        self.layers = tuple(layers)
        for i, layer in enumerate(self.layers):
            if not isinstance(layer, _LAYERS):
                raise TypeError(
                    f"layers[{i}] must be a lamina.Dielectric, Conductor or Diffuse, got {type(layer).__name__}"
                )
        if not isinstance(ext_ior, Real) or isinstance(ext_ior, bool):
            raise TypeError(f"ext_ior must be a number, got {ext_ior!r}")
        self.ext_ior = float(ext_ior)
        #: The free parameters (lamina.Param) of a template stack, in the order they first appear; () for a stack.
        self.params = _params(self.layers)
        at_start = self.bind(**{p.name: p.start for p in self.params}) if self.params else self
        _lamina.check_stack(at_start._resolve(None), self.ext_ior)

    def __repr__(self) -> str:
        return f"Stack({list(self.layers)!r}, ext_ior={self.ext_ior})"

    def __eq__(self, other) -> bool:
        return isinstance(other, Stack) and (self.layers, self.ext_ior) == (other.layers, other.ext_ior)

    def __hash__(self) -> int:
        return hash((self.layers, self.ext_ior))

    def _resolve(self, wavelengths) -> list:
        if self.params:
            raise ValueError(
                f"the stack has free parameters {[p.name for p in self.params]}: give their values (Stack.bind), "
                "differentiate by them (Stack.eval_grad) or fit them (lamina.fit)"
            )
        return [layer._resolve(wavelengths) for layer in self.layers]

    def bind(self, **values) -> Stack:
        """The stack with each free parameter (`params`) replaced by its value: bind(name=number, ...), every
        name given once, each value within its Param's [low, high]."""
        names = [p.name for p in self.params]
        unknown, missing = sorted(set(values) - set(names)), [n for n in names if n not in values]
        if unknown or missing:
            raise ValueError(f"bind takes the stack's free parameters {names}: unknown {unknown}, missing {missing}")
        for p in self.params:
            v = values[p.name]
            if not isinstance(v, Real) or isinstance(v, bool) or not p.low <= v <= p.high:
                raise ValueError(f"{p.name} must be a number in [{p.low}, {p.high}], got {v!r}")
        return Stack([bind_layer(layer, values) for layer in self.layers], self.ext_ior)

    def eval_grad(self, wi, wo, model: str = "microfacet", *, wavelengths=None, **kwargs) -> tuple:
        """f(wi, wo) and its gradient by the template's free parameters (`params`), exact (forward-mode automatic
        differentiation through the model: src/dual.rs), at their values given as keyword arguments (default
        each Param's start); other keyword arguments are the model's options. Returns (f (..., channels),
        grad (..., channels, len(params))), float64. `lamina.models()` lists the fields each model differentiates
        by (`.gradients`); a parameter of another field is a ValueError."""
        if not self.params:
            raise ValueError("eval_grad differentiates by a template's free parameters: this stack has no lamina.Param")
        m = _model(model)
        values = {p.name: kwargs.pop(p.name, p.start) for p in self.params}
        stack = self.bind(**values)
        wl = _wavelengths(wavelengths)
        resolved = stack._resolve(wl)
        seeds = _seeds(self, resolved)
        for _, layer, field, _, _ in seeds:
            if field not in m.gradients:
                raise ValueError(
                    f"model {m.name!r} has no gradient by {field} (layer {layer}); it differentiates by "
                    f"{list(m.gradients) or 'nothing yet'}"
                )
        wi, wo = broadcast(wi=(wi, 3), wo=(wo, 3))
        n = len(self.params)
        out = _lamina.eval_grad(resolved, self.ext_ior, m.name, wi, wo, seeds, n, kwargs)
        out = np.asarray(out, dtype=np.float64).reshape(out.shape[:-1] + (-1, n + 1))
        return out[..., 0], out[..., 1:]

    def _split(self, model: str, kwargs: dict) -> tuple:
        """`model`'s catalogue entry, its options and its per-element inputs from keyword arguments (Rust checks the
        options against the model's table); the inputs as `broadcast` takes them, (array, width) with width 0 for a
        scalar map."""
        m = _model(model)
        inputs = {
            k: (v, 0 if m.inputs[k].width == 1 else m.inputs[k].width) for k, v in kwargs.items() if k in m.inputs
        }
        options = {k: v for k, v in kwargs.items() if k not in m.inputs}
        return m, options, inputs

    def eval(
        self,
        wi,
        wo,
        model: str = "microfacet",
        *,
        wavelengths=None,
        samples: int = 10_000,
        seed: int = 0,
        device: str = "auto",
        tolerance: float | None = None,
        **kwargs,
    ) -> np.ndarray:
        """The BRDF f(wi, wo), not multiplied by cos θi.

        wi, wo: directions (..., 3) in the local frame (z = normal), both pointing away from the surface: wi towards
        the light, wo towards the viewer. They need not be unit length and broadcast against each other; directions
        below the horizon give 0. Returns (..., 3) linear RGB channels, or (..., len(wavelengths)) with `wavelengths`
        (nm); float32 when both inputs are float32, float64 otherwise. Units: 1/sr. Dirac (specular) lobes of smooth
        interfaces are not part of f: see `specular`.

        A template stack (holding lamina.Param) is a family: each Param's values per element are keyword arguments
        (arrays broadcast with the directions), and the family is interpolated on a grid of stacks chosen by measured
        error (lamina.family: within 1% of the model at the explicit stack).

        Keyword arguments are the model's options and its per-element inputs (arrays broadcast with the
        directions); anything else is a TypeError. model="reference" returns the mean of `Stack.reference` with
        `samples` paths per pair. Tables are built on the first call and kept for the next calls with the same stack
        and options. Measured against the reference in docs/validation.md.

        model="auto" evaluates with `lamina.choose(self, tolerance, wi)`: the cheapest model predicted within
        `tolerance` (relative L1 lobe error, default 0.05) for this stack and these incident directions.

        device: "auto" (default) evaluates on a hardware GPU when there is one, the model runs there and the inputs are
        float32 (so the result is float32 anyway; the GPU computes in float32, about 1e-5 from the CPU), else on the
        CPU; "cpu"; "gpu" evaluates on the GPU (wgpu compute shaders, float32 output; lamina.gpu.models() lists the
        models it has; ValueError for what it does not run, RuntimeError without an adapter). docs/conventions.md
        states the rule.

        Models, their options (default, allowed values) and per-element inputs:
        """
        if self.params:
            if model in ("auto", "reference"):
                raise ValueError(
                    f"a family of stacks (a template with lamina.Param) takes an analytic model, not {model!r}"
                )
            values = {p.name: kwargs.pop(p.name) for p in self.params if p.name in kwargs}
            return eval_family(self, wi, wo, model, values, kwargs)
        if model == "auto":
            c = choose(self, 0.05 if tolerance is None else tolerance, wi)
            samples = c.options.get("samples", samples)
            options = {k: v for k, v in c.options.items() if k != "samples"}
            return self.eval(
                wi, wo, c.model, wavelengths=wavelengths, samples=samples, seed=seed, device=device, **options, **kwargs
            )
        if tolerance is not None:
            raise TypeError(f"tolerance applies to model='auto' only, got model={model!r}")
        m, options, inputs = self._split(model, kwargs)
        on_gpu = _gpu.use_gpu(device, m.name, options, _float32(wi, wo, *(v for v, _ in inputs.values())))
        if m.name == "reference":
            return self._reference_f(wi, wo, wavelengths, samples, seed, None, options)[0]
        wl = _wavelengths(wavelengths)
        arrays = broadcast(wi=(wi, 3), wo=(wo, 3), **inputs)
        named = dict(zip(inputs, arrays[2:]))
        run = _lamina.eval_gpu if on_gpu else _lamina.eval
        return run(self._resolve(wl), self.ext_ior, m.name, arrays[0], arrays[1], options, named)

    def sample(self, wo, u, model: str = "microfacet", *, wavelengths=None, device: str = "auto", **kwargs):
        """Importance-samples the light direction for viewing directions wo (..., 3) from uniform numbers u (..., 3)
        in [0, 1] (broadcast): returns (wi (..., 3), weight (..., channels), pdf (...)) with weight = f(wi, wo)
        cos θi / pdf and pdf per unit solid angle — what a path tracer calls (Mitsuba's si.wi is lamina's wo).

        Each model samples a mixture of its lobes (GGX visible normals for reflection lobes, the cosine for diffuse
        terms), weighted by their energies for this wo; Dirac lobes are not sampled (`specular` gives them). A sample
        that leaves the hemisphere, or a wo with nothing to sample, has weight 0 and pdf 0. model="reference" traces
        one random walk per element (seeded by u, in the channel u[0] picks; weight = its throughput times the
        number of channels in that channel, 0 in the others) and reports pdf 0: a walk's density has no closed
        form; its samples include the Dirac paths. device: as for `eval` (the GPU's float32 samples follow the same
        mixture from the same u)."""
        m, options, inputs = self._split(model, kwargs)
        wl = _wavelengths(wavelengths)
        on_gpu = _gpu.use_gpu(device, m.name, options, _float32(wo, u, *(v for v, _ in inputs.values())))
        wo, u, *rest = broadcast(wo=(wo, 3), u=(u, 3), **inputs)
        if m.name == "reference":  # never on the GPU: use_gpu refuses it
            out = _lamina.reference_sample(self._resolve(wl), self.ext_ior, wo, u, options)
        else:
            run = _lamina.sample_gpu if on_gpu else _lamina.sample
            out = run(self._resolve(wl), self.ext_ior, m.name, wo, u, options, dict(zip(inputs, rest)))
        return out[..., :3], out[..., 3:-1], out[..., -1]

    def pdf(
        self, wi, wo, model: str = "microfacet", *, wavelengths=None, device: str = "auto", **options
    ) -> np.ndarray:
        """The pdf (per unit solid angle) with which `sample` draws wi for the viewing direction wo; (...). device:
        as for `eval`."""
        m, options, inputs = self._split(model, options)
        if m.name == "reference":
            raise ValueError("model 'reference' has no closed-form pdf: its samples come from random walks")
        if inputs:
            raise TypeError(
                f"pdf takes no per-element inputs (the sampling mixture does not depend on them), got {list(inputs)}"
            )
        on_gpu = _gpu.use_gpu(device, m.name, options, _float32(wi, wo))
        wi, wo = broadcast(wi=(wi, 3), wo=(wo, 3))
        run = _lamina.pdf_gpu if on_gpu else _lamina.pdf
        return run(self._resolve(_wavelengths(wavelengths)), self.ext_ior, m.name, wi, wo, options)[..., 0]

    def specular(self, wo, model: str = "microfacet", *, wavelengths=None, **options) -> np.ndarray:
        """The Dirac (mirror) reflection for viewing directions wo (..., 3): the fraction of light from the mirror
        direction that smooth interfaces reflect specularly, per channel (..., channels). It is what `eval` leaves
        out; a renderer adds it as a delta component."""
        m, options, _ = self._split(model, options)
        if m.name == "reference":
            raise ValueError(
                "model 'reference' includes Dirac paths in its samples and albedo; it has no separate specular part"
            )
        (wo,) = broadcast(wo=(wo, 3))
        return _lamina.specular(self._resolve(_wavelengths(wavelengths)), self.ext_ior, m.name, wo, options)

    def reference(
        self,
        wi,
        wo,
        *,
        wavelengths=None,
        samples: int = 100_000,
        seed: int = 0,
        progress=None,
        **options,
    ):
        """Monte Carlo ground truth for f(wi, wo): unbiased, with next-event estimation through the stack's delta
        interfaces (see src/reference.rs). wi, wo: (..., 3), broadcast. Returns (f, stderr), each (..., channels).
        Specular (Dirac) lobes are not part of f. Deterministic for a seed, whatever the thread count. Keyword
        arguments are the reference's options (lamina.models(): the microsurface's `distribution` and `g2`)."""
        return self._reference_f(wi, wo, wavelengths, samples, seed, progress, options)

    def _reference_f(self, wi, wo, wavelengths, samples: int, seed: int, progress, options: dict) -> tuple:
        """`reference` with the reference's options as a dict (checked by Rust against its table)."""
        wl = _wavelengths(wavelengths)
        wi, wo = broadcast(wi=(wi, 3), wo=(wo, 3))
        rows = (_unit_rows("wi", wi), _unit_rows("wo", wo))
        mean, err = _reference.f_estimate(self._resolve(wl), self.ext_ior, *rows, samples, seed, progress, options)
        shape = wi.shape[:-1] + (mean.shape[-1],)
        return mean.reshape(shape), err.reshape(shape)

    def simplify(self, tolerance: float = 0.01, model: str = "belcour") -> Simplified:
        """A simpler stack that is equivalent within `tolerance`, when some layers do not matter:

        - a smooth dielectric interface whose IOR equals the medium's above it does nothing (exact): it goes, and its
          slab joins the one above when that one is empty or of the same medium (adjacent dielectrics of equal IOR
          merge);
        - a slab whose round-trip optical depth at normal incidence, 2 · thickness · max(σa + σs), is below
          `tolerance` goes (it attenuates by at most that);
        - over a conductor base, the interfaces whose Belcour lobes carry less than tolerance / 2 of the reflected
          energy (at every θo ≤ 80°, in every channel) are pruned with everything beneath them, for a black
          (Diffuse(0)) base.

        The error it reports is measured: Σ|f − f_simplified| / Σ|f| under `model`, on the suite's direction grid
        (lamina.reference.suite_directions) at θi ≤ 80°."""
        if isinstance(tolerance, bool) or not isinstance(tolerance, Real) or not 0.0 < tolerance < 1.0:
            raise ValueError(f"tolerance must be in (0, 1), got {tolerance!r}")
        layers, steps = list(self.layers), []
        for i, layer in enumerate(layers):
            if isinstance(layer, Dielectric) and layer.thickness > 0.0:
                tau = layer.thickness * float(np.max(np.add(layer.sigma_a, layer.sigma_s)))
                if 2.0 * tau < tolerance:
                    layers[i] = replace(layer, thickness=0.0, sigma_a=0.0, sigma_s=0.0, g=0.0)
                    steps.append(f"layer {i}: slab of optical depth {tau:.3g} removed")
        i = removed = 0
        while i < len(layers):
            layer, above = layers[i], (layers[i - 1] if i else None)
            outside = above._resolve(None)["ior"] if above is not None else self.ext_ior
            medium = lambda x: (x.sigma_a, x.sigma_s, x.g)  # noqa: E731
            if (
                isinstance(layer, Dielectric)
                and np.all(np.ravel(layer.roughness) == 0.0)
                and isinstance(above, (Dielectric, type(None)))
                and np.allclose(layer._resolve(None)["ior"], outside, rtol=1e-12, atol=0.0)
                and (
                    layer.thickness == 0.0
                    or (above is not None and (above.thickness == 0.0 or medium(above) == medium(layer)))
                )
            ):
                if layer.thickness > 0.0:
                    layers[i - 1] = replace(
                        above,
                        thickness=above.thickness + layer.thickness,
                        sigma_a=layer.sigma_a,
                        sigma_s=layer.sigma_s,
                        g=layer.g,
                    )
                del layers[i]
                steps.append(f"layer {i + removed}: index-matched smooth interface (IOR {layer.ior}) removed")
                removed += 1
                continue
            i += 1
        if isinstance(layers[-1], Conductor) and len(layers) > 1:
            t = np.radians([0.0, 20.0, 40.0, 60.0, 80.0])
            wo = np.stack([np.sin(t), np.zeros_like(t), np.cos(t)], -1)
            energy = Stack(layers, self.ext_ior).lobes(wo)["energy"]  # (5, L, channels)
            share = energy / np.maximum(energy.sum(axis=1, keepdims=True), 1e-300)
            below = np.flip(np.cumsum(np.flip(share, axis=1), axis=1), axis=1).max(axis=(0, 2))  # share of lobes k..L
            keep = next((k for k in range(1, len(layers)) if below[k] < tolerance / 2), len(layers))
            if keep < len(layers):
                steps.append(
                    f"layers {keep}..{len(layers) - 1}: lobes with {below[keep]:.3g} of the energy pruned "
                    "for a black base"
                )
                layers = layers[:keep] + [Diffuse(0.0)]
        simple = Stack(layers, self.ext_ior) if steps else self
        wi, wo = _reference.suite_directions()
        wi = wi[np.array([0, 1, 2, 3])]
        f, g = self.eval(wi, wo, model), simple.eval(wi, wo, model)
        error = float(np.abs(f - g).sum() / max(np.abs(f).sum(), 1e-300))
        return Simplified(simple, error, tuple(steps))

    def lobes(self, wo, model: str = "belcour", *, wavelengths=None) -> dict:
        """The lobes a statistical model builds for viewing direction(s) wo (..., 3), one GGX lobe per interface
        (L = interfaces down to the first opaque one), all centred on the mirror direction of wo:
        {"energy": (..., L, channels), "covariance": (..., L, 2, 2) in the local tangent frame (Yamaguchi et al.
        2019; σI for isotropic stacks), "roughness": (..., L, 2) the GGX (alpha_x, alpha_y) along the covariance's
        eigenvectors, "angle": (..., L) the tangent angle (radians) of the alpha_x axis}. A lobe of roughness 0 is a
        specular (Dirac) reflection. Only model="belcour" has lobes."""
        if _model(model).name != "belcour":
            raise ValueError(f"model must be 'belcour' for lobes, got {model!r}")
        wl = _wavelengths(wavelengths)
        (wo,) = broadcast(wo=(wo, 3))
        rows = _unit_rows("wo", wo)
        lead = wo.shape[:-1]
        energy, cov, rough = (
            np.asarray(a, dtype=np.float64).reshape(lead + np.shape(a)[1:])
            for a in _lamina.belcour_lobes(self._resolve(wl), self.ext_ior, rows.tolist())
        )
        sigma = np.stack([cov[..., 0], cov[..., 1], cov[..., 1], cov[..., 2]], -1).reshape(cov.shape[:-1] + (2, 2))
        return {"energy": energy, "covariance": sigma, "roughness": rough[..., :2], "angle": rough[..., 2]}

    def albedo(
        self,
        wi,
        model: str = "microfacet",
        *,
        wavelengths=None,
        samples: int = 100_000,
        seed: int = 0,
        progress=None,
        **model_options,
    ):
        """Directional albedo ∫ f(wi, wo) cos θo dωo: the fraction of light from wi that the stack reflects.

        wi: (..., 3). Returns (..., channels). For an analytic model the integral is a midpoint quadrature
        (512 x 1024 in θo, φo) of `eval` with `model_options` (its smooth, Dirac parts are not included). With
        model="reference" it is the brute-force Monte Carlo walk with `samples` paths per direction (delta reflections
        included), and the result is a pair (albedo, standard error)."""
        m = _model(model)
        wl = _wavelengths(wavelengths)
        (wi,) = broadcast(wi=(wi, 3))
        rows = _unit_rows("wi", wi)
        if m.name == "reference":
            mean, err = _reference.tally(
                self._resolve(wl), self.ext_ior, rows, samples, seed, progress=progress, options=model_options
            )
            shape = wi.shape[:-1] + (mean.shape[1],)
            return mean[..., 0].reshape(shape), err[..., 0].reshape(shape)
        nt, npp = 512, 1024
        t = (np.arange(nt) + 0.5) * (np.pi / 2 / nt)
        p = (np.arange(npp) + 0.5) * (2 * np.pi / npp)
        wo = np.stack(
            [
                np.outer(np.sin(t), np.cos(p)),
                np.outer(np.sin(t), np.sin(p)),
                np.repeat(np.cos(t)[:, None], npp, axis=1),
            ],
            axis=-1,
        )
        weight = (np.cos(t) * np.sin(t))[:, None, None] * (np.pi / 2 / nt) * (2 * np.pi / npp)
        out = [np.sum(self.eval(w, wo, model, wavelengths=wl, **model_options) * weight, axis=(0, 1)) for w in rows]
        return np.array(out).reshape(wi.shape[:-1] + (len(out[0]),))

    def reference_lobe(
        self,
        wi,
        bins=(18, 36),
        *,
        wavelengths=None,
        samples: int = 1_000_000,
        seed: int = 0,
        progress=None,
        **options,
    ):
        """Brute-force Monte Carlo lobe for light from one direction `wi` (3,): the reflected energy per steradian,
        i.e. f·cos θo averaged over each of n_theta x n_phi bins uniform in (θo, φo) (delta lobes included). Keyword
        arguments are the reference's options, as for `reference`.

        Returns (f_cos, stderr, (theta_edges, phi_edges)) with f_cos and stderr of shape (n_theta, n_phi, channels)
        and edges in radians. bins: two positive integers with n_theta x n_phi at most 2**22."""
        wl = _wavelengths(wavelengths)
        (wi,) = broadcast(wi=(wi, 3))
        if wi.shape != (3,):
            raise ValueError(f"wi must be a single direction of shape (3,), got {wi.shape}")
        try:
            n_theta, n_phi = bins
        except (TypeError, ValueError):
            raise TypeError(f"bins must be a pair of positive integers (n_theta, n_phi), got {bins!r}") from None
        if not all(isinstance(b, Integral) and not isinstance(b, bool) for b in (n_theta, n_phi)):
            raise TypeError(f"bins must be a pair of positive integers (n_theta, n_phi), got {bins!r}")
        if n_theta < 1 or n_phi < 1 or n_theta * n_phi > 1 << 22:
            raise ValueError(f"bins must be positive with n_theta x n_phi in [1, 2**22], got {bins!r}")
        n_theta, n_phi = int(n_theta), int(n_phi)
        mean, err = _reference.tally(
            self._resolve(wl),
            self.ext_ior,
            _unit_rows("wi", wi),
            samples,
            seed,
            bins=(n_theta, n_phi),
            progress=progress,
            options=options,
        )
        te = np.linspace(0, np.pi / 2, n_theta + 1)
        pe = np.linspace(0, 2 * np.pi, n_phi + 1)
        solid = np.outer(np.cos(te[:-1]) - np.cos(te[1:]), np.diff(pe))  # (n_theta, n_phi) steradians
        per_sr = lambda x: np.moveaxis(x[0].reshape(-1, n_theta, n_phi), 0, -1) / solid[..., None]  # noqa: E731
        return per_sr(mean), per_sr(err), (te, pe)


Stack.eval.__doc__ += "\n".join("        " + line for line in options_doc().splitlines())


def _float32(*arrays) -> bool:
    """Whether every array is float32: the result is float32 then, on either device (device="auto"'s rule)."""
    return all(np.asarray(a).dtype == np.float32 for a in arrays)


def _unit_rows(name: str, w: np.ndarray) -> np.ndarray:
    """Rows of w as unit float64 directions above the surface; ValueError otherwise."""
    rows = np.asarray(w, dtype=np.float64).reshape(-1, 3)
    if rows.shape[0] == 0:
        raise ValueError(f"{name} must hold at least one direction, got shape {np.shape(w)}")
    norm = np.linalg.norm(rows, axis=-1, keepdims=True)
    if not np.all(np.isfinite(rows)) or np.any(norm == 0) or np.any(rows[:, 2] <= 0):
        raise ValueError(f"{name} must hold finite, non-zero directions above the surface (z > 0)")
    return rows / norm


def _params(layers) -> tuple:
    """The Params of `layers` in the order they first appear; a name used for two different Params is a ValueError."""
    found = {}
    for layer in layers:
        for _, p, _ in layer_params(layer):
            if found.setdefault(p.name, p) != p:
                raise ValueError(f"two different Params are named {p.name!r}: {found[p.name]} and {p}")
    return tuple(found.values())


def _seeds(template: Stack, resolved: list) -> list:
    """The seeds of Stack.eval_grad (models::Seed: parameter, layer, field, channel or −1, scale): where each Param of
    `template` enters the model, at the bound values `resolved`. The model sees each interface's IOR and κ relative to
    the medium above it, so a dielectric's IOR enters its own interface (scale 1/η above) and the next one
    (−η / ior²), or a diffuse base's η against the outside (1/ext_ior)."""
    index = {p.name: i for i, p in enumerate(template.params)}
    channels = len(next(r[k] for r in resolved for k in ("ior", "albedo") if k in r))
    above = [template.ext_ior] * channels
    seeds = []
    for i, (layer, r) in enumerate(zip(template.layers, resolved)):
        for field, p, entry in layer_params(layer):
            j = index[p.name]
            chans = range(channels) if entry is None else [entry]
            if field == "ior" and r["kind"] != "diffuse":
                for c in chans:
                    seeds.append((j, i, "ior", c, 1.0 / above[c]))
                    below = resolved[i + 1] if i + 1 < len(resolved) else None
                    if r["kind"] == "dielectric" and below is not None and below["kind"] != "diffuse":
                        seeds.append((j, i + 1, "ior", c, -below["ior"][c] / r["ior"][c] ** 2))
                        if below["kind"] == "conductor":
                            seeds.append((j, i + 1, "k", c, -below["k"][c] / r["ior"][c] ** 2))
                    elif r["kind"] == "dielectric" and below is not None:
                        # A diffuse base sees the medium above it against the outside.
                        seeds.append((j, i + 1, "ior", c, 1.0 / template.ext_ior))
            elif field in ("k", "sigma_a", "sigma_s"):
                seeds += [(j, i, field, c, 1.0 / above[c] if field == "k" else 1.0) for c in chans]
            elif field == "albedo":
                seeds += [(j, i, "albedo", c, 1.0) for c in chans]
            elif field == "roughness" and r["kind"] == "diffuse":
                seeds.append((j, i, "diffuse_roughness", -1, 1.0))
            elif field == "roughness":
                axes = ("roughness_x", "roughness_y") if entry is None else (("roughness_x", "roughness_y")[entry],)
                seeds += [(j, i, a, -1, 1.0) for a in axes]
            else:
                seeds.append((j, i, field, -1, 1.0))
        if r["kind"] == "dielectric":
            above = r["ior"]
    return seeds


def _wavelengths(wavelengths):
    if wavelengths is None:
        return None
    try:
        wl = np.atleast_1d(np.asarray(wavelengths, dtype=np.float64))
    except (TypeError, ValueError):
        raise TypeError(f"wavelengths must be a 1-D array of wavelengths in nm, got {wavelengths!r}") from None
    if wl.ndim != 1 or wl.size == 0 or not np.all(np.isfinite(wl)) or np.any(wl <= 0):
        raise ValueError(
            f"wavelengths must be a non-empty 1-D array of positive finite values in nm, got {wavelengths!r}"
        )
    return wl
