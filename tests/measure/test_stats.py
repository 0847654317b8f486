"""Numbers with their uncertainty (study.stats, study.measure.case_columns): intervals agree with scipy's closed
forms, paired tests find a planted difference and not a null one, fixed tolerances keep their meaning across cube
resolutions, and no statistic drops rays silently."""

import math

import numpy as np
import pytest
from conftest import BOX_HI, BOX_LO
from scipy import stats as sps

from study import backend as backends
from study import methods, stats
from study.impostor import analytic
from study.impostor.envmap import EnvMap
from study.measure import case_columns, metrics, outcomes
from study.stats import calibration


def test_bootstrap_mean_matches_the_t_interval():
    """A normal sample's mean: the percentile bootstrap agrees with the t-interval within a few % of its width."""
    x = np.random.default_rng(1).normal(3.0, 2.0, 400)
    lo, hi = stats.bootstrap_ci(x, np.mean)
    tlo, thi = sps.t.interval(0.95, len(x) - 1, loc=x.mean(), scale=sps.sem(x))
    width = thi - tlo
    assert abs(lo - tlo) < 0.05 * width and abs(hi - thi) < 0.05 * width
    assert stats.bootstrap_ci(x, np.mean) == (lo, hi)  # fixed seed: deterministic


def test_quantile_interval_matches_the_bootstrap_and_covers():
    """The order-statistic interval of a percentile agrees with scipy's percentile bootstrap on a large sample
    and covers the true 95th percentile of a normal in about 95 % of 200 samples."""
    x = np.random.default_rng(2).normal(0, 1, 3000)
    lo, hi = stats.quantile_ci(x, 95)
    blo, bhi = stats.bootstrap_ci(x, lambda v, axis=-1: np.percentile(v, 95, axis=axis))
    assert abs(lo - blo) < 0.1 * (hi - lo) + 0.02 and abs(hi - bhi) < 0.1 * (hi - lo) + 0.02
    true = sps.norm.ppf(0.95)
    rng = np.random.default_rng(3)
    cover = sum(a <= true <= b for a, b in (stats.quantile_ci(rng.normal(0, 1, 300), 95) for _ in range(200)))
    assert 180 <= cover <= 200
    assert stats.quantile_ci([1.0, 2.0], 95)[1] == np.inf  # too few values to bound it above


def test_fraction_interval_matches_the_bootstrap_and_stays_honest_at_zero():
    w = np.zeros(500, bool)
    w[:40] = True
    lo, hi = stats.fraction_ci(40, 500)
    blo, bhi = stats.bootstrap_ci(w.astype(float), np.mean)
    assert abs(lo - blo) < 0.01 and abs(hi - bhi) < 0.01
    lo0, hi0 = stats.fraction_ci(0, 300)  # no wrong ray seen: still not "exactly 0"
    assert lo0 == 0 and 0.005 < hi0 < 0.02


def test_paired_test_finds_a_planted_difference_and_not_a_null_one():
    """40 seeds, 20 cases with a case-to-case spread far larger than the planted difference (b = a + 0.1, noise
    σ = 0.05 per method): the Wilcoxon test finds it at 1 % in ≥ 95 % of the seeds; with no difference ≥ 95 % of
    the seeds find none at 1 %, and at 5 % no more than the binomial 99.9 % bound for a 5 % false-positive rate."""
    found, false, false5 = 0, 0, 0
    for seed in range(40):
        rng = np.random.default_rng(seed)
        case = rng.lognormal(0, 1.0, 20)  # what the cases share: much larger than the difference
        a = case + rng.normal(0, 0.05, 20)
        b = case + 0.1 + rng.normal(0, 0.05, 20)
        null = case + rng.normal(0, 0.05, 20)
        found += stats.paired(a, b)["p"] < 0.01
        p_null = stats.paired(a, null)["p"]
        false, false5 = false + (p_null < 0.01), false5 + (p_null < 0.05)
    assert found >= 38 and false <= 2
    assert false5 <= sps.binom.ppf(0.999, 40, 0.05)


