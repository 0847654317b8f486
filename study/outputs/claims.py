"""The paper's claims as checks over results tables: each gives ✓/✗ and the number behind it.

A claim reads the rows of one table (a figure's metrics.csv or a sweep's results.csv) and returns a
:class:`Verdict`; a claim whose table lacks the rows it needs returns ``None`` (not applicable).
"""

from __future__ import annotations

import itertools
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from study import methods as registry
from study.outputs.power import MIN_HIDDEN, counts
from study.outputs.summary import fraction_bounds


@dataclass
class Verdict:
    ok: bool
    number: str  # the evidence, e.g. "median 0.0005° vs 39.7° at the farthest position"


@dataclass
class Claim:
    id: str
    text: str  # the claim, in the paper's words where possible
    source: str  # where in the paper
    test: Callable[[list[dict]], Verdict | None]


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


def _sure(lo_ok: bool, hi_ok: bool) -> str:
    """Whether the bounds a claim tests lie wholly on one side (``lo_ok``, ``hi_ok``: each interval decided)."""
    return (
        "; beyond the rays' uncertainty" if lo_ok and hi_ok else "; within the rays' uncertainty of the bound"
    )


def _convex(rows):
    """Rows of cases without columns (the room is convex from the reference point)."""
    if rows and "axis:columns" in rows[0]:
        return [r for r in rows if r["axis:columns"] in ("none", "[]")]
    return [r for r in rows if r.get("occluded_fraction", 0) == 0]


# ---------------------------------------------------------------------------------------------- the claims
def localized_beats_classical(rows):
    """localized (default parameters: 10 iterations) has a lower median angular error than classical in every
    case off the
    reference point (object centre ≠ reference point)."""
    worst = None
    n = 0
    for c in _cases(rows):
        loc, cla = (
            _get(rows, c, _default("localized"), "angle_median_deg"),
            _get(rows, c, "classical", "angle_median_deg"),
        )
        disp = _get(rows, c, "classical", "displacement")
        if loc is None or cla is None or not disp:
            continue
        n += 1
        ratio = loc / cla if cla > 0 else np.inf
        if worst is None or ratio > worst[0]:
            worst = (ratio, c, loc, cla)
    if worst is None:
        return None
    ratio, c, loc, cla = worst
    return Verdict(
        ratio < 1, f"{n} cases; worst ratio localized/classical {ratio:.2g} ({c}: {loc:.3g}° vs {cla:.3g}°)"
    )


def _iteration_medians(rows):
    """(case, {iterations: median}) for localized (its knob is the false-position step count) in convex cases."""
    out = []
    conv = _convex(rows)
    for c in _cases(conv):
        meds = {
            int(r["knob_value"]): r["angle_median_deg"]
            for r in conv
            if r["case"] == c
            and r["method"] == "localized"
            and r.get("family") == "localized"
            and np.isfinite(r.get("knob_value", np.nan))
        }
        out.append((c, meds))
    return out


def iterations_do_not_hurt(rows):
    """In a convex room the median error does not rise from 1 to 10 iterations (false position 'converges
    surely')."""
    pairs = [(c, m[1], m[10]) for c, m in _iteration_medians(rows) if 1 in m and 10 in m]
    if not pairs:
        return None
    bad = [(c, a, b) for c, a, b in pairs if b > a * 1.001 + 1e-6]
    worst = max(pairs, key=lambda p: p[2] / max(p[1], 1e-12))
    return Verdict(
        not bad,
        f"{len(pairs)} convex cases, {len(bad)} rising; largest 10-it/1-it ratio "
        f"{worst[2] / max(worst[1], 1e-12):.2g} ({worst[0]})",
    )


def converges_quickly(rows):
    """'for such scenes where the environment is convex from the reference point … the new algorithm converges
    very quickly': with 3 iterations the median error is below 0.05° in every convex case."""
    meds = [(c, m[3]) for c, m in _iteration_medians(rows) if 3 in m]
    if not meds:
        return None
    c, worst = max(meds, key=lambda p: p[1])
    return Verdict(
        worst < 0.05, f"{len(meds)} convex cases; largest median at 3 iterations {worst:.3g}° ({c})"
    )


