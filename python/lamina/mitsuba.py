"""lamina and Mitsuba 3 (`pip install lamina[mitsuba]`): lamina materials as a Mitsuba BSDF plugin (`register`,
`bsdf`), and the closest Mitsuba `principled` material to a stack, for comparing the production model with lamina's
models and reference.

    import mitsuba as mi, lamina, lamina.mitsuba
    mi.set_variant("llvm_ad_rgb")
    lamina.mitsuba.register()
    scene = mi.load_dict({..., "ball": {"type": "sphere", "bsdf": lamina.mitsuba.bsdf(stack, "belcour")}})

Mitsuba works in radiance mode: its `si.wi` points towards the camera (lamina's wo) and `eval`'s wo towards the
light (lamina's wi), and `eval` returns f·cos θ of its wo. The functions here convert, so that they return lamina's f.

`principled(stack)` maps a stack onto principled's parameters (Mitsuba 3.9, src/bsdfs/principled.cpp):
- a conductor base becomes the metallic lobe: metallic 1, base_color its normal-incidence Fresnel reflectance F0
  (principled's Schlick F0), roughness √alpha (principled squares it; anisotropic bases map alpha_x/alpha_y onto
  principled's `anisotropic` aspect, and the tangent angle is dropped);
- a diffuse base becomes the diffuse lobe: metallic 0, base_color its albedo times the transmittance of the slabs
  above it, e^{−2 Σ σa d} at normal incidence; the top coat's IOR becomes `eta` of the specular lobe and its alpha
  the roughness;
- a coat over a conductor becomes the clearcoat: clearcoat 1, and clearcoat_gloss from the coat's alpha through
  principled's alpha = lerp(0.1, 0.001, gloss), clamped: its GTR1 lobe cannot be rougher than 0.1. Its IOR is fixed
  at 1.5 (F0 = 0.04), and it does not attenuate the base. A coat rougher than that roughens the metallic lobe
  instead, alpha = √(alpha_base² + alpha_coat²) per axis. Deeper coats and scattering are dropped.
- a smooth top's Dirac reflection is left out, as lamina's models leave it out of f (`Stack.specular` has it):
  principled's sharpest lobe (alpha 0.001) is a finite spike that no f comparison could weigh fairly. A smooth
  coat over a conductor therefore maps to no clearcoat, and over a diffuse base to specular 0.
docs/validation.md measures what these approximations cost against the reference.
"""

from __future__ import annotations

import numpy as np

from . import optics


def _mi():
    try:
        import mitsuba as mi
    except ImportError:
        raise ImportError("lamina.mitsuba needs Mitsuba 3: pip install lamina[mitsuba]") from None
    return mi


def variant() -> str:
    """The Mitsuba variant lamina's helpers use: the current one (mi.set_variant) if it is an RGB variant, else
    llvm_ad_rgb where Dr.Jit finds a libLLVM, else scalar_rgb."""
    mi = _mi()
    if mi.variant() in ("llvm_ad_rgb", "scalar_rgb"):
        return mi.variant()
    for v in ("llvm_ad_rgb", "scalar_rgb"):
        try:
            mi.set_variant(v)
            return v
        except Exception:  # no usable libLLVM: scalar_rgb computes the same BSDFs
            continue
    raise RuntimeError("Mitsuba has neither llvm_ad_rgb nor scalar_rgb")


