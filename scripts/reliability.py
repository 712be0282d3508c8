"""Writes docs/reliability.md: how lamina's public Python API answers bad input, the faults it survives (tests/faults.py
provokes each: a damaged or unwritable cache, concurrent writers, a killed Dask worker, Ctrl-C, GPU faults) with what
was measured, and (from docs/fuzz.json, written by scripts/fuzz.py) how often its models return NaN, Inf or negative
values on random input.

Every case is an input a new user could plausibly write. Each should raise a ValueError or TypeError whose message
names the offending parameter; anything else (another exception, a pyo3 PanicException, or no error at all) is
listed on stderr and makes the script exit with status 1, so that a regression is visible. `bad_inputs()` returns the
cases for reuse by tests.

Run: make reliability
"""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Callable, List, Optional, Tuple

import lamina
import numpy as np
from lamina import Conductor, Dielectric, Diffuse, Spectrum, Stack, materials, optics
from lamina.catalogue import model
from lamina.spectrum import ior, to_xyz, xyz_weights

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
import faults  # noqa: E402  (tests/faults.py: the fault scenarios, shared with tests/test_faults.py)

OUT = ROOT / "docs" / "reliability.md"
FUZZ = ROOT / "docs" / "fuzz.json"
MESSAGE_CHARS = 160

Case = Tuple[str, Callable[[], object]]

W = np.array([0.0, 0.0, 1.0])
WO = np.array([0.3, 0.0, 0.95])
U = np.array([0.5, 0.5, 0.5])
NAN = float("nan")
INF = float("inf")


def _gold() -> Stack:
    return materials.preset("gold")


def _coated() -> Stack:
    return materials.preset("coated-copper")


def _plastic_rgb() -> Stack:
    return Stack([Dielectric(1.5, 0.1), Diffuse((0.5, 0.4, 0.3))])


def _layer_cases() -> List[Case]:
    return [
        ("Dielectric(-1.5)", lambda: Dielectric(-1.5)),
        ("Dielectric(0.0)", lambda: Dielectric(0.0)),
        ("Dielectric(float('nan'))", lambda: Dielectric(NAN)),
        ("Dielectric(float('inf'))", lambda: Dielectric(INF)),
        ("Dielectric('1.5')", lambda: Dielectric("1.5")),
        ("Dielectric(None)", lambda: Dielectric(None)),
        ("Dielectric((1.5, 1.5))", lambda: Dielectric((1.5, 1.5))),
        ("Dielectric(1.5, roughness=1.5)", lambda: Dielectric(1.5, roughness=1.5)),
        ("Dielectric(1.5, roughness=-0.1)", lambda: Dielectric(1.5, roughness=-0.1)),
        ("Dielectric(1.5, roughness=float('nan'))", lambda: Dielectric(1.5, roughness=NAN)),
        ("Dielectric(1.5, roughness=(0.1, 2.0))", lambda: Dielectric(1.5, roughness=(0.1, 2.0))),
        ("Dielectric(1.5, roughness=(0.1, 0.2, 0.3))", lambda: Dielectric(1.5, roughness=(0.1, 0.2, 0.3))),
        ("Dielectric(1.5, roughness='rough')", lambda: Dielectric(1.5, roughness="rough")),
        ("Dielectric(1.5, angle=float('nan'))", lambda: Dielectric(1.5, angle=NAN)),
        ("Dielectric(1.5, thickness=-1.0)", lambda: Dielectric(1.5, thickness=-1.0)),
        ("Dielectric(1.5, thickness=float('inf'))", lambda: Dielectric(1.5, thickness=INF)),
        ("Dielectric(1.5, sigma_a=-0.1)", lambda: Dielectric(1.5, sigma_a=-0.1)),
        ("Dielectric(1.5, sigma_s=(1, 1))", lambda: Dielectric(1.5, sigma_s=(1, 1))),
        ("Dielectric(1.5, g=1.0)", lambda: Dielectric(1.5, g=1.0)),
        ("Dielectric(1.5, g=-1.5)", lambda: Dielectric(1.5, g=-1.5)),
        ("Dielectric(1.5, g='forward')", lambda: Dielectric(1.5, g="forward")),
        ("Conductor(0.2, -3.0)", lambda: Conductor(0.2, -3.0)),
        ("Conductor(-0.2, 3.0)", lambda: Conductor(-0.2, 3.0)),
        ("Conductor(0.2, 3.0, roughness=2.0)", lambda: Conductor(0.2, 3.0, roughness=2.0)),
        ("Conductor((0.2, 0.3), (3, 3, 3))", lambda: Conductor((0.2, 0.3), (3, 3, 3))),
        ("Conductor(0.2)  (k missing)", lambda: Conductor(0.2)),
        ("Diffuse(1.5)", lambda: Diffuse(1.5)),
        ("Diffuse(-0.1)", lambda: Diffuse(-0.1)),
        ("Diffuse((0.5, 0.5, 0.5, 0.5))", lambda: Diffuse((0.5, 0.5, 0.5, 0.5))),
        ("Diffuse('white')", lambda: Diffuse("white")),
        ("Diffuse(True)", lambda: Diffuse(True)),
        ("Diffuse(0.5, roughness=2.0)", lambda: Diffuse(0.5, roughness=2.0)),
        ("Diffuse(0.5, roughness=(0.1, 0.2))", lambda: Diffuse(0.5, roughness=(0.1, 0.2))),
        ("Dielectric(Spectrum([400, 700], [-1, -1]))", lambda: Dielectric(Spectrum([400, 700], [-1, -1]))),
    ]


