"""Statistics, below the case pipeline: intervals of one number (:mod:`.intervals`; spatially correlated pixels and
rays: :mod:`.spatial`), paired comparisons (:mod:`.compare`, :mod:`.signed_rank`), power (:mod:`.power`), and the
simulations with a known truth that measure each interval's coverage (:mod:`.calibration` over the fields of
:mod:`.fields`; ``scripts/calibration.py`` writes ``reports/calibration.md``). Nothing here knows a scene, a method
or a case: :mod:`study.measure.case_columns` applies these to a case's rays and pixels.

The public functions are importable from here (``from study import stats``; ``stats.case_interval(values)``).
"""

from study.stats.compare import min_p, paired, significance
from study.stats.intervals import (
    LEVEL,
    MIN_CASES_CI,
    N_RESAMPLES,
    SEED,
    bootstrap_ci,
    case_interval,
    debiased_root,
    fraction_ci,
    fraction_cis,
    median_ci,
    over_cases,
    quantile_ci,
    rmse_interval,
    seed_interval,
    segment_interval,
)
from study.stats.power import detectable_difference, detectable_fraction, detectable_shift
from study.stats.signed_rank import wilcoxon_p

__all__ = [
    "LEVEL",
    "MIN_CASES_CI",
    "N_RESAMPLES",
    "SEED",
    "bootstrap_ci",
    "case_interval",
    "debiased_root",
    "detectable_difference",
    "detectable_fraction",
    "detectable_shift",
    "fraction_ci",
    "fraction_cis",
    "median_ci",
    "min_p",
    "over_cases",
    "paired",
    "quantile_ci",
    "rmse_interval",
    "seed_interval",
    "segment_interval",
    "significance",
    "wilcoxon_p",
]