def principled(stack) -> dict:
    """The closest Mitsuba `principled` BSDF to `stack`, as a dict for mi.load_dict (see the module docstring)."""
    layers = stack._resolve(None)
    base, coats = layers[-1], [x for x in layers if x["kind"] == "dielectric"]
    d = {"type": "principled", "spec_tint": 0.0, "sheen": 0.0}
    if base["kind"] == "conductor":
        eta = np.asarray(base["ior"]) / (coats[-1]["ior"][0] if coats else stack.ext_ior)
        f0 = optics.fresnel_conductor(1.0, eta, np.asarray(base["k"]) / (coats[-1]["ior"][0] if coats else 1.0))
        ax, ay = base["roughness"]
        d |= {"metallic": 1.0, "base_color": {"type": "rgb", "value": np.ravel(f0).tolist()}}
        if coats and max(coats[0]["roughness"]) > 0.0:
            alpha = float(np.sqrt(np.prod(coats[0]["roughness"])))
            d |= {"clearcoat": 1.0, "clearcoat_gloss": float(np.clip((0.1 - alpha) / 0.099, 0.0, 1.0))}
            if alpha > 0.1:  # rougher than the clearcoat can be: it roughens the metal instead
                ax, ay = np.hypot(ax, alpha), np.hypot(ay, alpha)
        d |= _roughness(ax, ay)
        return d
    tau = sum(np.asarray(c["sigma_a"]) * c["thickness"] for c in coats) if coats else 0.0
    albedo = np.asarray(base["albedo"]) * np.exp(-2.0 * np.asarray(tau))
    d |= {"metallic": 0.0, "base_color": {"type": "rgb", "value": np.broadcast_to(albedo, 3).tolist()}}
    if coats and max(coats[0]["roughness"]) > 0.0:
        d["eta"] = max(float(np.mean(coats[0]["ior"])) / stack.ext_ior, 1.001)
        d |= _roughness(*coats[0]["roughness"])
    else:
        d |= {"specular": 0.0, "roughness": 0.5}  # no specular lobe; Burley's diffuse at principled's default roughness
    return d


def _roughness(ax: float, ay: float) -> dict:
    """principled's roughness and anisotropic for GGX (ax, ay): ax = r²/aspect, ay = r²·aspect, aspect =
    √(1 − 0.9 anisotropic) (principledhelpers.h, calc_dist_params)."""
    lo, hi = sorted((max(ax, 1e-3), max(ay, 1e-3)))
    aspect = np.sqrt(lo / hi)  # ≥ √0.1: principled's strongest anisotropy
    anisotropic = float(np.clip((1.0 - aspect**2) / 0.9, 0.0, 1.0))
    return {"roughness": float(np.sqrt(np.sqrt(lo * hi))), "anisotropic": anisotropic}


def _si(mi, dr, wo: np.ndarray):
    si = dr.zeros(mi.SurfaceInteraction3f, len(wo))
    si.wi = mi.Vector3f(np.ascontiguousarray(wo.T, dtype=np.float32))
    return si


def eval_f(bsdf: dict, wi, wo) -> np.ndarray:
    """f(wi, wo) (lamina's convention: wi towards the light, wo towards the viewer, f without cos θi) of a Mitsuba
    BSDF dict, for rows wi, wo (n, 3): (n, 3) float64."""
    mi = _mi()
    import drjit as dr

    v = variant()
    wi, wo = (np.ascontiguousarray(np.broadcast_arrays(wi, wo)[k].reshape(-1, 3), dtype=np.float64) for k in (0, 1))
    b, ctx = mi.load_dict(bsdf), mi.BSDFContext()
    if v.startswith("llvm"):
        value = np.array(b.eval(ctx, _si(mi, dr, wo), mi.Vector3f(np.ascontiguousarray(wi.T, dtype=np.float32)))).T
    else:
        value = []
        for a, o in zip(wi, wo):
            si = dr.zeros(mi.SurfaceInteraction3f)
            si.wi = mi.Vector3f(*map(float, o))
            value.append(np.array(b.eval(ctx, si, mi.Vector3f(*map(float, a)))).ravel())
        value = np.array(value)
    with np.errstate(divide="ignore", invalid="ignore"):
        f = value.astype(np.float64) / np.abs(wi[:, 2:3])
    return np.where(wi[:, 2:3] > 0, f, 0.0)


def albedo(bsdf: dict, wo, samples: int = 20_000, seed: int = 0) -> np.ndarray:
    """Directional albedo seen from wo (n, 3): the mean weight of the BSDF's own sampling, (n, 3)."""
    mi = _mi()
    import drjit as dr

    v = variant()
    wo = np.asarray(wo, dtype=np.float64).reshape(-1, 3)
    b, ctx = mi.load_dict(bsdf), mi.BSDFContext()
    u = np.random.default_rng(seed).uniform(size=(samples, 3)).astype(np.float32)
    out = []
    for w in wo:
        if v.startswith("llvm"):
            si = _si(mi, dr, np.repeat(w[None], samples, 0))
            _, weight = b.sample(ctx, si, mi.Float(u[:, 0]), mi.Point2f(np.ascontiguousarray(u[:, 1:].T)))
            out.append(np.array(weight).T.mean(axis=0))
        else:
            acc = np.zeros(3)
            for s in u:
                si = dr.zeros(mi.SurfaceInteraction3f)
                si.wi = mi.Vector3f(*map(float, w))
                acc += np.array(b.sample(ctx, si, float(s[0]), mi.Point2f(float(s[1]), float(s[2])))[1]).ravel()
            out.append(acc / samples)
    return np.array(out)


