"""Plots of BRDF slices (matplotlib, optional dependency)."""

from __future__ import annotations

import numpy as np

from .stack import Stack


def in_plane_directions(theta_deg) -> np.ndarray:
    """Unit directions in the x–z plane at signed zenith angles (degrees): (sin θ, 0, cos θ)."""
    t = np.radians(np.asarray(theta_deg, dtype=np.float64))
    return np.stack([np.sin(t), np.zeros_like(t), np.cos(t)], axis=-1)


def brdf_slices(
    stack: Stack,
    thetas_i_deg=(0, 30, 60, 80),
    model: str = "microfacet",
    title: str | None = None,
    n: int = 721,
    **options,
):
    """Figure of in-plane slices f(wi, wo) for several incident zenith angles (one panel each, log scale), the
    outgoing direction sweeping the plane of incidence from -90° (backward) to +90° (forward, specular side).
    Channels are drawn in red, green and blue. Returns the matplotlib Figure."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    theta_o = np.linspace(-89.5, 89.5, n)
    wo = in_plane_directions(theta_o)
    fig, axes = plt.subplots(
        1, len(thetas_i_deg), figsize=(3.2 * len(thetas_i_deg), 3.2), sharey=True, constrained_layout=True
    )
    for ax, ti in zip(np.atleast_1d(axes), thetas_i_deg):
        wi = in_plane_directions(-ti)  # light on the -x side: its mirror direction is at +θi
        f = stack.eval(wi, wo, model=model, **options)
        for c, colour in enumerate(("tab:red", "tab:green", "tab:blue")):
            ax.semilogy(theta_o, np.maximum(f[:, c], 1e-6), color=colour, lw=1.2)
        ax.axvline(ti, color="0.6", lw=0.8, ls=":")
        ax.set_title(f"θi = {ti:g}°")
        ax.set_xlabel("θo (°), plane of incidence")
        ax.set_xlim(-90, 90)
        ax.grid(True, which="both", alpha=0.25)
    np.atleast_1d(axes)[0].set_ylabel("f (1/sr), linear RGB")
    fig.suptitle(title or f"{model}: {stack!r}"[:110], fontsize=9)
    return fig
