"""Coverage of the pixel-RMSE and ray-fraction intervals on the designs made from study's own error maps
(study.stats.calibration.STUDY_ROWS: a reflected edge's error and a wrong-hit region, placed, turned, mirrored and
scaled at random, plus noise), and a check of each design's truth by simulation (the mean over the replicates).

    PYTHONPATH=. .venv/bin/python scripts/measure_study_fields.py [--replicates N] [--seed S]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from study.stats import calibration


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--replicates", type=int, default=calibration.SLOW)
    ap.add_argument("--seed", type=int, default=0)
    a = ap.parse_args()
    lo, hi = calibration.band(a.replicates)
    for name, (draw, truth, _, _) in calibration.STUDY_ROWS.items():
        t0 = time.time()
        (row,) = calibration.coverage(name, a.replicates, a.seed, before=0)
        truth = truth() if callable(truth) else truth
        rng = np.random.default_rng([a.seed, 99])
        est = np.array([draw(rng, False)[0] for _ in range(a.replicates)])
        power = 2 if name.startswith("RMSE") else 1  # the RMSE's square is the mean the truth is the root of
        sim, se = np.mean(est**power), np.std(est**power) / np.sqrt(len(est))
        flag = "" if lo <= row.coverage <= hi else f" outside {100 * lo:.0f}–{100 * hi:.0f} %"
        print(
            f"{name}: coverage {100 * row.coverage:.1f} % of {row.replicates}{flag}, width / ideal "
            f"{row.width_ratio:.2f}; truth {truth:.4f}, simulated mean {sim ** (1 / power):.4f} "
            f"(± {se / (power * sim ** (1 - 1 / power)):.4f}) [{time.time() - t0:.0f} s]"
        )


if __name__ == "__main__":
    main()
