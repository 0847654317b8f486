"""Write reports/calibration.md: how often each interval the report prints covers a known truth
(study.stats.calibration; slow tier, 2000 replicates per row, ≈ 10 minutes on one core; 400 in ≈ 2).

    PYTHONPATH=. .venv/bin/python scripts/calibration.py [--replicates N] [--seed S] [--out PATH]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from study.stats import calibration
from study.stats.calibration import Row, band
from study.stats.fields import SMALL_BLOB_SHOWN

#: What the table says of the rows no band applies to.
UNBANDED = {
    "case range (n < 10)": "(a range, not a CI)",
    "RMSE, ≈ 200 pixels with blobs, every draw": f"({100 * (1 - SMALL_BLOB_SHOWN):.0f} % of the draws show no error)",
}


def _pct(v: float) -> str:
    return "–" if not v == v else f"{100 * v:.1f} %"


def calibration_page(rows: list[Row], powers: dict[int, float], replicates: int, seed: int) -> str:
    """reports/calibration.md: the coverage table and the power check."""
    limits = band(replicates)
    lines = [
        "# Calibration: how often the printed 95 % intervals cover the truth",
        "",
        f"Simulated with known truths (`study/stats/calibration.py`), {replicates} replicates per row, seed "
        f"{seed}; written by `python scripts/calibration.py`. *width / ideal*: the mean width over 2 × 1.96 × "
        "the estimates' true spread over the replicates (1: as wide as a calibrated interval needs to be). "
        "*before*: the interval the tables printed until the calibration (fixed 64 × 64 pixel grid with a "
        f"percentile bootstrap, Wilson over independent rays, percentile bootstraps); *flag*: a coverage outside "
        f"{100 * limits[0]:.0f}–{100 * limits[1]:.0f} %.",
        "",
        "| interval | variant | n | coverage | width / ideal | contains its estimate | flag |",
        "|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        flag = "outside" if r.flagged(limits) else (UNBANDED.get(r.interval, "") if not r.banded else "")
        lines.append(
            f"| {r.interval} | {r.variant} | {r.n} | {_pct(r.coverage)} | {r.width_ratio:.2f} | "
            f"{_pct(r.contains_estimate)} | {flag} |"
        )
    every = {r.interval: r for r in rows if r.variant == "now"}
    shown, alone = (
        every.get("RMSE, ≈ 200 pixels with blobs"),
        every.get("RMSE, ≈ 200 pixels with blobs, every draw"),
    )
    if shown and alone:
        lines += [
            "",
            f"A ≈ 200-pixel object with blobs: a blob reaches into it in {_pct(SMALL_BLOB_SHOWN)} of the draws "
            "(`study.stats.fields.blob_shown_share`); in the others every pixel's error is 0, the estimate 0 and its "
            f"interval (0, 0), so over every draw the coverage ({_pct(alone.coverage)}) is at most that share. "
            f"Among the draws that show error (truth: their mean) it is {_pct(shown.coverage)}.",
        ]
    lines += [
        "",
        "Smallest detectable difference over cases (`study.stats.detectable_shift`, 80 % power, 5 %): "
        "the share of paired normal differences shifted by it that the Wilcoxon signed-rank test finds: "
        + ", ".join(f"{n} cases {100 * p:.0f} %" for n, p in powers.items())
        + ".",
        "",
    ]
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--replicates", type=int, default=calibration.SLOW)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", default="reports/calibration.md")
    a = ap.parse_args()
    t0 = time.time()
    rows, powers = calibration.coverage_table(a.replicates, a.seed)
    Path(a.out).write_text(calibration_page(rows, powers, a.replicates, a.seed), encoding="utf-8")
    limits = band(a.replicates)
    off = [f"{r.interval} ({r.variant})" for r in rows if r.variant == "now" and r.flagged(limits)]
    print(f"calibration: {a.out} in {time.time() - t0:.0f} s; outside the band: {', '.join(off) or 'none'}")


if __name__ == "__main__":
    main()
