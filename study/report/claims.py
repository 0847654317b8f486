"""The paper's claims as checks over results tables: each gives ✓/✗, the subset of rays or pixels it was judged
on, how many, and the number behind it with its interval.

A claim reads the rows of one table (a figure's metrics.csv or a sweep's results.csv) and returns a
:class:`Verdict`; a claim whose table lacks the rows it needs returns ``None`` (not applicable). Each claim is judged
on the rays or pixels it is about (hidden hits, pixels whose hits the views hold, convex rooms, cases off the
reference point) and on tails — wrong fractions with their calibrated intervals (the declared column table's,
:func:`study.report.intervals.bounds`), 95th percentiles — not on medians. A claim fails only where the evidence
says so ("fails: …"); where it decides neither way the verdict is "undecided at this sample size". Comparisons of
two methods on the same rays are paired over the cases (:func:`study.report.verdicts.decide`); a case is a
geometry (its seeds pooled).
"""

from __future__ import annotations

import itertools

import numpy as np

from study.report import geometry
from study.report.claims_convergence import _ladder, converges_occluded, converges_quickly
from study.report.claims_glossy import glossy_converges, glossy_localized
from study.report.intervals import bounds, fraction_bounds
from study.report.power import MIN_HIDDEN, counts
from study.report.verdicts import (
    Claim,
    Verdict,
    _cases,
    _ci,
    _convex,
    _default,
    _finite,
    _get,
    _measured,
    _row,
    _verdict,
    decide,
    pair,
)


def localized_beats_classical(rows):
    """In every case off the reference point (object centre ≠ reference point) localized (default: 10 iterations)
    is wrong (ε = max(1 cm, one texel)) on fewer rays than classical (:func:`~study.report.verdicts.decide`: the
    calibrated intervals of the same rays per case, and paired over the cases)."""
    lab = _default("localized")
    pairs = []
    for c in _cases(rows):
        b = _row(rows, c, "classical")
        if b is None or not b.get("displacement"):
            continue
        if (pr := pair(rows, c, lab, "classical", "wrong_fraction")) is not None:
            pairs.append(pr)
    if not pairs:
        return None
    ok, text = decide(pairs)
    w = min(pairs, key=lambda p: p.b_ci[0] - p.a_ci[1] if np.isfinite(p.b_ci[0] - p.a_ci[1]) else p.b - p.a)
    return _verdict(
        ok,
        "all rays, cases off the reference point",
        f"{len(pairs)} cases, {sum(counts(_row(rows, p.case, lab))[0] for p in pairs):.0f} rays",
        f"localized {text}; closest case {w.case}: wrong fraction localized {w.a:.3g} [{w.a_ci[0]:.3g}–"
        f"{w.a_ci[1]:.3g}] vs classical {w.b:.3g} [{w.b_ci[0]:.3g}–{w.b_ci[1]:.3g}]",
    )


def iterations_do_not_hurt(rows):
    """In a convex room the 95th percentile of the angular error does not rise from 1 to 10 iterations beyond its
    interval (false position 'converges surely')."""
    pairs = [(c, m[1], m[10]) for c, m in _ladder(rows, "angle_p95_deg") if 1 in m and 10 in m]
    if not pairs:
        return None
    col = "angle_p95_deg"
    ci = [(bounds(a, col), bounds(b, col)) for _, a, b in pairs]
    bad = [p for p, ((_, ahi), (blo, _)) in zip(pairs, ci) if blo > ahi * 1.001 + 1e-6]
    blind = sum(np.isnan([*x, *y]).any() for x, y in ci)  # no calibrated interval (inf: one-sided, kept)
    c, a, b = max(pairs, key=lambda p: p[2][col] / max(p[1][col], 1e-12))
    return _verdict(
        False if bad else (None if blind else True),
        "all rays, convex cases (no hidden hit), exact secondary rays",
        f"{len(pairs)} cases, {sum(counts(p[2])[0] for p in pairs):.0f} rays",
        f"{len(bad)} rising beyond the interval"
        + (f", {blind} without an interval" if blind else "")
        + f"; largest 10-it/1-it ratio of p95 {b[col]:.3g}° [{bounds(b, col)[0]:.3g}–{bounds(b, col)[1]:.3g}] vs "
        f"{a[col]:.3g}° ({c})",
    )


