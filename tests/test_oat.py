"""Oat 2006's gooey layers (lamina.oat): the primitives against the chapter's listings, written again here in NumPy;
the composite's limits on a flat plane, where every term has a closed form; the light map of the sphere against
N·L; the three variants against each other; the physical blur radius."""

from __future__ import annotations

import lamina
import numpy as np
import pytest
from conftest import uv_sphere_mesh
from lamina import oat

#: The chapter's 12 unit-disc taps (Oat 2006, Listing 2), as printed.
DISC = np.array(
    [
        [-0.326212, -0.40581],
        [-0.840144, -0.07358],
        [-0.695914, 0.457137],
        [-0.203345, 0.620716],
        [0.96234, -0.194983],
        [0.473434, -0.480026],
        [0.519456, 0.767022],
        [0.185461, -0.893124],
        [0.507431, 0.064425],
        [0.89642, 0.412458],
        [-0.32194, -0.932615],
        [-0.791559, -0.59771],
    ]
)


def test_poisson_disc_is_the_listing():
    np.testing.assert_array_equal(oat.POISSON_DISC, DISC)


def _reflect_listing(v, n):
    """HLSL reflect(i, n) = i − 2 (i·n) n, with i = −v (Listing 1)."""
    i = -v
    return i - 2 * np.sum(i * n, -1, keepdims=True) * n


def _unit(a):
    return a / np.linalg.norm(a, axis=-1, keepdims=True)


def test_parallax_is_listing_1(rng):
    uv = rng.uniform(size=(500, 2))
    v = _unit(rng.normal(size=(500, 3)) + [0, 0, 2])
    n = _unit(rng.normal(size=(500, 3)) * 0.3 + [0, 0, 1])
    d = rng.uniform(0, 20, 500)
    r = _reflect_listing(v, n)
    t = np.stack([r[:, 0], r[:, 1], -r[:, 2]], -1)
    s = d / np.abs(t[:, 2])
    uv_in, s_in = oat.parallax(uv, v, n, d)  # the chapter's texel, 1/1024
    np.testing.assert_allclose(s_in, s, rtol=1e-12)
    np.testing.assert_allclose(uv_in, uv + (1 / 1024) * s[:, None] * t[:, :2], rtol=1e-12, atol=1e-15)
    # Head-on, the inner layer lies straight beneath, at the layer's depth; a (u, v) texel pair scales each axis.
    uv_0, s_0 = oat.parallax([0.3, 0.6], [0, 0, 1.0], [0, 0, 1.0], 7.0, texel_size=(0.01, 0.02))
    np.testing.assert_allclose(uv_0, [0.3, 0.6])
    np.testing.assert_allclose(s_0, 7.0)
    uv_1, _ = oat.parallax([0.5, 0.5], _unit(np.array([0.6, 0.0, 0.8])), [0, 0, 1.0], 1.0, texel_size=(0.01, 0.02))
    # The eye is towards +u: the view goes on into the material towards −u, by texel · (d/0.8) · 0.6.
    np.testing.assert_allclose(uv_1, [0.5 - 0.01 * 0.6 / 0.8, 0.5], rtol=1e-14)


def _bilinear(img, uv, border):
    """Texel centres at ((i + ½)/W, (j + ½)/H), u along the columns."""
    h, w = img.shape[:2]
    x, y = uv[..., 0] * w - 0.5, uv[..., 1] * h - 0.5
    x0, y0 = np.floor(x), np.floor(y)
    tx, ty = (x - x0)[..., None], (y - y0)[..., None]

    def at(i, j):
        if border == "clamp":
            i, j = np.clip(i, 0, w - 1), np.clip(j, 0, h - 1)
        else:
            i, j = np.mod(i, w), np.mod(j, h)
        return img[j.astype(int), i.astype(int)]

    return (1 - ty) * ((1 - tx) * at(x0, y0) + tx * at(x0 + 1, y0)) + ty * (
        (1 - tx) * at(x0, y0 + 1) + tx * at(x0 + 1, y0 + 1)
    )


