"""The report's notes on a results table's columns and on the summary's intervals (text only)."""

from __future__ import annotations

from study import stats


def column_notes() -> list[str]:
    """What the uncertainty columns of a results table mean (:mod:`study.stats`), for the report."""
    return [
        "*wrong_fraction* (= *wrong_fraction_texel*): tolerance texel-relative, ε = max(1 cm, one cube-map texel "
        "at the hit), so it tightens as the map gets finer; *wrong_fraction_1cm / _3cm / _10cm*: the same "
        "distance at every resolution; *wrong_fraction_0p5deg*: |shown − exact| subtends > 0.5° seen from the "
        "shading point. A ray with no hit is wrong at every tolerance.",
        "*_lo / _hi*: 95 % interval of the column within its case: over the rays (fractions: Wilson at the "
        "effective number of rays, n_rays / rays_deff, the design effect measured with rays clustered by pixel; "
        "angle and dist percentiles: order-statistic interval) or over the pixels (rmse, relmse, flip: mean ± "
        "t·√variance, the variance from the error image's autocovariance over a lag window that follows its "
        "correlation length corr_px). *n_rays*, *n_hidden*, *n_wrong*, *n_pixels*: the counts behind them; "
        "their coverage: reports/calibration.md.",
        "*angle_dropped* / *dist_dropped*: the share of rays that angle_* / dist_* leave out (no hit; for dist "
        "also points at infinity): angle_* and dist_* describe only the rays that remain. "
        "*angle_p95_all_deg* counts the dropped rays as infinite error instead.",
        "*rmse_truth_trim*, *rmse_truth_debiased_trim*: RMSE without the worst 0.1 % of pixels; "
        "*sqerr_top_share_truth*: the share of the squared error those pixels carry (near 1: a handful of pixels "
        "decide the RMSE). *relmse_truth*: mean of (test − truth)² / (truth² + 0.01), ε absolute (W/m²/sr)², so in "
        "a dark scene it is the MSE / 0.01 and ranks as the RMSE does. *relmse_truth_exposed*: the same after "
        "the exposure normalisation (both images × 2^truth_exposure_ev, the truth's median over the object at "
        "0.18), ε = 0.01 in exposed units (√ε ≈ half of middle grey: darker pixels count about absolutely, so their "
        "noise cannot dominate): the same number for a scene and that scene × k; the summary ranks image error on "
        "it. *truth_noise_relmse*: the truth's own noise in that unit.",
        "*_oracle* columns (and the *oracle_map* row) are over the pixels whose every hit the reference point's "
        "views hold (*held_pixels*); *oracle_map* has no value on the others (*unheld_pixels*). `dec_*`: the error "
        "split over all object pixels (study/measure/split.py), each with a pixel interval.",
        "The exact rows (`traced`, `traced_glossy`) are not ranked among the stand-ins: on a mirror `traced` "
        "shows the truth's image, but on a glass object whose far side comes from its distance map it follows "
        "the methods' rays, not the exactly refracted ones, and on a rough object `traced_glossy` carries the "
        "noise of its K lobe rays, so a stand-in can score better there (a run's notes say so for that row).",
        "In these tables the value per table and method is the median over cases; the summary above gives it "
        "with an interval over the cases and tests differences between methods over the same cases "
        "(Wilcoxon signed-rank).",
    ]


def interval_note() -> str:
    """How the summary's intervals are made, and what its table of intervals holds."""
    return (
        "Intervals: 95 %, their coverage measured by simulation (reports/calibration.md); per case over the rays "
        "(Wilson at the rays' effective number, clustered by pixel) or over the spatially correlated pixels, "
        f"over cases the median's order-statistic interval from {stats.MIN_CASES_CI} cases on, else the cases' "
        "range (an interval over 2–4 cases covers the truth 52–87 % of the time; study/stats/intervals.py); "
        "*wrong hits* use the "
        "texel-relative tolerance ε = max(1 cm, one texel); the fixed-tolerance columns (wrong_fraction_1cm, "
        "_3cm, _10cm) keep one meaning at every cube resolution. A case is a distinct geometry (object position, "
        "scene, object): the seeds of one are pooled (*seeds*: how many; their geometric columns are copies, the "
        "image columns averaged) before any statistic over cases. The table: per table and method (best first), "
        "the medians over the cases with their interval over the cases (*interval* says which), the worst "
        "case, the cases where the method is wrong more often than the best beyond both rays' intervals, "
        "the Wilcoxon p-value against the best over the same cases, and *mdd_vs_best*: the smallest difference "
        "in wrong fraction from the best that those cases could detect (80 % power, 5 %, from the spread of the "
        "per-case differences; inf below 6 cases); *rmse* the noise-debiased RMSE and *relmse* the relMSE after "
        "exposure (ε = 0.01, the column the image-error sentences rank on), medians with their intervals."
    )
