"""Numbers with their uncertainty: intervals per case (over rays, over blocks of pixels), intervals over a table's
cases, paired comparisons of two methods, and the wrong fraction at tolerances with one meaning.

Units of uncertainty (what a column averages, and what is correlated within it); each interval's coverage is
measured by simulation with a known truth (:mod:`study.measure.calibration`, ``reports/calibration.md``):

* **rays** for per-ray columns (``wrong_fraction*``, ``angle_*``, ``dist_*``): the object's secondary rays of one
  case. Neighbouring rays share texels and surfaces, so they are not independent draws: fractions get a Wilson
  score interval at the effective number of rays, n over the design effect measured from the per-pixel counts'
  spatial autocovariance (:func:`fraction_cis`, :func:`study.measure.spatial.fraction_intervals`; it stays honest
  at 0 % and 100 %); percentiles get a distribution-free order-statistic interval over the rays
  (:func:`quantile_ci`, exact for independent rays).
* **pixels** for image columns (``rmse_*``, ``relmse_*``, ``flip_*``, the error split's ``dec_*``): the object's
  pixels of one case, spatially correlated (a wrong reflection is a blob of pixels, not independent evidence per
  pixel): the mean ± t·√variance, the variance summed from the image's own autocovariance over a lag window sized
  by its measured correlation length (:func:`study.measure.spatial.mean_intervals`; ``corr_px``). RMSE-like
  columns take the interval of the mean squared error and transform its ends, so each interval contains its
  estimate.
* **cases** for a table's summary: the median over cases with the interpolated order-statistic interval
  (:func:`median_ci`) from :data:`MIN_CASES_CI` cases on, else their range (:func:`case_interval`), and paired
  comparisons of two methods over the same cases (:func:`paired`: Wilcoxon signed-rank), with the smallest shift
  such a comparison detects (:func:`detectable_shift`).

A bootstrap (:func:`bootstrap_ci`, for statistics without a closed form) is percentile, :data:`N_RESAMPLES`
resamples, seed :data:`SEED` (deterministic), level :data:`LEVEL`.
"""

from __future__ import annotations

import functools
import math

import numpy as np
from scipy import stats as sps

from study.measure import spatial
from study.measure.signed_rank import wilcoxon_p

LEVEL = 0.95
N_RESAMPLES = 1000
SEED = 0
#: The fixed absolute tolerances of ``wrong_fraction_<tol>`` (metres, name suffix): the same distance at every
#: cube resolution, unlike the texel-relative ``wrong_fraction_texel``. They also sample the wrong-versus-tolerance
#: curve (:func:`tolerance_curve`).
TOLERANCES = {"1mm": 0.001, "3mm": 0.003, "1cm": 0.01, "3cm": 0.03, "10cm": 0.1, "30cm": 0.3}
#: The tolerances whose wrong fraction gets an interval (``_lo``/``_hi``).
TOLERANCES_CI = ("1cm", "3cm", "10cm")
#: The angular tolerance of ``wrong_fraction_0p5deg``: the shown point is wrong when |shown − exact| subtends more
#: than this angle seen from the shading point x (|shown − exact| > |exact − x|·tan θ), degrees.
ANGLE_TOL_DEG = 0.5
#: The share of worst pixels ``*_trim`` columns leave out (0.1 %, at least one pixel).
TRIM = 0.001


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
    clustered by pixel (:func:`study.measure.spatial.quantile_interval`)."""
    if pixels is not None:
        return spatial.quantile_interval(data, p, pixels, shape, level)
    x = np.asarray(data, float)
    x = x[~np.isnan(x)]
    if x.size == 0:
        return math.nan, math.nan
    ci = sps.quantile_test(x, q=float(np.percentile(x, p)), p=p / 100).confidence_interval(level)
    lo, hi = float(ci.low), float(ci.high)
    return lo, (math.inf if math.isnan(hi) else hi)


# ---------------------------------------------------------------------------------------------- per ray
def error_distance(outcomes, x, exact) -> np.ndarray:
    """Per ray, the distance |shown − exact| that fixed tolerances are compared with (m): ``inf`` for NO_HIT and
    for a point at infinity that the texel-relative classification did not call correct, 0 for one it did (both
    at infinity, same direction within one texel), else :attr:`Outcomes.dist`."""
    from study.measure.outcomes import CORRECT, NO_HIT

    c, d = np.asarray(outcomes.cls), np.asarray(outcomes.dist, float)
    return np.where(c == NO_HIT, np.inf, np.where(np.isnan(d), np.where(c == CORRECT, 0.0, np.inf), d))


def tolerance_curve(err: np.ndarray, tolerances=tuple(TOLERANCES.values())) -> np.ndarray:
    """The wrong fraction at each fixed tolerance (m): the share of rays with ``err`` > tolerance (no hit counts
    as wrong at every tolerance)."""
    e = np.asarray(err, float)
    return np.array([np.mean(e > t) if e.size else math.nan for t in tolerances])


def fraction_cis(flags, pixels=None, shape=None) -> tuple[list[tuple[float, float]], list[float]]:
    """([(lo, hi), …], [design effect, …]) of the fractions of several per-ray flags (k, N) of the same rays:
    clustered by pixel (:func:`study.measure.spatial.fraction_intervals`) when ``pixels`` (N,) (each ray's flat
    pixel index) and ``shape`` (H, W) are given, else Wilson's over independent rays (design effect NaN)."""
    flags = np.asarray(flags, bool).reshape(len(flags), -1)
    if pixels is None:
        return [fraction_ci(int(f.sum()), f.size) for f in flags], [math.nan] * len(flags)
    return spatial.fraction_intervals(flags, pixels, shape, LEVEL)


