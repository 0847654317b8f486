"""The claims about rough (glossy) objects, beyond the paper: registered in :data:`study.report.claims.CLAIMS`."""

from __future__ import annotations

from study.report.verdicts import _cases, _default, _finite, _get, _verdict


def glossy_localized(rows):
    """Beyond the paper, rough objects: ``localized_prefiltered`` (the lobe localized, then the roughness mip) has
    a lower noise-debiased RMSE against the lobe's truth than the engines' ``prefiltered`` lookup in every case;
    sure where the 95 % intervals over blocks of pixels do not overlap."""
    a_lab, b_lab, m = _default("localized_prefiltered"), _default("prefiltered"), "rmse_truth_debiased"
    pairs = [(c, _get(rows, c, a_lab, m), _get(rows, c, b_lab, m)) for c in _cases(rows)]
    pairs = [(c, a, b) for c, a, b in pairs if _finite(a) and _finite(b)]
    if not pairs:
        return None
    apart = sum(_get(rows, c, a_lab, m + "_hi") < _get(rows, c, b_lab, m + "_lo") for c, _, _ in pairs)
    c, a, b = max(pairs, key=lambda p: p[1] / max(p[2], 1e-12))
    return _verdict(
        all(a < b for _, a, b in pairs),
        "all object pixels, rough objects",
        f"{len(pairs)} cases",
        f"closest: {a:.3g} vs {b:.3g} ({c}); intervals apart in {apart} of {len(pairs)}",
    )


def glossy_converges(rows):
    """Beyond the paper, rough objects: the ``stochastic`` method's (localized) noise-debiased RMSE against the
    lobe's truth falls at every step of its sample ladder, in every case."""
    runs = []
    for c in _cases(rows):
        ladder = sorted(
            (float(r["knob_value"]), float(r["rmse_truth_debiased"]))
            for r in rows
            if r["case"] == c and r.get("method") == "stochastic" and "localize=False" not in str(r["label"])
        )
        if len(ladder) >= 2:
            runs.append((c, ladder))
    if not runs:
        return None
    bad = [c for c, lad in runs if any(b[1] >= a[1] for a, b in zip(lad, lad[1:]))]
    c, lad = runs[0]
    steps = " → ".join(f"{e:.3g} (N={n:g})" for n, e in lad)
    return _verdict(
        not bad,
        "all object pixels, rough objects",
        f"{len(runs)} cases",
        f"{len(runs) - len(bad)} of {len(runs)} cases fall at every step; e.g. {c}: {steps}",
    )
