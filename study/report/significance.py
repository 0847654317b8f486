"""How sure the tables let the report be, in words: the headline's "How sure" (and the README's bullet,
``scripts/headline.py --readme``) from the significance counted over distinct geometries
(:func:`study.report.summary.significance_counts`), so no significance statement is typed by hand."""

from __future__ import annotations

from study import stats
from study.outputs.markup import md_esc
from study.report.power import SIGNIFICANCE


def how_sure(counts: list[dict], names: bool = True) -> str:
    """The headline's "How sure" in words, from the rows of :func:`study.report.summary.significance_counts`;
    ``names``: list the tables (the README's bullet gives the counts alone)."""
    rows = [r for r in counts if r["runner_up"]]
    if not rows:
        return "no table compares two methods."
    n = [r["cases"] for r in rows]
    pooled = sum(r["seeds"] > 1 for r in rows)
    sig = [r for r in rows if r["p"] < SIGNIFICANCE]
    img = [r for r in rows if r["image_p"] < SIGNIFICANCE]
    few = [md_esc(r["table"]) for r in rows if stats.min_p(r["cases"]) >= SIGNIFICANCE]
    text = (
        "counted over distinct geometries (object position, scene, object; the seeds of one pooled"
        + (f", in {pooled} tables" if pooled else "")
        + f"), the tables have {min(n)}–{max(n)} cases. The best method beats the runner-up in wrong hits "
        f"significantly (Wilcoxon signed-rank over the geometries, {100 * SIGNIFICANCE:g} %) in {len(sig)} of "
        f"{len(rows)} tables"
        + (f" ({', '.join(md_esc(r['table']) for r in sig)})" if sig and names else "")
        + f", by image error (relMSE after exposure where a table has it) in {len(img)} of {len(rows)}."
    )
    if few:
        text += (
            f" {len(few)} table{'s have' if len(few) > 1 else ' has'} fewer than 6 geometries"
            + (f" ({', '.join(few)})" if names else "")
            + ": "
            "too few for any difference over cases to be significant (p ≥ 2/2ⁿ)."
        )
    return text