def occlusion_breaks_it(rows):
    """'should the ray hit a point that is not visible from the reference point … the approximation scheme would
    obviously be unable to find that': on the rays whose exact hit is hidden from the reference point localized(10)
    is wrong more often than on the others (:func:`~study.report.verdicts.decide`, visible against hidden rays of
    each case: their calibrated intervals, and paired over the cases), in every case with at least
    :data:`~study.report.power.MIN_HIDDEN` hidden rays."""
    lab, pairs = _default("localized"), []
    for c in _cases(rows):
        if _hidden_rays(rows, c, lab) < MIN_HIDDEN:
            continue
        if (pr := pair(rows, c, lab, lab, "wrong_fraction_visible", "wrong_fraction_hidden")) is not None:
            pairs.append(pr)
    if not pairs:
        return None
    ok, text = decide(pairs)
    w = min(pairs, key=lambda p: p.b_ci[0] - p.a_ci[1] if np.isfinite(p.b_ci[0] - p.a_ci[1]) else p.b - p.a)
    return _verdict(
        ok,
        "hidden vs visible rays, cases with ≥ 200 hidden rays",
        f"{len(pairs)} cases, {sum(_hidden_rays(rows, p.case, lab) for p in pairs):.0f} hidden rays",
        f"visible rays' wrong fraction {text}; closest case {w.case}: wrong on hidden {w.b:.3g} "
        f"[{w.b_ci[0]:.3g}–{w.b_ci[1]:.3g}] vs visible {w.a:.3g} [{w.a_ci[0]:.3g}–{w.a_ci[1]:.3g}]"
        f"{_few(rows, lab)}",
    )