def ray_columns(outcomes, angle, hidden, x, exact, *, pixels=None, shape=None) -> dict[str, float]:
    """The columns with counts, intervals and fixed tolerances of one method in one case (resampling unit: rays).

    Parameters
    ----------
    outcomes : study.measure.outcomes.Outcomes
        The rays' classes against the exact hits (texel-relative tolerance ε).
    angle : (N,) array
        Angular error per ray, degrees (NaN where nothing is shown).
    hidden : (N,) bool array
        The exact hit is hidden from the reference point.
    x, exact : (N, 3) arrays
        The rays' origins (shading points) and exact hits.
    pixels, shape : (N,) int array and (H, W), optional
        Each ray's flat pixel index in the frame (:func:`study.measure.spatial.ray_pixels`): the fractions'
        intervals are then clustered by pixel (:func:`fraction_cis`; neighbouring rays share texels), else over
        independent rays.

    Returns
    -------
    dict
        ``n_rays``, ``n_hidden``, ``n_wrong`` (counts behind every fraction); ``rays_deff``: the design effect
        of ``wrong_fraction`` (its variance over the binomial one, NaN without ``pixels``);
        ``wrong_fraction_texel`` (= the texel-relative ``wrong_fraction``: ε = max(1 cm, one texel)) with
        ``_lo``/``_hi``, and ``_lo``/``_hi`` of
        ``wrong_fraction_visible``/``_hidden``; ``wrong_fraction_<tol>`` for each fixed tolerance of
        :data:`TOLERANCES` (no hit = wrong), with intervals for :data:`TOLERANCES_CI`; ``wrong_fraction_0p5deg``
        (angular tolerance :data:`ANGLE_TOL_DEG` seen from x); ``angle_dropped`` / ``dist_dropped``: the share of
        rays that ``angle_*`` / ``dist_*`` leave out (no hit; for dist also points at infinity);
        ``angle_p95_all_deg``: the 95th percentile of the angle with dropped rays as infinite error (inf when more
        than 5 % are dropped); ``angle_median_deg_lo``/``_hi``, ``angle_p95_deg_lo``/``_hi``,
        ``dist_p95_lo``/``_hi``: order-statistic intervals (:func:`quantile_ci`, clustered by pixel with
        ``pixels``) over the rays the statistic keeps.
    """
    from study.measure.outcomes import CORRECT

    c = np.asarray(outcomes.cls)
    hidden = np.asarray(hidden, bool)
    wrong = c != CORRECT
    err = error_distance(outcomes, x, exact)
    ang = np.asarray(angle, float)
    out = {"n_rays": int(c.size), "n_hidden": int(hidden.sum()), "n_wrong": int(wrong.sum())}
    reach = np.linalg.norm(np.asarray(exact, float) - np.asarray(x, float), axis=-1)
    with np.errstate(invalid="ignore"):
        flags = {
            "wrong_fraction_texel": wrong,
            **{f"wrong_fraction_{name}": err > tol for name, tol in TOLERANCES.items()},
            "wrong_fraction_0p5deg": ~(err <= reach * math.tan(math.radians(ANGLE_TOL_DEG))),
        }
    for name, f in flags.items():
        out[name] = float(f.mean()) if c.size else math.nan
    ci = ["wrong_fraction_texel", *(f"wrong_fraction_{t}" for t in TOLERANCES_CI), "wrong_fraction_0p5deg"]
    cis, deff = fraction_cis([flags[k] for k in ci], pixels, shape)
    out["rays_deff"] = float(deff[0])
    for part, sel in (("visible", ~hidden), ("hidden", hidden)):
        ci.append(f"wrong_fraction_{part}")
        cis += fraction_cis([wrong[sel]], None if pixels is None else np.asarray(pixels)[sel], shape)[0]
    for name, (lo, hi) in zip(ci, cis):
        out[f"{name}_lo"], out[f"{name}_hi"] = lo, hi
    fa, fd = np.isfinite(ang), np.isfinite(np.asarray(outcomes.dist, float))
    out["angle_dropped"] = float(1 - fa.mean()) if c.size else math.nan
    out["dist_dropped"] = float(1 - fd.mean()) if c.size else math.nan
    full = np.where(fa, ang, np.inf)
    out["angle_p95_all_deg"] = float(np.percentile(full, 95, method="inverted_cdf")) if c.size else math.nan
    px = (lambda sel: None) if pixels is None else (lambda sel: np.asarray(pixels)[sel])
    for name, v, p, sel in (
        ("angle_median_deg", ang[fa], 50, fa),
        ("angle_p95_deg", ang[fa], 95, fa),
        ("dist_p95", np.asarray(outcomes.dist)[fd], 95, fd),
    ):
        out[f"{name}_lo"], out[f"{name}_hi"] = quantile_ci(v, p, pixels=px(sel), shape=shape)
    return out


