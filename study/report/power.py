"""How much a results table can tell: per table the cases, the object rays and hidden rays per case, and the
smallest difference in wrong fraction it could detect (two-sided 5 %, 80 % power;
:func:`study.stats.detectable_fraction` within a case over its rays,
:func:`study.stats.detectable_shift` over the cases), for the report's summary
(:func:`study.report.summary.headline_blocks`). Claims about hidden hits should rest on cases with at least
:data:`MIN_HIDDEN` hidden rays.
"""

from __future__ import annotations

import math

import numpy as np

from study import columns, stats
from study.report import geometry
from study.tables import REFERENCE_ROWS

#: The significance level of every test in the report: what the intervals' confidence (stats.LEVEL, 95 %) leaves.
SIGNIFICANCE = round(1 - stats.LEVEL, 12)
POWER = 0.8
#: Fewest hidden rays per case for a claim about hidden hits (wrong_fraction_hidden) to rest on.
MIN_HIDDEN = 200
WRONG = "wrong_fraction"

#: The columns of :func:`row`.
POWER_COLUMNS = columns.table_columns("power")  # study/column_tables.py


def _pct(v: float) -> str:
    return "–" if not v == v else f"{100 * v:.3g} %"


def _num(row: dict, col: str) -> float:
    v = row.get(col, math.nan)
    return float(v) if isinstance(v, (int, float)) and math.isfinite(v) else math.nan


def _values(tab: list[dict], label: str, col: str, cases: list[str]) -> np.ndarray:
    by = {r["case"]: r.get(col, math.nan) for r in tab if r["label"] == label}
    return np.array([float(by.get(c, math.nan)) for c in cases], float)


def counts(row: dict) -> tuple[float, float]:
    """(object rays, hidden rays) of one row: ``n_rays``/``n_hidden``, or ``rays`` × ``hidden_fraction`` (or
    ``occluded_fraction``) in tables written before those columns."""
    n = _num(row, "n_rays")
    n = n if math.isfinite(n) else _num(row, "rays")
    h = _num(row, "n_hidden")
    if not math.isfinite(h):
        f = _num(row, "hidden_fraction")
        h = n * (f if math.isfinite(f) else _num(row, "occluded_fraction"))
    return n, h


def _finite(v: np.ndarray, f) -> float:
    return float(f(v)) if np.isfinite(v).any() else math.nan


def row(name: str, tab: list[dict], rank: list[dict]) -> dict:
    """One table's sample sizes and detectable differences (:data:`POWER_COLUMNS`); ``rank``: its methods by median
    wrong fraction (:func:`study.report.summary.ranking`), best first. ``rays_min``/``rays_median`` and
    ``hidden_min``/``_max`` per case; ``hidden_cases``: cases with ≥ :data:`MIN_HIDDEN` hidden rays; ``mdd_rays``:
    the smallest rise above the best's median wrong fraction (``best_wrong``) one case detects over its fewest
    rays; ``mdd_hidden``: the same over the fewest hidden rays of the ``hidden_cases``, at the best's median hidden
    wrong fraction; ``mdd_cases_sd``: over the cases, in standard deviations of the per-case differences (``inf``:
    too few cases ever to reach 5 %), and ``mdd_cases`` in wrong fraction with the standard deviation of the
    differences between the best and the runner-up. Cases are distinct geometries: the seeds of one are pooled
    first (:func:`study.report.geometry.pooled`); ``seeds`` says how many per geometry."""
    seeds = geometry.seeds_per_geometry(tab)
    tab = geometry.pooled(tab)
    cases = list(dict.fromkeys(r["case"] for r in tab))
    first: dict = {}
    for r in tab:
        if r["label"] not in REFERENCE_ROWS:
            first.setdefault(r["case"], r)
    rays, hidden = np.array([counts(first[c]) for c in cases if c in first], float).reshape(-1, 2).T
    best = rank[0]
    many = hidden[np.isfinite(hidden) & (hidden >= MIN_HIDDEN)]
    hid_wrong = _finite(_values(tab, best["label"], f"{WRONG}_hidden", cases), np.nanmedian)
    sd = math.nan
    if len(rank) > 1:
        d = _values(tab, best["label"], WRONG, cases) - _values(tab, rank[1]["label"], WRONG, cases)
        d = d[np.isfinite(d)]
        sd = float(np.std(d, ddof=1)) if d.size > 1 else math.nan
    shift = stats.detectable_shift(best["n"], SIGNIFICANCE, POWER)
    return {
        "table": name,
        "cases": best["n"],
        "seeds": seeds,
        "rays_min": _finite(rays, np.nanmin),
        "rays_median": _finite(rays, np.nanmedian),
        "hidden_min": _finite(hidden, np.nanmin),
        "hidden_max": _finite(hidden, np.nanmax),
        "hidden_cases": int(many.size),
        "best_wrong": best["median"],
        "mdd_rays": stats.detectable_fraction(_finite(rays, np.nanmin), best["median"], SIGNIFICANCE, POWER),
        "mdd_hidden": stats.detectable_fraction(float(many.min()), hid_wrong, SIGNIFICANCE, POWER)
        if many.size and math.isfinite(hid_wrong)
        else math.nan,
        "mdd_cases_sd": shift,
        "mdd_cases": shift * sd if math.isfinite(shift) else math.inf,
    }