def test_paired_counts_and_the_smallest_p():
    r = stats.paired([1, 2, 3, np.nan], [2, 2, 4, 1])
    assert (r["n"], r["a_better"], r["ties"], r["b_better"]) == (3, 2, 1, 0)
    assert stats.paired([1, 2], [1, 2])["p"] == 1.0
    assert stats.min_p(5) > 0.05 > stats.min_p(6)  # fewer than 6 cases can never be significant at 5 %
    assert "no significant" in stats.significance(0.67) and "1 %" in stats.significance(0.001)


def test_fixed_tolerance_does_not_rise_with_cube_resolution():
    """A converged method (localized, 10 iterations) in the analytic box: its wrong fraction at 1 cm / 3 cm does
    not rise as the cube map gets finer, although the texel-relative tolerance shrinks from 6 cm to < 1 cm."""
    B = backends.get("numpy")
    x, R = analytic.random_rays(1500, extent=1.0, seed=3)
    exact = analytic.box_hit(x, R, BOX_LO, BOX_HI)
    curve, texel_eps = {}, {}
    for res in (32, 64, 128, 256):
        env = EnvMap(analytic.box_impostor(res, BOX_LO, BOX_HI), B)
        tr = methods.make("localized", iterations=10).trace(B, env, B.vec(x), B.vec(R))
        shown = B.to_numpy(tr.shown).astype(float)
        eps = outcomes.tolerance(np.zeros(3), exact, res)
        oc = outcomes.classify(x, R, shown, exact, eps=eps)
        cols = case_columns.ray_columns(
            oc, metrics.angular_error(x, shown, exact), np.zeros(len(x), bool), x, exact
        )
        curve[res] = (cols["wrong_fraction_1cm"], cols["wrong_fraction_3cm"], cols["wrong_fraction_10cm"])
        texel_eps[res] = float(np.median(eps))
    assert texel_eps[32] > 0.05 > 0.02 > texel_eps[256]  # the texel tolerance changes meaning
    res = sorted(curve)
    for lo, hi in zip(res, res[1:]):
        assert all(b <= a + 2e-3 for a, b in zip(curve[lo], curve[hi])), curve  # never rises (up to 3 rays)
    assert curve[256][0] <= 0.01, curve


def test_a_method_that_misses_most_rays_reports_what_it_dropped():
    """ssr(fallback='none')-like: 96 % no hit, the rest exact. The finite-only angle p95 is ~0, but the row says
    that 96 % were dropped, counts them as wrong at every tolerance and gives an infinite all-ray p95."""
    n = 1000
    x, R = analytic.random_rays(n, extent=1.0, seed=0)
    exact = analytic.box_hit(x, R, BOX_LO, BOX_HI)
    shown = exact.copy()
    shown[: int(0.96 * n)] = np.nan
    oc = outcomes.classify(x, R, shown, exact, eps=0.01)
    ang = metrics.angular_error(x, shown, exact)
    cols = case_columns.ray_columns(oc, ang, np.zeros(n, bool), x, exact)
    assert (
        metrics.value_stats(ang, "angle", "_deg")["angle_p95_deg"] < 1e-3
    )  # what the finite-only column says
    assert cols["angle_dropped"] >= 0.95 and cols["dist_dropped"] >= 0.95
    assert cols["angle_p95_all_deg"] == np.inf
    assert cols["wrong_fraction_1cm"] >= 0.95 and cols["wrong_fraction_0p5deg"] >= 0.95
    assert cols["n_rays"] == n and cols["n_wrong"] == int(0.96 * n)
    assert cols["wrong_fraction_texel_lo"] <= 0.96 <= cols["wrong_fraction_texel_hi"]


