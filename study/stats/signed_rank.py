"""The two-sided Wilcoxon signed-rank p-value of paired differences (:func:`study.stats.paired`), scipy's
to the bit, with its exact permutation branch as one matrix product."""

from __future__ import annotations

import functools

import numpy as np
from scipy import stats as sps

#: Above this many differences with ties or zeros, scipy's Wilcoxon leaves its exact permutation test (2ⁿ sign
#: flips ≤ its 9999 resamples) for the normal approximation.
EXACT_FLIPS_MAX_N = 13


@functools.lru_cache(maxsize=EXACT_FLIPS_MAX_N + 1)
def _sign_flips(n: int) -> np.ndarray:
    """All 2ⁿ sign patterns of n differences (2ⁿ × n of ±1.0)."""
    return 1.0 - 2.0 * ((np.arange(2**n)[:, None] >> np.arange(n)) & 1)


def wilcoxon_p(d) -> float:
    """The two-sided Wilcoxon signed-rank p-value of the differences ``d`` (some nonzero), zero differences split
    between the ranks: ``scipy.stats.wilcoxon(d, zero_method="zsplit").pvalue`` to the bit. Where scipy runs its
    exact permutation test (ties or zeros, n ≤ :data:`EXACT_FLIPS_MAX_N`) the 2ⁿ sign flips are one matrix
    product here (scipy calls its statistic once per flip: most of `study report`'s time); elsewhere (exact null
    distribution without ties, normal approximation above 50 or with ties above 13) it is scipy's own call."""
    d = np.asarray(d, float)
    n = d.size
    r = sps.rankdata(np.abs(d))
    zero = d == 0
    if n > EXACT_FLIPS_MAX_N or not (zero.any() or np.unique(r).size < n):
        return float(sps.wilcoxon(d, zero_method="zsplit").pvalue)
    half = float(np.sum(r[zero]) / 2)
    observed = float(np.sum(r[d > 0])) + half
    null = ((d * _sign_flips(n)) > 0) @ r + half  # r⁺ under every sign flip (multiples of ¼: exact sums)
    gamma = abs(np.finfo(float).eps * 100 * observed)  # scipy.stats.permutation_test's tolerance
    less = np.count_nonzero(null <= observed + gamma) / null.size
    greater = np.count_nonzero(null >= observed - gamma) / null.size
    return float(np.clip(2 * min(less, greater), 0.0, 1.0))
