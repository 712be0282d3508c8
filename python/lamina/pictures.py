"""Pictures that compare models. The gallery: material balls of the validation suite, car paint and the patina
under the built-in sky and sun, each layered model beside the Monte Carlo reference, with heatmaps of each
model's relative error. lamina's main job (`make demo`, `lamina gallery`: `write_gallery`). Needs matplotlib."""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from . import _lamina, materials, oat
from . import gpu as _gpu
from .renderer import DirectionalLight, relative_error, render, save_image, sky, to_srgb8
from .stack import Stack

#: The models the gallery compares: the layered analytic ones and lamina's tabulated one (microfacet takes single
#: interfaces only).
MODELS = ("belcour", "steinberg", "weidlich_wilkie", "albedo_scaling", "tabulated")


def gallery_materials() -> dict[str, Stack]:
    """The suite, Elek's car paint and patina (full coverage: the stack every model can evaluate)."""
    out = {name: materials.suite(name) for name in materials.SUITE}
    out["car-paint"] = materials.car_paint()
    out["patina"] = materials.patina().stack
    return out


def _represents(model: str, stack: Stack) -> bool:
    try:
        _lamina.check_stack(stack._resolve(None), stack.ext_ior, model)
        return True
    except ValueError:
        return False


def sphere_mask(width: int, height: int) -> np.ndarray:
    """Pixels whose centre sees the unit sphere under the orthographic camera contract."""
    x = (np.arange(width) + 0.5) / width * 2 - 1
    y = 1 - (np.arange(height) + 0.5) / height * 2
    return (x[None, :] ** 2 + y[:, None] ** 2) < 1