def test_pixel_columns_flag_a_handful_of_bad_pixels():
    """Ten pixels carry almost all of the squared error: the share says so and the trimmed RMSE leaves them out;
    the interval brackets the RMSE."""
    rng = np.random.default_rng(0)
    ref = rng.uniform(0.2, 0.8, (100, 100, 3))
    img = ref + rng.normal(0, 0.01, ref.shape)
    img[:1, :10] += 5.0  # 10 fireflies among 10⁴ pixels
    mask = np.ones((100, 100), bool)
    cols = case_columns.pixel_columns(img, ref, mask=mask, sigma=0.0, rel_eps=1e-2)
    r = metrics.rmse(ref, img, mask=mask)
    assert cols["rmse_truth_lo"] <= r <= cols["rmse_truth_hi"]
    assert cols["sqerr_top_share_truth"] > 0.99
    assert cols["rmse_truth_trim"] < 0.02 < r
    assert cols["n_pixels"] == 10000


def test_a_real_case_carries_counts_and_intervals(tmp_path):
    """The real pipeline on a small scene: every method's row has its counts, its texel-relative wrong fraction
    under both names, and intervals that bracket the value they belong to."""
    from conftest import small_scene_dict

    from study.cache import Cache
    from study.measure.case import run_case
    from study.scene import scene_from_dict

    scene = scene_from_dict(small_scene_dict())
    ms = [methods.make("classical"), methods.make("localized")]
    for r in run_case(scene, ms, cache=Cache(tmp_path)).rows:
        assert r["n_rays"] == r["rays"] and r["n_pixels"] >= 4
        assert r["wrong_fraction_texel"] == r["wrong_fraction"]
        for col in ("wrong_fraction_texel", "wrong_fraction_1cm", "rmse_truth", "relmse_truth", "flip_truth"):
            if r["label"] == "truth_at_hit" and col != "wrong_fraction_texel" and col != "wrong_fraction_1cm":
                continue
            lo, hi = r.get(f"{col}_lo"), r.get(f"{col}_hi")
            if lo is None:  # flip needs the FLIP map: only for methods
                assert col == "flip_truth" and r["label"] in ("oracle_map", "truth_at_hit")
                continue
            assert lo - 1e-12 <= r[col] <= hi + 1e-12, (r["label"], col, lo, r[col], hi)
        assert r["angle_dropped"] == 0 and r["wrong_fraction_1cm"] <= r["wrong_fraction_1cm_hi"]


def test_pixel_intervals_mean_the_same_at_every_resolution():
    """The same image at 4× the resolution (each pixel a 4×4 patch of equal values, as a finer render of smooth
    error would be) has the same error, and the lag window (following the measured correlation length, 4× longer)
    gives nearly the same interval; pixel by pixel the interval would shrink about 4×, claiming a precision the finer
    frame does not have."""
    rng = np.random.default_rng(1)
    ref = rng.uniform(0.2, 0.8, (64, 64, 3))
    img = ref + rng.normal(0, 0.05, ref.shape)
    mask = np.zeros((64, 64), bool)
    mask[8:56, 8:56] = True
    up = [np.repeat(np.repeat(a, 4, 0), 4, 1) for a in (img, ref, mask)]
    c1 = case_columns.pixel_columns(img, ref, mask=mask, sigma=0.0, rel_eps=1e-2)
    c4 = case_columns.pixel_columns(*up[:2], mask=up[2], sigma=0.0, rel_eps=1e-2)
    w1, w4 = (c["rmse_truth_hi"] - c["rmse_truth_lo"] for c in (c1, c4))
    assert c4["n_pixels"] == 16 * c1["n_pixels"]
    assert c1["corr_px"] < 1 and 2 < c4["corr_px"] < 5, (c1["corr_px"], c4["corr_px"])
    assert 0.7 < w4 / w1 < 1.4, (w1, w4)
    se = np.mean((up[0] - up[1]) ** 2, -1)[up[2]]
    ((plo, phi),) = calibration.mean_cis(se)  # pixel by pixel: too narrow
    assert (math.sqrt(phi) - math.sqrt(plo)) < 0.5 * w4