def _stack_cases() -> List[Case]:
    metal = Conductor(0.2, 3.0, 0.3)
    return [
        ("Stack([])", lambda: Stack([])),
        ("Stack([Dielectric(1.5)])  (no opaque base)", lambda: Stack([Dielectric(1.5)])),
        (
            "Stack([Diffuse(0.5), Dielectric(1.5)])  (opaque layer not last)",
            lambda: Stack([Diffuse(0.5), Dielectric(1.5)]),
        ),
        ("Stack([Conductor(...), Diffuse(0.5)])  (two opaque layers)", lambda: Stack([metal, Diffuse(0.5)])),
        ("Stack([Conductor(...)], ext_ior=0)", lambda: Stack([metal], ext_ior=0)),
        ("Stack([Conductor(...)], ext_ior=-1.0)", lambda: Stack([metal], ext_ior=-1.0)),
        ("Stack([Conductor(...)], ext_ior=float('nan'))", lambda: Stack([metal], ext_ior=NAN)),
        ("Stack([Conductor(...)], ext_ior=float('inf'))", lambda: Stack([metal], ext_ior=INF)),
        ("Stack([Conductor(...)], ext_ior='1.0')", lambda: Stack([metal], ext_ior="1.0")),
        ("Stack('gold')", lambda: Stack("gold")),
        ("Stack([1.5])", lambda: Stack([1.5])),
        ("Stack(None)", lambda: Stack(None)),
    ]


def _array_cases() -> List[Case]:
    return [
        ("gold.eval(np.ones(2), wo)  (wrong last axis)", lambda: _gold().eval(np.ones(2), WO)),
        ("gold.eval(np.ones((4, 2)), wo)", lambda: _gold().eval(np.ones((4, 2)), WO)),
        ("gold.eval(1.0, wo)  (scalar direction)", lambda: _gold().eval(1.0, WO)),
        ("gold.eval([nan, 0, 1], wo)", lambda: _gold().eval([NAN, 0, 1.0], WO)),
        ("gold.eval(wi, [inf, 0, 1])", lambda: _gold().eval(W, [INF, 0, 1.0])),
        ("gold.eval([0, 0, 0], wo)  (zero-length direction)", lambda: _gold().eval([0, 0, 0.0], WO)),
        (
            "gold.eval(np.ones((4, 3)), np.ones((5, 3)))  (shapes do not broadcast)",
            lambda: _gold().eval(np.ones((4, 3)), np.ones((5, 3))),
        ),
        (
            "gold.eval(np.array([0, 0, 1 + 0j]), wo)  (complex dtype)",
            lambda: _gold().eval(np.array([0, 0, 1 + 0j]), WO),
        ),
        (
            "gold.eval(np.array([0, 0, 1], dtype=object), wo)",
            lambda: _gold().eval(np.array([0, 0, 1.0], dtype=object), WO),
        ),
        ("gold.eval(np.array(['0', '0', '1']), wo)", lambda: _gold().eval(np.array(["0", "0", "1"]), WO)),
        (
            "gold.eval(np.array([0, 0, 1], dtype=np.float16), wo)",
            lambda: _gold().eval(np.array([0, 0, 1], dtype=np.float16), WO),
        ),
        ("gold.eval(None, wo)", lambda: _gold().eval(None, WO)),
        ("gold.eval([[0, 0, 1], [0, 1]], wo)  (ragged list)", lambda: _gold().eval([[0, 0, 1.0], [0, 1.0]], WO)),
        (
            "gold.reference(np.zeros((0, 3)), wo, samples=16)",
            lambda: _gold().reference(np.zeros((0, 3)), WO, samples=16),
        ),
        (
            "gold.reference([0, 0, -1], wo, samples=16)  (below the horizon)",
            lambda: _gold().reference([0, 0, -1.0], WO, samples=16),
        ),
        ("gold.reference([nan, 0, 1], wo, samples=16)", lambda: _gold().reference([NAN, 0, 1.0], WO, samples=16)),
        ("gold.albedo(np.zeros((0, 3)))", lambda: _gold().albedo(np.zeros((0, 3)))),
        (
            "gold.albedo(np.zeros((0, 3)), 'reference', samples=16)",
            lambda: _gold().albedo(np.zeros((0, 3)), "reference", samples=16),
        ),
        ("coated.lobes(np.zeros((0, 3)))", lambda: _coated().lobes(np.zeros((0, 3)))),
        ("coated.lobes([0, 0, 0])", lambda: _coated().lobes([0, 0, 0.0])),
        ("gold.specular(np.ones(2))", lambda: _gold().specular(np.ones(2))),
        ("gold.pdf([nan, 0, 1], wo)", lambda: _gold().pdf([NAN, 0, 1.0], WO)),
    ]


