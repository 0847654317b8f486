"""The uncertainty of a mean over an image's pixels whose values are spatially correlated: the variance of a ratio
Σ num / Σ den over the masked pixels, from the image's own autocovariance, summed over a lag window sized by its
measured correlation length.

A mean over pixels is a ratio estimator r = Σᵢ numᵢ / Σᵢ denᵢ (image errors: num = the pixel's value, den = 1; ray
fractions: num = the pixel's wrong rays, den = its rays). Linearised, its variance is Var(Σᵢ eᵢ) / (Σ den)² with the
residuals eᵢ = numᵢ − r·denᵢ, and Var(Σ eᵢ) = Σ over lags h of the summed products eᵢ·eᵢ₊ₕ (:func:`lag_sums`, one
FFT): independent pixels keep only h = 0; correlated ones (a wrong reflection is a blob of pixels, neighbouring
rays share a texel) add their neighbours' covariance. The sum runs over a flat-top lag window (Politis & Romano
1995): weight 1 up to :data:`WINDOW_LENGTHS` correlation lengths, falling linearly to 0 at twice that. It is the
block bootstrap's variance with blocks a few correlation lengths wide, moved pixel by pixel instead of cut from a
fixed grid, without the Bartlett taper that makes non-overlapping blocks miss the covariance across their edges
(with blocks three correlation lengths wide that bias alone halves the variance).

The window's flat part follows the 2-D correlogram, not its radial average: per direction (:data:`ANGLES` bins
over a half-turn) it reaches the farthest lag of the region around lag 0 where the correlogram (smoothed over 3 × 3
lags) stays at or above :data:`WINDOW_LEVEL`, so a streak (a reflected edge) is summed along its length; it is capped
only at :data:`MAX_REACH_SHARE` of the region's smaller extent (lags beyond have few pixel pairs), the few windows a
long correlation leaves lowering the degrees of freedom instead. The reported correlation length (``corr_px``) is
where the radially averaged correlogram first falls below 1/e (interpolated between rings, at most
:data:`MAX_LENGTH_SHARE` of the extent). A window that sums to less than the independent pixels' variance is raised
to it: correlation is never credited with narrowing an interval.

A mean of values ≥ 0 (squared errors, relMSE, FLIP) has a variance that grows with it: in the calibration's designs
(:mod:`study.stats.calibration`) the estimated standard deviation follows the estimate (correlation 0.63–0.92 over
replicates), so a low estimate comes with a narrow interval and the misses fell above it (sparse blobs 87 %, a
200-pixel object 90 %). Its ends are therefore also taken on the log scale, r·exp(±t·s/r) (the upper one stretched at
most to :data:`STRETCH` × the linear reach), and its degrees of freedom are at most the windows that carry its sum
(:func:`contributing_tiles`: one blob, one window), at least :data:`FEW_DOF`.
"""

from __future__ import annotations

import math
from collections import OrderedDict

import numpy as np

from study.stats.region import (  # noqa: F401 (the window's limits, named in this module's docstring)
    ANGLES,
    MAX_LENGTH_SHARE,
    MAX_REACH_SHARE,
    MIN_WINDOW,
    Region,
    centre,
    digest,
    kept,
    known,
    lag_sums,
    ray_region,
    region,
)