# ---------------------------------------------------------------------------------------------- per pixel
def _mean(x, axis=-1):
    return np.mean(x, axis=axis)


def trimmed_mean(values, trim: float = TRIM) -> float:
    """The mean of ``values`` without the largest ``trim`` share of them (at least one left out)."""
    return _trimmed_sorted(np.sort(np.asarray(values, float)), trim)


def _trimmed_sorted(v: np.ndarray, trim: float = TRIM) -> float:
    """:func:`trimmed_mean` of values ``v`` already sorted (ascending)."""
    drop = max(1, math.ceil(trim * v.size))
    return float(v[: v.size - drop].mean()) if v.size > drop else math.nan


def _debiased_root(mse: float, sigma: float) -> float:
    """√max(0, mse − σ²), NaN where either is NaN (``max(0.0, nan)`` is 0.0: a NaN σ would read as no error)."""
    d = mse - sigma * sigma
    return math.nan if math.isnan(d) else math.sqrt(max(0.0, d))


def pixel_columns(
    img, ref, *, mask, sigma: float, rel_eps: float, suffix: str = "truth", emap=None, shared=None
) -> dict:
    """Intervals and robust variants of one image's errors against ``ref`` over ``mask`` (pixels, spatially
    correlated: :mod:`study.measure.spatial`).

    Returns ``n_pixels``, ``corr_px`` (the squared error's correlation length, pixels); ``rmse_<suffix>_lo``/
    ``_hi`` (the interval of the mean squared error, :func:`study.measure.spatial.mean_intervals`, then √),
    ``rmse_<suffix>_debiased_lo``/``_hi`` (the same bounds debiased by the reference's noise σ, taken as known:
    √max(0, b² − σ²); σ must be measured over the same ``mask`` as the estimate's),
    ``relmse_<suffix>_lo``/``_hi`` (relMSE with ε = ``rel_eps``), ``flip_<suffix>_lo``/
    ``_hi`` (when the FLIP map ``emap`` is given); ``rmse_<suffix>_trim`` / ``rmse_<suffix>_debiased_trim``: the
    RMSE without the worst :data:`TRIM` of pixels (≥ 1 pixel); ``sqerr_top_share_<suffix>``: the share of the
    summed squared error that those worst pixels carry (near 1: the RMSE is decided by a handful of pixels).
    ``shared``: a dict the calls of one ``ref``, ``mask`` and ``rel_eps`` pass along (several images of a case),
    which keeps the reference's masked pixels and relMSE denominators for the next call."""
    mask = np.asarray(mask, bool)
    if shared is None or "r" not in shared:  # the masked pixels first, then float64 (not whole frames)
        r = np.asarray(ref)[mask].astype(float)
        shared = {} if shared is None else shared
        shared["r"], shared["den"] = r, r * r + rel_eps
    r, den = shared["r"], shared["den"]
    d = np.asarray(img)[mask].astype(float) - r
    dd = d * d
    se = np.mean(dd, axis=-1)  # per pixel, mean over channels: mean(se) = RMSE²
    rel = np.mean(dd / den, axis=-1)
    names, samples = [f"rmse_{suffix}", f"relmse_{suffix}"], [se, rel]
    if emap is not None:
        names.append(f"flip_{suffix}")
        samples.append(np.asarray(emap)[mask].astype(float))
    intervals, length = (
        spatial.mean_intervals(samples, mask, LEVEL) if se.size else ([(math.nan,) * 2] * 3, math.nan)
    )
    out = {"n_pixels": int(se.size), "corr_px": length}
    cis = dict(zip(names, intervals))
    lo, hi = cis.pop(f"rmse_{suffix}")
    lo = max(lo, 0.0)
    out[f"rmse_{suffix}_lo"], out[f"rmse_{suffix}_hi"] = math.sqrt(lo), math.sqrt(hi)
    for k, b in (("lo", lo), ("hi", hi)):
        out[f"rmse_{suffix}_debiased_{k}"] = _debiased_root(b, sigma)
    for name, (a, b) in cis.items():
        out[f"{name}_lo"], out[f"{name}_hi"] = a, b
    ranked = np.sort(se)  # sorted once: the trimmed mean and the worst pixels' share
    tm = _trimmed_sorted(ranked)
    out[f"rmse_{suffix}_trim"] = math.sqrt(tm) if tm == tm else math.nan
    out[f"rmse_{suffix}_debiased_trim"] = _debiased_root(tm, sigma)
    total = float(se.sum())
    top = ranked[::-1][: max(1, math.ceil(TRIM * se.size))].sum() if se.size else math.nan
    out[f"sqerr_top_share_{suffix}"] = float(top / total) if total > 0 else math.nan
    return out


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


