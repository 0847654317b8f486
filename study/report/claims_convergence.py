"""The claims about the false-position search's convergence along localized's iteration ladder, registered in
:data:`study.report.claims.CLAIMS`: the paper says "converges very quickly" (Fig. 4) and "still pretty fast"
(Fig. 5) without a number, so the ladder is measured and reported, never judged against an invented threshold."""

from __future__ import annotations

import numpy as np

from study.report.intervals import fraction_bounds
from study.report.power import counts
from study.report.verdicts import _cases, _convex, _finite, _measured


def _ladder(rows, col, *, convex: bool = True):
    """(case, {iterations: row}) for localized's false-position ladder in convex cases (nothing hidden; with
    ``convex`` False: the cases with something hidden) whose secondary rays are exact (glass whose exit comes from
    its own distance map errs there, not in the search)."""
    out = []
    free = _convex(rows)
    pool = free if convex else [r for r in rows if not any(r is f for f in free)]
    conv = [r for r in pool if r.get("exit") != "distance_map"]
    for c in _cases(conv):
        rs = {
            int(r["knob_value"]): r
            for r in conv
            if r["case"] == c
            and r.get("method") == "localized"
            and r.get("family") == "localized"
            and np.isfinite(r.get("knob_value", np.nan))
            and _finite(r.get(col))
        }
        out.append((c, rs))
    return out


def _convergence(rows, *, convex: bool):
    """localized's wrong fraction along its iteration ladder, measured (the paper gives no threshold): the worst
    case at each rung with its interval, and the fewest iterations on the ladder after which every case is wrong on
    at most 5 % and 1 % of its rays and stays so (upper bounds of the intervals)."""
    cases = [(c, m) for c, m in _ladder(rows, "wrong_fraction", convex=convex) if len(m) >= 2]
    if not cases:
        return None
    rungs = sorted({k for _, m in cases for k in m})
    worst = []
    for k in rungs:
        at = [(m[k]["wrong_fraction"], c, m[k]) for c, m in cases if k in m]
        if at:
            v, c, r = max(at, key=lambda a: a[0])
            lo, hi = fraction_bounds(r, "wrong_fraction")
            worst.append(f"{k}: {v:.3g} [{lo:.3g}–{hi:.3g}] ({c})")

    def reach(level):  # the first rung from which every case stays within ``level``
        within = [
            all(fraction_bounds(m[k], "wrong_fraction")[1] <= level for _, m in cases if k in m)
            for k in rungs
        ]
        if not within[-1]:
            return f"≤ {level:.0%} not reached by {rungs[-1]} iterations"
        k = len(within) - 1
        while k > 0 and within[k - 1]:
            k -= 1
        return f"≤ {level:.0%} from {rungs[k]} iterations on"

    subset = "all rays, convex cases (no hidden hit)" if convex else "all rays, cases with hidden hits"
    return _measured(
        f"{subset}, exact secondary rays",
        f"{len(cases)} cases, {sum(counts(next(iter(m.values())))[0] for _, m in cases):.0f} rays",
        f"worst case's wrong fraction by iterations — {'; '.join(worst)}; every case: {reach(0.05)}, {reach(0.01)}",
    )


def converges_quickly(rows):
    """'for such scenes where the environment is convex from the reference point … the new algorithm converges
    very quickly': the paper gives no number, so localized's wrong fraction (ε = max(1 cm, one texel)) along its
    iteration ladder in the convex cases is reported (:func:`_convergence`), with no verdict."""
    return _convergence(rows, convex=True)


def converges_occluded(rows):
    """Fig. 5: 'the convergence is still pretty fast': the same ladder in the cases with hidden hits, measured."""
    return _convergence(rows, convex=False)