#: The lag window is flat (weight 1) out to where the correlogram falls below this, tapering to 0 at twice that.
WINDOW_LEVEL = 0.1
#: The centring correction divides by at least this (a window as wide as the region would divide by 0).
MIN_KEPT = 0.25
#: Fewer tiles than this measure no kurtosis (:func:`kurtosis_factor`).
MIN_TILES = 8
#: The skewness shift of a mean's interval is at most this share of its half-width (the estimate stays inside).
MAX_SKEW_SHIFT = 0.5
#: Heavy tails lower the degrees of freedom to no fewer than this (a kurtosis from few tiles is itself noisy).
MIN_DOF = 4.0
#: A mean of values ≥ 0 has no more degrees of freedom than the windows that carry its sum
#: (:func:`contributing_tiles`, ≥ 1 for a sum > 0), and no fewer than this for that reason: the value that
#: calibrates the one-window case, a ≈ 200-pixel object whose error is one sliver of a blob (the calibration's
#: "≈ 200 pixels with blobs" among the draws that show error; its misses are the draws whose error is 1–3 pixels,
#: their upper end ≈ 0.8 of the truth). Coverage of 2000 draws, seeds 0 / 1 / 2: 1.3 → 97.9 / 97.8 / 98.3 %,
#: 1.35 → 95.8 / 95.8 / 95.6 %, 1.4 → 93.7 / 93.3 / 93.6 %, 2 → 92.4 % (seed 0), 1 → 99.7 %.
FEW_DOF = 1.35
#: A mean of values ≥ 0: its log-scale upper end reaches at most this many times the linear interval's upper reach.
STRETCH = 2.0


def correlogram(sums: np.ndarray, pairs: np.ndarray, radii: np.ndarray, top: int) -> np.ndarray:
    """(top + 1,) the radially averaged autocorrelation at integer rings 0 … ``top`` (``sums`` / ``pairs`` per lag,
    over its value at lag 0; NaN where no pixel pair has that lag, or where the field is constant)."""
    ring = np.rint(radii).astype(int)
    sel = (ring <= top) & (pairs > 0.5)
    acf = np.bincount(ring[sel], weights=(sums[sel] / pairs[sel]), minlength=top + 1)
    count = np.bincount(ring[sel], minlength=top + 1)
    with np.errstate(invalid="ignore", divide="ignore"):
        return acf / count / (sums.flat[0] / pairs.flat[0])


def crossing(rho: np.ndarray, level: float) -> float:
    """Where the correlogram ``rho`` first falls below ``level``, interpolated between rings (at least 0.5; its
    last ring if it never does)."""
    for r in range(1, len(rho)):
        if not rho[r] >= level:  # NaN (no pairs at that ring) ends it too
            prev = rho[r - 1]
            frac = (prev - level) / (prev - rho[r]) if np.isfinite(rho[r]) and prev > rho[r] else 0.0
            return float(max(0.5, r - 1 + frac))
    return float(len(rho) - 1)


def window(radii: np.ndarray, reach: float) -> np.ndarray:
    """The flat-top lag weights: 1 out to ``reach`` pixels (at least :data:`MIN_WINDOW`), linearly to 0 at twice
    that (lag 0 always 1)."""
    m = max(MIN_WINDOW, reach)
    return np.clip(2.0 - radii / m, 0.0, 1.0)


