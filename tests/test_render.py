"""The renderer against the evaluation interface: the camera contract (pixels under directional and point lights
are Σ f(l, v) max(0, n·l) E exactly), environment lighting against a quadrature of the same integral (statistically,
with the spread over seeds as the standard error), the reference against the models where they are exact, image
files, and bad input."""

import numpy as np
import pytest
from lamina import materials
from lamina import renderer as R

W, H = 24, 20  # not square, so that a transposed image fails


def _contract(width, height):
    """Pixel centres, sphere normals and tangents of the orthographic camera contract (lamina.render's docstring)."""
    x = (np.arange(width) + 0.5) / width * 2 - 1
    y = 1 - (np.arange(height) + 0.5) / height * 2
    x, y = np.meshgrid(x, y)
    r2 = x**2 + y**2
    z = np.sqrt(np.clip(1 - r2, 0, None))
    n = np.stack([x, y, z], -1)
    t = np.cross(np.array([0.0, 1.0, 0.0]), n)
    t /= np.linalg.norm(t, axis=-1, keepdims=True)
    return n, t, np.cross(n, t), r2 < 1


def _local(d, n, t, b):
    return np.stack([(d * t).sum(-1), (d * b).sum(-1), (d * n).sum(-1)], -1)


def _expected(stack, model, lights, n, t, b, p, **options):
    wo = _local(np.broadcast_to([0.0, 0.0, 1.0], n.shape), n, t, b)
    total = np.zeros(n.shape)
    for light in lights:
        if isinstance(light, R.DirectionalLight):
            d = np.broadcast_to(np.asarray(light.direction) / np.linalg.norm(light.direction), n.shape)
            e = np.asarray(light.irradiance)
            e = np.broadcast_to(e, n.shape)
        else:
            v = np.asarray(light.position) - p
            r2 = (v**2).sum(-1, keepdims=True)
            d, e = v / np.sqrt(r2), np.asarray(light.intensity) / r2
        wi = _local(d, n, t, b)
        f = stack.eval(np.where(wi[..., 2:] > 0, wi, [0, 0, -1.0]), wo, model, **options)
        total += f * np.clip(wi[..., 2:], 0, None) * e
    return total


LIGHTS = [
    R.DirectionalLight((-0.4, 0.5, 0.8), (2.0, 1.5, 1.0)),
    R.DirectionalLight((0.7, -0.2, 0.4), (0.5, 0.8, 1.2)),
    R.PointLight((1.5, 1.0, 2.5), (8.0, 8.0, 6.0)),
]


@pytest.mark.parametrize(
    "material,model",
    [
        ("gold", "microfacet"),
        ("brushed-aluminium", "microfacet"),
        ("anisotropic-coat-metal", "belcour"),
        ("rough-coat-rough-copper", "steinberg"),
        ("varnished-diffuse", "weidlich_wilkie"),
        ("thick-absorbing-slab", "albedo_scaling"),
    ],
)
def test_sphere_pixels_follow_the_camera_contract(material, model):
    stack = materials.preset(material) if material in materials.PRESETS else materials.suite(material)
    img = R.render(stack, model, width=W, height=H, lights=LIGHTS, spp=1)
    assert img.shape == (H, W, 3) and img.dtype == np.float32
    n, t, b, inside = _contract(W, H)
    want = _expected(stack, model, LIGHTS, n, t, b, n)
    want[~inside] = 0
    # float32 output of a float64 computation: 1e-6 relative, plus 1e-6 of the peak for values near 0.
    np.testing.assert_allclose(img, want, rtol=1e-6, atol=1e-6 * want.max())
    assert want.max() > 0.05


def test_per_element_textures_are_looked_up_by_uv():
    """Car paint's flake normals as a texture over the sphere's uv: u = ½ + atan2(n.x, n.z)/2π, v = acos(n.y)/π."""
    stack = materials.car_paint()
    tex = materials.flake_normals(np.stack(np.meshgrid(np.arange(32) / 32, np.arange(16) / 16), -1), density=1)
    img = R.render(stack, "weidlich_wilkie", width=W, height=H, lights=LIGHTS[:1], flake_normal=tex)
    n, t, b, inside = _contract(W, H)
    u = 0.5 + np.arctan2(n[..., 0], n[..., 2]) / (2 * np.pi)
    v = np.arccos(np.clip(n[..., 1], -1, 1)) / np.pi
    flakes = tex[np.minimum((v * 16).astype(int), 15), np.minimum((u * 32).astype(int), 31)]
    want = _expected(stack, "weidlich_wilkie", LIGHTS[:1], n, t, b, n, flake_normal=flakes)
    want[~inside] = 0
    np.testing.assert_allclose(img, want, rtol=1e-6, atol=1e-6 * want.max())
    plain = R.render(stack, "weidlich_wilkie", width=W, height=H, lights=LIGHTS[:1])
    assert np.abs(plain - img).max() > 1e-3  # the flakes change the image