def detectable(tab: list[dict], a: str, b: str, col: str) -> float:
    """The smallest difference in ``col`` between methods a and b that the table's cases could detect
    (:func:`study.stats.detectable_difference`: 80 % power, 5 %, from the spread of the per-case
    differences over the geometries: the seeds of one pooled, :func:`study.report.geometry.pooled`)."""
    tab = geometry.pooled(tab)
    cases = list(dict.fromkeys(r["case"] for r in tab))
    return stats.detectable_difference(
        _values(tab, a, col, cases), _values(tab, b, col, cases), SIGNIFICANCE, POWER
    )


def sentence(r: dict) -> str:
    """One table's sample sizes and detectable differences in words (a :func:`row`)."""
    n = r["cases"]
    pool = f" (distinct geometries, {r['seeds']} seeds each pooled)" if r.get("seeds", 1) > 1 else ""
    text = (
        f"**{r['table']}**: {n} case{'s' if n != 1 else ''}{pool}, {r['rays_min']:.0f}–{r['rays_median']:.0f} object "
        f"rays per case (fewest–median); within one case a wrong fraction {_pct(r['mdd_rays'])} above the best's "
        f"{_pct(r['best_wrong'])} is detectable"
    )
    if r["hidden_cases"]:
        text += (
            f"; {r['hidden_cases']} case(s) with ≥ {MIN_HIDDEN} hidden rays, there a difference of "
            f"{_pct(r['mdd_hidden'])} in wrong hidden hits"
        )
    elif math.isfinite(r["hidden_max"]) and r["hidden_max"] > 0:
        text += f"; at most {r['hidden_max']:.0f} hidden rays per case, too few for claims about hidden hits"
    if math.isinf(r["mdd_cases_sd"]):
        text += (
            f"; {n} cases are too few for any difference over cases to reach {100 * SIGNIFICANCE:g} % (2/2ⁿ)"
        )
    else:
        text += f"; over the cases a shift of {r['mdd_cases_sd']:.2g} standard deviations of the per-case differences"
        text += f" (≈ {_pct(r['mdd_cases'])})" if math.isfinite(r["mdd_cases"]) else ""
    return text + "."


def power_blocks(rows: list[dict]) -> list[tuple]:
    """The report blocks: a heading, what the numbers mean, one sentence and one table row per table."""
    if not rows:
        return []
    return [
        ("h", 3, "Sample sizes and the smallest detectable differences"),
        (
            "p",
            f"Per table: the cases, the object rays and hidden rays per case, and the smallest difference in wrong "
            f"fraction the table could detect (two-sided {100 * SIGNIFICANCE:g} %, {100 * POWER:g} % power): within "
            "one case over its fewest rays (two fractions, arcsine effect size, from the best method's median), over "
            f"the hidden rays of the cases with ≥ {MIN_HIDDEN} of them, and over the cases (Wilcoxon signed-rank: "
            "in standard deviations of the per-case differences, and in wrong fraction with those of the best "
            "method and the runner-up; with n cases its smallest p is 2/2ⁿ).",
        ),
        ("list", [sentence(r) for r in rows]),
        ("table", rows, POWER_COLUMNS),
    ]
