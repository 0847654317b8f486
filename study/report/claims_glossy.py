"""The claims about rough (glossy) objects, beyond the paper: registered in :data:`study.report.claims.CLAIMS`."""

from __future__ import annotations

from study.report.intervals import bounds
from study.report.verdicts import Pair, _cases, _default, _finite, _verdict, decide, pair


def glossy_localized(rows):
    """Beyond the paper, rough objects: ``localized_prefiltered`` (the lobe localized, then the roughness mip) has
    a lower noise-debiased RMSE against the lobe's truth than the engines' ``prefiltered`` lookup in every case
    (:func:`~study.report.verdicts.decide`: the calibrated intervals over the pixels of each case, and paired over
    the cases)."""
    a_lab, b_lab, m = _default("localized_prefiltered"), _default("prefiltered"), "rmse_truth_debiased"
    pairs = [p for c in _cases(rows) if (p := pair(rows, c, a_lab, b_lab, m)) is not None]
    if not pairs:
        return None
    ok, text = decide(pairs)
    w = max(pairs, key=lambda p: p.a / max(p.b, 1e-12))
    return _verdict(
        ok,
        "all object pixels, rough objects",
        f"{len(pairs)} cases",
        f"localized_prefiltered {text}; closest: {w.a:.3g} vs {w.b:.3g} ({w.case})",
    )


def glossy_converges(rows):
    """Beyond the paper, rough objects: the ``stochastic`` method's (localized) noise-debiased RMSE against the
    lobe's truth falls at every step of its sample ladder, in every case (each step judged by
    :func:`~study.report.verdicts.decide` over the cases: the calibrated intervals, and paired over the cases)."""
    ladders = {}
    for c in _cases(rows):
        ladder = sorted(
            [
                (float(r["knob_value"]), r)
                for r in rows
                if r["case"] == c
                and r.get("method") == "stochastic"
                and "localize=False" not in str(r["label"])
                and _finite(r.get("rmse_truth_debiased"))
            ],
            key=lambda t: t[0],
        )
        if len(ladder) >= 2:
            ladders[c] = ladder
    if not ladders:
        return None
    m = "rmse_truth_debiased"
    steps: dict[tuple[float, float], list[Pair]] = {}
    for c, lad in ladders.items():
        for (n0, r0), (n1, r1) in zip(lad, lad[1:]):
            steps.setdefault((n0, n1), []).append(Pair(c, r1[m], r0[m], bounds(r1, m), bounds(r0, m)))
    judged = {k: decide(v) for k, v in sorted(steps.items())}
    oks = [ok for ok, _ in judged.values()]
    ok = False if False in oks else (None if None in oks else True)
    words = "; ".join(f"N = {a:g} → {b:g}: {text}" for (a, b), (_, text) in judged.items())
    c, lad = next(iter(ladders.items()))
    ladder = " → ".join(f"{r[m]:.3g} (N={n:g})" for n, r in lad)
    return _verdict(
        ok,
        "all object pixels, rough objects",
        f"{len(ladders)} cases",
        f"the error at the larger N {words}; e.g. {c}: {ladder}",
    )