def _wavelength_cases() -> List[Case]:
    def spiky() -> Stack:
        n = Spectrum([400, 600, 620, 640, 800], [1.5, 1.5, -1.0, 1.5, 1.5])
        return Stack([Dielectric(n), Diffuse(0.5)])

    return [
        ("gold.eval(wi, wo, wavelengths=[])", lambda: _gold().eval(W, WO, wavelengths=[])),
        ("gold.eval(wi, wo, wavelengths=[-500])", lambda: _gold().eval(W, WO, wavelengths=[-500])),
        ("gold.eval(wi, wo, wavelengths=[nan])", lambda: _gold().eval(W, WO, wavelengths=[NAN])),
        ("gold.eval(wi, wo, wavelengths=[[500, 600]])", lambda: _gold().eval(W, WO, wavelengths=[[500, 600]])),
        ("gold.eval(wi, wo, wavelengths='red')", lambda: _gold().eval(W, WO, wavelengths="red")),
        (
            "gold.eval(wi, wo, wavelengths=[100])  (outside gold's measured table)",
            lambda: _gold().eval(W, WO, wavelengths=[100]),
        ),
        (
            "gold.reference(wi, wo, wavelengths=[5000], samples=16)",
            lambda: _gold().reference(W, WO, wavelengths=[5000], samples=16),
        ),
        (
            "Stack([Dielectric(1.5, 0.1), Diffuse((0.5, 0.4, 0.3))]).eval(..., 'belcour', wavelengths=[500])",
            lambda: _plastic_rgb().eval(W, WO, "belcour", wavelengths=[500]),
        ),
        (
            "Dielectric(Spectrum(..., negative at 620 nm)) over Diffuse: .eval(..., 'belcour', wavelengths=[620])",
            lambda: spiky().eval(W, WO, "belcour", wavelengths=[620]),
        ),
        ("coated.lobes(wo, wavelengths=[100])", lambda: _coated().lobes(WO, wavelengths=[100])),
    ]


def _model_cases() -> List[Case]:
    return [
        ("gold.eval(wi, wo, 'phong')", lambda: _gold().eval(W, WO, "phong")),
        ("gold.eval(wi, wo, 'Belcour')", lambda: _gold().eval(W, WO, "Belcour")),
        ("gold.eval(wi, wo, None)", lambda: _gold().eval(W, WO, None)),
        ("gold.eval(wi, wo, 3)", lambda: _gold().eval(W, WO, 3)),
        ("from lamina.catalogue import model; model('phong')", lambda: model("phong")),
        ("coated.eval(wi, wo)  (layered stack, default model 'microfacet')", lambda: _coated().eval(W, WO)),
        (
            "coated.eval(wi, wo, 'belcour', lut='fitted')  (option of steinberg)",
            lambda: _coated().eval(W, WO, "belcour", lut="fitted"),
        ),
        ("gold.eval(wi, wo, bogus=1)", lambda: _gold().eval(W, WO, bogus=1)),
        ("gold.eval(wi, wo, fresnel='bogus')", lambda: _gold().eval(W, WO, fresnel="bogus")),
        ("gold.eval(wi, wo, distribution=None)", lambda: _gold().eval(W, WO, distribution=None)),
        ("coated.eval(wi, wo, 'belcour', symmetric='yes')", lambda: _coated().eval(W, WO, "belcour", symmetric="yes")),
        (
            "coated.eval(wi, wo, 'steinberg', clamp_roughness=1)",
            lambda: _coated().eval(W, WO, "steinberg", clamp_roughness=1),
        ),
        (
            "coated.eval(wi, wo, 'weidlich_wilkie', extent=2)",
            lambda: _coated().eval(W, WO, "weidlich_wilkie", extent=2),
        ),
        (
            "coated.eval(wi, wo, 'weidlich_wilkie', transition=float('nan'))",
            lambda: _coated().eval(W, WO, "weidlich_wilkie", transition=NAN),
        ),
        (
            "coated.eval(wi, wo, 'weidlich_wilkie', tint=(1, 1))",
            lambda: _coated().eval(W, WO, "weidlich_wilkie", tint=(1, 1)),
        ),
        ("coated.eval(wi, wo, 'weidlich_wilkie', tint=-1)", lambda: _coated().eval(W, WO, "weidlich_wilkie", tint=-1)),
        (
            "gold.eval(wi, wo, 'weidlich_wilkie', tint=(1, 1, 1), wavelengths=[500, 600])",
            lambda: _gold().eval(W, WO, "weidlich_wilkie", tint=(1, 1, 1), wavelengths=[500, 600]),
        ),
        ("gold.specular(wo, fresnel='bogus')", lambda: _gold().specular(WO, fresnel="bogus")),
        ("gold.pdf(wi, wo, g2='smith')", lambda: _gold().pdf(W, WO, g2="smith")),
        ("gold.lobes(wo, 'microfacet')", lambda: _gold().lobes(WO, "microfacet")),
        ("gold.albedo(wi, fresnel='bogus')", lambda: _gold().albedo(W, fresnel="bogus")),
    ]


