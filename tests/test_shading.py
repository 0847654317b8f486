"""Shading pieces against closed forms and against Mitsuba's own Fresnel."""

import numpy as np
import pytest

from study.optics import interfaces as optics
from study.optics import shading
from study.scene import objects


def test_reflect_and_sphere_hit():
    V = np.array([[0.0, -1.0, 0.0]])
    N = np.array([[0.0, 1.0, 0.0]])
    np.testing.assert_allclose(optics.reflect(V, N), [[0.0, 1.0, 0.0]])
    t = objects.intersect_sphere(
        np.array([[0.0, 0.0, -5.0], [0.0, 3.0, -5.0]]),
        np.array([[0.0, 0.0, 1.0], [0.0, 0.0, 1.0]]),
        [0, 0, 0],
        1.0,
    )
    assert t[0] == pytest.approx(4.0) and np.isinf(t[1])


def test_fresnel_approx_is_exact_at_normal_incidence_and_grazing():
    n, k = np.array([0.155, 0.117, 0.138]), np.array([4.83, 3.12, 2.15])
    normal = ((n - 1) ** 2 + k**2) / ((n + 1) ** 2 + k**2)
    np.testing.assert_allclose(shading.fresnel_conductor(n, k, np.array([1.0]))[0], normal, rtol=1e-9)
    np.testing.assert_allclose(shading.fresnel_approx(n, k, np.array([1.0]))[0], normal, rtol=1e-12)
    np.testing.assert_allclose(shading.fresnel_conductor(n, k, np.array([1e-9]))[0], 1.0, atol=1e-6)


def test_fresnel_conductor_matches_mitsuba():
    from study.reference.mitsuba import mi

    m = mi()
    cos = np.linspace(0.01, 1.0, 50)
    n, k = np.array([0.2, 1.5, 2.0]), np.array([3.9, 2.0, 0.5])
    ours = shading.fresnel_conductor(n, k, cos)
    for c in range(3):
        theirs = np.array(m.fresnel_conductor(m.Float(cos), m.Complex2f(float(n[c]), float(k[c]))))
        np.testing.assert_allclose(ours[:, c], theirs, rtol=2e-5)
