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
"""

from __future__ import annotations

import math

import numpy as np

#: The lag window is flat (weight 1) out to where the correlogram falls below this, tapering to 0 at twice that.
WINDOW_LEVEL = 0.1
#: The flat part of the window reaches at least this many pixels.
MIN_WINDOW = 2.0
#: The centring correction divides by at least this (a window as wide as the region would divide by 0).
MIN_KEPT = 0.25
#: The reported correlation length is at most this share of the masked region's smaller extent.
MAX_LENGTH_SHARE = 0.125
#: The flat part of the lag window reaches at most this share of the masked region's smaller extent.
MAX_REACH_SHARE = 0.5
#: Angular bins of the lag window's reach (over a half-turn): a streak's correlation reaches far along it only.
ANGLES = 24
#: Fewer tiles than this measure no kurtosis (:func:`kurtosis_factor`).
MIN_TILES = 8
#: The skewness shift of a mean's interval is at most this share of its half-width (the estimate stays inside).
MAX_SKEW_SHIFT = 0.5
#: Heavy tails lower the degrees of freedom to no fewer than this (a kurtosis from few tiles is itself noisy).
MIN_DOF = 4.0


def lag_sums(fields: np.ndarray, reach: int | None = None) -> np.ndarray:
    """(k, H', W') the summed products fᵢ·fᵢ₊ₕ of each (H, W) field over the lags h (lag (dy, dx) at index
    (dy mod H', dx mod W')): every lag, or with ``reach`` only those within ``reach`` pixels along each axis come
    out exact (zero-padded to H + reach + 1, so none of them wraps; the others are not meaningful)."""
    from scipy import fft

    f = np.asarray(fields, float)
    pad = [2 * n if reach is None else min(2 * n, n + reach + 1) for n in f.shape[-2:]]
    shape = tuple(fft.next_fast_len(n, True) for n in pad)
    F = fft.rfft2(f, s=shape, axes=(-2, -1), workers=-1)
    return fft.irfft2(F.real**2 + F.imag**2, s=shape, axes=(-2, -1), workers=-1)


def _near_lags(shape: tuple[int, int], reach: int) -> tuple[np.ndarray, np.ndarray]:
    """The row and column indices of the lags within ``reach`` pixels along each axis (lag 0 first; each lag once)."""
    rows, cols = (np.unique(np.r_[0 : min(reach, n - 1) + 1, max(1, n - reach) : n]) for n in shape)
    return rows[:, None], cols[None, :]


def _radii(shape: tuple[int, int]) -> np.ndarray:
    hh, ww = shape
    dy = np.minimum(np.arange(hh), hh - np.arange(hh))[:, None]
    dx = np.minimum(np.arange(ww), ww - np.arange(ww))[None, :]
    return np.hypot(dy, dx)


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


def _tile_sums(resid: np.ndarray, mask: np.ndarray, area: float) -> np.ndarray:
    """The sums of ``resid`` over the square tiles of about ``area`` pixels that hold pixels of ``mask``."""
    t = max(1, round(math.sqrt(max(area, 1.0))))
    h, w = resid.shape
    hh, ww = -(-h // t) * t, -(-w // t) * t
    sums = np.zeros((2, hh, ww))
    sums[0, :h, :w], sums[1, :h, :w] = resid, mask
    s, inside = sums.reshape(2, hh // t, t, ww // t, t).sum(axis=(2, 4)).reshape(2, -1)
    return s[inside > 0]


def mean_skewness(resid: np.ndarray, mask: np.ndarray, area: float, windows: float) -> float:
    """The skewness of the mean of ``resid`` (residuals about it, over ``mask``): the skewness of its sums over
    tiles of about ``area`` pixels (the window's effective size) over √(tiles); with fewer than
    :data:`MIN_TILES` tiles the pixels' own skewness over √``windows`` (larger than the windows' would be: a sum
    over a window is less skewed than its pixels). A constant residual: 0."""
    s = _tile_sums(resid, mask, area)
    if s.size < MIN_TILES:
        s, scale = resid[mask], math.sqrt(max(windows, 1.0))
    else:
        scale = math.sqrt(s.size)
    s2 = float(np.mean(s * s))
    return float(np.mean(s**3)) / s2**1.5 / scale if s2 > 0 else 0.0


def kurtosis_factor(resid: np.ndarray, mask: np.ndarray, area: float) -> float:
    """2 / (2 + κ): the share of the window's degrees of freedom that heavy-tailed residuals keep. The window's
    count of independent windows holds for Gaussian residuals, whose squared window sums vary as 2σ⁴; sums with
    excess kurtosis κ vary as (2 + κ)σ⁴ (Satterthwaite), so the variance is less certain than the count says
    (rare events, e.g. the rays beyond a 95th percentile, are heavy-tailed). κ is measured on the sums of
    ``resid`` over square tiles of about ``area`` pixels (the window's effective size) that hold pixels of
    ``mask``; κ ≤ 0 or fewer than :data:`MIN_TILES` tiles: 1."""
    s = _tile_sums(resid, mask, area)
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


def _lag_grid(reach: int) -> tuple[np.ndarray, np.ndarray]:
    """The radii and angular bins (of :data:`ANGLES` over a half-turn: lags h and −h share one) of the centred
    (2·reach + 1)² lags."""
    dy, dx = np.mgrid[-reach : reach + 1, -reach : reach + 1]
    angle = np.mod(np.arctan2(dy, dx), math.pi)
    return np.hypot(dy, dx), np.minimum(ANGLES - 1, (angle / math.pi * ANGLES).astype(int))


def _centre(half: int, reach: int) -> tuple[slice, slice]:
    """The centred lags within ``half`` pixels along each axis of a (2·reach + 1)² lag array."""
    h = min(half, reach)
    return (slice(reach - h, reach + h + 1),) * 2


def ratio_variance(nums, den, mask, skews: bool = False) -> tuple[np.ndarray, ...]:
    """(ratios, variances, correlation lengths, degrees of freedom): per sample of ``nums`` (k, H, W) (or one
    (H, W)), the ratio Σ num / Σ den over ``mask`` (H, W), the variance of that ratio under spatial correlation
    (module docstring), the residuals' correlation length in pixels, and the degrees of freedom of that
    variance: the region's count of windows (1 / share − 1, share = Σ weight·pairs / n²) times
    :func:`kurtosis_factor` (at least min(that count, :data:`MIN_DOF`)). ``den`` (H, W): the weight of each
    pixel (1 for a mean over pixels). Pixels where a sample is NaN count as outside the mask for every sample.
    Fewer than two pixels, or Σ den = 0: NaN variance. ``skews``: a fifth result, the skewness of each ratio
    (:func:`mean_skewness`; 0 where the variance is NaN)."""
    mask = np.asarray(mask, bool)
    nums = np.asarray(nums, float)
    one = nums.ndim == 2
    nums = nums.reshape(-1, *mask.shape)
    den = np.broadcast_to(np.asarray(den, float), mask.shape)
    mask = mask & ~np.isnan(nums).any(axis=0)
    k = len(nums)
    ys, xs = np.nonzero(mask)
    total = float(den[mask].sum()) if ys.size else 0.0
    if ys.size < 2 or total <= 0:
        r = np.array([float(n[mask].sum() / total) if total > 0 else math.nan for n in nums])
        out = (r, np.full(k, math.nan), np.full(k, math.nan), np.full(k, math.nan)) + (
            (np.zeros(k),) if skews else ()
        )
        return tuple(v[0] for v in out) if one else out
    y0, y1, x0, x1 = ys.min(), ys.max() + 1, xs.min(), xs.max() + 1  # the mask's bounding box only
    m, d = mask[y0:y1, x0:x1], den[y0:y1, x0:x1]
    sub = np.where(m, nums[:, y0:y1, x0:x1], 0.0)
    r = sub.sum(axis=(1, 2)) / total
    resid = np.where(m, sub - r[:, None, None] * d, 0.0)
    length_limit = max(1.0, MAX_LENGTH_SHARE * min(m.shape))
    limit = max(1.0, MAX_REACH_SHARE * min(m.shape))
    # the lags the correlogram and the window (< 2 · limit) reach, centred: lag (dy, dx) at [R + dy, R + dx]
    reach = math.ceil(max(2 * max(MIN_WINDOW, limit), int(length_limit) + 1.5))
    sums = lag_sums(np.concatenate([resid, m[None].astype(float)]), reach)
    rows, cols = (np.arange(-reach, reach + 1) % n for n in sums.shape[-2:])
    sums = sums[:, rows[:, None], cols[None, :]]
    radii, bins = _lag_grid(reach)
    pairs, sums = sums[-1], sums[:-1]
    lengths, var, dof, skew = np.empty(k), np.empty(k), np.empty(k), np.zeros(k)
    n = float(m.sum())
    with np.errstate(invalid="ignore", divide="ignore"):
        per_pair = np.where(pairs > 0.5, 1.0 / pairs, math.nan)
    # what every sample shares: the lags the flat part may reach, and the rings of the correlation length (lag 0
    # first) with their pair counts and radii
    fc, rc = _centre(math.ceil(limit), reach), _centre(int(length_limit) + 2, reach)
    f_per_pair, f_radii, f_bins = per_pair[fc], radii[fc], bins[fc]
    r_pairs, r_radii = np.fft.ifftshift(pairs[rc]), np.fft.ifftshift(radii[rc])
    for i in range(k):
        with np.errstate(invalid="ignore", divide="ignore"):  # a constant sample: NaN, the smallest window
            rho = sums[i][fc] * f_per_pair / (sums[i, reach, reach] * per_pair[reach, reach])
        ring = correlogram(np.fft.ifftshift(sums[i][rc]), r_pairs, r_radii, int(length_limit) + 1)
        lengths[i] = min(length_limit, crossing(ring, math.exp(-1)))
        flat = _reach_by_angle(rho, f_radii, f_bins, limit)
        c = _centre(math.ceil(2 * flat.max()), reach)  # the lags the window reaches
        w = np.clip(2.0 - radii[c] / flat[bins[c]], 0.0, 1.0)
        # the residuals are centred on the estimated ratio, which takes (Σ w·pairs / n²) of the window's sum away
        share = float(np.sum(w * pairs[c])) / (n * n)
        gauss = max(1.0, 1.0 / share - 1.0)
        dof[i] = max(min(gauss, MIN_DOF), gauss * kurtosis_factor(resid[i], m, share * n))
        if skews:
            skew[i] = mean_skewness(resid[i], m, share * n, gauss)
        keep = max(MIN_KEPT, 1.0 - share)
        v = float(np.sum(w * sums[i][c])) / keep
        var[i] = max(v, float(sums[i, reach, reach])) / (total * total)  # never below independent pixels
    out = (r, var, lengths, dof) + ((skew,) if skews else ())
    return tuple(v[0] for v in out) if one else out


def _quantile(level: float, dof) -> np.ndarray:
    from scipy import stats as sps

    return sps.t.ppf(0.5 + level / 2, np.maximum(1.0, np.nan_to_num(np.asarray(dof, float), nan=1.0)))


def mean_intervals(samples, mask, level: float) -> tuple[list[tuple[float, float]], float]:
    """([(lo, hi), …], correlation length): the ``level`` intervals of the means of several per-pixel samples
    (each (P,), the values of ``mask``'s P True pixels in ``img[mask]`` order), each its mean ± t·√variance
    (:func:`ratio_variance`, Student's t with its degrees of freedom: the region holds about 1/share windows,
    share = Σ weight·pairs / n², fewer for heavy-tailed residuals; a sample of values ≥ 0 has its lower end at 0
    or above); the
    correlation length is the first sample's, in pixels. Fewer than two pixels: (mean, mean)."""
    mask = np.asarray(mask, bool)
    xs = np.asarray(samples, float).reshape(len(samples), -1)
    imgs = np.zeros((len(xs), *mask.shape))
    imgs[:, mask] = xs
    r, var, lengths, dof, skew = ratio_variance(imgs, 1.0, mask, skews=True)
    t = _quantile(level, dof)
    # skewed samples (squared errors, sparse blobs): both ends move by c·√var towards the long tail (Hall 1992)
    c = np.clip(skew * (2 * t * t + 1) / 6, -MAX_SKEW_SHIFT * t, MAX_SKEW_SHIFT * t)
    half = t * np.sqrt(var)
    r_lo, r_hi = r - (t - c) * np.sqrt(var), r + (t + c) * np.sqrt(var)
    floor = np.where((xs >= 0).all(axis=1), 0.0, -np.inf)  # a mean of values ≥ 0 is ≥ 0
    out = [
        (float(m), float(m)) if not h == h else (float(max(f, a)), float(b))
        for m, h, f, a, b in zip(r, half, floor, r_lo, r_hi)
    ]
    return out, float(lengths[0])


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
    size = int(np.prod(shape))
    pix = np.asarray(pixels, np.intp)
    rays = np.bincount(pix, minlength=size).reshape(shape).astype(float)
    counts = np.stack([np.bincount(pix, weights=f, minlength=size) for f in flags]).reshape(-1, *shape)
    p, var, _, dof = ratio_variance(counts, rays, rays > 0)
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
    rays = np.bincount(pix, minlength=int(np.prod(shape))).reshape(shape).astype(float)
    below = np.bincount(pix, weights=x <= q, minlength=rays.size).reshape(shape)
    share, var, _, dof = ratio_variance(below, rays, rays > 0)
    half = float(_quantile(level, dof)) * math.sqrt(max(var, share * (1 - share) / n)) if var == var else 0.0
    a, b = share - half, share + half
    s = np.sort(x)
    hi = math.ceil(b * n)
    return float(s[min(n - 1, max(0, math.floor(a * n) - 1))]), (math.inf if hi >= n else float(s[hi]))