def _input_cases() -> List[Case]:
    def car(**inputs):
        return materials.car_paint().eval(W, WO, "weidlich_wilkie", **inputs)

    return [
        ("Patina().eval(wi, wo, mask=1.5)", lambda: materials.Patina().eval(W, WO, 1.5)),
        ("Patina().eval(wi, wo, mask=-0.5)", lambda: materials.Patina().eval(W, WO, -0.5)),
        ("Patina().eval(wi, wo, mask=float('nan'))", lambda: materials.Patina().eval(W, WO, NAN)),
        (
            "Patina().eval(np.ones((4, 3)), wo, mask=np.zeros(5))  (shapes do not broadcast)",
            lambda: materials.Patina().eval(np.ones((4, 3)), WO, np.zeros(5)),
        ),
        ("car_paint().eval(..., 'weidlich_wilkie', flake_normal=np.zeros(2))", lambda: car(flake_normal=np.zeros(2))),
        ("car_paint().eval(..., 'weidlich_wilkie', flake_normal=[20, 0, 0])", lambda: car(flake_normal=[20, 0, 0.0])),
        ("car_paint().eval(..., 'weidlich_wilkie', flake_normal=[nan, 0, 0])", lambda: car(flake_normal=[NAN, 0, 0.0])),
        ("car_paint().eval(..., 'weidlich_wilkie', distance=-1.0)", lambda: car(distance=-1.0)),
        ("gold.eval(wi, wo, mask=0.5)  (input microfacet does not declare)", lambda: _gold().eval(W, WO, mask=0.5)),
        (
            "coated.eval(wi, wo, 'steinberg', flake_normal=[0, 0, 0])",
            lambda: _coated().eval(W, WO, "steinberg", flake_normal=[0, 0, 0.0]),
        ),
        ("coated.pdf(wi, wo, 'weidlich_wilkie', mask=0.5)", lambda: _coated().pdf(W, WO, "weidlich_wilkie", mask=0.5)),
    ]


def _sampling_cases() -> List[Case]:
    return [
        ("gold.sample(wo, [1.5, 0.5, 0.5])", lambda: _gold().sample(WO, [1.5, 0.5, 0.5])),
        ("gold.sample(wo, [-0.1, 0.5, 0.5])", lambda: _gold().sample(WO, [-0.1, 0.5, 0.5])),
        ("gold.sample(wo, [nan, 0.5, 0.5])", lambda: _gold().sample(WO, [NAN, 0.5, 0.5])),
        ("gold.sample(wo, [0.5, 0.5])  (u of width 2)", lambda: _gold().sample(WO, [0.5, 0.5])),
        ("gold.sample([0, 0, 0], u)", lambda: _gold().sample([0, 0, 0.0], U)),
        ("gold.sample(wo, [1.5, 0.5, 0.5], 'reference')", lambda: _gold().sample(WO, [1.5, 0.5, 0.5], "reference")),
        ("gold.sample(wo, u, mask=0.5)", lambda: _gold().sample(WO, U, mask=0.5)),
        ("gold.pdf(wi, wo, 'reference')", lambda: _gold().pdf(W, WO, "reference")),
        ("gold.specular(wo, 'reference')", lambda: _gold().specular(WO, "reference")),
    ]


def _reference_cases() -> List[Case]:
    def lobe(bins):
        return _gold().reference_lobe(W, bins, samples=16)

    return [
        ("gold.reference(wi, wo, samples=1)", lambda: _gold().reference(W, WO, samples=1)),
        ("gold.reference(wi, wo, samples=0)", lambda: _gold().reference(W, WO, samples=0)),
        ("gold.reference(wi, wo, samples=2.5)", lambda: _gold().reference(W, WO, samples=2.5)),
        ("gold.reference(wi, wo, samples=True)", lambda: _gold().reference(W, WO, samples=True)),
        ("gold.reference(wi, wo, samples=16, seed=-1)", lambda: _gold().reference(W, WO, samples=16, seed=-1)),
        ("gold.reference(wi, wo, samples=16, seed=2**64)", lambda: _gold().reference(W, WO, samples=16, seed=2**64)),
        ("gold.reference(wi, wo, samples=16, seed=1.5)", lambda: _gold().reference(W, WO, samples=16, seed=1.5)),
        (
            "gold.reference(wi, wo, samples=16, distribution='phong')",
            lambda: _gold().reference(W, WO, samples=16, distribution="phong"),
        ),
        ("gold.reference(wi, wo, samples=16, g2='smith')", lambda: _gold().reference(W, WO, samples=16, g2="smith")),
        ("gold.eval(wi, wo, 'reference', samples=1)", lambda: _gold().eval(W, WO, "reference", samples=1)),
        (
            "gold.eval(wi, wo, 'reference', samples=16, fresnel='exact')",
            lambda: _gold().eval(W, WO, "reference", samples=16, fresnel="exact"),
        ),
        ("gold.albedo(wi, 'reference', samples=1)", lambda: _gold().albedo(W, "reference", samples=1)),
        (
            "gold.albedo(wi, 'reference', samples=16, g2='smith')",
            lambda: _gold().albedo(W, "reference", samples=16, g2="smith"),
        ),
        ("gold.reference_lobe(wi, bins=(100000, 100000), samples=16)", lambda: lobe((100_000, 100_000))),
        ("gold.reference_lobe(wi, bins=(-1, 3), samples=16)", lambda: lobe((-1, 3))),
        ("gold.reference_lobe(wi, bins=(0, 3), samples=16)", lambda: lobe((0, 3))),
        ("gold.reference_lobe(wi, bins=(2.5, 3), samples=16)", lambda: lobe((2.5, 3))),
        ("gold.reference_lobe(wi, bins=18, samples=16)", lambda: lobe(18)),
        (
            "gold.reference_lobe(np.ones((2, 3)), samples=16)",
            lambda: _gold().reference_lobe(np.ones((2, 3)), samples=16),
        ),
        ("gold.reference_lobe(wi, samples=1)", lambda: _gold().reference_lobe(W, samples=1)),
    ]