def paired(a, b) -> dict:
    """Paired comparison of two methods over the same cases: per-case values ``a`` and ``b`` (lower is better;
    cases where either is not finite are left out).

    Returns ``n`` (cases compared), ``a_better`` / ``b_better`` / ``ties`` (case counts), ``median_diff``
    (median of a − b) and ``p``: the two-sided Wilcoxon signed-rank p-value (exact for small n, zero differences
    split between the ranks; 1.0 when every difference is 0, NaN when n = 0)."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    ok = np.isfinite(a) & np.isfinite(b)
    d = a[ok] - b[ok]
    out = {
        "n": int(d.size),
        "a_better": int((d < 0).sum()),
        "b_better": int((d > 0).sum()),
        "ties": int((d == 0).sum()),
        "median_diff": float(np.median(d)) if d.size else math.nan,
    }
    if d.size == 0:
        out["p"] = math.nan
    elif not np.any(d):
        out["p"] = 1.0
    else:
        out["p"] = wilcoxon_p(d)
    return out


def detectable_difference(a, b, alpha: float = 1 - LEVEL, power: float = 0.8) -> float:
    """The smallest difference between two methods' per-case values ``a`` and ``b`` (over the cases where both are
    finite) that :func:`paired` detects at ``alpha`` with ``power``: :func:`detectable_shift` × the standard
    deviation of the differences, in the values' unit (``inf`` with too few cases to reach ``alpha``, NaN with
    fewer than two differences)."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    d = (a - b)[np.isfinite(a) & np.isfinite(b)]
    shift = detectable_shift(int(d.size), alpha, power)
    if math.isinf(shift):
        return math.inf
    return float(shift * np.std(d, ddof=1)) if d.size > 1 else math.nan


def min_p(n: int) -> float:
    """The smallest two-sided p-value a Wilcoxon signed-rank test on n cases can give (2/2ⁿ): below 6 cases no
    difference can be significant at 5 %."""
    return min(1.0, 2.0 / 2**n) if n > 0 else 1.0