def _tile_sums(resid: np.ndarray, mask: np.ndarray, area: float, *more: np.ndarray):
    """The sums of ``resid`` over the square tiles of about ``area`` pixels that hold pixels of ``mask``; with
    ``more`` arrays, a list of the same for ``resid`` and each of them (the tiles made once)."""
    t = max(1, round(math.sqrt(max(area, 1.0))))
    h, w = resid.shape
    hh, ww = -(-h // t) * t, -(-w // t) * t
    k = 2 + len(more)
    sums = np.zeros((k, hh, ww))
    sums[0, :h, :w], sums[-1, :h, :w] = resid, mask
    for j, a in enumerate(more):
        sums[1 + j, :h, :w] = a
    *s, inside = sums.reshape(k, hh // t, t, ww // t, t).sum(axis=(2, 4)).reshape(k, -1)
    s = [x[inside > 0] for x in s]
    return s if more else s[0]


def mean_skewness(
    resid: np.ndarray, mask: np.ndarray, area: float, windows: float, *, tiles: np.ndarray | None = None
) -> float:
    """The skewness of the mean of ``resid`` (residuals about it, over ``mask``): the skewness of its sums over
    tiles of about ``area`` pixels (the window's effective size) over √(tiles); with fewer than
    :data:`MIN_TILES` tiles the pixels' own skewness over √``windows`` (larger than the windows' would be: a sum
    over a window is less skewed than its pixels). A constant residual: 0. ``tiles``: those sums, if made."""
    s = _tile_sums(resid, mask, area) if tiles is None else tiles
    if s.size < MIN_TILES:
        s, scale = resid[mask], math.sqrt(max(windows, 1.0))
    else:
        scale = math.sqrt(s.size)
    sq = s * s
    s2 = float(np.mean(sq))
    return float(np.mean(sq * s)) / s2**1.5 / scale if s2 > 0 else 0.0  # s·s·s: pow(s, 3) is ~20× slower


def contributing_tiles(
    values: np.ndarray, mask: np.ndarray, area: float, *, tiles: np.ndarray | None = None
) -> float:
    """(Σ s)² / Σ s²: how many tiles of about ``area`` pixels carry the sum of ``values`` ≥ 0 over ``mask`` (s:
    its sums over the tiles that hold pixels of ``mask``; as many as tiles for an even field, 1 for one blob);
    0 where the values sum to 0 (``tiles``: s, if made)."""
    s = _tile_sums(values, mask, area) if tiles is None else tiles
    s2 = float(np.sum(s * s))
    return float(np.sum(s)) ** 2 / s2 if s2 > 0 else 0.0


def kurtosis_factor(
    resid: np.ndarray, mask: np.ndarray, area: float, *, tiles: np.ndarray | None = None
) -> float:
    """2 / (2 + κ): the share of the window's degrees of freedom that heavy-tailed residuals keep. The window's
    count of independent windows holds for Gaussian residuals, whose squared window sums vary as 2σ⁴; sums with
    excess kurtosis κ vary as (2 + κ)σ⁴ (Satterthwaite), so the variance is less certain than the count says
    (rare events, e.g. the rays beyond a 95th percentile, are heavy-tailed). κ is measured on the sums of
    ``resid`` over square tiles of about ``area`` pixels (the window's effective size) that hold pixels of
    ``mask``; κ ≤ 0 or fewer than :data:`MIN_TILES` tiles: 1 (``tiles``: those sums, if made)."""
    s = _tile_sums(resid, mask, area) if tiles is None else tiles
    s2 = float(np.sum(s * s))
    if s.size < MIN_TILES or s2 <= 0:
        return 1.0
    kappa = s.size * float(np.sum(s**4)) / (s2 * s2) - 3.0
    return 2.0 / (2.0 + max(0.0, kappa))


def _reach_by_angle(rho: np.ndarray, radii: np.ndarray, bins: np.ndarray, limit: float) -> np.ndarray:
    """(:data:`ANGLES`,) the flat part of the lag window per direction: the farthest lag of each angular bin in
    the region around lag 0 where the correlogram ``rho`` (centred (2R + 1, 2R + 1) lags, smoothed over 3 × 3
    lags against single noisy lags) stays at or above :data:`WINDOW_LEVEL`, widened to its neighbouring bins,
    between :data:`MIN_WINDOW` and ``limit``."""
    from scipy import ndimage

    smooth = ndimage.uniform_filter(np.nan_to_num(rho, nan=0.0), 3, mode="constant")
    above = smooth >= WINDOW_LEVEL
    c = rho.shape[0] // 2
    above[c, c] = True
    labels, _ = ndimage.label(above)
    inside = labels == labels[c, c]
    reach = np.zeros(ANGLES)
    np.maximum.at(reach, bins[inside], radii[inside])
    reach = np.maximum(reach, np.maximum(np.roll(reach, 1), np.roll(reach, -1)))
    return np.clip(reach, MIN_WINDOW, max(MIN_WINDOW, limit))


def ratio_variance(nums, den, mask, skews: bool = False) -> tuple[np.ndarray, ...]:
    """(ratios, variances, correlation lengths, degrees of freedom): per sample of ``nums`` (k, H, W) (or one
    (H, W)), the ratio Σ num / Σ den over ``mask`` (H, W), the variance of that ratio under spatial correlation
    (module docstring), the residuals' correlation length in pixels, and the degrees of freedom of that
    variance: the region's count of windows (1 / share − 1, share = Σ weight·pairs / n²) times
    :func:`kurtosis_factor` (at least min(that count, :data:`MIN_DOF`)). ``den`` (H, W): the weight of each
    pixel (1 for a mean over pixels). Pixels where a sample is NaN count as outside the mask for every sample.
    Fewer than two pixels, or Σ den = 0: NaN variance. ``skews``: a fifth result, the skewness of each ratio
    (:func:`mean_skewness`; 0 where the variance is NaN). The region's own work (:func:`study.stats.region.region`)
    is kept for the next call over the same mask and weights."""
    mask = np.asarray(mask, bool)
    nums = np.asarray(nums, float)
    one = nums.ndim == 2
    nums = nums.reshape(-1, *mask.shape)
    den = np.broadcast_to(np.asarray(den, float), mask.shape)
    mask = mask & ~np.isnan(nums).any(axis=0)
    reg = region(mask, den)
    if reg is None:
        total = float(den[mask].sum()) if mask.any() else 0.0
        out = _degenerate([float(n[mask].sum() / total) if total > 0 else math.nan for n in nums])[
            : 4 + skews
        ]
    else:
        out = spread(np.where(reg.m, nums[(slice(None), *reg.box)], 0.0), reg, skews)[: 4 + skews]
    return tuple(v[0] for v in out) if one else out


def _degenerate(r) -> tuple[np.ndarray, ...]:
    """:func:`ratio_variance`'s results where no variance can be measured: the ratios ``r``, NaN elsewhere."""
    k = len(r)
    nan = np.full(k, math.nan)
    return np.asarray(r, float), nan, nan.copy(), nan.copy(), np.zeros(k), np.zeros(k)


def spread(sub: np.ndarray, reg: Region, skews: bool = False) -> tuple[np.ndarray, ...]:
    """:func:`ratio_variance` of samples ``sub`` (k, h, w) over the region ``reg``'s box (0 off its mask): one
    batched FFT per :attr:`Region.batch` samples, the region's pair counts and lag geometry from ``reg``."""
    k = len(sub)
    m, d, total, n, reach = reg.m, reg.d, reg.total, reg.n, reg.reach
    length_limit, limit, pairs, per_pair, radii, bins = (
        reg.length_limit, reg.limit, reg.pairs, reg.per_pair, reg.radii, reg.bins
    )  # fmt: skip
    r = sub.sum(axis=(1, 2)) / total
    resid = np.where(m, sub - r[:, None, None] * d, 0.0)
    lengths, var, dof, skew, teff = np.empty(k), np.empty(k), np.empty(k), np.zeros(k), np.zeros(k)
    # what every sample shares: the lags the flat part may reach, and the rings of the correlation length (lag 0
    # first) with their pair counts and radii
    fc, rc = centre(math.ceil(limit), reach), centre(int(length_limit) + 2, reach)
    f_per_pair, f_radii, f_bins = per_pair[fc], radii[fc], bins[fc]
    r_pairs, r_radii = np.fft.ifftshift(pairs[rc]), np.fft.ifftshift(radii[rc])
    batch = reg.batch
    for i in range(k):
        if i % batch == 0:  # the next batch's lag sums
            sums = reg.centred_sums(resid[i : i + batch])
        j = i % batch
        with np.errstate(invalid="ignore", divide="ignore"):  # a constant sample: NaN, the smallest window
            rho = sums[j][fc] * f_per_pair / (sums[j, reach, reach] * per_pair[reach, reach])
        ring = correlogram(np.fft.ifftshift(sums[j][rc]), r_pairs, r_radii, int(length_limit) + 1)
        lengths[i] = min(length_limit, crossing(ring, math.exp(-1)))
        flat = _reach_by_angle(rho, f_radii, f_bins, limit)
        c = centre(math.ceil(2 * flat.max()), reach)  # the lags the window reaches
        w = np.clip(2.0 - radii[c] / flat[bins[c]], 0.0, 1.0)
        # the residuals are centred on the estimated ratio, which takes (Σ w·pairs / n²) of the window's sum away
        share = float(np.sum(w * pairs[c])) / (n * n)
        gauss = max(1.0, 1.0 / share - 1.0)
        s_res, s_sub = _tile_sums(resid[i], m, share * n, sub[i])  # the window's tiles, made once
        dof[i] = max(min(gauss, MIN_DOF), gauss * kurtosis_factor(resid[i], m, share * n, tiles=s_res))
        if skews:
            skew[i] = mean_skewness(resid[i], m, share * n, gauss, tiles=s_res)
        teff[i] = contributing_tiles(sub[i], m, share * n, tiles=s_sub)
        keep = max(MIN_KEPT, 1.0 - share)
        v = float(np.sum(w * sums[j][c])) / keep
        var[i] = max(v, float(sums[j, reach, reach])) / (total * total)  # never below independent pixels
    return r, var, lengths, dof, skew, teff


def _quantile(level: float, dof) -> np.ndarray:
    from scipy import stats as sps

    return sps.t.ppf(0.5 + level / 2, np.maximum(1.0, np.nan_to_num(np.asarray(dof, float), nan=1.0)))


def mean_intervals(samples, mask, level: float) -> tuple[list[tuple[float, float]], float]:
    """([(lo, hi), …], correlation length): the ``level`` intervals of the means of several per-pixel samples
    (each (P,), the values of ``mask``'s P True pixels in ``img[mask]`` order), each its mean ± t·√variance
    (:func:`ratio_variance`, Student's t with its degrees of freedom: the region holds about 1/share windows,
    share = Σ weight·pairs / n², fewer for heavy-tailed residuals), both ends moved towards the long tail by the
    skewness (Hall 1992); a sample of values ≥ 0 has its lower end at 0 or above, its ends also on the log scale
    and no more degrees of freedom than the windows that carry its sum (module docstring); the correlation length
    is the first sample's, in pixels. Fewer than two pixels: (mean, mean).
    Many samples over one mask (a case's methods) are best given in one call: one batched FFT, the mask's own
    work once (:func:`mean_intervals_each` gives every sample's correlation length)."""
    out, lengths = mean_intervals_each(samples, mask, level)
    return out, float(lengths[0])


#: Samples measured over a region, by the digest of their values (equal samples of a case, e.g. a term that no
#: method changes, or the same squared errors in two column groups, are measured once).
_MEASURED: OrderedDict = OrderedDict()
#: How many of them are kept.
SAMPLES_KEPT = 4096


def _spread_kept(xs: np.ndarray, reg: Region) -> tuple[np.ndarray, ...]:
    """:func:`spread` (with skewness) of samples ``xs`` (k, P) of ``reg``'s P pixels (in ``reg.flat`` order), each
    distinct sample measured once and kept (by its digest, :data:`SAMPLES_KEPT` of them): a sample's results depend on
    its own values and the region alone."""
    keys = [digest(reg.key, x) for x in xs]
    found = known(keys, _MEASURED)
    todo = {key: i for i, key in enumerate(keys) if key not in found}
    if todo:
        sub = np.zeros((len(todo), reg.m.size))
        sub[:, reg.flat] = xs[list(todo.values())]
        res = np.stack(spread(sub.reshape(len(todo), *reg.m.shape), reg, skews=True), axis=1)
        for key, row in zip(todo, res):
            found[key] = kept(key, lambda row=row: row, _MEASURED, SAMPLES_KEPT)
    return tuple(np.array([found[key] for key in keys]).T)


def mean_intervals_each(samples, mask, level: float) -> tuple[list[tuple[float, float]], np.ndarray]:
    """([(lo, hi), …], (k,) correlation lengths): :func:`mean_intervals` of ``samples`` (k, P), each sample's
    correlation length."""
    mask = np.asarray(mask, bool)
    xs = np.asarray(samples, float).reshape(len(samples), -1)
    keep = ~np.isnan(xs).any(axis=0)  # a pixel NaN in some sample is outside the mask for every sample
    inside = mask
    if not keep.all():
        inside = mask.copy()
        inside[mask] = keep
    reg = region(inside)
    if reg is None:
        r, var, lengths, dof, skew, teff = _degenerate([float(x[keep].sum() / keep.sum()) for x in xs])
    else:
        r, var, lengths, dof, skew, teff = _spread_kept(xs[:, keep], reg)
    nonneg = (xs >= 0).all(axis=1)
    floor = np.where(nonneg, 0.0, -np.inf)  # a mean of values ≥ 0 is ≥ 0
    # values ≥ 0 carried by a few windows (sparse blobs): no more degrees of freedom than windows that carry them
    dof = np.where(nonneg, np.minimum(dof, np.maximum(FEW_DOF, teff)), dof)
    t = _quantile(level, dof)
    # skewed samples (squared errors, sparse blobs): both ends move by c·√var towards the long tail (Hall 1992)
    c = np.clip(skew * (2 * t * t + 1) / 6, -MAX_SKEW_SHIFT * t, MAX_SKEW_SHIFT * t)
    s = np.sqrt(var)
    half = t * s
    r_lo, r_hi = r - (t - c) * s, r + (t + c) * s
    # values ≥ 0: their variance grows with their mean (a low estimate comes with a low variance), so the ends
    # are also taken on the log scale, r·exp(±t·s/r), the upper one stretched at most to r + STRETCH·(t + c)·s
    on = nonneg & (r > 0) & (var > 0)
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        cv = np.where(on, s / np.where(on, r, 1.0), 0.0)
        up = np.minimum(r * np.exp(t * cv), r + STRETCH * (t + c) * s)
        r_lo = np.where(on, np.maximum(r_lo, r * np.exp(-t * cv)), r_lo)
        r_hi = np.where(on, np.maximum(r_hi, up), r_hi)
    out = [
        (float(m), float(m)) if not h == h else (float(max(f, a)), float(b))
        for m, h, f, a, b in zip(r, half, floor, r_lo, r_hi)
    ]
    return out, lengths


def grouped_intervals(groups, mask, level: float) -> list[tuple[list[tuple[float, float]], np.ndarray]]:
    """Per group of samples (each (k, P): one method's, say), :func:`mean_intervals_each` as a call of its own
    gives it: one call for every group where no sample holds NaN (a NaN pixel leaves the mask of its own group
    only), else a call per group."""
    xs = [np.asarray(g, float).reshape(len(g), -1) for g in groups]
    if not xs or any(np.isnan(x).any() for x in xs):
        return [mean_intervals_each(x, mask, level) for x in xs]
    cis, lengths = mean_intervals_each(np.concatenate(xs), mask, level)
    ends = np.cumsum([0] + [len(x) for x in xs])
    return [(cis[a:b], lengths[a:b]) for a, b in zip(ends[:-1], ends[1:])]


def wilson(p: float, n: float, z: float) -> tuple[float, float]:
    """The Wilson score interval of a fraction ``p`` out of ``n`` (real: an effective count) at normal quantile
    ``z``, without continuity correction (scipy's ``binomtest(…).proportion_ci(method="wilson")`` for whole n)."""
    z2 = z * z
    centre = (p + z2 / (2 * n)) / (1 + z2 / n)
    half = z / (1 + z2 / n) * math.sqrt(p * (1 - p) / n + z2 / (4 * n * n))
    return max(0.0, centre - half), min(1.0, centre + half)


def ray_pixels(hit: np.ndarray, src: np.ndarray | None = None) -> np.ndarray:
    """(N,) the flat pixel index (row-major over (H, W)) of each ray: ``hit`` (H, W, S) the sub-pixel rays that
    met the object (their order is the rays' order), ``src`` the camera ray of each secondary ray (dielectrics)."""
    pix = np.flatnonzero(np.asarray(hit, bool)) // np.shape(hit)[-1]
    return pix if src is None else pix[np.asarray(src)]


def _ray_ratios(weights, pixels, shape) -> tuple[np.ndarray, ...]:
    """:func:`ratio_variance` of the per-pixel sums of each of ``weights`` (k, N) over the per-pixel rays (N rays,
    ``pixels`` their flat pixel indices in ``shape``), counted over the rays' bounding box only
    (:func:`study.stats.region.ray_region`, kept for the next call over the same rays)."""
    reg, local = ray_region(pixels, shape)
    if reg is None:  # fewer than two pixels: no variance
        rays = np.bincount(local, minlength=int(np.prod(shape))).astype(float)
        return _degenerate(
            [np.bincount(local, weights=w, minlength=rays.size).sum() / rays.sum() for w in weights]
        )
    size = reg.m.size
    sub = np.stack([np.bincount(local, weights=w, minlength=size) for w in weights]).reshape(-1, *reg.m.shape)
    return spread(sub, reg)


def fraction_intervals(flags, pixels, shape, level: float) -> tuple[list[tuple[float, float]], list[float]]:
    """([(lo, hi), …], [design effect, …]): Wilson intervals of the fractions of several per-ray flags (k, N) bool
    of the same N rays, clustered by pixel: each fraction's variance under spatial correlation
    (:func:`ratio_variance` of the per-pixel counts over the per-pixel rays) over the binomial one is its design
    effect d (at least 1), and the interval is Wilson's at the effective count n / d, quantile Student's t as in
    :func:`mean_intervals`. A fraction of 0 or 1 has no variance to measure: d = 1. No rays: (NaN, NaN)."""
    flags = np.asarray(flags, bool).reshape(len(flags), np.size(pixels))
    n = flags.shape[1]
    if n == 0:
        return [(math.nan, math.nan)] * len(flags), [math.nan] * len(flags)
    p, var, _, dof, _, _ = _ray_ratios(flags, pixels, shape)
    z = _quantile(level, dof)
    cis, deffs = [], []
    for pi, vi, zi in zip(p, var, z):
        binom = pi * (1 - pi) / n
        d = max(1.0, vi / binom) if binom > 0 and vi == vi else 1.0
        cis.append(wilson(float(pi), n / d, float(zi)))
        deffs.append(d)
    return cis, deffs


def quantile_interval(values, p: float, pixels, shape, level: float) -> tuple[float, float]:
    """The ``level`` interval of the ``p``-th percentile (0–100) of per-ray ``values`` clustered by pixel
    (Woodruff 1952): the share of rays at or below the sample percentile gets a normal interval, its ± t·√variance
    of :func:`ratio_variance` (rays sharing pixels, heavy tails lowering the degrees of freedom; never narrower than
    over independent rays), whose ends are read back as order statistics. Not Wilson's: its centre leans towards
    ½ as if the variance shrank with p(1 − p) alone, which moved every miss of a 95th percentile to one side
    (5.5 % above, 1 % below in the calibration's simulation). An end the sample cannot give is ``inf`` above, the
    smallest value below. NaN values are dropped; none left: (NaN, NaN)."""
    x = np.asarray(values, float)
    keep = ~np.isnan(x)
    x, pix = x[keep], np.asarray(pixels)[keep]
    n = x.size
    if n == 0:
        return math.nan, math.nan
    q = np.percentile(x, p)
    ((share,), (var,), _, (dof,), _, _) = _ray_ratios([x <= q], pix, shape)
    half = float(_quantile(level, dof)) * math.sqrt(max(var, share * (1 - share) / n)) if var == var else 0.0
    a, b = share - half, share + half
    s = np.sort(x)
    hi = math.ceil(b * n)
    return float(s[min(n - 1, max(0, math.floor(a * n) - 1))]), (math.inf if hi >= n else float(s[hi]))
