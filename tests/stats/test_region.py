"""The spatial intervals' shared work (study.stats.region): a region's lag sums against a brute-force sum over pixel
pairs, a kept region against a fresh one, and many samples in one call against one call each (bit for bit)."""

import numpy as np
import pytest
from scipy import ndimage

from study.stats import region, spatial


def _mask(rng, shape):
    return ndimage.gaussian_filter(rng.normal(size=shape), 2) > rng.normal(0, 0.1)


def _brute(f: np.ndarray, reach: int) -> np.ndarray:
    """Σᵢ fᵢ·fᵢ₊ₕ over every pixel pair, lag h = (dy, dx) at [reach + dy, reach + dx]."""
    h, w = f.shape
    out = np.zeros((2 * reach + 1, 2 * reach + 1))
    for dy in range(-reach, reach + 1):
        for dx in range(-reach, reach + 1):
            if abs(dy) >= h or abs(dx) >= w:
                continue  # no pixel pair that far apart
            a = f[max(0, -dy) : h - max(0, dy), max(0, -dx) : w - max(0, dx)]
            b = f[max(0, dy) : h + min(0, dy), max(0, dx) : w + min(0, dx)]
            out[reach + dy, reach + dx] = float(np.sum(a * b))
    return out


@pytest.mark.parametrize("shape", [(9, 14), (4, 7), (30, 5), (17, 17), (3, 2), (1, 6)])
def test_the_centred_lag_sums_are_the_sums_over_pixel_pairs(shape):
    rng = np.random.default_rng(1)
    mask = np.ones(shape, bool)
    reg = region.region(mask)
    f = rng.normal(size=(3, *shape))
    got = reg.centred_sums(f)
    for i in range(3):
        np.testing.assert_allclose(got[i], _brute(f[i], reg.reach), atol=1e-9)
    np.testing.assert_allclose(reg.pairs, _brute(np.ones(shape), reg.reach), atol=1e-9)


def test_a_kept_region_is_the_fresh_one_and_not_the_callers_array():
    rng = np.random.default_rng(2)
    mask = _mask(rng, (40, 50))
    den = rng.integers(1, 5, mask.shape).astype(float)
    fresh = region._build(mask, den)
    kept = region.region(mask, den)
    assert region.region(mask.copy(), den.copy()) is kept  # the same bytes: the same region
    for name in ("m", "d", "flat", "pairs", "per_pair", "radii", "bins"):
        np.testing.assert_array_equal(getattr(kept, name), getattr(fresh, name))
    mask[:] = False  # the caller reuses its array: the kept region stays
    assert kept.m.any() and region.region(mask) is None


@pytest.mark.parametrize("seed", range(6))
def test_many_samples_in_one_call_are_each_sample_alone(seed):
    rng = np.random.default_rng(seed)
    mask = _mask(rng, tuple(rng.integers(6, 70, 2)))
    p = int(mask.sum())
    xs = ndimage.gaussian_filter(rng.normal(size=(7, *mask.shape)), (0, 2, 2))[:, mask] ** 2
    xs[3] = xs[1]  # a repeated sample (a term no method changes) is measured once, with the same values
    xs[5] = 0.0  # a constant one
    spatial._MEASURED.clear()
    together, lengths = spatial.mean_intervals_each(xs, mask, 0.95)
    alone = []
    for x in xs:
        spatial._MEASURED.clear()
        ci, length = spatial.mean_intervals([x], mask, 0.95)
        alone.append((ci[0], length))
    assert together == [a for a, _ in alone] and p > 1
    np.testing.assert_array_equal(lengths, [b for _, b in alone])
    # a NaN pixel of one group leaves the mask of that group only
    groups = [xs[:2].copy(), xs[2:4], xs[4:]]
    groups[0][1, 0] = np.nan
    got = spatial.grouped_intervals(groups, mask, 0.95)
    for g, (ci, ln) in zip(groups, got):
        want, wl = spatial.mean_intervals_each(g, mask, 0.95)
        assert ci == want and np.array_equal(ln, wl)
    assert got[1][0] == together[2:4]


def test_the_ray_intervals_count_over_the_rays_box_as_over_the_frame():
    rng = np.random.default_rng(4)
    mask = _mask(rng, (50, 60))
    pix = np.repeat(np.flatnonzero(mask), rng.integers(1, 5, int(mask.sum())))
    flags = rng.random((3, pix.size)) < 0.3
    rays = np.bincount(pix, minlength=mask.size).reshape(mask.shape).astype(float)
    counts = np.stack([np.bincount(pix, weights=f, minlength=mask.size) for f in flags]).reshape(
        -1, *mask.shape
    )
    want = spatial.ratio_variance(counts, rays, rays > 0)
    got = spatial._ray_ratios(flags, pix, mask.shape)
    for a, b in zip(want, got):
        np.testing.assert_array_equal(a, b)


def test_a_sample_kept_over_one_region_is_measured_anew_over_another():
    rng = np.random.default_rng(6)
    wide, tall = np.ones((6, 40), bool), np.ones((40, 6), bool)  # as many pixels, another geometry
    x = ndimage.gaussian_filter(rng.normal(size=(6, 40)), (0, 4)).ravel() ** 2
    spatial._MEASURED.clear()
    over_tall = spatial.mean_intervals([x], tall, 0.95)
    spatial._MEASURED.clear()
    spatial.mean_intervals([x], wide, 0.95)
    assert spatial.mean_intervals([x], tall, 0.95) == over_tall != spatial.mean_intervals([x], wide, 0.95)
