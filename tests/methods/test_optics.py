"""Snell's law, dielectric Fresnel and the sphere's two-interface path against closed forms and Mitsuba."""

import numpy as np

from study.impostor import analytic
from study.optics import interfaces as optics


def test_refract_obeys_snell_and_flags_tir():
    _, d = analytic.random_rays(2000, extent=0, seed=8)
    n = np.tile([0.0, 0.0, 1.0], (2000, 1))
    d[:, 2] = -np.abs(d[:, 2])  # arriving against n
    for eta in (1 / 1.5, 1.5):
        t, ok = optics.refract(d, n, eta)
        sin_i = np.linalg.norm(np.cross(d, n), axis=1)
        sin_t = np.linalg.norm(np.cross(t[ok], n[ok]), axis=1)
        np.testing.assert_allclose(sin_t, eta * sin_i[ok], atol=1e-12)
        np.testing.assert_array_equal(ok, eta * sin_i <= 1)
        assert np.all(np.isnan(t[~ok]))
        np.testing.assert_allclose(np.linalg.norm(t[ok], axis=1), 1, atol=1e-12)


def test_fresnel_dielectric_matches_mitsuba():
    from study.reference.mitsuba import mi

    m = mi()
    cos = np.linspace(0.01, 1, 60)
    for n_from, n_to in ((1.0, 1.5), (1.5, 1.0), (1.0, 1.3)):
        ours = optics.fresnel_dielectric(cos, n_from / n_to)
        theirs = np.array(m.fresnel(m.Float(cos), n_to / n_from)[0])
        np.testing.assert_allclose(ours, theirs, atol=2e-6)


def test_sphere_path_is_symmetric_and_conserves():
    """A ray through a sphere leaves at the entry angle, deviated in the plane of incidence; the chord length
    is 2 r cos(theta_t)."""
    c, r, ior = np.array([0.0, 0.0, 0.0]), 0.5, 1.3
    _, d = analytic.random_rays(1000, extent=0, seed=9)
    N = -d.copy()  # enter head-on at first …
    rng = np.random.default_rng(9)
    N = N + 0.6 * rng.normal(size=N.shape)
    N /= np.linalg.norm(N, axis=1, keepdims=True)
    d = np.where(np.sum(d * N, axis=1, keepdims=True) < 0, d, -d)
    x = c + r * N
    p = optics.through_sphere(x, d, N, c, r, ior)
    assert p.ok.all()
    Ne = (p.exit - c) / r
    np.testing.assert_allclose(np.sum(p.out * Ne, axis=1), -np.sum(d * N, axis=1), atol=1e-9)
    cos_t = -np.sum(p.inner * N, axis=1)
    np.testing.assert_allclose(np.linalg.norm(p.exit - x, axis=1), 2 * r * cos_t, atol=1e-9)
    assert np.all((p.transmittance > 0) & (p.transmittance < 1))
