"""The pieces every claim is judged with: a claim, its verdict (with the subset of rays or pixels it was judged on
and its n), and small lookups into a results table's rows."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from study import methods as registry
from study.report.summary import fraction_bounds


@dataclass
class Verdict:
    ok: bool | None  # None: measured, not judged (no threshold in the paper or a cited source)
    number: str  # the evidence with its interval; "fails: …" when the claim does not hold
    subset: str = ""  # the rays or pixels the claim was judged on
    n: str = ""  # how many (cases, rays or pixels)


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


def _verdict(ok: bool, subset: str, n: str, number: str) -> Verdict:
    return Verdict(ok, number if ok else f"fails: {number}", subset, n)


def _measured(subset: str, n: str, number: str) -> Verdict:
    """The numbers of a claim that no sourced threshold decides: reported as measured, no verdict."""
    return Verdict(None, number, subset, n)


def verdict_mark(v: Verdict) -> str:
    """✓ holds, ✗ fails, 'measured' (no verdict: no threshold in the paper or a cited source)."""
    return "measured" if v.ok is None else ("✓" if v.ok else "✗")


def _finite(v) -> bool:
    return v is not None and np.isfinite(v)
