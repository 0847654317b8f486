"""A column's calibrated 95 % interval within one case, as the declared column table names it
(:func:`study.columns.interval_bounds`), and the per-case separations of two methods read from it."""

from __future__ import annotations

import math

from study import columns
from study.report import geometry
from study.report.power import WRONG


def bounds(row: dict, col: str) -> tuple[float, float]:
    """The calibrated 95 % interval of ``col`` in one row: the ``_lo``/``_hi`` the declared column table names
    (:func:`study.columns.interval_bounds`; an infinite end kept: one-sided), else (NaN, NaN) — never one made from
    counts (Wilson's over independent rays covered 24 % where rays share texels: reports/calibration.md)."""
    names = columns.interval_bounds(col)
    if names is None:
        return math.nan, math.nan
    lo, hi = row.get(names[0], math.nan), row.get(names[1], math.nan)
    ok = all(isinstance(v, int | float) and not math.isnan(v) for v in (lo, hi))  # inf: a one-sided bound
    return (float(lo), float(hi)) if ok else (math.nan, math.nan)


fraction_bounds = bounds  # a fraction's interval: the name the claims read


def separated(tab: list[dict], a: str, b: str, col: str = WRONG) -> tuple[int, int, int]:
    """(cases where a's interval lies wholly below b's, cases where wholly above, cases compared), one case per
    geometry (:func:`study.report.geometry.pooled`)."""
    tab = geometry.pooled(tab)
    rows = {(r["case"], r["label"]): r for r in tab}
    below = above = n = 0
    for c in dict.fromkeys(r["case"] for r in tab):
        ra, rb = rows.get((c, a)), rows.get((c, b))
        if ra is None or rb is None:
            continue
        (alo, ahi), (blo, bhi) = bounds(ra, col), bounds(rb, col)
        if any(math.isnan(v) for v in (alo, ahi, blo, bhi)):
            continue
        n += 1
        below += ahi < blo
        above += alo > bhi
    return below, above, n