def gallery(
    stacks: dict[str, Stack] | None = None,
    models=MODELS,
    *,
    size: int = 128,
    spp: int = 32,
    reference_spp: int = 64,
    lights=None,
    seed: int = 0,
    log=print,
):
    """Renders every stack ({label: Stack}; default `gallery_materials()`) with every model (a batch per model, one
    call) and the reference, and composes the labelled grid of `gallery_figure`. Returns (figure, result): result
    holds "images" {model: (N, H, W, 3)}, "reference", "noise" (per material, the reference's own mean relative
    error, estimated from two independent halves), "errors" {model: per-material mean relative error over the
    ball} and "seconds" {model: s}."""
    stacks = gallery_materials() if stacks is None else stacks
    lights = [sky()] if lights is None else lights
    names = list(stacks)
    batch = [stacks[n] for n in names]
    mask = sphere_mask(size, size)
    out: dict = {"names": names, "models": list(models), "images": {}, "errors": {}, "seconds": {}}
    t = time.perf_counter()
    half = max(1, reference_spp // 2)
    halves = [
        render(batch, "reference", width=size, height=size, spp=half, lights=lights, seed=seed + k) for k in (1, 2)
    ]
    out["seconds"]["reference"] = time.perf_counter() - t
    out["reference"] = 0.5 * (halves[0] + halves[1])
    # The halves differ by twice the noise of their mean (independent, equal variance): half their error is the
    # reference's own noise, the floor under every model's error.
    out["noise"] = [0.5 * float(relative_error(halves[0][k], halves[1][k])[mask].mean()) for k in range(len(names))]
    seconds = out["seconds"]["reference"]
    log(f"reference: {len(names)} materials, {reference_spp} walks per pixel and channel, {seconds:.1f} s")
    for m in models:
        t = time.perf_counter()
        # A model that cannot represent a stack (microfacet and a layered one) leaves NaN: "n/a" in the figure.
        ok = [k for k, s in enumerate(batch) if _represents(m, s)]
        images = np.full_like(out["reference"], np.nan)
        if ok:
            images[ok] = render([batch[k] for k in ok], m, width=size, height=size, spp=spp, lights=lights, seed=seed)
        out["images"][m] = images
        out["seconds"][m] = time.perf_counter() - t
        err = relative_error(images, out["reference"])
        out["errors"][m] = [float(err[k][mask].mean()) for k in range(len(names))]
        log(f"{m}: {out['seconds'][m]:.1f} s, mean relative error {np.nanmean(out['errors'][m]):.3f}")
    out.update(spp=spp, reference_spp=reference_spp)
    return gallery_figure(out), out


def gallery_figure(result: dict, *, max_error: float = 0.5, exposure: float = 0.0):
    """A labelled grid: one column per material; rows: the reference, then per model its render and its relative
    error heatmap against the reference (luminance, capped at `max_error`) with a colour bar."""
    import matplotlib.pyplot as plt

    names, models = result["names"], result["models"]
    rows = 1 + 2 * len(models)
    fig, axes = plt.subplots(rows, len(names), figsize=(1.25 * len(names) + 1.3, 1.25 * rows + 0.6), squeeze=False)
    size = result["reference"].shape[1]
    mask = sphere_mask(size, size)
    for k, name in enumerate(names):
        axes[0, k].imshow(to_srgb8(result["reference"][k], exposure))
        axes[0, k].set_title(f"{name}\nnoise {100 * result['noise'][k]:.1f}%", fontsize=7)
        for r, m in enumerate(models):
            image = result["images"][m][k]
            if np.isnan(image).all():
                for ax in axes[1 + 2 * r : 3 + 2 * r, k]:
                    ax.text(0.5, 0.5, "n/a", ha="center", va="center", fontsize=8, transform=ax.transAxes)
                continue
            axes[1 + 2 * r, k].imshow(to_srgb8(image, exposure))
            err = np.where(mask, relative_error(image, result["reference"][k]), np.nan)
            axes[2 + 2 * r, k].imshow(err, cmap="magma", vmin=0, vmax=max_error)
            axes[2 + 2 * r, k].set_title(f"mean {100 * result['errors'][m][k]:.0f}%", fontsize=7, pad=2)
    axes[0, 0].set_ylabel("reference", fontsize=8)
    for r, m in enumerate(models):
        axes[1 + 2 * r, 0].set_ylabel(m, fontsize=8)
        axes[2 + 2 * r, 0].set_ylabel("rel. error", fontsize=8)
    for ax in axes.flat:
        ax.set_xticks([])
        ax.set_yticks([])
        for s in ax.spines.values():
            s.set_visible(False)
    fig.subplots_adjust(left=0.05, right=0.9, top=0.93, bottom=0.01, wspace=0.04, hspace=0.25)
    heat = plt.cm.ScalarMappable(plt.Normalize(0, max_error), "magma")
    bar = fig.colorbar(heat, cax=fig.add_axes([0.92, 0.2, 0.012, 0.6]))
    bar.set_label(f"|Y − Y_ref| / Y_ref (luminance), capped at {max_error:.0%}", fontsize=8)
    bar.ax.tick_params(labelsize=7)
    fig.suptitle(
        "lamina: layered models beside the Monte Carlo reference, built-in sky and sun "
        f"({size}², {result['spp']} spp; reference {result['reference_spp']} walks/px/channel)",
        fontsize=9,
    )
    return fig


def features_figure(size: int = 256, spp: int = 32, log=print):
    """What only weidlich_wilkie evaluates: car paint with per-texel flake normals (Elek 2010's sparkle) and the
    patina where a mask covers the copper, beside car paint without flakes."""
    import matplotlib.pyplot as plt

    t = time.perf_counter()
    paint = materials.car_paint()
    patina = materials.patina()
    panels = [
        ("car paint, no flakes", render(paint, "weidlich_wilkie", width=size, height=size, spp=spp)),
        (
            "car paint, flake normals",
            render(paint, "weidlich_wilkie", width=size, height=size, spp=spp, flake_normal=materials.flake_texture()),
        ),
        (
            "patina, fractal mask",
            render(patina, "weidlich_wilkie", width=size, height=size, spp=spp, mask=materials.patina_mask()),
        ),
    ]
    log(f"features (weidlich_wilkie, per-element textures): {time.perf_counter() - t:.1f} s")
    fig, axes = plt.subplots(1, len(panels), figsize=(3.0 * len(panels), 3.3))
    for ax, (title, image) in zip(axes, panels):
        ax.imshow(to_srgb8(image))
        ax.set_title(title, fontsize=9)
        ax.set_axis_off()
    fig.suptitle(f"weidlich_wilkie with per-element inputs as textures ({size}², {spp} spp, sky and sun)", fontsize=9)
    fig.tight_layout()
    return fig


def gooey_figure(size: int = 256, texture: int = 512, log=print):
    """Oat 2006's gooey ball (lamina.oat.organic_textures: a translucent membrane over veins, 3 texels deep) in the
    three variants, with the two optimizations' differences from the full technique and their render times."""
    import matplotlib.pyplot as plt

    m = oat.Material(**oat.organic_textures(texture, seed=1), thickness=3.0)
    light = [DirectionalLight((-0.5, 0.6, 0.8), (3.0, 3.0, 3.0))]
    images, seconds = [], []
    for v in oat.VARIANTS:
        start = time.perf_counter()
        images.append(render(material=m.with_variant(v), width=size, height=size, lights=light, progress=False))
        seconds.append(time.perf_counter() - start)
    fig, axes = plt.subplots(2, 3, figsize=(12, 8.4), constrained_layout=True)
    scale = images[0].mean()
    for k, (v, img, sec) in enumerate(zip(oat.VARIANTS, images, seconds)):
        axes[0, k].imshow(to_srgb8(img))
        axes[0, k].set_title(f'variant="{v}": {1e3 * sec:.0f} ms ({size}², CPU)', fontsize=10)
        diff = np.abs(img - images[0]).mean(-1) / scale
        if k == 0:
            continue
        im = axes[1, k].imshow(diff, cmap="magma", vmin=0.0, vmax=0.5)
        axes[1, k].set_title(f"|{v} − full| / mean(full): mean {diff.mean():.3f}", fontsize=9)
        log(f"gooey {v}: {1e3 * sec:.0f} ms, mean difference from full {diff.mean():.3f}")
    axes[1, 0].imshow(to_srgb8(oat.light_map(m, light)))
    axes[1, 0].set_title("full's texture-space light map (u →, v ↓)", fontsize=9)
    fig.colorbar(im, ax=axes[1, 1:], shrink=0.8)
    for ax in axes.ravel():
        ax.axis("off")
    fig.suptitle(
        "Oat 2006's gooey layers: a translucent membrane over veins. full: parallax and a blurred texture-space light "
        "map;\nnormal_filtered: the Poisson disc over the normal map; vertex_normal: inner layer lit by the vertex "
        "normal, unfiltered",
        fontsize=10,
    )
    return fig


def write_gallery(out="out", *, size: int = 128, spp: int = 32, reference_spp: int = 64, docs=None, log=print) -> Path:
    """Renders the gallery and writes `out`/gallery.png, `out`/features.png (weidlich_wilkie's textured car paint and
    patina), `out`/gooey.png (Oat 2006 in its three variants), one EXR per material and model (`out`/exr/), and
    copies of the PNGs into the folder `docs` if given. Returns the gallery PNG's path."""
    out = Path(out)
    (out / "exr").mkdir(parents=True, exist_ok=True)
    start = time.perf_counter()
    adapter = _gpu.adapter()
    found = f"{adapter['name']} ({adapter['device_type']})" if adapter else f"none ({_gpu._adapter()[1]})"
    hardware = _gpu.use_gpu("auto", None)  # device="auto" renders there (a hardware GPU; lavapipe is not faster)
    device = f"the GPU, {found}" if hardware else f"the CPU ({_threads()} threads; GPU adapter: {found})"
    log(f"lamina gallery: the models render on {device}, the reference and the textured scenes on the CPU.")
    fig, result = gallery(size=size, spp=spp, reference_spp=reference_spp, log=log)
    for k, name in enumerate(result["names"]):
        save_image(out / "exr" / f"{name}_reference.exr", result["reference"][k])
        for m in result["models"]:
            save_image(out / "exr" / f"{name}_{m}.exr", result["images"][m][k])
    path = out / "gallery.png"
    fig.savefig(path, dpi=110)
    features = features_figure(size=2 * size, spp=spp, log=log)
    features.savefig(out / "features.png", dpi=110)
    gooey = gooey_figure(size=2 * size, log=log)
    gooey.savefig(out / "gooey.png", dpi=100)
    if docs is not None:
        Path(docs).mkdir(parents=True, exist_ok=True)
        fig.savefig(Path(docs) / "gallery.png", dpi=110)
        features.savefig(Path(docs) / "features.png", dpi=110)
        gooey.savefig(Path(docs) / "gooey.png", dpi=100)
    log(
        f"wrote {path}, {out / 'features.png'}, {out / 'gooey.png'} and "
        f"{len(result['names']) * (1 + len(result['models']))} EXR images"
    )
    log(f"total {time.perf_counter() - start:.1f} s")
    return path


def _threads() -> int:
    import os

    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1