def test_plane_and_batch():
    """The plane faces +z with tangent x̂; a batch of N stacks gives the N single renders."""
    stacks = [materials.preset("gold"), materials.preset("red-plastic")]
    imgs = R.render(stacks, "belcour", shape="plane", width=W, height=H, lights=LIGHTS)
    assert imgs.shape == (2, H, W, 3)
    x = (np.arange(W) + 0.5) / W * 2 - 1
    y = 1 - (np.arange(H) + 0.5) / H * 2
    x, y = np.meshgrid(x, y)
    p = np.stack([x, y, np.zeros_like(x)], -1)
    n = np.broadcast_to([0.0, 0, 1], p.shape)
    t = np.broadcast_to([1.0, 0, 0], p.shape)
    for k, stack in enumerate(stacks):
        want = _expected(stack, "belcour", LIGHTS, n, t, np.cross(n, t), p)
        np.testing.assert_allclose(imgs[k], want, rtol=1e-6, atol=1e-6 * want.max())
        np.testing.assert_array_equal(
            imgs[k], R.render(stack, "belcour", shape="plane", width=W, height=H, lights=LIGHTS)
        )


def test_perspective_camera_sees_the_sphere_centre_as_the_orthographic_one():
    stack = materials.preset("gold")
    ortho = R.render(stack, width=21, height=21, lights=LIGHTS[:1])
    persp = R.render(stack, width=21, height=21, lights=LIGHTS[:1], camera=((0, 0, 6), (0, 0, 0), 30))
    np.testing.assert_allclose(persp[10, 10], ortho[10, 10], rtol=1e-6)
    assert persp[0, 0].sum() == 0 and (persp > 0).mean() < (ortho > 0).mean()  # smaller on screen


def _env_map():
    """A strongly varying environment: a bright warm blob, a cool sky and a dark floor (32 x 64)."""
    v, u = np.meshgrid((np.arange(32) + 0.5) / 32, (np.arange(64) + 0.5) / 64, indexing="ij")
    blob = 6.0 * np.exp(-((u - 0.58) ** 2 + (v - 0.3) ** 2) / 0.01)
    base = np.where(v < 0.5, 0.4, 0.05)
    return np.stack([base + blob, base + 0.6 * blob, base + 0.3 * blob + 0.2 * (v < 0.5)], -1)


def _env_quadrature(stack, model, env, wo_world, n_theta=256, n_phi=512):
    """∫ f(wi, wo) cos θi L(wi) dωi on the plane (frame = world x, y, z) by midpoint quadrature, L looked up as the
    renderer does (φ from −z towards +x, θ from +y, nearest texel)."""
    th = (np.arange(n_theta) + 0.5) / n_theta * np.pi / 2
    ph = (np.arange(n_phi) + 0.5) / n_phi * 2 * np.pi
    th, ph = np.meshgrid(th, ph, indexing="ij")
    wi = np.stack([np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), np.cos(th)], -1)
    h, w = env.shape[:2]
    u = (np.arctan2(wi[..., 0], -wi[..., 2]) / (2 * np.pi) + 0.5) % 1
    v = np.arccos(np.clip(wi[..., 1], -1, 1)) / np.pi
    L = env[np.minimum((v * h).astype(int), h - 1), np.minimum((u * w).astype(int), w - 1)]
    f = stack.eval(wi, np.asarray(wo_world, float), model)
    dw = (np.pi / 2 / n_theta) * (2 * np.pi / n_phi) * np.sin(th)
    return (f * L * (np.cos(th) * dw)[..., None]).sum((0, 1))


@pytest.mark.parametrize("model", ["microfacet", "belcour", "steinberg"])
def test_environment_lighting_is_unbiased(model):
    """The plane seen head-on under an environment: every pixel estimates the same integral with its own samples
    (MIS of map and BSDF sampling); their mean is within 4 standard errors of the quadrature."""
    stack = materials.preset("copper") if model == "microfacet" else materials.suite("rough-coat-rough-copper")
    env = _env_map()
    img = R.render(stack, model, shape="plane", width=32, height=32, spp=8, lights=[R.EnvironmentLight(env)])
    px = img.reshape(-1, 3).astype(np.float64)
    mean, se = px.mean(0), px.std(0, ddof=1) / np.sqrt(len(px))
    want = _env_quadrature(stack, model, env, [0.0, 0.0, 1.0])
    assert np.all(np.abs(mean - want) <= 4 * se + 2e-3 * want), (mean, se, want)
    assert np.all(se < 0.05 * want)  # the test has power: 5% of the value resolves a lost MIS weight