# --- lamina materials inside Mitsuba -------------------------------------------------------------------------------

PLUGIN = "lamina"


def bsdf(stack, model: str = "belcour", **options) -> dict:
    """The dict `mi.load_dict` accepts for a lamina material (after `register()`): `stack` under `model` with its
    options, pickled into the plugin's `material` string property. Any analytic model of the catalogue works;
    per-element inputs and model="reference" (a random walk, with no closed-form pdf) do not."""
    import base64
    import pickle

    from .catalogue import model as _model

    m = _model(model)
    if m.name == "reference":
        raise ValueError("model must be an analytic model of lamina.MODELS: 'reference' has no closed-form pdf")
    stack.eval([0.0, 0.0, 1.0], [0.0, 0.0, 1.0], m.name, **options)  # refuses bad options and stacks here
    data = base64.b64encode(pickle.dumps((stack, m.name, options))).decode("ascii")
    return {"type": PLUGIN, "material": data}


def register() -> None:
    """Registers the `lamina` BSDF plugin with Mitsuba (in the current variant: call it after mi.set_variant).

    It turns off Dr.Jit's symbolic loops and calls (dr.JitFlag.SymbolicLoops / SymbolicCalls), so that the
    plugin, which evaluates on NumPy arrays, sees concrete values when Mitsuba renders in a JIT variant."""
    mi = _mi()
    import drjit as dr

    dr.set_flag(dr.JitFlag.SymbolicLoops, False)
    dr.set_flag(dr.JitFlag.SymbolicCalls, False)
    mi.register_bsdf(PLUGIN, lambda props: _plugin_class(mi)(props))