def occlusion_breaks_it(rows):
    """'should the ray hit a point that is not visible from the reference point … the approximation scheme would
    obviously be unable to find that': where rays hit points hidden from the reference point, localized(10)
    shows a larger image error against the oracle than where nothing is hidden."""
    occ, free = [], []
    for c in _cases(rows):
        e = _get(rows, c, _default("localized"), "rmse_oracle")
        f = _get(rows, c, _default("localized"), "occluded_fraction")
        if e is None:
            continue
        (occ if f > 0.02 else free).append(e)
    if not occ or not free:
        return None
    return Verdict(
        np.median(occ) > np.median(free),
        f"median RMSE vs oracle {np.median(occ):.3g} with > 2 % hidden rays ({len(occ)} cases) vs "
        f"{np.median(free):.3g} without ({len(free)} cases)",
    )


def hardly_visible(rows):
    """'these errors can hardly be recognized visually': localized(10) is as close to the path-traced image as
    the oracle (perfect localization) is — its FLIP against Mitsuba within 0.01 of the oracle's, in cases where
    nothing is hidden from the reference point."""
    diffs = []
    for c in _cases(rows):
        a = _get(rows, c, _default("localized"), "flip_mitsuba")
        b = _get(rows, c, "oracle_map", "flip_mitsuba")
        f = _get(rows, c, "oracle_map", "occluded_fraction")
        if _finite(a) and _finite(b) and f == 0:  # a table without FLIP against Mitsuba: not judged
            diffs.append((a - b, c))
    if not diffs:
        return None
    d, c = max(diffs)
    return Verdict(d <= 0.01, f"{len(diffs)} cases; largest FLIP excess over the oracle {d:.3g} ({c})")


def _finite(v) -> bool:
    return v is not None and np.isfinite(v)


def _hidden_rays(rows, case, label) -> float:
    """The rays of a case whose exact hit is hidden from the reference point (``n_hidden``, or from fractions)."""
    hit = [r for r in rows if r["case"] == case and r["label"] == label]
    return counts(hit[0])[1] if hit else np.nan


def _few(rows, label) -> str:
    """', k more with 1–199 hidden rays left out' (the cases too small for a claim about hidden hits)."""
    k = sum(0 < _hidden_rays(rows, c, label) < MIN_HIDDEN for c in _cases(rows))
    return f"; {k} more with 1–{MIN_HIDDEN - 1} hidden rays left out" if k else ""


def hidden_wrong(rows):
    """The outcome classes of Fig. 5: localized(10) is wrong (not within ε = max(1 cm, one texel) of the exact
    hit) on almost every ray whose exact hit is hidden from the reference point (wrong_fraction_hidden ≥ 0.9) and
    on almost no ray whose hit is visible (wrong_fraction_visible ≤ 0.05), in every case with at least
    :data:`~study.outputs.power.MIN_HIDDEN` hidden rays (fewer cannot tell 90 % from much less)."""
    found = []
    for c in _cases(rows):
        hid = _get(rows, c, _default("localized"), "wrong_fraction_hidden")
        vis = _get(rows, c, _default("localized"), "wrong_fraction_visible")
        if _finite(hid) and _finite(vis) and _hidden_rays(rows, c, _default("localized")) >= MIN_HIDDEN:
            found.append((c, hid, vis))
    if not found:
        return None
    c_h, low, _ = min(found, key=lambda f: f[1])
    c_v, _, high = max(found, key=lambda f: f[2])
    lab = _default("localized")
    ci_h, ci_v = _ci(rows, c_h, lab, "wrong_fraction_hidden"), _ci(rows, c_v, lab, "wrong_fraction_visible")
    lo_h = fraction_bounds(
        next(r for r in rows if r["case"] == c_h and r["label"] == lab), "wrong_fraction_hidden"
    )
    hi_v = fraction_bounds(
        next(r for r in rows if r["case"] == c_v and r["label"] == lab), "wrong_fraction_visible"
    )
    sure = (
        _sure((lo_h[0] >= 0.9) == (lo_h[1] >= 0.9), (hi_v[0] <= 0.05) == (hi_v[1] <= 0.05))
        if ci_h and ci_v
        else ""
    )
    return Verdict(
        low >= 0.9 and high <= 0.05,
        f"{len(found)} cases with ≥ {MIN_HIDDEN} hidden rays; lowest wrong fraction on hidden hits {low:.3g}{ci_h} "
        f"({c_h}), highest on visible hits {high:.3g}{ci_v} ({c_v}){sure}{_few(rows, lab)}",
    )


