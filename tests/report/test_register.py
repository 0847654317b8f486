"""The claims register (study/report/register.py → reports/claims.md): every claim with its quote, place,
operationalisation and threshold, and per table its verdict — ✓, ✗, or 'measured' where no sourced threshold
decides."""

import re
from pathlib import Path

from study.report import claims, register

PAPER = Path(__file__).resolve().parents[3] / "shared/paper/ray-tracing-effects-without-tracing-rays.txt"


def _ci(w: float) -> dict:
    """wrong_fraction's calibrated interval (wrong_fraction_texel's), ± 0.02 about it."""
    return {"wrong_fraction": w, "wrong_fraction_texel_lo": w - 0.02, "wrong_fraction_texel_hi": w + 0.02}


def _tables():
    loc, cls = claims._default("localized"), "classical"
    base = {"n_rays": 10_000.0, "occluded_fraction": 0.0, "displacement": 0.3}
    good = [
        base | {"case": "p1", "label": loc, "flip_oracle_p95": 0.02, "held_pixels": 500} | _ci(0.03),
        base | {"case": "p1", "label": cls} | _ci(0.9),
    ]
    bad = [
        base | {"case": "p1", "label": loc} | _ci(0.95),
        base | {"case": "p1", "label": cls} | _ci(0.1),
    ]
    close = [  # within each other's intervals: the evidence decides neither way
        base | {"case": "p1", "label": loc} | _ci(0.10),
        base | {"case": "p1", "label": cls} | _ci(0.12),
    ]
    return {"fig_good": good, "fig_bad": bad, "fig_close": close}


def test_register_lists_every_claim_with_its_words_and_verdicts():
    text = register.register_markdown(
        _tables(), ["localized: 9.7 JOD … the claim holds"], "From bench: 0.05 ms"
    )
    for c in claims.CLAIMS:
        assert f"## {c.id} ({c.source})" in text
        assert not c.quote or f"> “{c.quote}”" in text
    # beats-classical holds on one table and fails on the other; hardly-visible is measured, never judged
    assert "| beats-classical | Sec. 1; Fig. 4 | ✓ 1, ✗ 1, undecided 1 of 3 tables |" in text
    assert re.search(r"\| hardly-visible \| [^|]+ \| measured 1 of 1 tables \|", text)
    assert "| fig\\_bad | ✗ |" in text and "| fig\\_good | measured |" in text
    assert "| fig\\_close | undecided |" in text
    assert "9.7 JOD" in text and "From bench: 0.05 ms" in text


def test_bench_sentence_reads_the_close_up_rows(tmp_path):
    csv = tmp_path / "bench-gpu.csv"
    csv.write_text(
        "label,batch,path,ms_per_frame\n"
        'localized(iterations=10),"fig4 close-up (1, 1, 1) 1024²",,0.05\n'
        'exact: Mitsuba cuda_ad_rgb,"fig4 close-up (1, 1, 1) 1024²",ray_test,0.14\n'
        'exact: Mitsuba cuda_ad_rgb,"fig4 close-up (1, 1, 1) 1024²",ray_intersect,0.16\n'
        "localized(iterations=10),synthetic 1048576,,0.01\n"
    )
    s = register.bench_sentence(csv)
    assert "in 0.05 ms (400× within" in s and "(ray_test) takes 0.14 ms" in s
    assert register.bench_sentence(tmp_path / "none.csv") == ""


def test_claims_quoted_elsewhere_are_the_papers_words():
    if not PAPER.exists():  # the team's shared folder beside the checkout; not in a clean clone
        return
    text = " ".join(re.sub(r"\*|\s*\[\w+\]", "", PAPER.read_text()).split())
    for _, _, quote, _ in register.ELSEWHERE:
        assert quote in text
