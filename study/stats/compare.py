"""Paired comparisons of two methods over the same cases (Wilcoxon signed-rank, exact for small n) and the words
a p-value earns."""

from __future__ import annotations

import math

import numpy as np

from study.stats.intervals import LEVEL
from study.stats.signed_rank import wilcoxon_p


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
