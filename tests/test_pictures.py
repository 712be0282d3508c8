"""The gallery: its error maps separate an exact model from a failing one, measured against the reference's own
noise, and the figure and files are written."""

import lamina
import numpy as np
import pytest
from lamina import materials, pictures

pytest.importorskip("matplotlib")


def test_gallery_errors_separate_exact_and_failing_models():
    """gold with microfacet is exact (the reference samples the same single-scattering BRDF), so its mean error is
    the reference's noise (within 50%, the noise estimate being itself a 2-sample spread); belcour loses the
    scattering slab's light (the README's gallery), an error many times the noise. microfacet cannot represent the
    layered stack: n/a, not an exception."""
    stacks = {"gold": materials.preset("gold"), "scattering-slab": materials.suite("scattering-slab")}
    fig, result = lamina.gallery(stacks, ["microfacet", "belcour"], size=32, spp=64, reference_spp=16, log=lambda _: 0)
    noise, errors = result["noise"], result["errors"]
    assert 0.5 * noise[0] < errors["microfacet"][0] < 1.5 * noise[0], (errors, noise)
    assert errors["belcour"][1] > 4 * noise[1], (errors, noise)
    assert np.isnan(errors["microfacet"][1]) and np.isnan(result["images"]["microfacet"][1]).all()
    assert len(fig.axes) == 2 * (1 + 2 * 2) + 1  # 5 rows x 2 materials, and the colour bar
    fig.clf()


def test_write_gallery_writes_the_figures_and_exr(tmp_path, monkeypatch):
    small = {"gold-clearcoat": materials.suite("gold-clearcoat")}
    monkeypatch.setattr(pictures, "gallery_materials", lambda: small)
    path = pictures.write_gallery(tmp_path, size=16, spp=2, reference_spp=2, docs=tmp_path / "docs", log=lambda _: 0)
    assert path.is_file() and (tmp_path / "features.png").is_file() and (tmp_path / "docs" / "gallery.png").is_file()
    exr = lamina.read_image(tmp_path / "exr" / "gold-clearcoat_belcour.exr")
    assert exr.shape == (16, 16, 3) and np.isfinite(exr).all() and exr.max() > 0
