"""Numbers with their uncertainty: intervals per case (over rays, over blocks of pixels), intervals over a table's
cases, paired comparisons of two methods, and the wrong fraction at tolerances with one meaning.

Resampling units (each an independent draw of the quantity a column averages):

* **rays** for per-ray columns (``wrong_fraction*``, ``angle_*``, ``dist_*``): the object's secondary rays of one
  case. Fractions get a Wilson score interval (:func:`fraction_ci`: ``scipy.stats.binomtest(k, n).proportion_ci``;
  it is what a bootstrap of a Bernoulli mean approximates and stays honest at 0 % and 100 %); percentiles get a
  distribution-free order-statistic interval over the rays (:func:`quantile_ci`, exact and cheap).
* **blocks of pixels** for image columns (``rmse_*``, ``relmse_*``, ``flip_*``, the error split's ``dec_*``): the
  object's pixels of one case, grouped into the tiles of a :data:`BLOCK_GRID` × :data:`BLOCK_GRID` grid over the
  frame (:func:`pixel_blocks`), each tile's summed error and pixel count resampled together (a block bootstrap of
  the mean: neighbouring pixels see the same surfaces, so their errors are correlated, and a wrong reflection is a
  blob of pixels, not independent evidence per pixel). The tiles are a fixed share of the frame, so the interval
  means the same at 256² and at 1024², and its cost does not grow with the resolution (:func:`pixel_columns`).
* **cases** for a table's summary: the median over cases with a bootstrap interval (:func:`over_cases`), and
  paired comparisons of two methods over the same cases (:func:`paired`: Wilcoxon signed-rank).

Rays of one pixel are not quite independent (sub-pixel rays see nearby surfaces), so the per-case intervals are a
little narrow where supersampling is high; they are meant to say which differences are noise, not to be exact.
Every bootstrap is percentile, :data:`N_RESAMPLES` resamples, seed :data:`SEED` (deterministic), level
:data:`LEVEL`.
"""

from __future__ import annotations

import functools
import math

import numpy as np
from scipy import stats as sps

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
#: Pixel intervals resample the tiles of a BLOCK_GRID × BLOCK_GRID grid over the frame (:func:`pixel_blocks`):
#: 4×4-pixel tiles at 256², 16×16 at 1024².
BLOCK_GRID = 64


