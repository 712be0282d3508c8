"""Jacobians of the projected reflection and refraction maps against central finite differences of the maps
themselves (written here independently with NumPy). Step 1e-6: truncation ~1e-12, rounding ~1e-10."""

from __future__ import annotations

import lamina
import numpy as np
import pytest


def reflect_map(theta_i, xh, yh):
    wi = np.array([np.sin(theta_i), 0.0, np.cos(theta_i)])
    h = np.array([xh, yh, np.sqrt(1 - xh * xh - yh * yh)])
    wo = 2 * wi.dot(h) * h - wi
    return wo[:2]


def refract_map(theta_i, eta, xh, yh):
    wi = np.array([np.sin(theta_i), 0.0, np.cos(theta_i)])
    h = np.array([xh, yh, np.sqrt(1 - xh * xh - yh * yh)])
    d = wi.dot(h)
    ct = np.sqrt(1 - (1 - d * d) / eta**2)
    return (-wi / eta + (d / eta - ct) * h)[:2]


def finite_difference(f, xh, yh, step=1e-6):
    cols = [(f(xh + step, yh) - f(xh - step, yh)) / (2 * step), (f(xh, yh + step) - f(xh, yh - step)) / (2 * step)]
    return np.stack(cols, axis=-1)


@pytest.mark.parametrize("theta", [0.0, 0.3, 0.9, 1.4])
@pytest.mark.parametrize("xh, yh", [(0.0, 0.0), (0.2, -0.1), (-0.35, 0.4)])
def test_reflection_jacobian(theta, xh, yh):
    j = lamina.jacobian_reflect(theta, xh, yh)
    np.testing.assert_allclose(j, finite_difference(lambda x, y: reflect_map(theta, x, y), xh, yh), atol=1e-8)


@pytest.mark.parametrize("theta, eta", [(0.0, 1.5), (0.5, 1.5), (1.2, 1.33), (0.3, 0.8), (0.9, 2.4)])
@pytest.mark.parametrize("xh, yh", [(0.0, 0.0), (0.15, 0.05), (-0.2, -0.25)])
def test_refraction_jacobian(theta, eta, xh, yh):
    j = lamina.jacobian_refract(theta, eta, xh, yh)
    np.testing.assert_allclose(j, finite_difference(lambda x, y: refract_map(theta, eta, x, y), xh, yh), atol=1e-8)


def test_first_order_forms_and_shapes():
    t = np.linspace(0, 1.4, 8)
    np.testing.assert_allclose(lamina.jacobian_reflect(t, exact=False), 2 * np.cos(t)[:, None, None] * np.eye(2))
    ct = np.sqrt(1 - np.sin(t) ** 2 / 1.5**2)
    np.testing.assert_allclose(
        lamina.jacobian_refract(t, 1.5, exact=False), ((np.cos(t) - 1.5 * ct) / 1.5)[:, None, None] * np.eye(2)
    )
    np.testing.assert_allclose(lamina.jacobian_refract(t, 1.5), lamina.jacobian_refract(t, 1.5, exact=False))
    assert lamina.jacobian_reflect(t[:, None], np.zeros(3)).shape == (8, 3, 2, 2)


def test_jacobian_errors():
    with pytest.raises(ValueError, match="total internal reflection"):
        lamina.jacobian_refract(1.2, 0.6)
    with pytest.raises(ValueError, match="theta_i"):
        lamina.jacobian_reflect(2.0)
    with pytest.raises(ValueError, match="unit disc"):
        lamina.jacobian_reflect(0.3, 0.8, 0.8)
    with pytest.raises(ValueError, match="eta"):
        lamina.jacobian_refract(0.3, -1.0)
