"""Compare results tables made on the GPU (--backend cuda: cuda_ad_rgb renders, OptiX exact hits) with the CPU ones.

    python scripts/device_compare.py CPU_REPORTS GPU_REPORTS

Both are report trees holding fig4/metrics.csv, fig5/metrics.csv, fig6/metrics.csv and sweep-sweep/results.csv
(whichever exist in both). Rows are matched by (case, label). For each headline column: the largest and the median
absolute difference over the matched rows, beside the column's median absolute value; a Markdown table on stdout.
Renders differ by Monte Carlo noise (another device, another float order), exact hits by float32 rounding.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from study.tables import read_csv

TABLES = ["fig4/metrics.csv", "fig5/metrics.csv", "fig6/metrics.csv", "sweep-sweep/results.csv"]
COLUMNS = [
    "wrong_fraction",
    "wrong_fraction_visible",
    "wrong_fraction_hidden",
    "dist_p95",
    "angle_median_deg",
    "rmse_oracle",
    "rmse_mitsuba",
    "flip_truth",
    "rmse_truth",
]


def _num(v) -> float:
    try:
        return float(v)
    except (TypeError, ValueError):
        return float("nan")


def compare(cpu: Path, gpu: Path) -> list[str]:
    out = [
        "| table | rows matched | column | max abs diff | median abs diff | median abs value |",
        "|---|---|---|---|---|---|",
    ]
    for t in TABLES:
        if not (cpu / t).exists() or not (gpu / t).exists():
            continue
        a = {(r["case"], r["label"]): r for r in read_csv(cpu / t)}
        b = {(r["case"], r["label"]): r for r in read_csv(gpu / t)}
        keys = sorted(set(a) & set(b))
        for c in COLUMNS:
            x = np.array([_num(a[k].get(c)) for k in keys])
            y = np.array([_num(b[k].get(c)) for k in keys])
            ok = np.isfinite(x) & np.isfinite(y)
            if not ok.any():
                continue
            d = np.abs(x[ok] - y[ok])
            out.append(
                f"| {t} | {len(keys)} | {c} | {d.max():.3g} | {np.median(d):.3g} | "
                f"{np.median(np.abs(x[ok])):.3g} |"
            )
    return out


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    print("\n".join(compare(Path(sys.argv[1]), Path(sys.argv[2]))))