# ---------------------------------------------------------------------------------------------- intervals
def pixel_blocks(mask) -> np.ndarray:
    """(P,) int: the block (tile of the :data:`BLOCK_GRID` × :data:`BLOCK_GRID` grid over the frame; square tiles
    of round(max(H, W) / BLOCK_GRID) ≥ 1 pixels) of each of the P True pixels of ``mask`` (H, W), in the order of
    ``mask``'s True pixels (``img[mask]``), numbered 0 … (blocks used − 1)."""
    mask = np.asarray(mask, bool)
    h, w = mask.shape
    t = max(1, round(max(h, w) / BLOCK_GRID))
    ys, xs = np.nonzero(mask)
    return np.unique((ys // t) * (-(-w // t)) + xs // t, return_inverse=True)[1].reshape(-1)


def mean_cis(*samples, blocks=None, level: float = LEVEL, n_resamples: int = N_RESAMPLES, seed: int = SEED):
    """[(lo, hi), …]: percentile-bootstrap intervals of the means of several samples of the same units (e.g. one
    value per pixel each), resampled together (``scipy.stats.bootstrap`` drawing the blocks, as its ``paired=True``
    does: one draw of units for all, so one pass). Units where any sample is NaN are dropped; fewer than two
    resampled units give (mean, mean).

    ``blocks``: (P,) int, the block of each unit (e.g. :func:`pixel_blocks`): blocks are resampled, not units (a
    block bootstrap: each block's sum and count drawn together, the statistic the ratio of the drawn sums to the
    drawn counts, which is the mean over the drawn units). None: every unit its own block."""
    xs = np.asarray(samples, float).reshape(len(samples), -1)
    keep = ~np.isnan(xs).any(axis=0)
    xs = xs[:, keep]
    mean = xs.mean(axis=1) if xs.shape[1] else np.full(len(samples), math.nan)
    b = np.arange(xs.shape[1]) if blocks is None else np.asarray(blocks).reshape(-1)[keep]
    _, b = np.unique(b, return_inverse=True)
    nb = int(b.max()) + 1 if b.size else 0
    if nb < 2:
        return [(float(v), float(v)) for v in mean]
    # per block: its pixel count and the summed values of each sample, (nb, 1 + k)
    table = np.stack(
        [np.bincount(b, minlength=nb)] + [np.bincount(b, weights=x, minlength=nb) for x in xs], 1
    )

    def ratio_of_drawn_sums(i, axis=-1):  # i (..., nb): drawn block numbers, one row per resample
        rows = np.asarray(i, np.intp).reshape(-1, nb)
        m = len(rows)
        drawn = np.bincount((np.arange(m)[:, None] * nb + rows).ravel(), minlength=m * nb).reshape(m, nb)
        t = drawn @ table  # (m, 1 + k): drawn counts and sums, as one matrix product
        return (t[:, 1:] / t[:, :1]).T.reshape(len(xs), *np.shape(i)[:-1])

    # scipy draws the block numbers (as its paired=True does, with the same draws), the statistic sums the drawn
    # blocks by a matrix product instead of gathering every sample: 6× faster, equal to 1e-15
    res = sps.bootstrap(
        (np.arange(nb),),
        ratio_of_drawn_sums,
        vectorized=True,
        axis=-1,
        n_resamples=n_resamples,
        batch=max(1, min(n_resamples, int(2e7 // nb))),  # the drawn-count matrix is (batch, nb)
        method="percentile",
        confidence_level=level,
        random_state=np.random.default_rng(seed),
    )
    lo, hi = np.atleast_1d(res.confidence_interval.low), np.atleast_1d(res.confidence_interval.high)
    # a constant sample has a degenerate bootstrap (NaN): its interval is its value
    return [
        (float(m if np.isnan(a) else a), float(m if np.isnan(b_) else b_)) for m, a, b_ in zip(mean, lo, hi)
    ]


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


def quantile_ci(data, p: float, level: float = LEVEL) -> tuple[float, float]:
    """Distribution-free interval of the ``p``-th percentile (0–100) of ``data`` (NaN dropped): the binomial
    order-statistic interval of ``scipy.stats.quantile_test`` (exact coverage, no resampling, O(n log n)). A bound
    the sample cannot give (too few values beyond the quantile) is ``inf`` above, NaN below; an empty sample
    (NaN, NaN)."""
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


def _frac_cols(name: str, wrong, n_only=False) -> dict:
    w = np.asarray(wrong, bool)
    k, n = int(w.sum()), int(w.size)
    out = {name: k / n if n else math.nan}
    if not n_only:
        out[f"{name}_lo"], out[f"{name}_hi"] = fraction_ci(k, n)
    return out


def ray_columns(outcomes, angle, hidden, x, exact) -> dict[str, float]:
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

    Returns
    -------
    dict
        ``n_rays``, ``n_hidden``, ``n_wrong`` (counts behind every fraction); ``wrong_fraction_texel`` (= the
        texel-relative ``wrong_fraction``: ε = max(1 cm, one texel)) with ``_lo``/``_hi``, and ``_lo``/``_hi`` of
        ``wrong_fraction_visible``/``_hidden``; ``wrong_fraction_<tol>`` for each fixed tolerance of
        :data:`TOLERANCES` (no hit = wrong), with intervals for :data:`TOLERANCES_CI`; ``wrong_fraction_0p5deg``
        (angular tolerance :data:`ANGLE_TOL_DEG` seen from x); ``angle_dropped`` / ``dist_dropped``: the share of
        rays that ``angle_*`` / ``dist_*`` leave out (no hit; for dist also points at infinity);
        ``angle_p95_all_deg``: the 95th percentile of the angle with dropped rays as infinite error (inf when more
        than 5 % are dropped); ``angle_median_deg_lo``/``_hi``, ``angle_p95_deg_lo``/``_hi``,
        ``dist_p95_lo``/``_hi``: order-statistic intervals (:func:`quantile_ci`) over the rays the statistic
        keeps.
    """
    from study.measure.outcomes import CORRECT

    c = np.asarray(outcomes.cls)
    hidden = np.asarray(hidden, bool)
    wrong = c != CORRECT
    err = error_distance(outcomes, x, exact)
    ang = np.asarray(angle, float)
    out = {"n_rays": int(c.size), "n_hidden": int(hidden.sum()), "n_wrong": int(wrong.sum())}
    out.update(_frac_cols("wrong_fraction_texel", wrong))
    for part, sel in (("visible", ~hidden), ("hidden", hidden)):
        cols = _frac_cols(f"wrong_fraction_{part}", wrong[sel])
        out.update({k: v for k, v in cols.items() if k.endswith(("_lo", "_hi"))})
    for name, tol in TOLERANCES.items():
        out.update(_frac_cols(f"wrong_fraction_{name}", err > tol, n_only=name not in TOLERANCES_CI))
    reach = np.linalg.norm(np.asarray(exact, float) - np.asarray(x, float), axis=-1)
    with np.errstate(invalid="ignore"):
        out.update(
            _frac_cols("wrong_fraction_0p5deg", ~(err <= reach * math.tan(math.radians(ANGLE_TOL_DEG))))
        )
    fa, fd = np.isfinite(ang), np.isfinite(np.asarray(outcomes.dist, float))
    out["angle_dropped"] = float(1 - fa.mean()) if c.size else math.nan
    out["dist_dropped"] = float(1 - fd.mean()) if c.size else math.nan
    full = np.where(fa, ang, np.inf)
    out["angle_p95_all_deg"] = float(np.percentile(full, 95, method="inverted_cdf")) if c.size else math.nan
    for name, v, p in (
        ("angle_median_deg", ang[fa], 50),
        ("angle_p95_deg", ang[fa], 95),
        ("dist_p95", np.asarray(outcomes.dist)[fd], 95),
    ):
        out[f"{name}_lo"], out[f"{name}_hi"] = quantile_ci(v, p)
    return out


# ---------------------------------------------------------------------------------------------- per pixel
def _mean(x, axis=-1):
    return np.mean(x, axis=axis)


def trimmed_mean(values, trim: float = TRIM) -> float:
    """The mean of ``values`` without the largest ``trim`` share of them (at least one left out)."""
    v = np.sort(np.asarray(values, float))
    drop = max(1, math.ceil(trim * v.size))
    return float(v[: v.size - drop].mean()) if v.size > drop else math.nan


def _debiased_root(mse: float, sigma: float) -> float:
    """√max(0, mse − σ²), NaN where either is NaN (``max(0.0, nan)`` is 0.0: a NaN σ would read as no error)."""
    d = mse - sigma * sigma
    return math.nan if math.isnan(d) else math.sqrt(max(0.0, d))


def pixel_columns(img, ref, *, mask, sigma: float, rel_eps: float, suffix: str = "truth", emap=None) -> dict:
    """Intervals and robust variants of one image's errors against ``ref`` over ``mask`` (unit: blocks of pixels,
    :func:`pixel_blocks`).

    Returns ``n_pixels``, ``n_blocks``; ``rmse_<suffix>_lo``/``_hi`` (block bootstrap of the mean squared error, then
    √), ``rmse_<suffix>_debiased_lo``/``_hi`` (the same bounds debiased by the reference's noise σ, taken as
    known: √max(0, b² − σ²)), ``relmse_<suffix>_lo``/``_hi`` (relMSE with ε = ``rel_eps``), ``flip_<suffix>_lo``/
    ``_hi`` (when the FLIP map ``emap`` is given); ``rmse_<suffix>_trim`` / ``rmse_<suffix>_debiased_trim``: the
    RMSE without the worst :data:`TRIM` of pixels (≥ 1 pixel); ``sqerr_top_share_<suffix>``: the share of the
    summed squared error that those worst pixels carry (near 1: the RMSE is decided by a handful of pixels)."""
    img, ref, mask = np.asarray(img, float), np.asarray(ref, float), np.asarray(mask, bool)
    d, r = (img - ref)[mask], ref[mask]
    se = np.mean(d * d, axis=-1)  # per pixel, mean over channels: mean(se) = RMSE²
    rel = np.mean(d * d / (r * r + rel_eps), axis=-1)
    blocks = pixel_blocks(mask)
    out = {"n_pixels": int(se.size), "n_blocks": int(blocks.max()) + 1 if blocks.size else 0}
    names, samples = [f"rmse_{suffix}", f"relmse_{suffix}"], [se, rel]
    if emap is not None:
        names.append(f"flip_{suffix}")
        samples.append(np.asarray(emap, float)[mask])
    cis = dict(zip(names, mean_cis(*samples, blocks=blocks)))
    lo, hi = cis.pop(f"rmse_{suffix}")
    out[f"rmse_{suffix}_lo"], out[f"rmse_{suffix}_hi"] = math.sqrt(lo), math.sqrt(hi)
    for k, b in (("lo", lo), ("hi", hi)):
        out[f"rmse_{suffix}_debiased_{k}"] = _debiased_root(b, sigma)
    for name, (a, b) in cis.items():
        out[f"{name}_lo"], out[f"{name}_hi"] = a, b
    tm = trimmed_mean(se)
    out[f"rmse_{suffix}_trim"] = math.sqrt(tm) if tm == tm else math.nan
    out[f"rmse_{suffix}_debiased_trim"] = _debiased_root(tm, sigma)
    total = float(se.sum())
    top = np.sort(se)[::-1][: max(1, math.ceil(TRIM * se.size))].sum() if se.size else math.nan
    out[f"sqerr_top_share_{suffix}"] = float(top / total) if total > 0 else math.nan
    return out


# ---------------------------------------------------------------------------------------------- over cases
def over_cases(values, statistic=np.median) -> tuple[float, float, float, int]:
    """(statistic, lo, hi, n) of the finite per-case ``values``: the bootstrap interval over cases."""
    v = np.asarray(values, float)
    v = v[np.isfinite(v)]
    if v.size == 0:
        return math.nan, math.nan, math.nan, 0
    lo, hi = bootstrap_ci(v, lambda x, axis=-1: statistic(x, axis=axis))
    return float(statistic(v)), lo, hi, int(v.size)


#: Fewer cases than this and an interval over cases is their range, not a "95 % CI": a percentile bootstrap over
#: 2–4 cases covers the truth 52–87 % of the time in simulation (with 3 cases it is just [min, max]).
MIN_CASES_CI = 10


def case_interval(values) -> tuple[float, float, float, int, str]:
    """(median, lo, hi, n, kind) of per-case values: ``kind`` "ci", the bootstrap's 95 % interval over the cases
    (:func:`over_cases`), from :data:`MIN_CASES_CI` cases on; else "range", their min and max."""
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
        out["p"] = float(sps.wilcoxon(d, zero_method="zsplit").pvalue)
    return out


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


def detectable_shift(n: int, alpha: float = 1 - LEVEL, power: float = 0.8) -> float:
    """The smallest shift of paired per-case differences, in their standard deviations, that a two-sided Wilcoxon
    signed-rank test over ``n`` cases detects at ``alpha`` with ``power`` (normal approximation, Wilcoxon's
    efficiency 3/π against the paired t-test: (z₁₋α/₂ + z_power) / √(3n/π)); ``inf`` where no p-value it can give
    reaches ``alpha`` (:func:`min_p` = 2/2ⁿ ≥ alpha: fewer than 6 cases at 5 %)."""
    if n < 1 or min_p(n) >= alpha:
        return math.inf
    return float((sps.norm.ppf(1 - alpha / 2) + sps.norm.ppf(power)) / math.sqrt(3 * n / math.pi))