def _spectrum_cases() -> List[Case]:
    return [
        ("Spectrum([600, 500], [1, 2])  (decreasing wavelengths)", lambda: Spectrum([600, 500], [1, 2])),
        ("Spectrum([500, 600], [1])  (mismatched lengths)", lambda: Spectrum([500, 600], [1])),
        ("Spectrum([], [])", lambda: Spectrum([], [])),
        ("Spectrum([500, 600], [1, nan])", lambda: Spectrum([500, 600], [1, NAN])),
        ("Spectrum([500, 600], [[1, 2]])", lambda: Spectrum([500, 600], [[1, 2]])),
        ("Spectrum([-500, 600], [1, 2])", lambda: Spectrum([-500, 600], [1, 2])),
        (
            "Spectrum([500, 600], [1, 2], extrapolate=False)(700)",
            lambda: Spectrum([500, 600], [1, 2], extrapolate=False)(700),
        ),
        ("lamina.spectrum.ior('Gold')", lambda: ior("Gold")),
        ("lamina.to_xyz([500, 600], np.zeros((4, 3)))", lambda: to_xyz([500, 600], np.zeros((4, 3)))),
        ("lamina.xyz_weights([600, 500])", lambda: xyz_weights([600, 500])),
    ]


def _optics_cases() -> List[Case]:
    return [
        ("optics.ndf(m, 0.0)", lambda: optics.ndf(W, 0.0)),
        ("optics.ndf(m, 1.5)", lambda: optics.ndf(W, 1.5)),
        ("optics.ndf(m, (0.1, -0.2))", lambda: optics.ndf(W, (0.1, -0.2))),
        ("optics.ndf(m, 0.3, distribution='phong')", lambda: optics.ndf(W, 0.3, distribution="phong")),
        ("optics.ndf([nan, 0, 1], 0.3)", lambda: optics.ndf([NAN, 0, 1.0], 0.3)),
        ("optics.smith_lambda(w, -0.1)", lambda: optics.smith_lambda(WO, -0.1)),
        (
            "optics.masking_shadowing(wi, wo, m, 0.3, g2='smith')",
            lambda: optics.masking_shadowing(W, WO, W, 0.3, g2="smith"),
        ),
        (
            "optics.sample_visible_normal(wi, [0.5, 0.5, 0.5], 0.3)  (u of width 3)",
            lambda: optics.sample_visible_normal(W, U, 0.3),
        ),
        ("optics.sample_visible_normal(wi, [1.5, 0.5], 0.3)", lambda: optics.sample_visible_normal(W, [1.5, 0.5], 0.3)),
        ("optics.visible_normal_pdf(wi, m, 0.0)", lambda: optics.visible_normal_pdf(W, W, 0.0)),
        ("optics.fresnel_dielectric(0.5, 0.0)", lambda: optics.fresnel_dielectric(0.5, 0.0)),
        ("optics.fresnel_dielectric(0.5, -1.5)", lambda: optics.fresnel_dielectric(0.5, -1.5)),
        ("optics.fresnel_dielectric(2.0, 1.5)  (cos_i > 1)", lambda: optics.fresnel_dielectric(2.0, 1.5)),
        ("optics.fresnel_dielectric(nan, 1.5)", lambda: optics.fresnel_dielectric(NAN, 1.5)),
        ("optics.fresnel_conductor(0.5, -1.0, 3.0)", lambda: optics.fresnel_conductor(0.5, -1.0, 3.0)),
        ("optics.fresnel_conductor(0.5, 0.2, -3.0)", lambda: optics.fresnel_conductor(0.5, 0.2, -3.0)),
        ("optics.fresnel_lazanyi(1.5, 0.2, 3.0)  (cos_i > 1)", lambda: optics.fresnel_lazanyi(1.5, 0.2, 3.0)),
        ("optics.fresnel_schlick(0.5, 1.5)  (f0 > 1)", lambda: optics.fresnel_schlick(0.5, 1.5)),
        ("optics.fresnel_diffuse_reflectance(0.0)", lambda: optics.fresnel_diffuse_reflectance(0.0)),
        (
            "optics.rough_conductor(wi, wo, [0.2, 0.3], [3.0], 0.3)",
            lambda: optics.rough_conductor(W, WO, [0.2, 0.3], [3.0], 0.3),
        ),
        (
            "optics.rough_conductor(wi, wo, 0.2, 3.0, 0.3, g2='smith')",
            lambda: optics.rough_conductor(W, WO, 0.2, 3.0, 0.3, g2="smith"),
        ),
        ("optics.rough_dielectric(wi, wo, 0.0, 0.3)", lambda: optics.rough_dielectric(W, WO, 0.0, 0.3)),
        ("optics.rough_dielectric(wi, wo, 'glass', 0.3)", lambda: optics.rough_dielectric(W, WO, "glass", 0.3)),
        ("optics.rough_dielectric(wi, wo, [], 0.3)", lambda: optics.rough_dielectric(W, WO, [], 0.3)),
        ("lamina.jacobian_reflect(2.0)", lambda: lamina.jacobian_reflect(2.0)),
        ("lamina.jacobian_refract(0.3, eta=0.0)", lambda: lamina.jacobian_refract(0.3, eta=0.0)),
        (
            "lamina.jacobian_refract(1.2, eta=0.5)  (total internal reflection)",
            lambda: lamina.jacobian_refract(1.2, eta=0.5),
        ),
        ("optics.steinberg_lut(0.0, 0.3, 1.5)", lambda: optics.steinberg_lut(0.0, 0.3, 1.5)),
        ("optics.steinberg_lut(0.5, 0.3, 10.0)", lambda: optics.steinberg_lut(0.5, 0.3, 10.0)),
        ("optics.steinberg_lut(0.5, 0.3, 1.5, lut='bogus')", lambda: optics.steinberg_lut(0.5, 0.3, 1.5, lut="bogus")),
    ]


