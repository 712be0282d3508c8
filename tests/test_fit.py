"""Parameter gradients (Stack.eval_grad: forward-mode automatic differentiation, optics/dual.rs) and lamina.fit: from
measured f back to a stack's free parameters (lamina.Param). Gradients against central finite differences; fits
recover the parameters of data lamina made, within their reported standard errors."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import random_hemisphere
from lamina import Conductor, Dielectric, Diffuse, Param, Stack, fit, measured, models
from lamina.materials import metal


def _central(template: Stack, values: dict, wi, wo, h: float = 1e-6) -> np.ndarray:
    """∂f/∂p by central differences of Stack.eval at the bound stacks: (..., channels, params)."""
    out = []
    for p in template.params:
        up, down = dict(values), dict(values)
        up[p.name] += h
        down[p.name] -= h
        f = lambda v: template.bind(**v).eval(wi, wo, "microfacet")  # noqa: E731
        out.append((f(up) - f(down)) / (2 * h))
    return np.stack(out, -1)


def _check(template: Stack, values: dict, wi, wo):
    f, grad = template.eval_grad(wi, wo, "microfacet", **values)
    # f as Stack.eval gives it, to rounding (another loop).
    np.testing.assert_allclose(f, template.bind(**values).eval(wi, wo, "microfacet"), rtol=1e-13)
    fd = _central(template, values, wi, wo)
    # float64 central differences with h = 1e-6: O(h²) truncation and 1e-16/h rounding, far below the bound.
    np.testing.assert_allclose(grad, fd, rtol=1e-5, atol=1e-9 * np.abs(fd).max())
    return grad


def test_a_rough_conductor_s_gradients_are_its_central_differences(rng):
    """η (all channels), κ (two channels of three), both roughnesses and the frame angle of an anisotropic conductor,
    at random values and directions down to 1° above the horizon; the catalogue says which fields microfacet
    differentiates."""
    template = Stack(
        [
            Conductor(
                ior=Param("eta", 0.1, 3.0),
                k=(Param("k_r", 0.0, 6.0), 2.5, Param("k_b", 0.0, 6.0)),
                roughness=(Param("ax", 0.005, 1.0), Param("ay", 0.005, 1.0)),
                angle=Param("phi", -3.0, 3.0),
            )
        ],
        ext_ior=1.2,
    )
    assert [p.name for p in template.params] == ["eta", "k_r", "k_b", "ax", "ay", "phi"]
    wi, wo = random_hemisphere(rng, 400, 0.02), random_hemisphere(rng, 400, 0.02)
    for _ in range(3):
        values = dict(
            eta=rng.uniform(0.2, 2.5),
            k_r=rng.uniform(0.0, 5.0),
            k_b=rng.uniform(0.5, 5.0),
            ax=rng.uniform(0.02, 0.8),
            ay=rng.uniform(0.02, 0.8),
            phi=rng.uniform(-3, 3),
        )
        grad = _check(template, values, wi, wo)
        assert np.all(grad[..., 1, 1:3] == 0.0)  # κ of the green channel is not a parameter
    assert set(models()[0].gradients) >= {"ior", "k", "roughness_x", "roughness_y", "angle", "albedo"}
    assert all(not m.gradients for m in models() if m.name != "microfacet")


def test_a_diffuse_base_s_gradients_and_a_parameter_f_ignores(rng):
    """Oren–Nayar: albedo per channel and σ. A conductor's frame angle under isotropic roughness leaves f unchanged:
    its gradient is 0 (to rounding)."""
    template = Stack([Diffuse((Param("r", 0.0, 1.0), 0.5, Param("b", 0.0, 1.0)), roughness=Param("sigma", 0.0, 1.0))])
    wi, wo = random_hemisphere(rng, 300, 0.02), random_hemisphere(rng, 300, 0.02)
    _check(template, dict(r=0.7, b=0.2, sigma=0.4), wi, wo)
    iso = Stack([Conductor(ior=1.1, k=3.0, roughness=0.3, angle=Param("phi", -1.0, 1.0))])
    f, grad = iso.eval_grad(wi, wo, phi=0.4)
    assert np.all(np.abs(grad[..., 0]) <= 1e-12 * f.max())


def test_gradients_refuse_what_a_model_does_not_differentiate():
    coated = Stack([Dielectric(Param("n", 1.2, 2.0), roughness=0.2), metal("Cu", 0.3)])
    with pytest.raises(ValueError, match="model 'belcour' has no gradient by ior"):
        coated.eval_grad([0, 0, 1], [0, 0, 1], "belcour")
    with pytest.raises(ValueError, match="this stack has no lamina.Param"):
        Stack([metal("Cu", 0.3)]).eval_grad([0, 0, 1], [0, 0, 1])
    with pytest.raises(ValueError, match=r"the stack is a family over \['n'\]: give each one's values per element"):
        coated.eval([0, 0, 1], [0, 0, 1], "belcour")
    with pytest.raises(ValueError, match=r"free parameters \['n'\]: give their values"):
        coated.specular([0, 0, 1], "belcour")
    with pytest.raises(ValueError, match=r"n must be a number in \[1.2, 2.0\]"):
        coated.bind(n=2.5)
    with pytest.raises(ValueError, match=r"unknown \['m'\], missing \['n'\]"):
        coated.bind(m=1.5)
    # A Param whose range leaves the layer's: roughness is at most 1.
    with pytest.raises(ValueError, match=r"the range of Param 'r' \[0.5, 2.0\] leaves the layer's"):
        Conductor(1.0, 3.0, roughness=Param("r", 0.5, 2.0))
    with pytest.raises(ValueError, match="low must be below high"):
        Param("r", 0.5, 0.1)


def test_fit_recovers_a_rough_conductor_within_its_standard_errors(rng):
    """Data made by lamina (η, κ, α of a rough conductor, RGB, 1500 pairs, additive Gaussian noise of 1% of the mean
    f): the fit recovers each parameter within 3 of its reported standard errors in ≥ 90% of 10 cases, and within 2%
    relative where the data determine it (standard error below 0.5%)."""
    template = Stack([Conductor(Param("eta", 0.1, 3.0), Param("k", 0.5, 6.0), roughness=Param("alpha", 0.02, 0.9))])
    within, determined = 0, []
    for case in range(10):
        truth = dict(eta=rng.uniform(0.2, 2.0), k=rng.uniform(1.0, 5.0), alpha=rng.uniform(0.05, 0.7))
        wi, wo = random_hemisphere(rng, 1500, 0.05), random_hemisphere(rng, 1500, 0.05)
        f = template.bind(**truth).eval(wi, wo, "microfacet")
        noisy = np.maximum(f + rng.normal(0.0, 0.01 * f.mean(), f.shape), 0.0)
        r = fit(template, wi, wo, noisy, starts=3, seed=case)
        assert r.converged, r.message
        within += all(abs(r.params[k] - v) <= 3 * r.stderr[k] for k, v in truth.items())
        determined += [abs(r.params[k] / v - 1) for k, v in truth.items() if r.stderr[k] < 0.005 * v]
    assert within >= 9, within
    assert determined and max(determined) < 0.02, determined


def test_fit_reads_measured_data_and_refuses_bad_input(tmp_path, rng):
    """Lamina's rough gold written as a MERL table and read back as 2000 samples: the fit of a conductor's α finds the
    roughness the table was made from (within 3%: the table's nearest-bin lookup; measured 0.0% to 1.5% over three
    sample seeds; its standard error, 5e-5, knows only noise, not the bins)."""
    gold = metal("Au", 0.3)
    table = measured.merl_table(lambda wi, wo: Stack([gold]).eval(wi, wo, "microfacet"))
    data = table.samples(2000, seed=1)
    template = Stack([Conductor(gold.ior, gold.k, roughness=Param("alpha", 0.02, 0.9))])
    r = fit(template, None, None, data, starts=2)
    assert abs(r.params["alpha"] / 0.3 - 1) < 0.03, r.params
    assert set(r.residual) == {"0-60", "60-80", "80-90"}
    wi, wo, f = data.wi, data.wo, data.f
    with pytest.raises(ValueError, match="f must hold finite values ≥ 0"):
        fit(template, wi, wo, -f)
    with pytest.raises(ValueError, match="must have n rows each"):
        fit(template, wi, wo[:10], f)
    with pytest.raises(ValueError, match="measured must have 3 channels"):
        fit(template, wi, wo, f[:, :1])
    with pytest.raises(ValueError, match="at least one free parameter"):
        fit(Stack([gold]), wi, wo, f)
    with pytest.raises(ValueError, match="loss must be one of"):
        fit(template, wi, wo, f, loss="huber")
    with pytest.raises(ValueError, match="weights must be"):
        fit(template, wi, wo, f, weights=np.ones(7))
