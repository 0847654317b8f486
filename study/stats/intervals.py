"""Intervals of one number: over a sample (bootstrap, Wilson, order statistics), over spatially correlated pixels
and rays (:mod:`study.stats.spatial`), over a table's cases (the median's interval, or the range below
:data:`MIN_CASES_CI` cases) and over seeds or segments (Student t).

Each interval's coverage is measured by simulation with a known truth (:mod:`study.stats.calibration`,
``reports/calibration.md``). A bootstrap (:func:`bootstrap_ci`, for statistics without a closed form) is percentile,
:data:`N_RESAMPLES` resamples, seed :data:`SEED` (deterministic), level :data:`LEVEL`.
"""

from __future__ import annotations

import functools
import math

import numpy as np
from scipy import stats as sps

from study.stats.spatial import fraction_intervals, mean_intervals, quantile_interval

LEVEL = 0.95
N_RESAMPLES = 1000
SEED = 0


# ---------------------------------------------------------------------------------------------- intervals
def bootstrap_ci(data, statistic, *, level: float = LEVEL, n_resamples: int = N_RESAMPLES, seed: int = SEED):
    """(lo, hi): percentile-bootstrap interval of ``statistic`` over the 1-d sample ``data`` (NaN dropped).

    ``statistic(x, axis)`` must be vectorised (numpy reductions are). A sample of one value, or of equal values,
    gives (value, value); an empty one (NaN, NaN)."""
    x = np.asarray(data, float)
    x = x[~np.isnan(x)]
    if x.size == 0:
        return math.nan, math.nan
    if x.size == 1 or np.all(x == x[0]):
        v = float(statistic(x, axis=-1))
        return v, v
    res = sps.bootstrap(
        (x,),
        statistic,
        vectorized=True,
        axis=-1,
        n_resamples=n_resamples,
        batch=max(1, min(n_resamples, int(2e7 // x.size))),  # bounded memory for large samples
        method="percentile",
        confidence_level=level,
        random_state=np.random.default_rng(seed),
    )
    return float(res.confidence_interval.low), float(res.confidence_interval.high)


@functools.lru_cache(maxsize=65536)
def _wilson(k: int, n: int, level: float) -> tuple[float, float]:
    ci = sps.binomtest(k, n).proportion_ci(confidence_level=level, method="wilson")
    return float(ci.low), float(ci.high)


def fraction_ci(k: int, n: int, level: float = LEVEL) -> tuple[float, float]:
    """Wilson score interval of a fraction k/n (NaN, NaN when n = 0); ``scipy.stats.binomtest``, memoised."""
    if n <= 0:
        return math.nan, math.nan
    return _wilson(int(k), int(n), float(level))


def quantile_ci(data, p: float, level: float = LEVEL, *, pixels=None, shape=None) -> tuple[float, float]:
    """Distribution-free interval of the ``p``-th percentile (0–100) of ``data`` (NaN dropped): the binomial
    order-statistic interval of ``scipy.stats.quantile_test`` (exact coverage for independent values, no
    resampling, O(n log n)). A bound the sample cannot give (too few values beyond the quantile) is ``inf`` above,
    NaN below; an empty sample (NaN, NaN). With ``pixels`` (each value's flat pixel index) and ``shape``: rays
    clustered by pixel (:func:`study.stats.spatial.quantile_interval`)."""
    if pixels is not None:
        return quantile_interval(data, p, pixels, shape, level)
    x = np.asarray(data, float)
    x = x[~np.isnan(x)]
    if x.size == 0:
        return math.nan, math.nan
    ci = sps.quantile_test(x, q=float(np.percentile(x, p)), p=p / 100).confidence_interval(level)
    lo, hi = float(ci.low), float(ci.high)
    return lo, (math.inf if math.isnan(hi) else hi)


def fraction_cis(flags, pixels=None, shape=None) -> tuple[list[tuple[float, float]], list[float]]:
    """([(lo, hi), …], [design effect, …]) of the fractions of several per-ray flags (k, N) of the same rays:
    clustered by pixel (:func:`study.stats.spatial.fraction_intervals`) when ``pixels`` (N,) (each ray's flat
    pixel index) and ``shape`` (H, W) are given, else Wilson's over independent rays (design effect NaN)."""
    flags = np.asarray(flags, bool).reshape(len(flags), -1)
    if pixels is None:
        return [fraction_ci(int(f.sum()), f.size) for f in flags], [math.nan] * len(flags)
    return fraction_intervals(flags, pixels, shape, LEVEL)


# ---------------------------------------------------------------------------------------------- over cases
def median_ci(values, level: float = LEVEL) -> tuple[float, float]:
    """The distribution-free interval of the median of ``values`` (NaN dropped), interpolated between order
    statistics (Hettmansperger & Sheather 1986): [X₍ₖ₎, X₍ₙ₋ₖ₊₁₎] covers the median with probability γₖ =
    P(k ≤ Bin(n, ½) ≤ n − k); k is the last with γₖ ≥ ``level``, and each end moves towards the next order statistic
    by λ = (n − k)·I / (k + (n − 2k)·I), I = (γₖ − level) / (γₖ − γₖ₊₁), so the coverage is ``level`` for any
    continuous distribution instead of the next γₖ above it (97.9 % at n = 10). Too few values for γ₁ ≥ ``level``
    (n ≤ 5 at 95 %): their range. It contains the sample median."""
    x = np.sort(np.asarray(values, float)[~np.isnan(np.asarray(values, float))])
    n = x.size
    if n == 0:
        return math.nan, math.nan
    gamma = [1 - 2 * sps.binom.cdf(k - 1, n, 0.5) for k in range(1, n // 2 + 2)]
    k = max([i + 1 for i, g in enumerate(gamma) if g >= level], default=1)
    if gamma[k - 1] < level or k >= n - k + 1:
        return float(x[0]), float(x[-1])
    frac = (gamma[k - 1] - level) / (gamma[k - 1] - gamma[k])
    lam = (n - k) * frac / (k + (n - 2 * k) * frac)
    return float((1 - lam) * x[k - 1] + lam * x[k]), float((1 - lam) * x[n - k] + lam * x[n - k - 1])


def over_cases(values, statistic=np.median) -> tuple[float, float, float, int]:
    """(statistic, lo, hi, n) of the finite per-case ``values``: the median's interval :func:`median_ci`, another
    statistic's the percentile bootstrap over cases."""
    v = np.asarray(values, float)
    v = v[np.isfinite(v)]
    if v.size == 0:
        return math.nan, math.nan, math.nan, 0
    if statistic is np.median:
        lo, hi = median_ci(v)
    else:
        lo, hi = bootstrap_ci(v, lambda x, axis=-1: statistic(x, axis=axis))
    return float(statistic(v)), lo, hi, int(v.size)


#: Fewer cases than this and an interval over cases is their range, not a "95 % CI": a percentile bootstrap over
#: 2–4 cases covers the truth 52–87 % of the time in simulation (with 3 cases it is just [min, max]).
MIN_CASES_CI = 10


def case_interval(values) -> tuple[float, float, float, int, str]:
    """(median, lo, hi, n, kind) of per-case values: ``kind`` "ci", the median's 95 % interval over the cases
    (:func:`median_ci`), from :data:`MIN_CASES_CI` cases on; else "range", their min and max."""
    v = np.asarray(values, float)
    v = v[np.isfinite(v)]
    if 0 < v.size < MIN_CASES_CI:  # no bootstrap to throw away
        return float(np.median(v)), float(v.min()), float(v.max()), int(v.size), "range"
    return (*over_cases(v), "ci")


def segment_interval(whole: float, parts, level: float = 0.95) -> tuple[float, float]:
    """(lo, hi): the ``level`` interval of a whole sequence's score from its k segments' scores ``parts``: ``whole``
    ± t₍ₖ₋₁₎ · sd(parts) / √k (the segments as independent draws of the score, the whole as their mean; it
    contains ``whole``). Equal parts: (whole, whole)."""
    from scipy.stats import t

    p = np.asarray(parts, float)
    if p.size < 2 or np.ptp(p) == 0:
        return float(whole), float(whole)
    half = float(t.ppf(0.5 + level / 2, p.size - 1) * p.std(ddof=1) / np.sqrt(p.size))
    return float(whole) - half, float(whole) + half


def seed_interval(values) -> tuple[float, float, float]:
    """(mean, 95 % low, high) of per-seed values: Student-t over the seeds (the replicates are independent);
    (mean, nan, nan) from one seed; NaN values are left out."""
    from scipy.stats import t as student

    v = np.asarray([x for x in values if np.isfinite(x)], float)
    if v.size == 0:
        return np.nan, np.nan, np.nan
    mean = float(v.mean())
    if v.size < 2:
        return mean, np.nan, np.nan
    half = float(student.ppf(0.975, v.size - 1) * v.std(ddof=1) / np.sqrt(v.size))
    return mean, mean - half, mean + half


def debiased_root(mse: float, sigma: float) -> float:
    """√max(0, mse − σ²), NaN where either is NaN (``max(0.0, nan)`` is 0.0: a NaN σ would read as no error)."""
    d = mse - sigma * sigma
    return math.nan if math.isnan(d) else math.sqrt(max(0.0, d))


def rmse_interval(se, mask, sigma: float = 0.0, level: float = LEVEL):
    """((lo, hi), (debiased lo, hi)): the ``level`` interval of an RMSE from its per-pixel squared errors ``se``
    (P,) over ``mask``'s P pixels: the interval of their mean (:func:`study.stats.spatial.mean_intervals`), its ends
    floored at 0 and rooted; debiased by a reference noise σ taken as known, √max(0, b² − σ²). What
    :func:`study.measure.case_columns.pixel_columns` writes as ``rmse_*_lo``/``_hi`` (a test holds them equal)."""
    ((lo, hi),), _ = mean_intervals([se], mask, level)
    return root_bounds(lo, hi, sigma)


def root_bounds(lo: float, hi: float, sigma: float = 0.0):
    """((√lo, √hi), (debiased lo, hi)): an interval (lo, hi) of a mean squared error as one of its RMSE, ``lo``
    floored at 0, and debiased by a reference noise σ taken as known, √max(0, b² − σ²)."""
    lo = max(lo, 0.0)
    return (math.sqrt(lo), math.sqrt(hi)), (debiased_root(lo, sigma), debiased_root(hi, sigma))