def test_block_bootstrap_is_scipys_bootstrap_of_the_mean_for_single_units():
    """Every unit its own block: the interval is scipy.stats.bootstrap's percentile interval of the mean (same
    seed, same resamples), so the block code adds nothing of its own to the statistics."""
    x = np.random.default_rng(3).exponential(1.0, 500)
    ((lo, hi),) = calibration.mean_cis(x, blocks=np.arange(500)[::-1])
    ref = sps.bootstrap(
        (x[::-1],),
        np.mean,
        n_resamples=stats.N_RESAMPLES,
        method="percentile",
        random_state=np.random.default_rng(stats.SEED),
    ).confidence_interval
    assert abs(lo - ref.low) < 0.02 * (ref.high - ref.low) and abs(hi - ref.high) < 0.02 * (
        ref.high - ref.low
    )


def test_pixel_blocks_tile_the_frame():
    """4×4 tiles at 256², 16×16 at 1024²; labels follow the mask's pixel order and are numbered densely."""
    m = np.zeros((256, 256), bool)
    m[0:8, 0:8] = True
    b = calibration.pixel_blocks(m)
    assert b.shape == (64,) and sorted(set(b.tolist())) == [0, 1, 2, 3]
    assert b[0] == b[3] and b[0] != b[4]  # row 0: pixels 0–3 one tile, 4–7 the next
    big = np.ones((1024, 1024), bool)
    assert calibration.pixel_blocks(big).max() + 1 == 64 * 64


def test_block_bootstrap_equals_scipys_paired_bootstrap_of_the_block_sums():
    """Several samples over uneven blocks: the matrix-product statistic gives the intervals of the obvious twin,
    ``scipy.stats.bootstrap(paired=True)`` gathering each block's count and sums (same seed, so the same draws), to
    1e-12; a wrong block weight or a sample paired with another's draw would move them by far more."""
    rng = np.random.default_rng(7)
    blocks = rng.integers(0, 300, 4000)
    xs = [rng.gamma(2.0, 1.0, 4000), rng.normal(0, 1, 4000) ** 2, rng.uniform(0, 1, 4000)]
    got = calibration.mean_cis(*xs, blocks=blocks)
    _, b = np.unique(blocks, return_inverse=True)
    counts = np.bincount(b).astype(float)
    sums = [np.bincount(b, weights=x) for x in xs]
    ref = sps.bootstrap(
        (counts, *sums),
        lambda n, *s, axis=-1: np.stack([np.sum(v, axis=axis) / np.sum(n, axis=axis) for v in s]),
        vectorized=True,
        paired=True,
        n_resamples=stats.N_RESAMPLES,
        method="percentile",
        random_state=np.random.default_rng(stats.SEED),
    ).confidence_interval
    np.testing.assert_allclose(np.array(got), np.stack([ref.low, ref.high], 1), rtol=0, atol=1e-12)
    assert got[0] != got[1]


def test_an_unknown_noise_gives_an_unknown_debiased_rmse():
    """σ = NaN (a reference whose noise is unknown): every debiased RMSE is NaN, not 0.0 (``max(0.0, nan)`` is
    0.0, which read as "no error left"); a known σ above the error still clips to 0."""
    from study.measure import truth

    rng = np.random.default_rng(0)
    ref = rng.uniform(0.2, 0.8, (40, 40, 3))
    img = ref + rng.normal(0, 0.05, ref.shape)
    mask = np.ones((40, 40), bool)
    cols = case_columns.pixel_columns(img, ref, mask=mask, sigma=math.nan, rel_eps=1e-2)
    debiased = {k: v for k, v in cols.items() if "debiased" in k}
    assert set(debiased) == {"rmse_truth_debiased_lo", "rmse_truth_debiased_hi", "rmse_truth_debiased_trim"}
    assert all(math.isnan(v) for v in debiased.values()), debiased
    assert cols["rmse_truth_lo"] > 0  # the plain columns are unaffected
    known = case_columns.pixel_columns(img, ref, mask=mask, sigma=1.0, rel_eps=1e-2)
    assert known["rmse_truth_debiased_lo"] == 0.0 == known["rmse_truth_debiased_trim"]
    assert math.isnan(truth.debiased(0.3, math.nan)) and math.isnan(truth.debiased(math.nan, 0.1))
    assert truth.debiased(0.1, 0.2) == 0.0 and truth.debiased(0.5, 0.3) == 0.4