def test_reference_agrees_with_the_exact_model():
    """A single rough conductor: the microfacet model is its exact single-scattering BRDF, which is what the reference
    walks sample. Directional light: per-pixel f estimates; environment: random walks against MIS."""
    stack = materials.preset("gold")
    for lights in ([LIGHTS[0]], [R.EnvironmentLight(_env_map())]):
        ref = R.render(stack, "reference", shape="plane", width=16, height=16, spp=16, lights=lights)
        mod = R.render(stack, "microfacet", shape="plane", width=16, height=16, spp=64, lights=lights)
        r, m = ref.reshape(-1, 3).astype(float), mod.reshape(-1, 3).astype(float)
        se = np.sqrt(r.var(0, ddof=1) / len(r) + m.var(0, ddof=1) / len(m))
        assert np.all(np.abs(r.mean(0) - m.mean(0)) <= 4 * se + 1e-6), (r.mean(0), m.mean(0), se)


def test_renders_are_deterministic_and_the_sky_has_a_sun():
    stack = materials.suite("frosted-metal")
    a = R.render(stack, "belcour", width=16, height=16, spp=4, seed=3)
    np.testing.assert_array_equal(a, R.render(stack, "belcour", width=16, height=16, spp=4, seed=3))
    assert not np.array_equal(a, R.render(stack, "belcour", width=16, height=16, spp=4, seed=4))
    sky = R.sky()
    assert sky.sun is not None and sky.map.shape == (256, 512, 3)
    turned = R.sky(rotation=np.pi / 2)
    # Turning the sky turns its sun about +y by the same angle.
    d0, d1 = np.asarray(sky.sun.direction), np.asarray(turned.sun.direction)
    assert d1[1] == pytest.approx(d0[1]) and np.dot(d0[[0, 2]], d1[[0, 2]]) == pytest.approx(0, abs=1e-12)


def test_image_files_round_trip(tmp_path):
    img = R.render(materials.preset("gold"), width=W, height=H, spp=2)
    exr = R.save_image(tmp_path / "a.exr", img)
    np.testing.assert_array_equal(R.read_image(exr), img)
    png = R.save_image(tmp_path / "a.png", img, exposure=0.5, tonemap="clamp")
    np.testing.assert_array_equal(np.round(R.read_image(png) * 255), R.to_srgb8(img, 0.5, "clamp"))
    # Environment maps load from files: the same render from the array and from its EXR.
    env = _env_map().astype(np.float32)
    path = R.save_image(tmp_path / "env.exr", env)
    stack = materials.preset("copper")
    a = R.render(stack, width=8, height=8, spp=2, lights=[R.EnvironmentLight(env)])
    np.testing.assert_array_equal(a, R.render(stack, width=8, height=8, spp=2, lights=[R.EnvironmentLight(path)]))


@pytest.mark.parametrize(
    "kwargs,error,match",
    [
        (dict(device="gpu", model="weidlich_wilkie", mask=0.5), ValueError, "mask: a patina stack is a Dielectric"),
        (dict(device="gpu", model="reference"), ValueError, "model .reference. has no GPU implementation"),
        (dict(device="tpu"), ValueError, "device must be"),
        (dict(width=0), ValueError, "width must be in"),
        (dict(spp=1.5), TypeError, "spp must be an integer"),
        (dict(shape="torus"), ValueError, "shape must be"),
        (dict(lights=["sun"]), TypeError, r"lights\[0\]"),
        (dict(lights=[R.sky(), R.sky()]), ValueError, "at most one EnvironmentLight"),
        (dict(model="belcour", lut="fitted"), TypeError, "has no option 'lut'"),
        (dict(model="nope"), ValueError, "model must be one of"),
        (dict(model="weidlich_wilkie", mask=np.ones((4, 4, 2))), ValueError, r"mask must be a constant or a texture"),
        (dict(camera=((0, 0, 1), (0, 0, 1), 40)), ValueError, "must differ"),
    ],
)
def test_bad_input(kwargs, error, match):
    with pytest.raises(error, match=match):
        R.render(materials.preset("gold"), width=kwargs.pop("width", 8), height=8, **kwargs)