@pytest.mark.parametrize("border", ["clamp", "wrap"])
def test_poisson_filter_is_listing_2(rng, border):
    img = rng.uniform(size=(37, 53, 3))
    uv = rng.uniform(-0.2, 1.2, size=(400, 2))
    radius = rng.uniform(0, 9, 400)
    texel = np.array([1 / 53, 1 / 37])
    taps = [uv] + [uv + texel * p * radius[:, None] for p in DISC]
    expected = np.mean([_bilinear(img, t, border) for t in taps], axis=0)
    np.testing.assert_allclose(oat.poisson_filter(img, uv, radius, border=border), expected, rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(
        oat.poisson_filter(img[..., 0], uv, 0.0, border=border), _bilinear(img, uv, border)[:, 0]
    )
    np.testing.assert_allclose(oat.poisson_filter(np.full((8, 8), 0.3), uv, radius, border=border), 0.3, rtol=1e-14)


def _flat(size=32, albedo=0.6, opacity=0.0, inner=0.3, depth=4.0, **kw):
    c = lambda v, k=3: np.full((size, size, k), v)  # noqa: E731
    return oat.Material(c(albedo), c(opacity, 1)[..., 0], c(0.0) + [0, 0, 1], c(inner), depth, **kw)


LIGHT = lamina.DirectionalLight((0.3, 0.2, 1.0), (2.0, 2.0, 2.0))
E_COS_PI = 2.0 * (1.0 / np.linalg.norm([0.3, 0.2, 1.0])) / np.pi  # the plane's N·L term, seen head-on


@pytest.mark.parametrize("variant", oat.VARIANTS)
def test_composite_limits_on_a_flat_plane(variant):
    """Head-on over the plane (orthographic, v = n): w = transparency, and every texture is constant."""
    kw = dict(shape="plane", width=16, height=16, lights=[LIGHT])
    opaque = lamina.render(material=_flat(opacity=1.0, variant=variant), **kw)
    np.testing.assert_allclose(opaque, 0.6 * E_COS_PI, rtol=1e-6)  # the outer layer alone
    clear = lamina.render(material=_flat(opacity=0.0, variant=variant), **kw)
    np.testing.assert_allclose(clear, 0.3 * E_COS_PI, rtol=1e-6)  # the inner layer alone
    half = lamina.render(material=_flat(opacity=0.5, variant=variant), **kw)
    np.testing.assert_allclose(half, 0.5 * (0.6 + 0.3) * E_COS_PI, rtol=1e-6)
    shadowed = lamina.render(material=_flat(opacity=0.5, variant=variant, shadowing=True), **kw)
    np.testing.assert_allclose(shadowed, 0.5 * (0.6 + 0.3 * 0.5) * E_COS_PI, rtol=1e-6)


def test_more_than_two_layers():
    size = 16
    c = lambda v, k=3: np.full((size, size, k), v)  # noqa: E731
    args = (c(0.6), c(0.0, 1)[..., 0], c(0.0) + [0, 0, 1])
    kw = dict(shape="plane", width=8, height=8, lights=[LIGHT])
    hides = oat.Material(*args, [c(0.2), c(0.9)], [2.0, 6.0], inner_opacity=[c(1.0, 1)[..., 0]])
    np.testing.assert_allclose(lamina.render(material=hides, **kw), 0.2 * E_COS_PI, rtol=1e-6)
    shows = oat.Material(*args, [c(0.2), c(0.9)], [2.0, 6.0], inner_opacity=[c(0.0, 1)[..., 0]])
    np.testing.assert_allclose(lamina.render(material=shows, **kw), 0.9 * E_COS_PI, rtol=1e-6)


def test_light_map_of_the_sphere_is_n_dot_l():
    """With flat normals every texel of the sphere's light map is E max(0, n·l)/π at its surface point."""
    size = 64
    m = _flat(size=size)
    lmap = lamina._lamina.oat_light_map(m.outer_normal, "sphere", [LIGHT._spec()], 0)
    u, v = np.meshgrid((np.arange(size) + 0.5) / size, (np.arange(size) + 0.5) / size)
    phi, theta = (u - 0.5) * 2 * np.pi, v * np.pi
    n = np.stack([np.sin(theta) * np.sin(phi), np.cos(theta), np.sin(theta) * np.cos(phi)], -1)
    light = np.array([0.3, 0.2, 1.0]) / np.linalg.norm([0.3, 0.2, 1.0])
    np.testing.assert_allclose(lmap[..., 0], 2.0 * np.maximum(n @ light, 0) / np.pi, atol=1e-12)


def test_mesh_light_map_is_rasterized_and_dilated():
    """A uv-sphere mesh's light map, rasterized in uv, matches the analytic sphere's where the mesh's facets are
    close to it; dilation fills every texel."""
    mesh = uv_sphere_mesh(48, 96)
    m = _flat(size=64)
    ours = lamina._lamina.oat_light_map(m.outer_normal, mesh._spec(), [LIGHT._spec()], 4)
    sphere = lamina._lamina.oat_light_map(m.outer_normal, "sphere", [LIGHT._spec()], 0)
    assert np.all(np.isfinite(ours))
    np.testing.assert_allclose(ours[4:-4], sphere[4:-4], atol=0.01 * sphere.max())


@pytest.mark.parametrize("device", ["cpu", "gpu"])
def test_variants_agree_on_the_organic_sphere(device):
    """The three variants of the same gooey ball: relative mean absolute difference to "full", measured 0.064
    (normal_filtered) and 0.110 (vertex_normal) on this 96² ball (6 texels deep), on either device; the stated
    tolerance is 0.15. One call renders the three: (3, H, W, 3)."""
    tex = oat.organic_textures(256, seed=1)
    m = oat.Material(**tex, thickness=6.0)
    images = lamina.render(
        material=[m.with_variant(v) for v in oat.VARIANTS], width=96, height=96, lights=[LIGHT], device=device
    )
    assert images.shape == (3, 96, 96, 3) and images.dtype == np.float32
    full = images[0]
    assert np.all(np.isfinite(images)) and full.mean() > 0.05
    for other in images[1:]:
        assert np.abs(other - full).mean() / full.mean() <= 0.15


POINT = lamina.PointLight((1.5, 1.0, 2.5), (6.0, 5.0, 4.0))
MESH = uv_sphere_mesh(48, 96)
PERSPECTIVE = ((0.5, 0.8, 3.0), (0.0, 0.0, 0.0), 45.0)


@pytest.mark.parametrize("variant", oat.VARIANTS)
@pytest.mark.parametrize("shadowing", [False, True])
@pytest.mark.parametrize("camera", [None, PERSPECTIVE])
def test_gpu_renders_what_the_cpu_renders(variant, shadowing, camera):
    """The WGSL port of oat.rs against it, on the organic textures under a directional and a point light, relative
    to the mean radiance. The plane, whose uv is affine in the hit point: mean |gpu − cpu| ≤ 1e-5 and 99th
    percentile ≤ 1e-4 (measured ≤ 1.1e-6 and ≤ 6e-6: float32). The sphere: ≤ 1e-3 and ≤ 1e-2 (measured ≤ 4.4e-4
    and ≤ 4.6e-3): its float32 uv (atan2, acos) moves each lookup by ~1e-5 texel, which the bumpy normal map amplifies
    (docs/conventions.md). A latitude-longitude sphere mesh, rasterized on the GPU through the camera and in uv
    space (the light map, dilated), traced on the CPU: ≤ 1e-3 and ≤ 1e-4 (measured ≤ 1.2e-4 and ≤ 1.4e-5; the mean
    carries the few silhouette and seam pixels where rasterization and ray casting pick different triangles)."""
    m = oat.Material(**oat.organic_textures(256, seed=1), thickness=6.0, variant=variant, shadowing=shadowing)
    for shape, (mean_tol, p99_tol) in (("plane", (1e-5, 1e-4)), ("sphere", (1e-3, 1e-2)), (MESH, (1e-3, 1e-4))):
        kw = dict(material=m, shape=shape, width=64, height=64, lights=[LIGHT, POINT], camera=camera)
        cpu, gpu = lamina.render(device="cpu", **kw), lamina.render(device="gpu", **kw)
        assert gpu.shape == cpu.shape == (64, 64, 3) and np.all(np.isfinite(gpu))
        d = np.abs(gpu - cpu) / cpu.mean()
        assert d.mean() <= mean_tol and np.quantile(d, 0.99) <= p99_tol, (shape, d.mean(), np.quantile(d, 0.99))


def test_gpu_composite_limits_and_layers():
    """The flat plane's closed forms (test_composite_limits_on_a_flat_plane) on the GPU, three layers included."""
    kw = dict(shape="plane", width=16, height=16, lights=[LIGHT], device="gpu")
    for variant in oat.VARIANTS:
        half = lamina.render(material=_flat(opacity=0.5, variant=variant, shadowing=True), **kw)
        np.testing.assert_allclose(half, 0.5 * (0.6 + 0.3 * 0.5) * E_COS_PI, rtol=1e-5)
    size = 16
    c = lambda v, k=3: np.full((size, size, k), v)  # noqa: E731
    args = (c(0.6), c(0.0, 1)[..., 0], c(0.0) + [0, 0, 1])
    shows = oat.Material(*args, [c(0.2), c(0.9)], [2.0, 6.0], inner_opacity=[c(0.0, 1)[..., 0]])
    np.testing.assert_allclose(lamina.render(material=shows, **kw), 0.9 * E_COS_PI, rtol=1e-5)


def test_radius_from_slab():
    thin = lamina.Dielectric(1.0, thickness=1.0, sigma_a=0.5)
    r = oat.radius_from_slab(thin, texel_size=0.01, samples=100_000)
    assert r["rms"] == 0.0  # no scattering: straight through
    se = np.sqrt(np.exp(-0.5) * (1 - np.exp(-0.5)) / 100_000)
    assert abs(r["transmittance"] - np.exp(-0.5)) <= 4 * se
    # The walk scales with the slab: twice as thick, half the coefficients, the same paths at twice the radius.
    a = oat.radius_from_slab(lamina.Dielectric(1.0, thickness=1.0, sigma_s=2.0, sigma_a=0.2, g=0.5), 0.01, 20_000)
    b = oat.radius_from_slab(lamina.Dielectric(1.0, thickness=2.0, sigma_s=1.0, sigma_a=0.1, g=0.5), 0.01, 20_000)
    np.testing.assert_allclose(b["rms"], 2 * a["rms"], rtol=1e-9)
    assert a["rms"] > 10 and a["radius"] == pytest.approx(a["rms"] / np.sqrt((DISC**2).sum() / 13))


def test_bad_input():
    c = np.full((8, 8, 3), 0.5)
    with pytest.raises(ValueError, match="outer_opacity"):
        oat.Material(c, np.full((8, 8), 1.5), c, c, 1.0)
    with pytest.raises(ValueError, match="outer_albedo"):
        oat.Material(np.zeros((8, 8, 2)), c[..., 0], c, c, 1.0)
    with pytest.raises(ValueError, match="variant"):
        oat.Material(c, c[..., 0], c, c, 1.0, variant="fast")
    with pytest.raises(ValueError, match="thickness"):
        oat.Material(c, c[..., 0], c, c, -1.0)
    with pytest.raises(ValueError, match="thickness"):
        oat.Material(c, c[..., 0], c, [c, c], [1.0])
    with pytest.raises(ValueError, match="border"):
        oat.poisson_filter(c, [0.5, 0.5], 1.0, border="mirror")
    m = oat.Material(c, c[..., 0], c, c, 1.0)
    with pytest.raises(TypeError, match="not both"):
        lamina.render(lamina.materials.suite("three-layer"), material=m)
    with pytest.raises(TypeError, match="lights"):
        lamina.render(material=m, lights=[lamina.EnvironmentLight("sky")])
