"""ObjectRays.per_pixel, shading.composite and outcomes.majority against slow, obvious references written here
(NaN-filled (H, W, S, ...) arrays reduced by numpy, a per-pixel loop), bit for bit: same dtype, shape, NaNs and
float bits, on random hits (whole, partial and empty pixels), NaN rays, signed zeros, infinities and values
spread over many decades, so that a different order of the additions changes the last bits."""

import warnings

import numpy as np
import pytest

from study.measure import outcomes
from study.optics import shading

SHAPES = [(), (1,), (3,), (4,), (2, 3)]


def same_bits(got: np.ndarray, want: np.ndarray) -> None:
    assert got.dtype == want.dtype and got.shape == want.shape, (got.dtype, got.shape, want.dtype, want.shape)
    u = {4: np.uint32, 8: np.uint64}[want.dtype.itemsize]
    bad = got.view(u) != want.view(u)
    assert not bad.any(), f"{bad.sum()} of {bad.size} differ, first at {np.argwhere(bad)[0]}"


def hits(rng, H, W, S, kind):
    """(H, W, S) sub-pixel hits: 'random' (every pixel a mix), or a 'disc' with an outline of partial pixels."""
    if kind == "random":
        return rng.random((H, W, S)) < rng.uniform(0.2, 0.9)
    y, x = np.mgrid[0:H, 0:W]
    jitter, r = rng.random((H, W, S)), 0.35 * min(H, W)
    return (x[..., None] + jitter - W / 2) ** 2 + (y[..., None] + jitter - H / 2) ** 2 < r**2


def ray_values(rng, M, tail, dtype=float):
    """(M, *tail) values over 12 decades of both signs, with ±0, ±inf, NaN entries and whole NaN rays."""
    shape = (M,) + tail
    v = rng.random(shape) * 10.0 ** rng.integers(-6, 7, shape) * rng.choice([-1.0, 1.0], shape)
    r = rng.random((M,) + tail)
    v[r < 0.15] = 0.0
    v[(r >= 0.15) & (r < 0.3)] = -0.0
    v[(r >= 0.3) & (r < 0.4)] = np.nan
    v[(r >= 0.4) & (r < 0.41)] = np.inf
    v[(r >= 0.41) & (r < 0.42)] = -np.inf
    v[rng.random(M) < 0.05] = np.nan
    return v.astype(dtype)


def reference_per_pixel(hit, values, fill, reduce):
    """The NaN-filled (H, W, S, ...) rays, np.nanmean / np.nanmax over the sub-pixel axis; one ray per pixel
    (S = 1) is its value."""
    H, W, S = hit.shape
    full = np.full((H, W, S) + values.shape[1:], np.nan)
    full[hit] = values
    if S == 1:
        red = full[:, :, 0]
    else:
        with np.errstate(invalid="ignore"), warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            red = np.nanmean(full, axis=2) if reduce == "mean" else np.nanmax(full, axis=2)
    return np.where(np.isnan(red), fill, red)


@pytest.mark.parametrize("S", [1, 2, 4, 9, 16, 25])
@pytest.mark.parametrize("tail", SHAPES)
@pytest.mark.parametrize("reduce", ["mean", "max"])
def test_per_pixel_is_the_nan_reduction_of_the_filled_rays_bit_for_bit(S, tail, reduce):
    rng = np.random.default_rng([S, len(tail), sum(tail), reduce == "max"])
    for kind, (H, W), dtype, fill in [
        ("random", (13, 11), float, np.nan),
        ("disc", (40, 33), float, 0.0),
        ("disc", (24, 31), np.float32, -1.0),
        ("random", (1, 7), np.float32, np.nan),
    ]:
        hit = hits(rng, H, W, S, kind)
        M = int(hit.sum())
        values = ray_values(rng, M, tail, dtype)
        rays = shading.ObjectRays(hit, *(np.zeros((M, 3)),) * 4)
        same_bits(
            rays.per_pixel(values, fill=fill, reduce=reduce), reference_per_pixel(hit, values, fill, reduce)
        )


@pytest.mark.parametrize("S", [1, 4, 9])
def test_per_pixel_without_hits_and_with_every_ray_hitting(S):
    rng = np.random.default_rng(S)
    for hit in (np.zeros((5, 6, S), bool), np.ones((5, 6, S), bool)):
        M = int(hit.sum())
        values = ray_values(rng, M, (3,))
        rays = shading.ObjectRays(hit, *(np.zeros((M, 3)),) * 4)
        for fill in (np.nan, 0.0):
            same_bits(rays.per_pixel(values, fill=fill), reference_per_pixel(hit, values, fill, "mean"))


def test_per_pixel_of_a_pixel_of_negative_zeros_is_positive_zero_as_numpys_sum_gives():
    """numpy reduces onto 0.0: S rays of -0.0 sum to +0.0 (the sign bit is compared); one ray per pixel keeps it."""
    for S, tail in [(4, ()), (4, (3,)), (9, ()), (9, (4,))]:
        hit = np.ones((2, 2, S), bool)
        got = shading.ObjectRays(hit, *(np.zeros((4 * S, 3)),) * 4).per_pixel(np.full((4 * S,) + tail, -0.0))
        assert not np.signbit(got).any()
    got = shading.ObjectRays(np.ones((2, 2, 1), bool), *(np.zeros((4, 3)),) * 4).per_pixel(np.full(4, -0.0))
    assert np.signbit(got).all()


