"""An O(pixels) spatial variance (issue 52.2, prototype, not used by the pipeline) beside the FFT one of
study.stats.spatial: coverage on the calibration's rows and time per sample, side by side in one run.

The lag-window sum Σ_h w(h)·C(h) (C(h) = Σᵢ eᵢ·eᵢ₊ₕ) needs no FFT when the window is separable and piecewise
linear: the squared sums of a by × bx block over every placement that overlaps the region add up to
Σ_h C(h)·(by − |hy|)₊(bx − |hx|)₊ (each pixel pair at lag h shares that many placements), a summed-area table
(two cumulative sums) away; the flat-top trapezoid (1 out to m, 0 at 2m) is 2·T(2m) − T(m) per axis, T(b) the
triangle (b − |h|)₊ / b, so one window is four block passes (:func:`window_sum`; equal to the FFT's weighted lag sums,
tests/stats/test_block_variance.py). The window's flat reach per axis is where the correlogram along that axis, read
at log-spaced lags from shifted products (:data:`LAGS`), falls below spatial.WINDOW_LEVEL; everything else (degrees
of freedom, skewness, the ends of a mean of values ≥ 0) is study.stats.spatial's. Cumulative sums and shifted
products are what Dr.Jit runs on the device; an FFT it does not.

    PYTHONPATH=. .venv/bin/python scripts/block_variance.py [--replicates 400] [--rows RMSE "ray fraction"]
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from study.stats import spatial  # noqa: E402
from study.stats.region import MIN_WINDOW  # noqa: E402

#: The lags (pixels) at which the correlogram along each axis is read.
LAGS = (1, 2, 3, 4, 6, 8, 11, 16, 23, 32, 45, 64, 90, 128, 180, 256, 360, 512)


def block_squares(fields: np.ndarray, by: int, bx: int) -> np.ndarray:
    """(k,) Σ over every placement of a by × bx block that overlaps the (h, w) box of (Σ of ``fields`` (k, h, w)
    over the block)²: Σ_h C(h)·(by − |hy|)₊(bx − |hx|)₊."""
    k, h, w = fields.shape
    c = np.zeros((k, h + 2 * by + 1, w + 2 * bx + 1))
    c[:, by + 1 : by + 1 + h, bx + 1 : bx + 1 + w] = fields
    c = c.cumsum(axis=1).cumsum(axis=2)
    s = c[:, by:, bx:] - c[:, :-by, bx:] - c[:, by:, :-bx] + c[:, :-by, :-bx]
    return (s * s).sum(axis=(1, 2))


def window_sum(fields: np.ndarray, my: int, mx: int) -> np.ndarray:
    """(k,) Σ_h w(h)·C(h) of ``fields`` (k, h, w), w the separable flat-top window: per axis 1 out to m pixels,
    linearly to 0 at 2m (module docstring)."""
    out = np.zeros(len(fields))
    for cy, by in ((2.0, 2 * my), (-1.0, my)):
        for cx, bx in ((2.0, 2 * mx), (-1.0, mx)):
            out += cy * cx * block_squares(fields, by, bx) / (by * bx)
    return out


#: The directions (dy, dx) the correlogram is read along: the axes and the diagonals (a streak at 45° reaches far
#: along a diagonal only; the separable window then reaches as far along both axes).
DIRECTIONS = ((1, 0), (0, 1), (1, 1), (1, -1))


def _shifted(a: np.ndarray, dy: int, dx: int) -> tuple[np.ndarray, np.ndarray]:
    """The overlapping parts of ``a`` (…, h, w) and of ``a`` shifted by (dy, dx): element i of the first and of
    the second are the pixels p and p + (dy, dx)."""
    h, w = a.shape[-2:]
    ys, yt = (slice(0, h - dy), slice(dy, h)) if dy >= 0 else (slice(-dy, h), slice(0, h + dy))
    xs, xt = (slice(0, w - dx), slice(dx, w)) if dx >= 0 else (slice(-dx, w), slice(0, w + dx))
    return a[..., ys, xs], a[..., yt, xt]


def axis_reach(resid: np.ndarray, m: np.ndarray, limit: float) -> tuple[np.ndarray, np.ndarray]:
    """((k, 2) flat reach along rows and columns, (k,) correlation length): per sample and direction of
    :data:`DIRECTIONS`, where its correlogram (Σ eᵢ·eᵢ₊h over the pairs at h, over the lag-0 mean) first falls
    below spatial.WINDOW_LEVEL (interpolated between the steps of :data:`LAGS`); each axis reaches as far as the
    farthest direction's steps along it (at least MIN_WINDOW, at most ``limit``); the correlation length is the
    mean over the two axes of where theirs falls below 1/e."""
    k = len(resid)
    c0 = (resid * resid).sum(axis=(1, 2)) / m.sum()
    reach, length = np.full((k, 2), MIN_WINDOW), np.zeros((k, 2))
    for dy, dx in DIRECTIONS:
        prev, prev_d = np.ones(k), 0
        flat, e_len = np.zeros(k, bool), np.zeros(k, bool)
        at, e_at = np.full(k, float(limit)), np.zeros(k)
        for d in (lag for lag in LAGS if lag < min(m.shape) and lag <= 2 * limit):
            ma, mb = _shifted(m, dy * d, dx * d)
            ra, rb = _shifted(resid, dy * d, dx * d)
            pairs = float((ma & mb).sum())
            s = (ra * rb).sum(axis=(1, 2))
            with np.errstate(invalid="ignore", divide="ignore"):
                rho = s / pairs / c0 if pairs > 0 else np.full(k, math.nan)
            for level, done, out in ((spatial.WINDOW_LEVEL, flat, at), (math.exp(-1), e_len, e_at)):
                cross = ~done & ~(rho >= level)
                frac = np.clip(
                    np.where(prev > rho, (prev - level) / np.where(prev > rho, prev - rho, 1.0), 0.0), 0, 1
                )
                out[:] = np.where(cross, prev_d + frac * (d - prev_d), out)
                done |= cross
            prev, prev_d = rho, d
        e_at[~e_len] = prev_d
        for ax, step in ((0, dy), (1, dx)):
            if step:
                reach[:, ax] = np.maximum(reach[:, ax], at)
        if dy * dx == 0:
            length[:, 0 if dy else 1] = e_at
    return np.clip(reach, MIN_WINDOW, max(MIN_WINDOW, limit)), np.maximum(0.5, length.mean(axis=1))


def block_spread(sub: np.ndarray, reg, skews: bool = False) -> tuple[np.ndarray, ...]:
    """study.stats.spatial.spread's results with the window's sum from block sums (:func:`window_sum`) and its
    reach per axis (:func:`axis_reach`): O(pixels) per sample."""
    k = len(sub)
    m, d, total, n = reg.m, reg.d, reg.total, reg.n
    r = sub.sum(axis=(1, 2)) / total
    resid = np.where(m, sub - r[:, None, None] * d, 0.0)
    c0 = (resid * resid).sum(axis=(1, 2))
    reach, lengths = axis_reach(resid, m, reg.limit)
    lengths = np.minimum(lengths, reg.length_limit)
    var, dof, skew, teff = np.empty(k), np.empty(k), np.zeros(k), np.zeros(k)
    mask = m[None].astype(float)
    for i in range(k):
        my, mx = (max(1, math.ceil(v)) for v in reach[i])
        share = float(window_sum(mask, my, mx)[0]) / (n * n)
        gauss = max(1.0, 1.0 / share - 1.0)
        dof[i] = max(min(gauss, spatial.MIN_DOF), gauss * spatial.kurtosis_factor(resid[i], m, share * n))
        if skews:
            skew[i] = spatial.mean_skewness(resid[i], m, share * n, gauss)
        teff[i] = spatial.contributing_tiles(sub[i], m, share * n)
        v = float(window_sum(resid[i : i + 1], my, mx)[0]) / max(spatial.MIN_KEPT, 1.0 - share)
        var[i] = max(v, float(c0[i])) / (total * total)
    return r, var, lengths, dof, skew, teff


def _coverage(rows, replicates: int) -> list[tuple[str, float, float]]:
    from study.stats import calibration

    out = []
    for name in calibration.ROWS:
        draw, truth, _, banded = calibration.ROWS[name]
        if not banded or not any(p in name for p in rows):
            continue
        (now,) = calibration.coverage(name, replicates, before=0)
        out.append((name, now.coverage, now.width_ratio))
    return out


def _diagonal(replicates: int, seed: int = 0) -> tuple[float, float]:
    """(coverage, width / ideal) of the RMSE interval on the streak design turned by 45° (not a calibration row:
    study.stats.fields.streaks lies along an axis): the error 0.5 + a unit-variance field filtered by a Gaussian of
    σ 0.8 × 12 px along a diagonal (either), over the calibration's 40 px disc; truth √1.25."""
    from study import stats
    from study.stats import fields

    n = fields.SIZE
    yy, xx = (np.where(v > n // 2, v - n, v) for v in np.mgrid[:n, :n])
    kernels = []
    for sign in (1, -1):
        u, v = (xx + sign * yy) / math.sqrt(2), (xx - sign * yy) / math.sqrt(2)
        k = np.exp(-(u**2 / (2 * 12.0**2) + v**2 / (2 * 0.8**2)))
        kernels.append(np.fft.rfft2(k / math.sqrt(float((k**2).sum()))))
    mask, truth = fields.disc(), math.sqrt(1.25)
    rng = np.random.default_rng([seed, 99])
    hits, widths, est = 0, [], []
    for _ in range(replicates):
        err = 0.5 + np.fft.irfft2(np.fft.rfft2(rng.normal(size=(n, n))) * kernels[rng.integers(2)], s=(n, n))
        (lo, hi), _ = stats.rmse_interval(err[mask] ** 2, mask)
        hits += lo <= truth <= hi
        widths.append(hi - lo)
        est.append(math.sqrt(float(np.mean(err[mask] ** 2))))
    return hits / replicates, float(np.mean(widths)) / (2 * 1.96 * float(np.std(est)))


def _per_sample_ms(n: int = 1024, k: int = 12) -> tuple[float, float]:
    """ms per sample of the FFT spread and the block one on the bench's 1024² disc (a fifth of the frame wide)."""
    from scipy import ndimage

    from study.stats import region

    yy, xx = np.mgrid[:n, :n]
    mask = (yy - 0.48 * n) ** 2 + (xx - 0.55 * n) ** 2 < (0.1 * n) ** 2
    xs = ndimage.gaussian_filter(np.random.default_rng(0).normal(size=(k, n, n)), (0, 3, 3))[:, mask] ** 2
    reg = region.region(mask)
    sub = np.zeros((k, reg.m.size))
    sub[:, reg.flat] = xs
    sub = sub.reshape(k, *reg.m.shape)
    times = []
    for fn in (spatial.spread, block_spread):
        fn(sub[:1], reg, True)
        t = time.perf_counter()
        fn(sub, reg, True)
        times.append((time.perf_counter() - t) / k * 1e3)
    return times[0], times[1]


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--replicates", type=int, default=400)
    ap.add_argument("--rows", nargs="+", default=["RMSE", "pixel", "split", "ray"])
    a = ap.parse_args(argv)
    fft = _coverage(a.rows, a.replicates) + [("RMSE, streaks turned by 45° (not a calibration row)",
                                              *_diagonal(a.replicates))]  # fmt: skip
    spread = spatial.spread
    spatial.spread = block_spread  # the same intervals with the block window
    spatial._MEASURED.clear()  # samples kept by their digest were measured with the FFT window
    try:
        blocks = _coverage(a.rows, a.replicates) + [("", *_diagonal(a.replicates))]
    finally:
        spatial.spread = spread
        spatial._MEASURED.clear()
    print(f"{a.replicates} replicates per row, seed 0: coverage (width / ideal)\n")
    print("| row | FFT window | block sums |\n|---|---|---|")
    for (name, c1, w1), (_, c2, w2) in zip(fft, blocks):
        print(f"| {name} | {c1:.1%} ({w1:.2f}) | {c2:.1%} ({w2:.2f}) |")
    f, b = _per_sample_ms()
    print(f"\nms per sample on a 1024² frame's disc (205² box), numpy: FFT {f:.1f}, block sums {b:.1f}")


if __name__ == "__main__":
    main()
