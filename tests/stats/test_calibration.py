"""Coverage of the printed intervals, measured against known truths (study.stats.calibration): every interval type
covers 95 % of the time within the tier's band, a planted too-narrow interval (and each interval the tables printed
before) is flagged, the harness is deterministic, and no committed table holds an interval that excludes its own
estimate."""

import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from study import stats
from study.report import summary
from study.stats import calibration, fields, spatial

REPORTS = Path(__file__).resolve().parents[2] / "reports"
FAST_BAND = calibration.BANDS[calibration.FAST]


#: Designs the estimator still misses in the fast band. Before the 2-D lag window, 1000 replicates: σ 8 px 86.0 %,
#: streaks 81.8 %, blobs 81.6 %, 200 px 81.3 %, 200 px + blobs 27.4 %; ray fraction σ 8 px 88.6 %, streaks 74.7 %,
#: 200 px 83.6 %. The wrong-hit template's interval is too wide instead (1.8 × the ideal width: 100 % of 100).
KNOWN_MISSES = {"ray fraction, study's wrong-hit map"}


@pytest.mark.parametrize(
    "name",
    [
        pytest.param(n, marks=pytest.mark.xfail(strict=True)) if n in KNOWN_MISSES else n
        for n, row in calibration.ROWS.items()
        if row[3]
    ],
)
def test_every_interval_covers_the_truth_in_the_fast_band(name):
    (now,) = calibration.coverage(name, calibration.FAST, before=0)
    assert not now.flagged(FAST_BAND), now
    if math.isfinite(now.contains_estimate):
        assert now.contains_estimate == 1.0, now


