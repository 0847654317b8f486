"""Write reports/calibration.md: how often each interval the report prints covers a known truth
(study.stats.calibration; slow tier, 2000 replicates per row, ≈ 10 minutes on one core; 400 in ≈ 2).

    PYTHONPATH=. .venv/bin/python scripts/calibration.py [--replicates N] [--seed S] [--out PATH]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from study.stats import calibration


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--replicates", type=int, default=calibration.SLOW)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", default="reports/calibration.md")
    a = ap.parse_args()
    t0 = time.time()
    rows, powers = calibration.coverage_table(a.replicates, a.seed)
    Path(a.out).write_text(calibration.calibration_page(rows, powers, a.replicates, a.seed), encoding="utf-8")
    band = calibration.band(a.replicates)
    off = [f"{r.interval} ({r.variant})" for r in rows if r.variant == "now" and r.flagged(band)]
    print(f"calibration: {a.out} in {time.time() - t0:.0f} s; outside the band: {', '.join(off) or 'none'}")


if __name__ == "__main__":
    main()