def _plugin_class(mi):
    import base64
    import pickle

    import drjit as dr

    glossy, delta = mi.BSDFFlags.GlossyReflection, mi.BSDFFlags.DeltaReflection

    def rows(v) -> np.ndarray:
        """A Dr.Jit or scalar 3-vector as float64 rows (n, 3)."""
        return np.array(v, dtype=np.float64).reshape(3, -1).T

    def mask(active, n: int) -> np.ndarray:
        """Mitsuba's `active` (a bool, or a Bool of width 1 or n) as a bool array (n,)."""
        return np.broadcast_to(np.array(active, dtype=bool).reshape(-1), (n,))

    def out(a: np.ndarray, kind, jit: bool):
        """Rows (n, 3) as a Color3f / Vector3f, or a float array (n,) as a Float, in the variant's form."""
        a = np.asarray(a, dtype=np.float32)
        if a.ndim == 1:
            return mi.Float(a) if jit else float(a[0])
        return kind(np.ascontiguousarray(a.T)) if jit else kind(*map(float, a[0]))

    class LaminaBSDF(mi.BSDF):
        """A lamina stack under one of lamina's models: eval, its own importance sampling and pdf, and the Dirac
        reflection of a smooth top as a second, delta component. Mitsuba's si.wi is lamina's wo."""

        def __init__(self, props):
            super().__init__(props)
            self.stack, self.model, self.options = pickle.loads(base64.b64decode(props["material"]))
            top = self.stack.layers[0]
            self.smooth_top = getattr(top, "roughness", 1.0) in (0.0, (0.0, 0.0))
            components = [glossy | mi.BSDFFlags.FrontSide]
            if self.smooth_top:
                components.append(delta | mi.BSDFFlags.FrontSide)
            self.m_components = components
            flags = components[0]
            for c in components[1:]:
                flags = flags | c
            self.m_flags = flags

        def _enabled(self, ctx) -> tuple:
            return bool(ctx.is_enabled(glossy, 0)), self.smooth_top and bool(ctx.is_enabled(delta, 1))

        def _delta_probability(self, ctx, wo: np.ndarray) -> np.ndarray:
            """The chance of sampling the Dirac component: its reflectance (mean over channels)."""
            has_glossy, has_delta = self._enabled(ctx)
            if not has_delta:
                return np.zeros(len(wo))
            if not has_glossy:
                return np.ones(len(wo))
            return self.stack.specular(wo, self.model, **self.options).mean(axis=-1)

        def _pairs(self, ctx, si, wo, active) -> tuple:
            """lamina's (wi, wo) rows (n, 3) from Mitsuba's (wo, si.wi), and where the glossy component applies."""
            lwo, lwi = rows(si.wi), rows(wo)
            n = max(len(lwo), len(lwi))
            lwo, lwi = np.broadcast_to(lwo, (n, 3)), np.broadcast_to(lwi, (n, 3))
            return lwi, lwo, mask(active, n) & (lwo[:, 2] > 0) & (lwi[:, 2] > 0) & self._enabled(ctx)[0]

        def eval(self, ctx, si, wo, active=True):
            lwi, lwo, ok = self._pairs(ctx, si, wo, active)
            f = self.stack.eval(lwi, lwo, self.model, **self.options) * lwi[:, 2:3]
            return out(np.where(ok[:, None], f, 0.0), mi.Color3f, dr.is_jit_v(si.wi))

        def pdf(self, ctx, si, wo, active=True):
            lwi, lwo, ok = self._pairs(ctx, si, wo, active)
            p = self.stack.pdf(lwi, lwo, self.model, **self.options) * (1.0 - self._delta_probability(ctx, lwo))
            return out(np.where(ok, p, 0.0), None, dr.is_jit_v(si.wi))

        def eval_pdf(self, ctx, si, wo, active=True):
            return self.eval(ctx, si, wo, active), self.pdf(ctx, si, wo, active)

        def sample(self, ctx, si, sample1, sample2, active=True):
            jit = dr.is_jit_v(si.wi)
            u1, u2 = np.array(sample1, dtype=np.float64).reshape(-1), np.array(sample2, dtype=np.float64).reshape(2, -1)
            lwo = rows(si.wi)
            n = max(len(lwo), len(u1), u2.shape[1])
            lwo, u1, u2 = np.broadcast_to(lwo, (n, 3)), np.broadcast_to(u1, (n,)), np.broadcast_to(u2, (2, n))
            ok = mask(active, n) & (lwo[:, 2] > 0)
            p_delta = self._delta_probability(ctx, lwo)
            pick_delta = u1 < p_delta
            # The glossy sample reuses u1, rescaled to [0, 1) past the delta's share.
            u = np.stack([np.clip((u1 - p_delta) / np.maximum(1.0 - p_delta, 1e-12), 0.0, 1.0 - 1e-7), *u2], -1)
            wi, weight, pdf = self.stack.sample(lwo, u, self.model, **self.options)
            weight = weight / np.maximum(1.0 - p_delta, 1e-12)[:, None]
            pdf = pdf * (1.0 - p_delta)
            if self.smooth_top:
                mirror = lwo * np.array([-1.0, -1.0, 1.0])
                spec = self.stack.specular(lwo, self.model, **self.options) / np.maximum(p_delta, 1e-12)[:, None]
                wi = np.where(pick_delta[:, None], mirror, wi)
                weight = np.where(pick_delta[:, None], spec, weight)
                pdf = np.where(pick_delta, p_delta, pdf)
            ok &= pdf > 0
            bs = dr.zeros(mi.BSDFSample3f, n) if jit else dr.zeros(mi.BSDFSample3f)
            bs.wo = out(wi, mi.Vector3f, jit)
            bs.pdf = out(np.where(ok, pdf, 0.0), None, jit)
            bs.eta = 1.0
            kinds = np.where(pick_delta, int(delta), int(glossy)).astype(np.uint32)
            bs.sampled_type = mi.UInt32(kinds) if jit else int(kinds[0])
            bs.sampled_component = mi.UInt32(pick_delta.astype(np.uint32)) if jit else int(pick_delta[0])
            return bs, out(np.where(ok[:, None], weight, 0.0), mi.Color3f, jit)

        def to_string(self):
            return f"LaminaBSDF[model={self.model!r}, stack={self.stack!r}]"

    return LaminaBSDF