def _wilcoxon_p_by_hand(d) -> float:
    """The obvious twin of stats.wilcoxon_p for ties or zeros: r⁺ (zero ranks split in half) over every one of the
    2ⁿ sign flips, one at a time; the two-sided p-value is twice the smaller tail, at most 1."""
    import itertools

    from scipy.stats import rankdata

    r = rankdata(np.abs(d))

    def r_plus(x):
        return sum(ri for xi, ri in zip(x, r) if xi > 0) + sum(ri for xi, ri in zip(x, r) if xi == 0) / 2

    obs = r_plus(d)
    null = [r_plus(np.asarray(s) * d) for s in itertools.product((1.0, -1.0), repeat=len(d))]
    return min(1.0, 2 * min(sum(v <= obs for v in null), sum(v >= obs for v in null)) / len(null))


def test_wilcoxon_p_is_scipys_to_the_bit():
    """stats.wilcoxon_p (paired's p-value, its sign flips one matrix product) equals the old call,
    scipy.stats.wilcoxon(d, zero_method="zsplit").pvalue, and a by-hand enumeration, on random differences with
    ties and zeros (scipy's permutation branch), without (its exact distribution) and above 13 and 50 cases
    (its normal approximation)."""
    from scipy.stats import wilcoxon

    rng = np.random.default_rng(7)
    draws = {
        "ties and zeros": lambda n: rng.integers(-3, 4, n).astype(float),
        "halves": lambda n: rng.integers(-1, 2, n) * 0.5,
        "rounded": lambda n: np.round(rng.normal(size=n), 1),
        "distinct": lambda n: rng.normal(size=n),
    }
    seen = 0
    for kind, draw in draws.items():
        for n in [*range(1, 12), 13, 14, 20, 51, 60]:
            d = draw(n)
            if not d.any():
                continue
            p = stats.wilcoxon_p(d)
            assert p == float(wilcoxon(d, zero_method="zsplit").pvalue), (kind, d)
            if n <= 9 and (np.any(d == 0) or np.unique(np.abs(d)).size < n):
                assert p == pytest.approx(_wilcoxon_p_by_hand(d), abs=1e-15), (kind, d)
                seen += 1
    assert seen >= 10
    assert stats.paired([1, 2, 2, 3, 0], [1, 1, 3, 1, 1])["p"] == float(
        wilcoxon(np.array([0, 1, -1, 2, -1.0]), zero_method="zsplit").pvalue
    )


def test_the_calibrated_rmse_interval_is_the_one_pixel_columns_writes():
    """The calibration simulates stats.rmse_interval (study.stats sits below the case pipeline); the pipeline writes
    case_columns.pixel_columns' rmse_*_lo/_hi. They are one interval: equal to the bit on random correlated
    images with a noisy reference (debiased ends too), so the coverage measured is the coverage of the tables."""
    rng = np.random.default_rng(5)
    for _ in range(3):
        mask = np.zeros((48, 64), bool)
        mask[6:40, 10:55] = rng.random((34, 45)) < 0.9
        ref = rng.normal(0.0, 0.3, (48, 64, 3))
        img = ref + rng.normal(0.5, 1.0, (48, 64, 1)) * rng.random((48, 64, 3))
        sigma = float(rng.uniform(0.0, 0.4))
        cols = case_columns.pixel_columns(img, ref, mask=mask, sigma=sigma, rel_eps=1e-2)
        se = np.mean((img - ref)[mask] ** 2, axis=-1)
        (lo, hi), (dlo, dhi) = stats.rmse_interval(se, mask, sigma)
        assert (lo, hi) == (cols["rmse_truth_lo"], cols["rmse_truth_hi"])
        assert (dlo, dhi) == (cols["rmse_truth_debiased_lo"], cols["rmse_truth_debiased_hi"])