def significance(p: float, alpha: float = 1 - LEVEL) -> str:
    """Words for a p-value: 'significant at 1 %' / 'at 5 %' or 'no significant difference'."""
    if not p == p:
        return "not tested"
    if p < 0.01:
        return f"significant at 1 % (p = {p:.2g})"
    if p < alpha:
        return f"significant at {alpha:.0%} (p = {p:.2g})"
    return f"no significant difference (p = {p:.2g})"


# ---------------------------------------------------------------------------------------------- power
def detectable_fraction(n: float, p0: float, alpha: float = 1 - LEVEL, power: float = 0.8) -> float:
    """The smallest rise δ of a fraction from ``p0`` that a two-sided test comparing two fractions over ``n`` rays
    each detects at level ``alpha`` with ``power``: Cohen's arcsine effect size h = 2 asin√p₁ − 2 asin√p₀ needs
    n = 2 ((z₁₋α/₂ + z_power) / h)² per group, so h = (z₁₋α/₂ + z_power) √(2/n) and δ = sin²(asin√p₀ + h/2) − p₀
    (NaN for n < 1). The rays of two methods in one case are the same rays (paired), for which this is
    conservative."""
    if not (n >= 1 and 0 <= p0 <= 1):
        return math.nan
    h = (sps.norm.ppf(1 - alpha / 2) + sps.norm.ppf(power)) * math.sqrt(2 / n)
    a = math.asin(math.sqrt(p0)) + h / 2
    return (1.0 if a >= math.pi / 2 else math.sin(a) ** 2) - p0


#: Draws of the Monte Carlo power in :func:`detectable_shift` (fixed seed :data:`SEED`: deterministic).
POWER_DRAWS = 2000


def _signed_rank_null(n: int) -> np.ndarray:
    """P(W⁺ = w), w = 0 … n(n+1)/2: the exact null distribution of the Wilcoxon signed-rank statistic."""
    counts = np.zeros(n * (n + 1) // 2 + 1)
    counts[0] = 1.0
    for k in range(1, n + 1):
        counts[k:] = counts[k:] + counts[:-k].copy()
    return counts / counts.sum()


@functools.lru_cache(maxsize=256)
def detectable_shift(n: int, alpha: float = 1 - LEVEL, power: float = 0.8) -> float:
    """The smallest shift of paired per-case differences, in their standard deviations, that the two-sided Wilcoxon
    signed-rank test over ``n`` cases (:func:`paired`) detects at ``alpha`` with ``power``, for normal
    differences: the exact null distribution of W⁺ gives the test's rejection region, the power is counted over
    :data:`POWER_DRAWS` draws of n normal differences (seed :data:`SEED`), shifted until it reaches ``power``
    (bisection; the same draws for every shift, so the power rises with it). Above 100 cases the normal
    approximation (z₁₋α/₂ + z_power) / √(3n/π) (Wilcoxon's efficiency 3/π against the paired t-test). ``inf`` where
    no p-value it can give reaches ``alpha`` (:func:`min_p` = 2/2ⁿ ≥ alpha: fewer than 6 cases at 5 %)."""
    if n < 1 or min_p(n) >= alpha:
        return math.inf
    if n > 100:
        return float((sps.norm.ppf(1 - alpha / 2) + sps.norm.ppf(power)) / math.sqrt(3 * n / math.pi))
    pmf = _signed_rank_null(n)
    cdf = np.cumsum(pmf)
    sf = cdf[-1] - np.concatenate([[0.0], cdf[:-1]])  # P(W⁺ ≥ w)
    p = np.minimum(1.0, 2 * np.minimum(cdf, sf))  # two-sided p-value of each w
    z = np.random.default_rng(SEED).normal(size=(POWER_DRAWS, n))
    ranks = np.arange(1, n + 1)

    def found(shift: float) -> float:
        d = z + shift
        order = np.argsort(np.abs(d), axis=1)
        w = np.sum(np.where(np.take_along_axis(d, order, 1) > 0, ranks, 0), axis=1)
        return float(np.mean(p[w] < alpha))

    approx = (sps.norm.ppf(1 - alpha / 2) + sps.norm.ppf(power)) / math.sqrt(3 * n / math.pi)
    lo, hi = 0.5 * approx, 2 * approx
    while found(hi) < power:
        lo, hi = hi, 2 * hi
    for _ in range(12):  # to 2⁻¹² of the bracket
        mid = (lo + hi) / 2
        lo, hi = (lo, mid) if found(mid) >= power else (mid, hi)
    return float(hi)
