"""The pieces every claim is judged with: a claim, its verdict (with the subset of rays or pixels it was judged on
and its n), and small lookups into a results table's rows."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from study import methods as registry
from study import stats
from study.report.intervals import bounds, fraction_bounds
from study.report.power import SIGNIFICANCE


@dataclass
class Verdict:
    ok: bool | None  # None: measured, not judged (no threshold in the paper or a cited source), or undecided
    number: str  # the evidence with its interval; "fails: …" when the claim does not hold
    subset: str = ""  # the rays or pixels the claim was judged on
    n: str = ""  # how many (cases, rays or pixels)
    undecided: bool = False  # judged, but the evidence decides neither way at this sample size


@dataclass
class Claim:
    """One claim: the paper's own words (``quote``) and place (``source``), the project's operationalisation in
    words (``text``: subset, metric, what decides) and the threshold with where it comes from (``threshold``:
    a comparison needs none; a number the paper does not give and no cited source states is never invented —
    such a claim is measured (:func:`_measured`) and its numbers reported, with no verdict)."""

    id: str
    text: str  # the operationalisation: subset of rays or pixels, metric, what decides
    source: str  # where in the paper (section, figure), or "beyond the paper: …"
    test: Callable[[list[dict]], Verdict | None]
    quote: str = ""  # the paper's words ("" for a claim beyond the paper)
    threshold: str = "none: a comparison of intervals"  # the threshold and its source


def _by(rows, **eq):
    return [r for r in rows if all(r.get(k) == v for k, v in eq.items())]


def _cases(rows):
    return list(dict.fromkeys(r["case"] for r in rows))


def _default(name: str) -> str:
    """The label of method ``name`` with its default parameters (what the claims speak of)."""
    return registry.make(name).label


def _get(rows, case, label, metric):
    hit = [r.get(metric) for r in rows if r["case"] == case and r["label"] == label]  # None: an older table
    return hit[0] if hit else None


def _ci(rows, case, label, metric) -> str:
    """' [lo–hi]': the 95 % interval over the case's rays of a fraction (``_lo``/``_hi`` or from the counts)."""
    hit = [r for r in rows if r["case"] == case and r["label"] == label]
    lo, hi = fraction_bounds(hit[0], metric) if hit else (np.nan, np.nan)
    return f" [{lo:.3g}–{hi:.3g}]" if np.isfinite(lo) and np.isfinite(hi) else ""


def _convex(rows):
    """Rows of cases without columns (the room is convex from the reference point)."""
    if rows and "axis:columns" in rows[0]:
        return [r for r in rows if r["axis:columns"] in ("none", "[]")]
    return [r for r in rows if r.get("occluded_fraction", 0) == 0]


# ---------------------------------------------------------------------------------------------- the claims
def _row(rows, case, label):
    return next((r for r in rows if r["case"] == case and r["label"] == label), None)


def _verdict(ok: bool | None, subset: str, n: str, number: str) -> Verdict:
    """✓ (``ok`` True), ✗ (False: the evidence says the claim does not hold) or undecided (None: it says neither)."""
    if ok is None:
        return Verdict(None, f"undecided at this sample size: {number}", subset, n, undecided=True)
    return Verdict(ok, number if ok else f"fails: {number}", subset, n)


@dataclass
class Pair:
    """One case of a comparison: a's and b's values of one column (lower is better) with their calibrated 95 %
    intervals (:func:`study.report.intervals.bounds`; NaN where the table has none)."""

    case: str
    a: float
    b: float
    a_ci: tuple[float, float]
    b_ci: tuple[float, float]

    @property
    def side(self) -> str:
        """ "below": a's interval wholly below b's; "above": wholly above; "overlap" (or no interval)."""
        (alo, ahi), (blo, bhi) = self.a_ci, self.b_ci
        if ahi < blo:
            return "below"
        return "above" if alo > bhi else "overlap"


def pair(rows, case, a_label, b_label, col, b_col: str | None = None) -> Pair | None:
    """The :class:`Pair` of ``col`` for labels a and b in ``case`` (b's column ``b_col`` where it differs, e.g.
    hidden against visible rays of one method); None where either value is missing."""
    ra, rb = _row(rows, case, a_label), _row(rows, case, b_label)
    b_col = b_col or col
    if ra is None or rb is None or not (_finite(ra.get(col)) and _finite(rb.get(b_col))):
        return None
    return Pair(case, float(ra[col]), float(rb[b_col]), bounds(ra, col), bounds(rb, b_col))


def decide(pairs: list[Pair]) -> tuple[bool | None, str]:
    """Is a lower than b? From each case's calibrated intervals and, paired over the cases (the same geometries;
    :func:`study.stats.paired`, Wilcoxon signed-rank), their differences: True where every case has a's
    interval wholly below b's, or none has it above and the paired test finds a lower (p < 5 %); False where the
    evidence says otherwise — a case with a's interval wholly above, or the paired test finding a higher; None
    (undecided at this sample size) else. Returns the verdict and its evidence in words."""
    sides = [p.side for p in pairs]
    below, above, over = (sides.count(k) for k in ("below", "above", "overlap"))
    cmp = stats.paired([p.a for p in pairs], [p.b for p in pairs])
    n, p = cmp["n"], cmp["p"]
    sig = p == p and p < SIGNIFICANCE
    paired = (
        f"lower in {cmp['a_better']} of {n} cases ({cmp['ties']} tied), paired over the cases p = {p:.2g}"
    )
    if n and stats.min_p(n) >= SIGNIFICANCE:
        paired += f" ({n} cases cannot reach {100 * SIGNIFICANCE:g} %)"
    text = f"{paired}; the 95 % intervals apart (below) in {below}, above in {above}, overlapping in {over}"
    if above or (sig and cmp["b_better"] > cmp["a_better"]):
        return False, text
    if below == len(pairs) or (sig and cmp["a_better"] > cmp["b_better"]):
        return True, text
    return None, text


def _measured(subset: str, n: str, number: str) -> Verdict:
    """The numbers of a claim that no sourced threshold decides: reported as measured, no verdict."""
    return Verdict(None, number, subset, n)


def verdict_mark(v: Verdict) -> str:
    """✓ holds, ✗ fails, 'undecided' (the evidence decides neither way at this sample size), 'measured' (no
    verdict: no threshold in the paper or a cited source)."""
    if v.undecided:
        return "undecided"
    return "measured" if v.ok is None else ("✓" if v.ok else "✗")


def _finite(v) -> bool:
    return v is not None and np.isfinite(v)
