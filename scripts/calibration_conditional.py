"""Coverage of a calibration row among the draws whose sample shows an error (issue 53): the row "RMSE, ≈ 200 pixels
with blobs" of reports/calibration.md misses in the draws where the 8 px disc holds no blob (every pixel's error 0),
which no interval from the sample alone can bound; among the others it covers. Same draws as the table (its seed).

    PYTHONPATH=. .venv/bin/python scripts/calibration_conditional.py [REPLICATES] [ROW NAME]
"""

import sys

import numpy as np

from study.stats import calibration as C

R = int(sys.argv[1]) if len(sys.argv) > 1 else 2000
name = sys.argv[2] if len(sys.argv) > 2 else "RMSE, ≈ 200 pixels with blobs"
draw, truth, _, _ = C.ROWS[name]
truth = truth() if callable(truth) else truth
rng = np.random.default_rng(
    [0, list(C.ROWS).index(name)]
)  # the table's stream (study.stats.calibration.coverage)
covered, zero, covered_nonzero = 0, 0, 0
for _ in range(R):
    est, ci, _ = draw(rng, False)
    c = bool(ci[0] <= truth <= ci[1])
    covered += c
    zero += est == 0
    covered_nonzero += c and est != 0
print(
    f"{name}: {R} draws, truth {truth:.4g}; coverage {covered / R:.1%}; samples all zero {zero / R:.1%}; "
    f"coverage among the samples with an error {covered_nonzero / max(R - zero, 1):.1%} ({R - zero} draws)"
)