def _material_cases() -> List[Case]:
    return [
        ("materials.flake_normals(np.zeros((4, 3)))", lambda: materials.flake_normals(np.zeros((4, 3)))),
        ("materials.flake_normals([nan, 0])", lambda: materials.flake_normals([NAN, 0.0])),
        ("materials.flake_normals(uv, density=-1)", lambda: materials.flake_normals(np.zeros(2), density=-1)),
        ("materials.flake_normals(uv, density='fine')", lambda: materials.flake_normals(np.zeros(2), density="fine")),
        ("materials.flake_normals(uv, spread=-1)", lambda: materials.flake_normals(np.zeros(2), spread=-1)),
        ("materials.flake_normals(uv, seed=-1)", lambda: materials.flake_normals(np.zeros(2), seed=-1)),
        ("materials.flake_normals(uv, seed=1.5)", lambda: materials.flake_normals(np.zeros(2), seed=1.5)),
        ("materials.preset('Gold')", lambda: materials.preset("Gold")),
        ("materials.preset(None)", lambda: materials.preset(None)),
        ("materials.suite('gold')", lambda: materials.suite("gold")),
        ("materials.metal('Unobtainium')", lambda: materials.metal("Unobtainium")),
        ("materials.metal('Au', roughness=2.0)", lambda: materials.metal("Au", roughness=2.0)),
        ("materials.plastic(albedo=2.0)", lambda: materials.plastic(albedo=2.0)),
        ("materials.car_paint(coat_thickness=-1.0)", lambda: materials.car_paint(coat_thickness=-1.0)),
        ("materials.patina(extent=2.0)", lambda: materials.patina(extent=2.0)),
        ("materials.patina(transition=-0.1)", lambda: materials.patina(transition=-0.1)),
        ("materials.Patina(tint=(1, 1))", lambda: materials.Patina(tint=(1, 1))),
        ("materials.Patina(thickness=-0.5)", lambda: materials.Patina(thickness=-0.5)),
        ("materials.patina(colour='green')", lambda: materials.patina(colour="green")),
    ]


def bad_inputs() -> List[Case]:
    """Every case: (the input as a user would write it, a zero-argument callable that should raise)."""
    return (
        _layer_cases()
        + _stack_cases()
        + _array_cases()
        + _wavelength_cases()
        + _model_cases()
        + _input_cases()
        + _sampling_cases()
        + _reference_cases()
        + _spectrum_cases()
        + _optics_cases()
        + _material_cases()
    )


def first_line(text: str, limit: int = MESSAGE_CHARS) -> str:
    """The first non-empty line of `text`, truncated to `limit` characters."""
    line = next((ln.strip() for ln in str(text).splitlines() if ln.strip()), "")
    return line if len(line) <= limit else line[: limit - 1] + "…"


def summarize(value) -> str:
    """A short description of what a call returned (for cases that raised nothing)."""
    if isinstance(value, np.ndarray):
        return f"returned array {value.shape} {np.array2string(value.ravel()[:4], precision=3)}"
    if isinstance(value, tuple):
        return "returned (" + ", ".join(summarize(v).replace("returned ", "") for v in value) + ")"
    return f"returned {type(value).__name__} {value!r}"