def test_bad_lights_and_files(tmp_path):
    with pytest.raises(ValueError, match="irradiance must be in"):
        R.DirectionalLight((0, 0, 1), (-1, 0, 0))
    with pytest.raises(ValueError, match="direction must not be the zero vector"):
        R.DirectionalLight((0, 0, 0))
    with pytest.raises(ValueError, match="no file"):
        R.EnvironmentLight(tmp_path / "missing.hdr")
    with pytest.raises(ValueError, match="non-negative"):
        R.EnvironmentLight(-np.ones((4, 8, 3)))
    with pytest.raises(ValueError, match="must end in .png or .exr"):
        R.save_image(tmp_path / "a.jpg", np.zeros((2, 2, 3)))
    bad = tmp_path / "bad.hdr"
    bad.write_text("not an image")
    with pytest.raises(ValueError, match="cannot read"):
        R.EnvironmentLight(bad)


SQUARE = dict(
    vertices=[[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]],
    triangles=[[0, 1, 2], [0, 2, 3]],
    uvs=[[0, 1], [1, 1], [1, 0], [0, 0]],
)


def test_a_mesh_of_the_square_renders_as_the_plane(tmp_path):
    """Two triangles spanning [−1, 1]² with normal +z, tangent x̂ and the plane's uv are the plane: same pixels, same
    texture lookups. The same square read from an OBJ file (with vt and vn) too."""
    stack = materials.car_paint()
    tex = materials.flake_texture(60, density=15)  # no texel edge falls on a pixel centre
    kwargs = dict(width=W, height=H, lights=LIGHTS, flake_normal=tex)
    plane = R.render(stack, "weidlich_wilkie", shape="plane", **kwargs)
    mesh = R.Mesh(**SQUARE, tangents=np.tile([1.0, 0, 0], (4, 1)))
    np.testing.assert_allclose(R.render(stack, "weidlich_wilkie", shape=mesh, **kwargs), plane, rtol=1e-5, atol=1e-7)
    obj = tmp_path / "square.obj"
    obj.write_text(
        "v -1 -1 0\nv 1 -1 0\nv 1 1 0\nv -1 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvn 0 0 1\n"
        "f 1/1/1 2/2/1 3/3/1 4/4/1\n"  # a quad: the loader triangulates it; OBJ's v runs upwards
    )
    loaded = R.Mesh.from_obj(obj)
    assert len(loaded.triangles) == 2
    np.testing.assert_allclose(loaded.normals, np.tile([0, 0, 1.0], (len(loaded.vertices), 1)))
    # No tangents in OBJ: t = normalize(ŷ × n) = x̂ on this plane, as given above.
    np.testing.assert_allclose(R.render(stack, "weidlich_wilkie", shape=loaded, **kwargs), plane, rtol=1e-5, atol=1e-7)


def test_a_fine_mesh_sphere_approaches_the_analytic_sphere():
    """A UV sphere of 128 x 256 quads, normals from the faces (area-weighted): within 1% of the analytic sphere on
    average (the facets move hit points by up to 3e-4 and normals by about as much)."""
    n = 128
    th, ph = np.meshgrid(np.linspace(0, np.pi, n + 1), np.linspace(0, 2 * np.pi, 2 * n + 1), indexing="ij")
    v = np.stack([np.sin(th) * np.sin(ph), np.cos(th), np.sin(th) * np.cos(ph)], -1).reshape(-1, 3)
    idx = np.arange((n + 1) * (2 * n + 1)).reshape(n + 1, 2 * n + 1)
    a, b, c, d = idx[:-1, :-1], idx[:-1, 1:], idx[1:, :-1], idx[1:, 1:]
    tris = np.concatenate([np.stack([a, c, b], -1).reshape(-1, 3), np.stack([b, c, d], -1).reshape(-1, 3)])
    stack = materials.suite("rough-coat-rough-copper")
    mesh = R.render(stack, "belcour", shape=R.Mesh(v, tris), width=48, height=48, lights=LIGHTS[:1])
    ball = R.render(stack, "belcour", width=48, height=48, lights=LIGHTS[:1])
    inside = _contract(48, 48)[3] & (np.hypot(*np.meshgrid(np.linspace(-1, 1, 48), np.linspace(-1, 1, 48))) < 0.95)
    rel = np.abs(mesh - ball)[inside].sum() / ball[inside].sum()
    assert rel < 0.01, rel


def test_bad_meshes():
    with pytest.raises(ValueError, match="triangles must index vertices"):
        R.Mesh(SQUARE["vertices"], [[0, 1, 4]])
    with pytest.raises(ValueError, match=r"uvs must have shape \(4, 2\)"):
        R.Mesh(SQUARE["vertices"], SQUARE["triangles"], uvs=[[0, 0]])
    with pytest.raises(ValueError, match="triangles must be a non-empty"):
        R.Mesh(SQUARE["vertices"], [[0.5, 1, 2]])
    with pytest.raises(ValueError, match="no file"):
        R.Mesh.from_obj("/nonexistent.obj")