def iterations_never_raise_wrong(rows):
    """In a convex room every further step on localized's iteration ladder leaves the fraction of wrong rays
    where it was or lowers it (up to one ray in 10⁴)."""
    conv = _convex(rows)
    steps, bad, worst = 0, [], None
    for c in _cases(conv):
        wf = sorted(
            (r["knob_value"], r["wrong_fraction"])
            for r in conv
            if r["case"] == c
            and r["method"] == "localized"
            and r.get("family") == "localized"
            and np.isfinite(r.get("knob_value", np.nan))
            and _finite(r.get("wrong_fraction"))
        )
        for (k0, a), (k1, b) in itertools.pairwise(wf):
            steps += 1
            rise = (b - a, c, k0, k1, a, b)
            worst = rise if worst is None or rise > worst else worst
            if b > a + 1e-4:
                bad.append(rise)
    if not steps:
        return None
    d, c, k0, k1, a, b = worst
    return Verdict(
        not bad,
        f"{steps} ladder steps in convex cases, {len(bad)} raising the wrong fraction; largest "
        f"change {d:+.2g} ({c}: {a:.3g} at {k0:g} → {b:.3g} at {k1:g} iterations)",
    )


def layered_fixes_occlusion(rows):
    """Beyond the paper: where localized(iterations=10) is wrong on the hidden hits (wrong_fraction_hidden ≥ 0.5,
    > 2 % and ≥ :data:`~study.outputs.power.MIN_HIDDEN` hidden rays), searching several depth layers (``layered``)
    is wrong on at most 5 % of them."""
    pairs = []
    for c in _cases(rows):
        a = _get(rows, c, _default("localized"), "wrong_fraction_hidden")
        b = _get(rows, c, _default("layered"), "wrong_fraction_hidden")
        f = _get(rows, c, _default("layered"), "occluded_fraction")
        many = _hidden_rays(rows, c, _default("layered")) >= MIN_HIDDEN
        if _finite(a) and _finite(b) and f is not None and f > 0.02 and a >= 0.5 and many:
            pairs.append((b, c, a))
    if not pairs:
        return None
    b, c, a = max(pairs)
    lab = _default("layered")
    ci = _ci(rows, c, lab, "wrong_fraction_hidden")
    lo, hi = fraction_bounds(
        next(r for r in rows if r["case"] == c and r["label"] == lab), "wrong_fraction_hidden"
    )
    sure = _sure((lo <= 0.05) == (hi <= 0.05), True) if ci else ""
    return Verdict(
        b <= 0.05,
        f"{len(pairs)} cases with > 2 % and ≥ {MIN_HIDDEN} hidden rays that localized gets wrong; worst wrong "
        f"fraction on hidden hits: layered {b:.3g}{ci} vs localized {a:.3g} ({c}){sure}",
    )


CLAIMS = [
    Claim(
        "beats-classical",
        "Localized lookup is more accurate than classical environment mapping off the reference point",
        "Fig. 4",
        localized_beats_classical,
    ),
    Claim(
        "monotone",
        "More iterations do not increase the error in a convex room (false position converges)",
        "Sec. 'Localization', Fig. 4",
        iterations_do_not_hurt,
    ),
    Claim(
        "fast-convergence",
        "In a convex room the search converges very quickly (3 iterations: median < 0.05°)",
        "Fig. 4 text",
        converges_quickly,
    ),
    Claim(
        "occlusion",
        "Points hidden from the reference point cannot be found: larger error where rays hit them",
        "Fig. 5",
        occlusion_breaks_it,
    ),
    Claim(
        "hardly-visible",
        "Remaining localization errors are hardly visible (FLIP within 0.01 of a perfect localization)",
        "Sec. 'Localization'",
        hardly_visible,
    ),
    Claim(
        "hidden-wrong",
        "Hidden hits are wrong, visible ones right: localized is wrong on ≥ 90 % of the rays "
        "whose hit is hidden from the reference point and on ≤ 5 % of the others",
        "Fig. 5",
        hidden_wrong,
    ),
    Claim(
        "monotone-wrong",
        "More iterations never raise the fraction of wrong rays in a convex room",
        "Sec. 'Localization'",
        iterations_never_raise_wrong,
    ),
    Claim(
        "layered",
        "Beyond the paper: layered distance maps are wrong on ≤ 5 % of the hidden hits that "
        "localized gets wrong",
        "beyond the paper: related methods",
        layered_fixes_occlusion,
    ),
]


def judge_claims(rows: list[dict]) -> list[tuple[Claim, Verdict]]:
    """Every claim that applies to ``rows``."""
    out = []
    for cl in CLAIMS:
        v = cl.test(rows)
        if v is not None:
            out.append((cl, v))
    return out