def run_case(fn: Callable[[], object]) -> Tuple[Optional[BaseException], str]:
    """Calls `fn`: (the exception it raised or None, the exception's message or a summary of what it returned)."""
    try:
        value = fn()
    except BaseException as exc:  # noqa: B036 - pyo3's PanicException derives from BaseException
        if isinstance(exc, KeyboardInterrupt):
            raise
        return exc, first_line(str(exc) or repr(exc))
    return None, first_line(summarize(value))


def is_clean(exc: Optional[BaseException]) -> bool:
    """Whether a case raised what lamina promises for bad input: a ValueError or a TypeError."""
    return isinstance(exc, (ValueError, TypeError))


def cell(text: str) -> str:
    """`text` made safe for a markdown table cell."""
    return str(text).replace("\\", "\\\\").replace("|", "\\|").replace("\n", " ")


def run_all(cases: List[Case]) -> List[Tuple[str, str, str, bool]]:
    """(input, exception class name or 'no error', message, clean) for each case."""
    rows = []
    for description, fn in cases:
        exc, message = run_case(fn)
        rows.append((description, "no error" if exc is None else type(exc).__name__, message, is_clean(exc)))
    return rows


def bad_input_section(rows: List[Tuple[str, str, str, bool]]) -> List[str]:
    """The 'Bad input' section: one table row per case and a summary line."""
    clean = sum(r[3] for r in rows)
    lines = [
        "## Bad input",
        "",
        "Inputs a new user could write; each should raise a ValueError or TypeError that names the parameter.",
        "",
        "| # | input | exception | message |",
        "|---:|---|---|---|",
    ]
    for i, (description, name, message, ok) in enumerate(rows, 1):
        shown = name if ok else f"**{name}**"
        lines.append(f"| {i} | `{cell(description)}` | {shown} | {cell(message)} |")
    lines += [
        "",
        f"{len(rows)} cases: {clean} raised ValueError or TypeError, {len(rows) - clean} raised anything "
        "else or nothing.",
    ]
    return lines


def load_fuzz(path: Path):
    """(rows, metadata) from docs/fuzz.json: a list of rows, or an object holding one ('rows' or 'results') next to
    top-level metadata. None if the file is missing; a string saying why if it cannot be read."""
    if not path.exists():
        return None
    try:
        data = json.loads(path.read_text())
    except (OSError, ValueError) as exc:
        return f"{path.name} could not be read ({first_line(str(exc))})"
    meta = {}
    if isinstance(data, dict):
        meta = {k: v for k, v in data.items() if not isinstance(v, (list, dict))}
        data = next((data[k] for k in ("rows", "results", "models") if isinstance(data.get(k), list)), None)
    if not isinstance(data, list) or not all(isinstance(r, dict) for r in data):
        return f"{path.name} holds no list of rows"
    return data, meta


def _number(row: dict, key: str, kind=int):
    try:
        return kind(row.get(key, 0) or 0)
    except (TypeError, ValueError):
        return kind(0)


def fuzz_section(path: Path = FUZZ) -> List[str]:
    """The 'Fuzzing' section from scripts/fuzz.py's results, or a line saying how to produce them."""
    lines = ["## Fuzzing", ""]
    loaded = load_fuzz(path)
    if loaded is None:
        return lines + ["No fuzzing results yet: run `make fuzz` (writes docs/fuzz.json), then this script again."]
    if isinstance(loaded, str):
        return lines + [f"{loaded}: run `make fuzz` again, then this script."]
    rows, meta = loaded
    lines.append(
        "Random stacks, directions and options from `scripts/fuzz.py` (`make fuzz`); counts of output values "
        "that are NaN, Inf or negative, over float64 and float32 directions (float32 ones take the models' float32 "
        "lanes where they have them)."
    )
    if meta:
        lines += ["", "; ".join(f"{k}: {v}" for k, v in meta.items()) + "."]
    lines += [
        "",
        "| model | options | evaluations | of which float32 | NaN | Inf | negative | seconds |",
        "|---|---|---:|---:|---:|---:|---:|---:|",
    ]
    keys = ("evaluations", "float32", "nan", "inf", "negative")
    totals = dict.fromkeys(keys, 0)
    seconds = 0.0
    for r in rows:
        counts = [_number(r, k) for k in keys]
        for k, c in zip(keys, counts):
            totals[k] += c
        seconds += _number(r, "seconds", float)
        lines.append(
            f"| {cell(r.get('model', '?'))} | {cell(r.get('options') or '') or '—'} | "
            + " | ".join(f"{c:,}" for c in counts)
            + f" | {_number(r, 'seconds', float):.2f} |"
        )
    lines.append("| **total** | | " + " | ".join(f"**{totals[k]:,}**" for k in keys) + f" | **{seconds:.2f}** |")
    return lines


def _yes(ok: bool) -> str:
    return "yes" if ok else "**no**"


