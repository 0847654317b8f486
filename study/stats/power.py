"""Power: the smallest difference a comparison detects at a level with a power (a fraction over rays, a shift of
paired per-case differences under the Wilcoxon signed-rank test)."""

from __future__ import annotations

import functools
import math

import numpy as np
from scipy import stats as sps

from study.stats.compare import min_p
from study.stats.intervals import LEVEL, SEED


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
