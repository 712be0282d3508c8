"""lamina.measured: BRDF samples as NumPy archives and the MERL 100 binary format, read and written. No measured file
is shipped (licences): the tests write their own, from lamina's models."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import mitsuba_f, random_hemisphere
from lamina import Stack, measured
from lamina.materials import metal
from lamina.measured import MERL_SHAPE, Merl, Samples


def test_half_difference_angles_invert(rng):
    wi, wo = random_hemisphere(rng, 1000, 0.01), random_hemisphere(rng, 1000, 0.01)
    theta_h, theta_d, phi_d = measured.half_difference(wi, wo)
    h = (wi + wo) / np.linalg.norm(wi + wo, axis=-1, keepdims=True)
    a, b = measured.from_half_difference(theta_h, theta_d, phi_d, np.arctan2(h[:, 1], h[:, 0]))
    np.testing.assert_allclose(a, wi, atol=1e-12)
    np.testing.assert_allclose(b, wo, atol=1e-12)
    # θd is the angle between wi and the half vector.
    np.testing.assert_allclose(np.cos(theta_d), np.sum(wi * h, axis=-1), atol=1e-12)


def test_merl_lookup_reads_the_bin_the_database_defines(rng):
    """A table whose value encodes its own bin: a pair built at a bin's centre reads that bin, whatever its φh, and
    the folded azimuth φd + π reads φd (reciprocity)."""
    code = np.arange(np.prod(MERL_SHAPE), dtype=np.float64).reshape(MERL_SHAPE)
    merl = Merl(np.stack([code, code + 0.25, code + 0.5]))
    n_h, n_d, n_p = MERL_SHAPE
    ih, id_, ip = rng.integers(0, n_h, 500), rng.integers(0, n_d, 500), rng.integers(0, n_p, 500)
    theta_h = ((ih + 0.5) / n_h) ** 2 * (np.pi / 2)
    theta_d, phi_d = (id_ + 0.5) / n_d * (np.pi / 2), (ip + 0.5) / n_p * np.pi
    for shift in (0.0, -np.pi):
        wi, wo = measured.from_half_difference(theta_h, theta_d, phi_d + shift, rng.uniform(-np.pi, np.pi, 500))
        ok = (wi[:, 2] > 0) & (wo[:, 2] > 0)
        f = merl.eval(wi[ok], wo[ok])
        np.testing.assert_array_equal(f[:, 0], ((ih * n_d + id_) * n_p + ip)[ok])
        np.testing.assert_array_equal(f[:, 2] - f[:, 0], 0.5)


def test_a_merl_file_round_trips_and_reads_lamina_s_model(tmp_path, rng):
    """lamina's rough gold written as a MERL table at the bins' centres, read back: the bytes round-trip (the scales
    applied and removed), and at random pairs the table is the model within its bins' resolution. Measured: median
    relative difference 1.9%, 90th percentile 7% (the bins are 1° wide in θd and φd, and narrower in θh near the
    peak)."""
    stack = Stack([metal("Au", 0.3)])
    merl = measured.merl_table(lambda wi, wo: stack.eval(wi, wo, "microfacet"))
    path = tmp_path / "gold.binary"
    measured.write_merl(path, merl)
    assert path.stat().st_size == 12 + 3 * 8 * np.prod(MERL_SHAPE)
    back = measured.read_merl(path)
    np.testing.assert_allclose(back.table, merl.table, rtol=1e-15)
    wi, wo = random_hemisphere(rng, 4000, 0.2), random_hemisphere(rng, 4000, 0.2)
    f, exact = back.eval(wi, wo), stack.eval(wi, wo, "microfacet")
    big = exact > 1e-2 * exact.max()
    rel = np.abs(f - exact)[big] / exact[big]
    assert np.median(rel) < 0.025 and np.quantile(rel, 0.9) < 0.05, (np.median(rel), np.quantile(rel, 0.9))
    # Samples from the table: measured bins only, values as eval gives them.
    s = back.samples(500, seed=3)
    assert len(s) == 500 and np.all(back.measured(s.wi, s.wo))
    np.testing.assert_array_equal(s.f, back.eval(s.wi, s.wo))


def test_merl_files_that_are_not_tables_are_refused(tmp_path):
    bad = tmp_path / "bad.binary"
    bad.write_bytes(np.array([90, 90, 360], dtype="<i4").tobytes())
    with pytest.raises(ValueError, match=r"not a MERL BRDF: its header gives dimensions \(90, 90, 360\)"):
        measured.read_merl(bad)
    bad.write_bytes(np.array(MERL_SHAPE, dtype="<i4").tobytes() + b"\0" * 80)
    with pytest.raises(ValueError, match="truncated"):
        measured.read_merl(bad)
    with pytest.raises(ValueError, match="a MERL table has shape"):
        measured.write_merl(bad, Merl(np.zeros((3, 90, 90))))


def test_samples_round_trip_and_refuse_bad_input(tmp_path, rng):
    wi, wo = random_hemisphere(rng, 100, 0.01), random_hemisphere(rng, 100, 0.01)
    f = Stack([metal("Cu", 0.2)]).eval(wi, wo, "microfacet")
    s = Samples(wi, wo, f, wavelengths=[650.0, 550.0, 450.0])
    measured.save_samples(tmp_path / "cu.npz", s)
    back = measured.load_samples(tmp_path / "cu.npz")
    for name in ("wi", "wo", "f", "wavelengths"):  # directions normalised again on reading: to rounding
        np.testing.assert_allclose(getattr(back, name), getattr(s, name), rtol=0, atol=1e-15)
    with pytest.raises(ValueError, match="f must hold finite values ≥ 0"):
        Samples(wi, wo, -f)
    with pytest.raises(ValueError, match="f must hold finite values ≥ 0"):
        Samples(wi, wo, np.where(f > f.mean(), np.nan, f))
    with pytest.raises(ValueError, match="must have n rows each"):
        Samples(wi, wo[:50], f)
    with pytest.raises(ValueError, match="wo must hold finite, non-zero directions above the surface"):
        Samples(wi, -wo, f)
    with pytest.raises(ValueError, match="wavelengths must hold one positive wavelength"):
        Samples(wi, wo, f, wavelengths=[500.0])
    np.savez(tmp_path / "partial.npz", wi=wi, f=f)
    with pytest.raises(ValueError, match=r"lacks the arrays \['wo'\]"):
        measured.load_samples(tmp_path / "partial.npz")


def _rgl_fields(rng, n_phi: int, rgb=None, vndf=None) -> dict:
    """The fields of an RGL .bsdf file over 5 θi nodes and `n_phi` φi nodes (1: isotropic; else over [−π, π]),
    tables of positive random values unless given, periodic in azimuth as a BSDF is (their rows at φ = −π and π
    equal; an isotropic file's ndf and σ the same at every azimuth)."""
    theta = np.array([0.0, 0.3, 0.7, 1.1, 1.5], np.float32)
    phi = np.zeros(1, np.float32) if n_phi == 1 else np.linspace(-np.pi, np.pi, n_phi).astype(np.float32)
    shape = (n_phi, len(theta))

    def periodic(a):
        a[..., -1, :] = a[..., 0, :]
        return a.astype(np.float32)

    def over_azimuth():
        rows = rng.uniform(0.5, 2.0, (1 if n_phi == 1 else 7, 9))
        return periodic(np.repeat(rows, 2, axis=0) if n_phi == 1 else rows)

    return {
        "description": np.frombuffer(b"lamina test", np.uint8),
        "jacobian": np.ones(1, np.uint8),
        "theta_i": theta,
        "phi_i": phi,
        "ndf": over_azimuth(),
        "sigma": over_azimuth(),
        "vndf": periodic(rng.uniform(0.1, 3.0, shape + (6, 8)) if vndf is None else vndf),
        "luminance": np.ones(shape + (4, 4), np.float32),
        "rgb": periodic(rng.uniform(0.0, 1.0, shape + (3, 4, 4)) if rgb is None else rgb),
    }


def test_tensor_files_round_trip(tmp_path, rng):
    fields = _rgl_fields(rng, 3)
    measured.write_tensor_file(tmp_path / "t.bsdf", fields)
    back = measured.read_tensor_file(tmp_path / "t.bsdf")
    assert list(back) == list(fields)
    for k in fields:
        assert back[k].dtype == fields[k].dtype and np.array_equal(back[k], fields[k]), k
    (tmp_path / "bad.bsdf").write_bytes(b"tensor_file\0\2\0" + bytes(8))
    with pytest.raises(ValueError, match="not a tensor file"):
        measured.read_tensor_file(tmp_path / "bad.bsdf")
    measured.write_tensor_file(tmp_path / "spectral.bsdf", {**fields, "spectra": fields["rgb"]})
    with pytest.raises(ValueError, match="spectral RGL file"):
        measured.read_rgl(tmp_path / "spectral.bsdf")
    measured.write_tensor_file(tmp_path / "short.bsdf", {**fields, "vndf": fields["vndf"][:, :2]})
    with pytest.raises(ValueError, match=r"vndf must be \(φi 3, θi 5, H, W\)"):
        measured.read_rgl(tmp_path / "short.bsdf")


def test_rgl_constant_tables_give_their_closed_form(tmp_path, rng):
    """A uniform warp (constant vndf: the unit square is the half vectors' u-square itself), rgb ≡ c, ndf ≡ n and
    σ ≡ s: f cos θo = c n / (4 s). With rgb a ramp a + b x over the square's x, f cos θo = (a + b √(2θm/π)) n / (4 s)
    (bilinear interpolation is exact on linear data)."""
    fields = _rgl_fields(rng, 1, vndf=np.ones((1, 5, 6, 8)))
    fields["ndf"][:], fields["sigma"][:] = 2.0, 0.5
    x = np.linspace(0.0, 1.0, 4)
    fields["rgb"][:] = np.stack([np.full((4, 4), 0.3), 0.1 + 0.6 * x[None, :] + 0 * x[:, None], np.ones((4, 4))])
    measured.write_tensor_file(tmp_path / "c.bsdf", fields)
    rgl = measured.read_rgl(tmp_path / "c.bsdf")
    assert rgl.isotropic and rgl.description == "lamina test"
    s = rgl.samples(300, seed=1)
    np.testing.assert_array_equal(s.f, rgl.eval(s.wi, s.wo))
    wi, wo = random_hemisphere(rng, 500, 0.05), random_hemisphere(rng, 500, 0.05)
    f = rgl.eval(wi, wo) * wo[:, 2:3]
    theta_m = np.arccos(np.clip(((wi + wo) / np.linalg.norm(wi + wo, axis=-1, keepdims=True))[:, 2], -1, 1))
    np.testing.assert_allclose(f[:, 0], 0.3 * 2.0 / (4 * 0.5), rtol=1e-6)
    np.testing.assert_allclose(f[:, 1], (0.1 + 0.6 * np.sqrt(2 * theta_m / np.pi)) * 2.0 / (4 * 0.5), rtol=1e-5)


def test_rgl_warp_inverse_has_the_visible_normals_density_as_jacobian(tmp_path, rng):
    """The visible normals' warp, inverted, maps the half vectors' u-square onto the unit square: with rgb the
    identity ramps (R = s_x, G = s_y) the evaluation returns s, whose Jacobian determinant ∂s/∂u must be the
    bilinear density of the vndf slice (normalised over the square), and whose corners are (0, 0) and (1, 1)."""
    x = np.linspace(0.0, 1.0, 4)
    ramps = np.stack([x[None, :] + 0 * x[:, None], x[:, None] + 0 * x[None, :], np.ones((4, 4))])
    vndf = rng.uniform(0.2, 3.0, (1, 5, 6, 8))
    vndf[:, 1:] = vndf[:, :1]  # every θi node alike: the blend of nodes is then the slice itself
    fields = _rgl_fields(rng, 1, vndf=vndf)
    fields["rgb"] = np.broadcast_to(ramps, (1, 5, 3, 4, 4)).astype(np.float32)  # not periodic: s itself
    fields["ndf"][:], fields["sigma"][:] = 4.0, 1.0
    measured.write_tensor_file(tmp_path / "w.bsdf", fields)
    rgl = measured.read_rgl(tmp_path / "w.bsdf")
    wi = np.array([np.sin(0.2), 0.0, np.cos(0.2)])

    def s_of(u):  # the half vector of u-square point u (θm = u_x² π/2, φm − φi = (2 u_y − 1) π), then s
        theta_m, phi_m = u[:, 0] ** 2 * np.pi / 2, (2 * u[:, 1] - 1) * np.pi
        wm = np.stack([np.sin(theta_m) * np.cos(phi_m), np.sin(theta_m) * np.sin(phi_m), np.cos(theta_m)], -1)
        wo = 2 * (wm @ wi)[:, None] * wm - wi
        return (rgl.eval(wi, wo) * wo[:, 2:3])[:, :2]

    u = np.stack([rng.uniform(0.05, 0.45, 200), rng.uniform(0.05, 0.95, 200)], -1)  # wo above the horizon
    h = 1e-6
    dx = (s_of(u + [h, 0]) - s_of(u - [h, 0])) / (2 * h)
    dy = (s_of(u + [0, h]) - s_of(u - [0, h])) / (2 * h)
    jacobian = dx[:, 0] * dy[:, 1] - dx[:, 1] * dy[:, 0]
    d = vndf[0, 0].astype(np.float32).astype(np.float64)
    area = np.trapezoid(np.trapezoid(d, axis=1), axis=0)  # the bilinear interpolant's integral, in index units
    density = measured._bilinear(d, u) * 5 * 7 / area
    np.testing.assert_allclose(jacobian, density, rtol=1e-5)


@pytest.mark.parametrize("n_phi", [1, 5])
def test_rgl_files_read_as_mitsuba_s_measured_plugin_reads_them(tmp_path, rng, n_phi):
    """Random tables (isotropic, and anisotropic over φi ∈ [−π, π]) read by lamina and by Mitsuba 3's `measured`
    BSDF: the same f. Mitsuba indexes the tables by its si.wi, lamina by wi (mitsuba_f swaps them into lamina's
    convention, so the pair is passed reversed). Tolerance: float32 (Mitsuba) against float64 (lamina), through the
    warp's inversion; measured 4.5e-6 at most over 20,000 pairs (relative, where f ≥ 1e-3 of its peak). The tables
    must be periodic in azimuth, as a BSDF's are: where an isotropic file's σ differs between φ = −π and π, Mitsuba
    and the authors' evaluator (powitacq) read it differently (up to 39%)."""
    measured.write_tensor_file(tmp_path / "r.bsdf", _rgl_fields(rng, n_phi))
    rgl = measured.read_rgl(tmp_path / "r.bsdf")
    wi, wo = random_hemisphere(rng, 2000, 0.05), random_hemisphere(rng, 2000, 0.05)
    ours = rgl.eval(wi, wo)
    theirs = mitsuba_f({"type": "measured", "filename": str(tmp_path / "r.bsdf")}, wo, wi)
    big = np.abs(theirs) > 1e-3 * np.abs(theirs).max()
    rel = np.abs(ours - theirs)[big] / np.abs(theirs)[big]
    assert rel.max() < 3e-5, rel.max()