def _study_means(replicates: int = 1000):
    """The edge design's mean squared error over the disc and the wrong-hit design's ray fraction, each averaged
    over ``replicates`` simulated draws, with their standard errors."""
    rng, disc = np.random.default_rng(7), fields.disc()
    mse = np.array([fields.study_edge(rng)[disc].mean() for _ in range(replicates)])
    wrong = np.array([calibration._study_wrong(rng, False)[0] for _ in range(replicates // 2)])
    return [(v.mean(), v.std() / np.sqrt(len(v))) for v in (mse, wrong)]


def test_the_designs_on_studys_own_maps_have_the_truth_they_declare():
    """The analytic truths (every pixel a uniform draw of the template's tile) against the means over simulated
    replicates, within 4 standard errors. Planted (each > 4 SE off at this seed, checked): E[a]² for E[a²] in the
    edge's truth (1.09 for 1.17: 4.8 SE), the wrong-hit's truth without its background term (0.278 for 0.299)."""
    edge, wrong = calibration.STUDY_ROWS.values()
    for (mean, se), truth in zip(_study_means(), (edge[1] ** 2, wrong[1]())):
        assert abs(mean - truth) < 4 * se, (mean, se, truth)


def test_the_small_object_with_blobs_shows_error_in_the_share_it_declares():
    """fields.SMALL_BLOB_SHOWN (20,000 fields, seed 0) against 500 fields of another seed, within 4 standard errors
    (0.0037 each: the spread of one field's share over √500); planted: the disc's radius 7.5 px, not 8, gives
    0.267, 7.5 SE off (seed 1 at 8 px: 0.304, 2.5 SE)."""
    assert abs(fields.blob_shown_share(500, seed=1) - fields.SMALL_BLOB_SHOWN) < 4 * 0.0037


def test_the_small_object_rows_draw_what_they_say():
    """The banded row draws only objects that show error (its truth their mean, ≈ 3.4 × the mean squared error
    over every draw); a sample of error 0 gets the interval (0, 0), the same for every such draw."""
    rng = np.random.default_rng(5)
    ests = [calibration._small_blobs_shown(rng, False)[0] for _ in range(30)]
    assert min(ests) > 0
    assert fields.SMALL_BLOB_MSE == pytest.approx(fields.BLOB_MSE / fields.SMALL_BLOB_SHOWN)
    (lo, hi), _ = stats.rmse_interval(np.zeros(int(fields.small_disc().sum())), fields.small_disc())
    assert (lo, hi) == (0.0, 0.0)


def test_one_window_gets_the_calibrated_degrees_of_freedom():
    """A mean of values ≥ 0 carried by one window (one pixel of error in the ≈ 200-pixel disc, a blob's sliver):
    Student's t at FEW_DOF = 1.35 degrees of freedom (the value that calibrates the calibration's "≈ 200 pixels
    with blobs" row), the upper end 22.1 × the estimate (its mean squared error), the lower 0.0009 ×; planted
    FEW_DOF = 2 (the value before): 13.9 × (and 0.014 ×), FEW_DOF = 1: 39 × (and 3e-6 ×)."""
    disc = fields.small_disc()
    img = np.zeros(disc.shape)
    img[48, 48] = 7.5  # a blob's edge: just above the blob level (e² = exp(2) ≈ 7.4)
    ((lo, hi),), _ = spatial.mean_intervals([img[disc]], disc, 0.95)
    r = float(img[disc].mean())
    assert 20 * r < hi < 25 * r and 0.0005 * r < lo < 0.002 * r, (lo / r, hi / r)


@pytest.mark.parametrize("name", ["pixel error (RMSE)", "ray fraction", "case median", "JOD over segments"])
def test_a_too_narrow_interval_is_flagged(name):
    """Planted: every interval narrowed to a third about its estimate covers well below the band."""
    (now,) = calibration.coverage(name, calibration.FAST, shrink=0.35, before=0)
    assert now.flagged(FAST_BAND) and now.coverage < FAST_BAND[0], now


def test_the_intervals_printed_before_are_flagged():
    """Wilson over independent rays (7× too narrow for rays sharing texels) and the fixed 64 × 64 pixel grid: the
    harness catches both, where the clustered intervals pass."""
    for name in ("ray fraction", "pixel error (RMSE)"):
        now, before = calibration.coverage(name, 60, before=40)
        assert before.flagged(FAST_BAND) and before.coverage < 0.8 and before.width_ratio < 0.5, before
        assert not now.flagged(FAST_BAND), now


def test_the_harness_is_deterministic_for_a_seed():
    a = calibration.coverage("ray fraction", 20, seed=3, before=5)
    assert a == calibration.coverage("ray fraction", 20, seed=3, before=5)
    assert a != calibration.coverage("ray fraction", 20, seed=4, before=5)


def test_the_lag_window_variance_matches_the_field_it_was_planted_with():
    """A field of known correlation: the variance of its mean over many draws is what the lag window estimates
    from single draws (within 15 %); white noise keeps the independent pixels' variance."""
    mask = np.ones((64, 64), bool)
    rng = np.random.default_rng(2)
    fields = [calibration.correlated_field(rng, (64, 64), 2.0) for _ in range(150)]
    est = np.array([spatial.ratio_variance(f, 1.0, mask) for f in fields], dtype=object)
    means, var, lengths = np.array([e[0] for e in est]), np.array([e[1] for e in est]), [e[2] for e in est]
    assert 0.85 < np.mean(var) / np.var(means) < 1.15, (np.mean(var), np.var(means))
    assert (
        2.5 < np.median(lengths) < 4.5
    )  # ρ(r) = exp(−r²/4σ²) of a σ = 2 filter: 1/e at r = 4 (ring-averaged)
    white = rng.normal(size=(64, 64))
    _, v, _, _ = spatial.ratio_variance(white, 1.0, mask)
    assert 0.9 < v / (white.var() / white.size) < 1.6


def test_wilson_at_an_effective_count_is_scipys_wilson():
    for k, n in ((0, 50), (7, 50), (50, 50), (3, 1000)):
        lo, hi = spatial.wilson(k / n, n, 1.959963984540054)
        assert np.allclose((lo, hi), stats.fraction_ci(k, n), atol=1e-9)


def test_independent_rays_keep_wilsons_interval():
    """Rays drawn independently of their pixels: the design effect is ≈ 1 and the interval Wilson's, widened only by
    Student's t at the window's degrees of freedom (1.025 × with the flat part at least 2 pixels, 1.06 × at 3)."""
    rng = np.random.default_rng(4)
    pix = np.repeat(np.arange(40 * 40), 4)
    wrong = rng.random(pix.size) < 0.2
    (ci,), (deff,) = stats.fraction_cis([wrong], pix, (40, 40))
    assert 1.0 <= deff < 1.3, deff
    w = stats.fraction_ci(int(wrong.sum()), wrong.size)
    assert abs((ci[1] - ci[0]) / (w[1] - w[0]) - math.sqrt(deff)) < 0.08


@pytest.mark.slow
def test_every_interval_covers_93_to_97_percent_in_the_slow_tier():
    """Every interval in 93–97 %, the clustered ray percentile too (92.5 % at seed 0 with Wilson's interval of
    the share and the window's Gaussian degrees of freedom; 94.5 % with a normal interval and the degrees of
    freedom lowered for heavy tails, study.stats.spatial.kurtosis_factor)."""
    rows, powers = calibration.coverage_table(calibration.SLOW)
    band = calibration.BANDS[calibration.SLOW]
    flagged = {r.interval for r in rows if r.variant == "now" and r.flagged(band)}
    assert flagged == OUTSIDE_IN_THE_REPORT, flagged  # the declared open misses, no other
    assert all(0.75 < p < 0.85 for p in powers.values()), powers


def _committed_tables() -> list[Path]:
    return sorted(p for p in REPORTS.rglob("*.csv") if "viewer" not in p.parts)


def _excluded(tab: pd.DataFrame) -> list[str]:
    bad = []
    for c in tab.columns:
        if f"{c}_lo" in tab.columns and f"{c}_hi" in tab.columns:
            v, lo, hi = (
                pd.to_numeric(tab[x], errors="coerce").to_numpy(float) for x in (c, f"{c}_lo", f"{c}_hi")
            )
            ok = np.isfinite(v) & np.isfinite(lo) & np.isfinite(hi)
            tol = 1e-9 * np.maximum(1.0, np.abs(v))
            n = int((ok & ((lo > v + tol) | (v > hi + tol))).sum())
            bad += [f"{c} ({n} rows)"] if n else []
    return bad


def test_the_table_check_catches_a_planted_exclusion():
    tab = pd.DataFrame({"x": [0.5, 0.2], "x_lo": [0.4, 0.25], "x_hi": [0.6, 0.3]})
    assert _excluded(tab) == ["x (1 rows)"]


def test_no_committed_interval_excludes_its_estimate():
    tables = _committed_tables()
    assert len(tables) > 20
    bad = {
        str(p.relative_to(REPORTS)): b for p in tables if (b := _excluded(pd.read_csv(p, low_memory=False)))
    }
    assert bad == {}  # no exception by name: a stale table is removed or regenerated, never listed


def test_the_summary_intervals_over_cases_contain_their_medians():
    """The summary's intervals over cases (median_ci, or the range), recomputed from every committed table."""
    from study.report.check import read_table

    tables = {
        d.name: read_table(d / f)
        for f in ("metrics.csv", "results.csv")
        for d in REPORTS.glob("*")
        if (d / f).is_file()
    }
    rows = summary.interval_rows(tables)
    assert rows
    for r in rows:
        for col in ("wrong", "rmse"):
            if math.isfinite(r[col]):
                tol = 1e-12 * abs(r[col])  # a median of equal values may round one ulp past them
                assert r[f"{col}_lo"] - tol <= r[col] <= r[f"{col}_hi"] + tol, r


#: The committed table's rows outside 93–97 % (the estimator's open misses: the wrong-hit template from study's own
#: error maps above it).
#: A new row outside, or one of these brought inside without updating this set, fails.
OUTSIDE_IN_THE_REPORT = {
    # in the band since the log-scale ends of a mean of values ≥ 0 (study.stats.spatial): blobs 87.0 → 93.2 %,
    # 200 px 89.8 → 93.5 % of 400; and since the window's flat part reaches at least 3 pixels (study.stats.region.
    # MIN_WINDOW, was 2): the ray fraction on a 200-pixel object 91.2 → 94.2 % of 400 (its misses held a third of
    # the true wrong rays, scattered: a short correlogram). Of 2000: blobs 94.5 %, 200 px 95.5 %, its ray fraction
    # 95.2 %. 200 px + blobs: over every draw 29.4 % (70.5 % of the draws hold no blob: the sample is 0, its
    # interval [0, 0]; that row has no band); among the draws that show error (truth their mean) 92.4 % with at
    # least 2 degrees of freedom (every miss a sliver of 1–3 pixels), 95.8 % since at least 1.35
    # (study.stats.spatial.FEW_DOF)
    # In the band since the copies of study's maps are placed at random (dead leaves, study.stats.fields.mosaic)
    # instead of on a lattice: the reflected edge 99.5 → 96.8 % of 400 (99.0 → 96.8 % of 2000). Above the band, too
    # wide: the wrong-hit map, 99.2 → 98.8 % of 400 (99.4 → 97.5 % of 2000; width 2.24 → 1.79 × ideal): the lag
    # window's variance is 1.91 × the true one (scripts/diagnose_study_fields.py), of which the ensemble covariance
    # under each draw's own window gives 1.26 × (each copy's wrong region comes with its copy's right remainder: a
    # negative lobe at 16–44 px beyond the window) and the reach each draw picks from its own correlogram the rest
    # (one fixed 11.4 px reach: 1.43 ×); with the variance divided by its bias the interval covers 95.8 %.
    "ray fraction, study's wrong-hit map",
}


def test_the_committed_calibration_table_is_in_the_band():
    """reports/calibration.md (scripts/calibration.py, ≥ SLOW_FROM replicates per row) holds every row of ROWS,
    and its banded *now* rows lie in 93–97 %, but for the declared open misses."""
    text = (REPORTS / "calibration.md").read_text(encoding="utf-8")
    replicates = int(text.split(" replicates per row")[0].split()[-1])
    assert replicates >= calibration.SLOW_FROM, replicates
    lo, hi = calibration.band(replicates)
    cover = {}
    for line in text.splitlines():
        cells = [c.strip() for c in line.strip("|").split("|")]
        if len(cells) == 7 and cells[1] == "now":
            cover[cells[0]] = float(cells[3].rstrip(" %")) / 100
    assert set(cover) == set(calibration.ROWS), set(calibration.ROWS) ^ set(cover)
    outside = {n for n, c in cover.items() if calibration.ROWS[n][3] and not lo <= c <= hi}
    assert outside == OUTSIDE_IN_THE_REPORT, outside