def dielectric_rays(rng, hit):
    """ObjectRays with two secondary rays per camera ray (the reflected one, and the transmitted one for some)."""
    M = int(hit.sum())
    keep = np.flatnonzero(rng.random(M) < 0.7)
    src = np.concatenate([np.arange(M), keep])
    w = rng.random(len(src))
    K = len(src)
    return shading.ObjectRays(
        hit, *(np.zeros((K, 3)),) * 4, src=src, weight=np.repeat(w[:, None], 3, axis=1)
    ), K


@pytest.mark.parametrize("S", [1, 4, 9])
def test_per_pixel_of_dielectric_secondary_rays(S):
    """With ``src`` the secondary rays are first merged per camera ray (ObjectRays.per_camera_ray), then reduced."""
    rng = np.random.default_rng(10 + S)
    hit = hits(rng, 20, 17, S, "random")
    rays, K = dielectric_rays(rng, hit)
    for tail in [(), (3,)]:
        values = ray_values(rng, K, tail)
        values[np.isinf(values)] = 1.0  # per_camera_ray weights them: inf × 0 would be a NaN of its own
        per_ray = rays.per_camera_ray(values)
        for reduce in ("mean", "max"):
            same_bits(
                rays.per_pixel(values, reduce=reduce), reference_per_pixel(hit, per_ray, np.nan, reduce)
            )


def reference_composite(hit, reflected, background):
    """The (H, W, S, 3) sub-pixel image (the background where a ray misses) averaged by np.mean, as float32."""
    H, W, S = hit.shape
    sub = np.empty((H, W, S, 3), background.dtype)
    sub[...] = background[:, :, None, :]
    sub[hit] = reflected
    return np.mean(sub, axis=2).astype(np.float32)


@pytest.mark.parametrize("S", [1, 4, 9, 16])
@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_composite_is_the_mean_of_the_sub_pixel_image_bit_for_bit(S, dtype):
    rng = np.random.default_rng([S, np.dtype(dtype).itemsize])
    for kind, (H, W) in [("disc", (70, 90)), ("random", (9, 8)), ("random", (1, 3))]:
        hit = hits(rng, H, W, S, kind)
        M = int(hit.sum())
        background = ray_values(rng, H * W, (3,), dtype).reshape(H, W, 3)
        background[np.isnan(background)] = 0.5
        reflected = ray_values(rng, M, (3,))
        reflected[np.isnan(reflected)] = -0.0
        rays = shading.ObjectRays(hit, *(np.zeros((M, 3)),) * 4)
        same_bits(
            shading.composite(rays, reflected, background), reference_composite(hit, reflected, background)
        )
        # the background alone: the mean of S equal values is not always the value
        none = np.zeros_like(hit)
        empty = shading.ObjectRays(none, *(np.zeros((0, 3)),) * 4)
        same_bits(
            shading.composite(empty, np.zeros((0, 3)), background),
            reference_composite(none, np.zeros((0, 3)), background),
        )


def test_composite_of_dielectric_rays_sums_each_camera_rays_secondary_rays():
    rng = np.random.default_rng(3)
    hit = hits(rng, 16, 12, 4, "random")
    rays, K = dielectric_rays(rng, hit)
    reflected = rng.random((K, 3))
    background = rng.random((16, 12, 3)).astype(np.float32)
    total = rays.per_camera_ray(reflected, total=True)
    same_bits(shading.composite(rays, reflected, background), reference_composite(hit, total, background))


def test_majority_is_the_per_pixel_most_frequent_class_of_nan_to_num():
    """A loop over pixels: the class with the largest np.nan_to_num'd fraction, ties to the higher code, NaN where
    none is > 0; fractions with NaN, ties, ±inf, ±max and negatives."""
    rng = np.random.default_rng(4)
    big = np.finfo(float).max
    f = rng.choice([0.0, -0.0, 0.25, 0.5, 1.0, np.nan, np.inf, -np.inf, big, -big, -0.5], (23, 17, 4))
    f[:3] = rng.integers(0, 3, (3, 17, 4)) / 2  # many ties
    f[3:5] = np.nan
    want = np.empty(f.shape[:2])
    for i in range(f.shape[0]):
        for j in range(f.shape[1]):
            v = np.nan_to_num(f[i, j])
            top = v.max()
            want[i, j] = max(c for c in range(4) if v[c] == top) if top > 0 else np.nan
    same_bits(outcomes.majority(f), want)
    with np.errstate(over="ignore"):  # ±max → ±inf in float32: nan_to_num'd back to ±max, the same classes
        same_bits(outcomes.majority(f.astype(np.float32)), want)


def test_per_pixel_and_composite_refuse_a_value_count_other_than_the_hits():
    hit = np.zeros((3, 4, 4), bool)
    hit[1, 1, :3] = hit[2, 0, 1] = True  # 4 hit rays
    rays = shading.ObjectRays(hit, *(np.zeros((4, 3)),) * 4)
    for M in (3, 5):
        with pytest.raises(ValueError):
            rays.per_pixel(np.ones(M))
        with pytest.raises(ValueError):
            shading.composite(rays, np.ones((M, 3)), np.zeros((3, 4, 3), np.float32))