def hardly_visible(rows):
    """'these errors can hardly be recognized visually': on the pixels whose hits the views hold (where only the
    search can err), the 95th percentile of localized(10)'s per-pixel FLIP against the oracle, reported as measured
    (FLIP states no just-noticeable value; the motion sequence is judged in JOD, study.measure.video), in every
    case whose secondary rays are exact (mirrors, glass with the exact exit); glass whose exit comes from the
    object's own distance map is reported beside, as the exit's error, not the search's."""
    lab, exact, approx = _default("localized"), [], []
    for c in _cases(rows):
        r = _row(rows, c, lab)
        if r is None or not _finite(r.get("flip_oracle_p95")):
            continue
        (approx if r.get("exit") == "distance_map" else exact).append((r["flip_oracle_p95"], c, r))
    if not exact:
        return None
    v, c, r = max(exact, key=lambda e: e[0])
    side = ""
    if approx:
        va, ca, _ = max(approx, key=lambda e: e[0])
        side = f"; with the exit from the distance map (not judged): {va:.3g} ({ca})"
    return _measured(
        "pixels whose hits the views hold; exact secondary rays",
        f"{len(exact)} cases, {sum(_row(rows, e[1], lab).get('held_pixels', 0) for e in exact):.0f} pixels",
        f"worst p95 FLIP vs the oracle {v:.3g} ({c}; mean {r.get('flip_oracle', np.nan):.3g}){side}",
    )


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
    hit) on the rays whose exact hit is hidden from the reference point and on those whose hit is visible,
    measured (the paper names no fractions): the lowest wrong fraction on hidden hits and the highest on visible
    ones, in every case with at least :data:`~study.report.power.MIN_HIDDEN` hidden rays."""
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
    sure = "; the two intervals apart" if ci_h and ci_v and hi_v[1] < lo_h[0] else ""
    return _measured(
        "hidden and visible rays, cases with ≥ 200 hidden rays",
        f"{len(found)} cases, {sum(_hidden_rays(rows, f[0], lab) for f in found):.0f} hidden rays",
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
            and r.get("method") == "localized"
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
    return _verdict(
        not bad,
        "all rays, convex cases (no hidden hit), exact secondary rays",
        f"{steps} ladder steps",
        f"{steps} ladder steps in convex cases, {len(bad)} raising the wrong fraction; largest "
        f"change {d:+.2g} ({c}: {a:.3g} at {k0:g} → {b:.3g} at {k1:g} iterations)",
    )


def layered_fixes_occlusion(rows):
    """Beyond the paper: where localized(iterations=10) is wrong on the hidden hits (wrong_fraction_hidden ≥ 0.5,
    > 2 % and ≥ :data:`~study.report.power.MIN_HIDDEN` hidden rays), searching several depth layers (``layered``)
    is wrong on fewer of them, in every such case (:func:`~study.report.verdicts.decide`: the calibrated
    intervals of the same hidden rays, and paired over the cases)."""
    pairs = []
    loc, lay = _default("localized"), _default("layered")
    for c in _cases(rows):
        a = _get(rows, c, loc, "wrong_fraction_hidden")
        f = _get(rows, c, lay, "occluded_fraction")
        many = _hidden_rays(rows, c, lay) >= MIN_HIDDEN
        if _finite(a) and f is not None and f > 0.02 and a >= 0.5 and many:
            if (pr := pair(rows, c, lay, loc, "wrong_fraction_hidden")) is not None:
                pairs.append(pr)
    if not pairs:
        return None
    ok, text = decide(pairs)
    w = max(pairs, key=lambda p: p.a_ci[1] - p.b_ci[0] if np.isfinite(p.a_ci[1] - p.b_ci[0]) else p.a - p.b)
    return _verdict(
        ok,
        "hidden rays, cases with > 2 % and ≥ 200 of them",
        f"{len(pairs)} cases, {sum(_hidden_rays(rows, p.case, lay) for p in pairs):.0f} hidden rays",
        f"{len(pairs)} cases with > 2 % and ≥ {MIN_HIDDEN} hidden rays that localized gets wrong; layered {text}; "
        f"closest case {w.case}: wrong fraction on hidden hits layered {w.a:.3g}"
        f"{_ci(rows, w.case, lay, 'wrong_fraction_hidden')} vs localized {w.b:.3g}"
        f"{_ci(rows, w.case, loc, 'wrong_fraction_hidden')}",
    )


def layered_radiance(rows):
    """Beyond the paper: where layered finds the hidden hits, the radiance it shows there is as good as elsewhere —
    its RMSE against truth_at_hit on the pixels with a hit the views do not hold beside its RMSE on the others,
    measured (no threshold has a source), in every case with ≥ 50 such pixels: the case with the largest ratio."""
    lab, found = _default("layered"), []
    for c in _cases(rows):
        r = _row(rows, c, lab)
        if r is None or not r.get("unheld_pixels", 0) >= 50 or not _finite(r.get("rmse_truth_unheld")):
            continue
        found.append((r["rmse_truth_unheld"] / max(r.get("rmse_truth_held", np.nan), 1e-12), c, r))
    if not found:
        return None
    ratio, c, r = max(found, key=lambda f: f[0] if np.isfinite(f[0]) else -1)
    return _measured(
        "pixels with a hit the views do not hold vs the others, cases with ≥ 50 of them",
        f"{len(found)} cases, {sum(f[2]['unheld_pixels'] for f in found):.0f} such pixels",
        f"worst case {c}: RMSE on those pixels {r['rmse_truth_unheld']:.3g}{_ci_of(r, 'rmse_truth_unheld')} vs "
        f"{r['rmse_truth_held']:.3g}{_ci_of(r, 'rmse_truth_held')} on the others (×{ratio:.3g})",
    )


def _ci_of(r: dict, col: str) -> str:
    """' [lo–hi]' of a column's interval where the table has it (a sweep's table holds the values alone)."""
    lo, hi = bounds(r, col)  # the declared calibrated interval
    return f" [{lo:.3g}–{hi:.3g}]" if _finite(lo) and _finite(hi) else " (no interval in a sweep's table)"


#: the paper's words, quoted once (ray-tracing-effects-without-tracing-rays.txt in the shared paper folder)
SURELY = (
    "the proposed iteration method solves the ray equation with the false position root finding method, which "
    "converges surely"
)
OCCLUDED = (
    "should the ray hit a point that is not visible from the reference point of the environment map, the "
    "presented approximation scheme would obviously be unable to find that"
)
#: a comparison needs no number; a claim the paper gives no number for is measured, never given an invented one
COMPARE = "none: the two calibrated 95 % intervals per case, and the pairs over the cases (Wilcoxon, 5 %)"
NO_NUMBER = "none in the paper or a cited source: measured, no verdict"

CLAIMS = [
    Claim(
        "beats-classical",
        "Localized lookup is more accurate than classical environment mapping off the reference point (fewer "
        "wrong rays in every case)",
        "Sec. 1; Fig. 4",
        localized_beats_classical,
        quote="when the object size and the scale of its movements are comparable with the distance from the "
        "surrounding surface, errors occur, which create the impression that the object is independent of its "
        "illuminating environment",
        threshold=COMPARE,
    ),
    Claim(
        "monotone",
        "More iterations do not increase the error in a convex room (p95 angle, 1 → 10 iterations)",
        "Sec. 2 (localization)",
        iterations_do_not_hurt,
        quote=SURELY,
        threshold=COMPARE,
    ),
    Claim(
        "fast-convergence",
        "In a convex room localized's wrong fraction along its iteration ladder: the worst case per rung and the "
        "iterations after which every case is within 5 % and 1 %",
        "Fig. 4 text",
        converges_quickly,
        quote="for such scenes where the environment is convex from the reference point of the environment map, "
        "and there are larger planar surfaces, the new algorithm converges very quickly",
        threshold=NO_NUMBER + " (the 5 % and 1 % rungs are reported, not judged)",
    ),
    Claim(
        "still-fast",
        "Where the tops of columns are hidden, localized's wrong fraction along its iteration ladder (as above)",
        "Fig. 5 text",
        converges_occluded,
        quote="the convergence is still pretty fast, but the reflection of the top of the columns is not exactly "
        "what we expect",
        threshold=NO_NUMBER,
    ),
    Claim(
        "occlusion",
        "Points hidden from the reference point cannot be found: more wrong rays where they hit them",
        "Sec. 2; Fig. 5",
        occlusion_breaks_it,
        quote=OCCLUDED,
        threshold=COMPARE,
    ),
    Claim(
        "hardly-visible",
        "Remaining localization errors on still frames: p95 FLIP against the oracle where the views hold the hits "
        "(the moving, curved case is judged in JOD on the motion sequence)",
        "Sec. 2 (localization)",
        hardly_visible,
        quote="when the object is curved and moving, these errors can hardly be recognized visually",
        threshold="none for FLIP (its paper states no just-noticeable value): measured; the motion sequence uses "
        "ColorVideoVDP's JOD, where 1 JOD is the difference 75 % of observers notice (Mantiuk et al. 2024)",
    ),
    Claim(
        "hidden-wrong",
        "Wrong fractions of localized on rays whose hit is hidden from the reference point and on the others",
        "Fig. 5",
        hidden_wrong,
        quote="the algorithm can go only to the edge of the column and substitutes the reflection of the occluded "
        "points by the blurred image of the edge",
        threshold=NO_NUMBER,
    ),
    Claim(
        "monotone-wrong",
        "More iterations never raise the fraction of wrong rays in a convex room",
        "Sec. 2 (localization)",
        iterations_never_raise_wrong,
        quote=SURELY,
        threshold="a rise of more than one ray in 10⁴ fails (the tables' float rounding)",
    ),
    Claim(
        "layered",
        "Beyond the paper: layered distance maps are wrong on fewer of the hidden hits that localized gets wrong",
        "beyond the paper: related methods",
        layered_fixes_occlusion,
        threshold=COMPARE,
    ),
    Claim(
        "layered-radiance",
        "Beyond the paper: layered's radiance error on pixels whose hits the reference point cannot see, beside "
        "its error elsewhere",
        "beyond the paper: related methods",
        layered_radiance,
        threshold=NO_NUMBER,
    ),
    Claim(
        "glossy-localized",
        "Beyond the paper: on rough objects the localized, prefiltered lookup errs less than the engines' "
        "prefiltered cube map",
        "beyond the paper: glossy reflections",
        glossy_localized,
        threshold=COMPARE,
    ),
    Claim(
        "glossy-converges",
        "Beyond the paper: the stochastic glossy method converges to the lobe's truth as its samples grow",
        "beyond the paper: glossy reflections",
        glossy_converges,
        threshold="none: a fall at every step (each step as in the comparisons: intervals per case, pairs over cases)",
    ),
]


CLAIMS_BY_ID = {c.id: c for c in CLAIMS}


def judge_claims(rows: list[dict]) -> list[tuple[Claim, Verdict]]:
    """Every claim that applies to ``rows``, one case per geometry (the seeds of one pooled:
    :func:`study.report.geometry.pooled`)."""
    rows = geometry.pooled(rows)
    out = []
    for cl in CLAIMS:
        v = cl.test(rows)
        if v is not None:
            out.append((cl, v))
    return out
