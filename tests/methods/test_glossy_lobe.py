"""The GGX lobe and the prefiltered impostor against brute force.

Provenance: the environment is an analytic, smooth function of direction (no Mitsuba, no Embree); the brute-force
integrals sample the sphere *uniformly* (not the GGX lobe the code under test samples), seed 0, 2²¹ directions.
"""

import numpy as np
import pytest

from study.impostor import cubemap, ggx, prefilter


def radiance(d):  # smooth, positive, three different channels
    x, y, z = d[..., 0], d[..., 1], d[..., 2]
    return np.stack([1 + 0.6 * x + 0.3 * y * z, 1 + 0.5 * z * z - 0.2 * y, 0.5 + 0.4 * np.abs(y)], -1)


def uniform_sphere(n, seed=0):
    d = np.random.default_rng(seed).normal(size=(n, 3))
    return d / np.linalg.norm(d, axis=-1, keepdims=True)


def brute_force(n, alpha, dirs):
    """∫ L(l) D(h)(n·l)⁺ dl / ∫ D(h)(n·l)⁺ dl by uniform sampling of l."""
    nl = dirs @ n
    h = dirs + n
    h /= np.linalg.norm(h, axis=-1, keepdims=True)
    w = np.where(nl > 0, ggx.ndf(h @ n, alpha) * nl, 0.0)
    return (radiance(dirs) * w[:, None]).sum(0) / w.sum()


@pytest.mark.parametrize("m", [2, 3, 5])
def test_split_sum_convolution_agrees_with_brute_force(m):
    res = 32
    d = cubemap.texel_directions(res)
    texels = np.concatenate([radiance(d), np.ones(d.shape[:-1] + (1,))], -1)
    alpha = prefilter.level_alpha(m)
    level = prefilter.convolve(texels, alpha, 16)
    dirs = uniform_sphere(1 << 21)
    for n in (np.array([0.3, 0.8, -0.52]), np.array([1.0, 0.0, 0.0]), np.array([-0.2, -0.3, 0.93])):
        n = n / np.linalg.norm(n)
        got = cubemap.lookup_ref(level, n[None])[0, :3]
        want = brute_force(n, alpha, dirs)
        assert np.allclose(got, want, rtol=0.01), (m, n, got, want)
        assert np.allclose(cubemap.lookup_ref(level, n[None])[0, 3], 1.0, rtol=1e-5)  # mean distance of 1s


def test_albedo_is_one_minus_masking_loss():
    """E of a mirror-like GGX surface (F = 1) at normal incidence: 1 at α → 0, below 1 at α = 1, and equal to
    the brute-force ∫ D G /(4 n·v) dl by uniform sampling."""
    n = np.array([[0.0, 0.0, 1.0]])
    v = np.array([[0.6, 0.0, 0.8]])
    one = lambda c: np.ones(np.shape(c) + (3,))  # noqa: E731
    assert ggx.albedo(n, v, 1e-4, one)[0, 0] == pytest.approx(1.0, abs=1e-3)
    for alpha in (0.3, 1.0):
        e = ggx.albedo(n, v, alpha, one, samples=4096)[0, 0]
        l = uniform_sphere(1 << 21, seed=1)
        nl = l[:, 2]
        h = l + v[0]
        h /= np.linalg.norm(h, axis=-1, keepdims=True)
        g = ggx.smith_g1(0.8, alpha) * ggx.smith_g1(np.maximum(nl, 1e-9), alpha)
        f = np.where(nl > 0, ggx.ndf(h[:, 2], alpha) * g / (4 * 0.8), 0.0)
        want = 4 * np.pi * np.mean(f)
        assert e == pytest.approx(want, rel=0.01)
        assert e < 1.0