def fault_section() -> List[str]:
    """Each fault of tests/faults.py, provoked now, and its outcome (make test asserts the same, tests/test_faults.py
    and tests/test_gpu.py)."""
    lines = [
        "## Faults",
        "",
        "Each fault is provoked for real by `tests/faults.py` (`make test` asserts the outcomes: tests/test_faults.py, "
        "tests/test_gpu.py) in a temporary cache, and in a child process where it would touch the caller.",
        "",
        "### A damaged cache entry (`$LAMINA_CACHE`)",
        "",
        "Cached by one process, damaged, asked for by a fresh one: every entry carries a header and a checksum "
        "(src/cache.rs).",
        "",
        "| entry | damage | results bit-identical | entry rebuilt intact |",
        "|---|---|---|---|",
    ]
    for what, damage, same, intact in faults.cache_corruption():
        lines.append(f"| {what} | {damage} | {_yes(same)} | {_yes(intact)} |")
    lines += [
        "",
        "### A cache that cannot be written",
        "",
        "| cache | results as with a writable cache | warnings | temporary files left |",
        "|---|---|---|---|",
    ]
    described = {
        "unwritable": "LAMINA_CACHE through a regular file (creating its folder fails, as for a read-only one)",
        "full": "a file-size limit of 64 KiB (RLIMIT_FSIZE): a table's write fails midway, as on a full disk",
    }
    for name, run in faults.unwritable_cache().items():
        warning = cell(first_line(run["warnings"][0], 120)) if run["warnings"] else ""
        left = len(run["left behind"])
        lines.append(f"| {described[name]} | {_yes(run['same'])} | {len(run['warnings'])}: {warning} | {left} |")
    lines += [
        "",
        "### Concurrent writers of one table",
        "",
        "| writers | the same bits | files | intact | temporary files left |",
        "|---|---|---:|---|---:|",
    ]
    for who, run in faults.concurrent_writers().items():
        same, intact, left = _yes(run["same"]), _yes(run["intact"]), run["left behind"]
        lines.append(f"| two {who} at once | {same} | {run['files']} | {intact} | {left} |")
    lost = faults.lost_worker()
    lines += [
        "",
        "### A Dask worker killed mid-sweep",
        "",
        "`lamina.dask.suite_reference` over three materials on a two-worker `LocalCluster`; one worker is killed "
        "(SIGKILL) while it runs a task.",
        "",
        "| worker killed | sweep completed | bit-identical to a local run |",
        "|---|---|---|",
        f"| {_yes(lost['killed'])} | {_yes(lost['completed'])} | {_yes(lost['same'])} |",
        "",
        "### Ctrl-C",
        "",
        "| interrupted | KeyboardInterrupt | seconds after the signal | cache entries or temporary files left |",
        "|---|---|---:|---|",
    ]
    for what, run in faults.interrupts().items():
        extra = f" (a child that solves it in {run['solve seconds']:.1f} s)" if "solve seconds" in run else ""
        left = len(run.get("left behind", []))
        seconds = f"{run['seconds']:.2f}" if run["seconds"] is not None else "—"
        lines.append(f"| {what}{extra} | {_yes(run['raised'])} | {seconds} | {left} |")
    lines += [
        "| a fit (`lamina.fit`) | not yet: lamina has no fit (the Fit issue) | | |",
        "",
        "### GPU faults",
        "",
    ]
    if lamina.gpu.adapter() is None:
        lines.append(f"Not measured: no GPU adapter ({lamina.gpu._adapter()[1]}).")
        return lines
    gpu = faults.gpu_faults()
    lines += [
        f"On {gpu['adapter']}. A render that needs more than the device holds, then a device lost in the middle of an "
        "evaluation of 5M pairs (it destroys itself after one of its three dispatches: lamina's fault injection, "
        "`_lamina._gpu_lose_after`).",
        "",
        "| fault | exception | the next call |",
        "|---|---|---|",
        f"| render of 16384 x 16384 | {cell(first_line(gpu['too large'] or 'none', 220))} | a 32 x 32 render works |",
        f"| device lost mid-batch | {cell(first_line(gpu['lost'] or 'none', 220))} | evaluates again, "
        f"{gpu['after lost']:.1e} from the CPU |",
    ]
    return lines


def document(rows: List[Tuple[str, str, str, bool]], fuzz_path: Path = FUZZ) -> str:
    """docs/reliability.md's text."""
    head = ["# Reliability", "", "Generated by `scripts/reliability.py` (`make reliability`); do not edit by hand.", ""]
    body = bad_input_section(rows) + [""] + fault_section() + [""] + fuzz_section(fuzz_path)
    return "\n".join(head + body) + "\n"


def main() -> int:
    rows = run_all(bad_inputs())
    OUT.write_text(document(rows))
    bad = [r for r in rows if not r[3]]
    print(f"wrote {OUT.relative_to(ROOT)}: {len(rows)} cases, {len(bad)} not a ValueError / TypeError")
    for description, name, message, _ in bad:
        print(f"  {description}: {name}: {message}", file=sys.stderr)
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
