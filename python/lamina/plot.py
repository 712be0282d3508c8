"""Plots of BRDF slices (matplotlib, optional dependency): `brdf_slices` draws f along a plane of outgoing
directions for several incident angles, for one or several models, with the reference and its ±2 SE band."""

from __future__ import annotations

import numpy as np

from .layers import Conductor, Dielectric, Diffuse
from .spectrum import RGB_WAVELENGTHS
from .stack import Stack

#: Where the outgoing directions sweep: the plane of incidence, or the plane through the normal perpendicular to it.
PLANES = ("incidence", "perpendicular")
_CHANNELS = ("tab:red", "tab:green", "tab:blue")
_STYLES = ("-", "--", "-.", ":")


def in_plane_directions(theta_deg) -> np.ndarray:
    """Unit directions in the x–z plane at signed zenith angles (degrees): (sin θ, 0, cos θ)."""
    t = np.radians(np.asarray(theta_deg, dtype=np.float64))
    return np.stack([np.sin(t), np.zeros_like(t), np.cos(t)], axis=-1)


def describe(stack: Stack) -> str:
    """A short description of a stack's layers, top first, for titles."""
    parts = []
    for layer in stack.layers:
        r = layer.roughness if not isinstance(layer, Diffuse) else layer.roughness
        alpha = f"α {r:g}" if np.isscalar(r) else f"α ({r[0]:g}, {r[1]:g})"
        if isinstance(layer, Dielectric):
            ior = np.round(np.mean(layer.ior), 3)
            slab = f", d {layer.thickness:g}, σa {layer.sigma_a}, σs {layer.sigma_s}" if layer.thickness else ""
            parts.append(f"dielectric η {ior:g} {alpha}{slab}")
        elif isinstance(layer, Conductor):
            name = str(getattr(layer.ior, "name", None) or "conductor").removeprefix("n of ")
            parts.append(f"{name} {alpha}")
        else:
            parts.append(f"diffuse {np.round(layer.albedo, 2).tolist()} σ {layer.roughness:g}")
    return " / ".join(parts)


def brdf_slices(
    stack: Stack,
    thetas_i_deg=(0, 30, 60, 80),
    model="microfacet",
    title: str | None = None,
    n: int = 721,
    *,
    plane: str = "incidence",
    reference: int | None = None,
    channels: bool | None = None,
    **options,
):
    """Figure of slices f(wi, wo) (log scale, one panel per incident angle θi). The light comes from the −x side,
    so the mirror direction is at θo = +θi (dotted line). `plane`: "incidence" sweeps wo through the plane of
    incidence from −90° (back towards the light) to +90° (forward); "perpendicular" through the plane containing
    the normal and the y axis (shows anisotropy across the plane of incidence).

    model: a model name or a list of them, overlaid (line styles); `reference`: paths per direction for the Monte
    Carlo reference, drawn as a ±2 SE band (None: none). channels: draw R, G and B (the legend gives their
    wavelengths, RGB_WAVELENGTHS) — the default for one model; with several models, the green channel only.
    Zeros (e.g. below the horizon, or a lobe that ends) leave gaps on the log axis; nothing is floored. A smooth top's
    Dirac reflection, which f leaves out, is marked at the mirror direction with its weight. Returns the Figure;
    save it as PNG, PDF or SVG by the file name."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    if plane not in PLANES:
        raise ValueError(f"plane must be one of {PLANES}, got {plane!r}")
    models = [model] if isinstance(model, str) else list(model)
    channels = len(models) == 1 if channels is None else channels
    shown = range(3) if channels else (1,)
    theta_o = np.linspace(-89.5, 89.5, n)
    wo = in_plane_directions(theta_o)
    if plane == "perpendicular":
        wo = wo[:, [1, 0, 2]]  # the y–z plane
    fig, axes = plt.subplots(
        1,
        len(thetas_i_deg),
        figsize=(3.4 * len(thetas_i_deg), 3.6),
        sharey=True,
        constrained_layout=True,
        squeeze=False,
    )
    wl = [f"{w:g} nm" for w in RGB_WAVELENGTHS]
    for ax, ti in zip(axes[0], thetas_i_deg):
        wi = in_plane_directions(-ti)
        if reference:
            f, se = stack.reference(wi, wo, samples=reference, progress=False)
            for c in shown:
                lo, hi = f[:, c] - 2 * se[:, c], f[:, c] + 2 * se[:, c]
                ax.fill_between(theta_o, np.where(lo > 0, lo, np.nan), hi, color=_CHANNELS[c], alpha=0.2, lw=0)
        for m, style in zip(models, _STYLES):
            f = stack.eval(wi, wo, model=m, **options)
            for c in shown:
                ax.semilogy(theta_o, np.where(f[:, c] > 0, f[:, c], np.nan), style, color=_CHANNELS[c], lw=1.2)
        if plane == "incidence":
            ax.axvline(ti, color="0.5", lw=0.8, ls=":")
            dirac = stack.specular(in_plane_directions(ti), models[0] if models[0] != "reference" else "microfacet")
            if np.max(dirac) > 0:
                ax.annotate(
                    f"Dirac ×{np.mean(dirac):.3f}",
                    (ti, 1.0),
                    xycoords=("data", "axes fraction"),
                    xytext=(ti - 5 if ti > 45 else ti + 3, 0.92),
                    textcoords=("data", "axes fraction"),
                    fontsize=7,
                    ha="right" if ti > 45 else "left",
                    arrowprops={"arrowstyle": "->", "lw": 0.6},
                )
        ax.set_title(f"θi = {ti:g}°", fontsize=10)
        ax.set_xlabel("θo (°), " + ("+ = forward (mirror side)" if plane == "incidence" else "across the plane"))
        ax.set_xlim(-90, 90)
        ax.grid(True, which="both", alpha=0.25)
    axes[0, 0].set_ylabel("f (1/sr), no cosine")
    handles = [plt.Line2D([], [], color=_CHANNELS[c], label=f"{'RGB'[c]} ({wl[c]})") for c in shown]
    handles += [plt.Line2D([], [], color="0.3", ls=s, label=m) for m, s in zip(models, _STYLES)]
    if reference:
        handles.append(
            plt.matplotlib.patches.Patch(color="0.6", alpha=0.3, label=f"reference ±2 SE ({reference} paths)")
        )
    if plane == "incidence":
        handles.append(plt.Line2D([], [], color="0.5", ls=":", label="mirror direction θo = θi"))
    fig.legend(handles=handles, fontsize=7, loc="outside right center")
    head = title or ", ".join(models)
    fig.suptitle(f"{head}\n{describe(stack)}", fontsize=9)
    return fig
