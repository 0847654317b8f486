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


@pytest.mark.parametrize("S", [1, 4])
@pytest.mark.parametrize("reduce", ["mean", "max"])
def test_per_pixel_is_the_nan_mean_of_each_pixels_rays(S, reduce):
    """ObjectRays.per_pixel against a brute-force loop over pixels: the mean (or max) of the finite values of the
    sub-pixel rays that hit, ``fill`` where none does or all are NaN; one ray per pixel (S = 1, paper quality:
    its own shortcut) as several (S = 4); vector values (M, 4) too."""
    rng = np.random.default_rng(S)
    H, W = 7, 5
    hit = rng.random((H, W, S)) < 0.6
    M = int(hit.sum())
    vals = rng.random((M, 4))
    vals[rng.random(M) < 0.2, 1] = np.nan  # some rays without a value
    rays = shading.ObjectRays(hit, *(np.zeros((M, 3)),) * 4)
    got = rays.per_pixel(vals, fill=-1.0, reduce=reduce)
    idx = np.full(hit.shape, -1)
    idx[hit] = np.arange(M)
    for i in range(H):
        for j in range(W):
            for c in range(4):
                v = [vals[k, c] for k in idx[i, j] if k >= 0 and np.isfinite(vals[k, c])]
                want = (np.mean(v) if reduce == "mean" else np.max(v)) if v else -1.0
                assert got[i, j, c] == pytest.approx(want), (i, j, c)


def test_per_pixel_mean_is_numpys_nanmean_bit_for_bit():
    """The mean's sum / count is np.nanmean of the NaN-filled (H, W, S, C) rays, bit for bit (an inf stays)."""
    rng = np.random.default_rng(9)
    H, W, S = 33, 21, 9
    hit = rng.random((H, W, S)) < 0.5
    M = int(hit.sum())
    vals = rng.random((M, 3)) * 10.0 ** rng.integers(-3, 4, (M, 1))
    vals[rng.random(M) < 0.1, 0] = np.nan
    vals[5, 2] = np.inf
    full = np.full((H, W, S, 3), np.nan)
    full[hit] = vals
    with np.errstate(invalid="ignore"), pytest.warns(RuntimeWarning):
        want = np.nanmean(full, axis=2)
    got = shading.ObjectRays(hit, *(np.zeros((M, 3)),) * 4).per_pixel(vals)
    np.testing.assert_array_equal(got, want)
