"""How often the intervals the report prints cover the truth: a simulation harness with known truths.

Each row of :func:`coverage_table` draws many replicates of a quantity whose truth is known and measures how often the
interval the study prints for it contains that truth (its *coverage*, 95 % intended), how wide it is against the
ideal (``width_ratio``: the mean width over 2·z·the estimates' true spread over the replicates, 1 for a calibrated
normal interval) and how often it contains its own estimate:

==================  ===========================================================================================
pixel error         an image whose per-pixel error is 0.5 + a Gaussian-filtered noise field (correlation length
                    :data:`FIELD_SIGMA` px of filter σ) on a disc of :data:`DISC` px radius: RMSE (truth √1.25)
                    by :func:`study.stats.rmse_interval` (what :func:`study.measure.case_columns.pixel_columns` writes)
debiased RMSE       the same against a reference with white noise of σ = 0.5 (measured, as the study does):
                    √max(0, MSE − σ²) (truth √1.25)
split term          a signed cross term 2·a·b of two correlated fields (truth 1), paired with a² and b² in one
                    call, as the error split's terms are (:func:`study.stats.spatial.mean_intervals`)
ray fraction        4 rays per pixel, each wrong with probability Φ(−1.5 + z) for a correlated field z (rays of
                    neighbouring pixels share texels): the wrong fraction (truth Φ(−1.5/√2))
ray percentile      4 rays per pixel, each 0.8·z + 0.6·(own noise), so N(0, 1): the 95th percentile (truth
                    1.645), as the angle and distance percentiles
case median         12 cases drawn lognormal (truth: the median 1): the median over cases with its interval
case range          3 cases: below 10 cases the study prints their range, not a CI (coverage 1 − 2/2ⁿ, told)
paired difference   12 paired differences, symmetric about 0: the Wilcoxon signed-rank test keeps the null
                    (its coverage: 1 − its false-positive rate)
JOD over segments   4 segment scores, truth + normal noise; the whole sequence's score their mean
other fields        the pixel error and ray fraction on the fields of :mod:`study.stats.fields` beyond the tuned
                    one: long correlation (σ 8 px), streaks along an axis and at 45°, sparse heavy-tailed blobs, a
                    ≈ 200-pixel object, that object with blobs: among the draws where a blob reaches into it (truth
                    their mean, :data:`study.stats.fields.SMALL_BLOB_MSE`), and over every draw (no band: an
                    object that shows no error gets (0, 0), which no interval from its pixels can widen)
study's own maps    :data:`STUDY_ROWS`: copies of study's error map of a reflected edge (classical, a room case)
                    or of its wrong-hit region (localized, no iteration) at random places (dead leaves,
                    :func:`study.stats.fields.mosaic`), turned, mirrored and scaled at random, plus correlated noise:
                    the RMSE and the wrong ray fraction (truths analytic: every pixel a uniform draw of the tile)
==================  ===========================================================================================

Each row has its interval *before* (what the tables printed until then: a fixed 64 × 64 grid of pixel blocks
with a percentile bootstrap, Wilson over independent rays, a percentile bootstrap of the median or of the
segments) and *now*. ``power`` rows check the smallest detectable shift over cases
(:func:`study.stats.detectable_shift`): paired differences shifted by it are detected ≈ 80 % of the time.

Deterministic for a seed; ``replicates`` sets the tier (the tests' fast tier 100, ``reports/calibration.md`` and
the slow tests 2000). ``shrink`` < 1 narrows every *now* interval about its estimate: a planted error that the
coverage must flag.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import stats as sps

from study import stats
from study.stats import spatial
from study.stats.fields import (  # the synthetic fields (correlated_field re-exported: the tests draw it here)
    BLOB_MSE,
    EDGE_MSE,
    FIELD_SIGMA,
    LONG_SIGMA,
    SMALL_BLOB_MSE,
    STREAK_SIGMA,
    correlated_field,
    study_wrong_probit,
    study_wrong_truth,
)
from study.stats.fields import blobs as _blobs
from study.stats.fields import disc as _disc
from study.stats.fields import small_disc as _small_disc
from study.stats.fields import streaks as _streaks
from study.stats.fields import streaks_diagonal as _diagonal
from study.stats.fields import study_edge as _study_edge

#: Replicates of the fast tier (tests) and of the slow tier (tests marked slow, reports/calibration.md).
FAST, SLOW = 100, 2000
#: Resamples of the *before* bootstraps in the harness (fewer than the study's 1000: the harness runs thousands).
BEFORE_RESAMPLES = 200
#: Replicates of the *before* intervals (at most): they are the slow part of the pixel rows.
BEFORE_REPLICATES = 500
#: The band a calibrated 95 % interval's coverage must lie in, per tier.
BANDS = {FAST: (0.85, 0.99), SLOW: (0.93, 0.97)}
#: From this many replicates on, a row is judged by the slow tier's band (binomial spread ≤ 1.1 points).
SLOW_FROM = 400


def band(replicates: int) -> tuple[float, float]:
    """The coverage band for a table of ``replicates`` per row: :data:`SLOW`'s from :data:`SLOW_FROM` on."""
    return BANDS[SLOW] if replicates >= SLOW_FROM else BANDS[FAST]


#: Pixel intervals resample the tiles of a BLOCK_GRID × BLOCK_GRID grid over the frame (:func:`pixel_blocks`):
#: 4×4-pixel tiles at 256², 16×16 at 1024².
BLOCK_GRID = 64


def pixel_blocks(mask) -> np.ndarray:
    """(P,) int: the block (tile of the :data:`BLOCK_GRID` × :data:`BLOCK_GRID` grid over the frame; square tiles
    of round(max(H, W) / BLOCK_GRID) ≥ 1 pixels) of each of the P True pixels of ``mask`` (H, W), in the order of
    ``mask``'s True pixels (``img[mask]``), numbered 0 … (blocks used − 1)."""
    mask = np.asarray(mask, bool)
    h, w = mask.shape
    t = max(1, round(max(h, w) / BLOCK_GRID))
    ys, xs = np.nonzero(mask)
    return np.unique((ys // t) * (-(-w // t)) + xs // t, return_inverse=True)[1].reshape(-1)


def mean_cis(
    *samples,
    blocks=None,
    level: float = stats.LEVEL,
    n_resamples: int = stats.N_RESAMPLES,
    seed: int = stats.SEED,
):
    """[(lo, hi), …]: percentile-bootstrap intervals of the means of several samples of the same units (e.g. one
    value per pixel each), resampled together (``scipy.stats.bootstrap`` drawing the blocks, as its ``paired=True``
    does: one draw of units for all, so one pass). Units where any sample is NaN are dropped; fewer than two
    resampled units give (mean, mean).

    ``blocks``: (P,) int, the block of each unit (e.g. :func:`pixel_blocks`): blocks are resampled, not units (a
    block bootstrap: each block's sum and count drawn together, the statistic the ratio of the drawn sums to the
    drawn counts, which is the mean over the drawn units). None: every unit its own block."""
    xs = np.asarray(samples, float).reshape(len(samples), -1)
    keep = ~np.isnan(xs).any(axis=0)
    xs = xs[:, keep]
    mean = xs.mean(axis=1) if xs.shape[1] else np.full(len(samples), math.nan)
    b = np.arange(xs.shape[1]) if blocks is None else np.asarray(blocks).reshape(-1)[keep]
    _, b = np.unique(b, return_inverse=True)
    nb = int(b.max()) + 1 if b.size else 0
    if nb < 2:
        return [(float(v), float(v)) for v in mean]
    # per block: its pixel count and the summed values of each sample, (nb, 1 + k)
    table = np.stack(
        [np.bincount(b, minlength=nb)] + [np.bincount(b, weights=x, minlength=nb) for x in xs], 1
    )

    def ratio_of_drawn_sums(i, axis=-1):  # i (..., nb): drawn block numbers, one row per resample
        rows = np.asarray(i, np.intp).reshape(-1, nb)
        m = len(rows)
        drawn = np.bincount((np.arange(m)[:, None] * nb + rows).ravel(), minlength=m * nb).reshape(m, nb)
        t = drawn @ table  # (m, 1 + k): drawn counts and sums, as one matrix product
        return (t[:, 1:] / t[:, :1]).T.reshape(len(xs), *np.shape(i)[:-1])

    # scipy draws the block numbers (as its paired=True does, with the same draws), the statistic sums the drawn
    # blocks by a matrix product instead of gathering every sample: 6× faster, equal to 1e-15
    res = sps.bootstrap(
        (np.arange(nb),),
        ratio_of_drawn_sums,
        vectorized=True,
        axis=-1,
        n_resamples=n_resamples,
        batch=max(1, min(n_resamples, int(2e7 // nb))),  # the drawn-count matrix is (batch, nb)
        method="percentile",
        confidence_level=level,
        random_state=np.random.default_rng(seed),
    )
    lo, hi = np.atleast_1d(res.confidence_interval.low), np.atleast_1d(res.confidence_interval.high)
    # a constant sample has a degenerate bootstrap (NaN): its interval is its value
    return [
        (float(m if np.isnan(a) else a), float(m if np.isnan(b_) else b_)) for m, a, b_ in zip(mean, lo, hi)
    ]


# ---------------------------------------------------------------------------------------------- synthetic draws
def _pixel_error(rng, before: bool, debias: bool):
    mask = _disc()
    err = 0.5 + correlated_field(rng)
    ref = np.zeros((*mask.shape, 3))
    img = ref + err[..., None]
    sigma = 0.0
    if debias:  # a noisy reference, its noise measured on the pixels as the study does (study.measure.truth)
        noise = rng.normal(0, 0.5, (*mask.shape, 1))
        ref = ref + noise
        sigma = float(np.sqrt(np.mean(noise[mask] ** 2)))
    se = np.mean((img - ref)[mask] ** 2, axis=-1)
    est = math.sqrt(se.mean())
    now, now_debiased = stats.rmse_interval(se, mask, sigma)
    old = None
    if before:
        ((blo, bhi),) = mean_cis(se, blocks=pixel_blocks(mask), n_resamples=BEFORE_RESAMPLES)
        old = (math.sqrt(blo), math.sqrt(bhi))
        if debias:
            old = (stats.debiased_root(blo, sigma), stats.debiased_root(bhi, sigma))
    if debias:
        est = stats.debiased_root(se.mean(), sigma)
        return est, now_debiased, old
    return est, now, old


def _split_term(rng, before: bool):
    mask = _disc()
    a, g = correlated_field(rng), correlated_field(rng)
    b = 0.3 + 0.5 * a + g
    terms = [2 * a[mask] * b[mask], a[mask] ** 2, b[mask] ** 2]
    (now, *_), _ = spatial.mean_intervals(terms, mask, stats.LEVEL)
    old = mean_cis(*terms, blocks=pixel_blocks(mask), n_resamples=BEFORE_RESAMPLES)[0] if before else None
    return float(terms[0].mean()), now, old


def _ray_fraction(rng, before: bool, rays_per_pixel: int = 4):
    mask = _disc()
    p = sps.norm.cdf(-1.5 + correlated_field(rng))[mask]
    pix = np.repeat(np.flatnonzero(mask), rays_per_pixel)
    wrong = rng.random(pix.size) < np.repeat(p, rays_per_pixel)
    ((now,), _) = stats.fraction_cis([wrong], pix, mask.shape)
    return float(wrong.mean()), now, stats.fraction_ci(int(wrong.sum()), wrong.size) if before else None


def _ray_percentile(rng, before: bool, rays_per_pixel: int = 4):
    mask = _disc()
    z = np.repeat(correlated_field(rng)[mask], rays_per_pixel)
    pix = np.repeat(np.flatnonzero(mask), rays_per_pixel)
    v = 0.8 * z + 0.6 * rng.normal(
        size=z.size
    )  # N(0, 1) per ray, 64 % of its variance shared by the pixel's area
    now = stats.quantile_ci(v, 95, pixels=pix, shape=mask.shape)
    return float(np.percentile(v, 95)), now, stats.quantile_ci(v, 95) if before else None


def _case_median(rng, before: bool, n: int):
    v = rng.lognormal(0.0, 1.0, n)
    med, lo, hi, _, _ = stats.case_interval(v)
    return med, (lo, hi), stats.bootstrap_ci(v, np.median, n_resamples=BEFORE_RESAMPLES) if before else None


def _paired(rng, n: int, shift: float = 0.0):
    """(estimate, interval, None): the estimate is the shift; the 'interval' is (−inf, inf) where the test keeps
    the null, else empty (nan, nan) — its coverage of 0 is then 1 − the rejection rate."""
    d = rng.normal(shift, 1.0, n)
    keep = not stats.paired(d, np.zeros(n))["p"] < 1 - stats.LEVEL
    return shift, ((-math.inf, math.inf) if keep else (math.nan, math.nan)), None


def _jod(rng, before: bool, segments: int = 4):
    parts = rng.normal(0.0, 1.0, segments)
    whole = float(parts.mean())
    old = None
    if before:
        ci = sps.bootstrap((parts,), np.mean, n_resamples=2000, method="percentile", random_state=0)
        old = (ci.confidence_interval.low, ci.confidence_interval.high)
    return whole, stats.segment_interval(whole, parts, stats.LEVEL), old


# ------------------------------------------------------------------------------- error fields beyond the tuned one
# (the fields themselves in study.stats.fields: long correlation, streaks, blobs, a small object, study's own maps)
def _field_rmse(rng, before: bool, field, mask, squared: bool = False):
    """(RMSE, its interval by :func:`study.stats.rmse_interval`, as
    :func:`study.measure.case_columns.pixel_columns` writes it, None): the per-pixel error 0.5 + the
    unit-variance ``field`` (truth √1.25), or, ``squared``, the field is the squared error itself."""
    f = field(rng)
    err = np.sqrt(f) if squared else 0.5 + f
    now, _ = stats.rmse_interval(err[mask] ** 2, mask)
    return math.sqrt(float(np.mean(err[mask] ** 2))), now, None


def _small_blobs_shown(rng, before: bool):
    """The blob design on the ≈ 200-pixel object, drawn until a blob reaches into it (:data:`SMALL_BLOB_SHOWN` of
    the draws): an object whose every pixel shows error 0 has the estimate 0 and the interval (0, 0), the same for
    every such draw, which no interval from its pixels can widen (they hold no trace of the errors it did not meet);
    the row asks how the interval holds on the small objects that do show error, and its truth is their mean
    squared error (:data:`SMALL_BLOB_MSE`). The row "… every draw" counts the others too."""
    while True:
        est, now, old = _field_rmse(rng, before, _blobs, _small_disc(), squared=True)
        if est > 0:
            return est, now, old


def _rays_wrong(rng, probit: np.ndarray, mask, rays_per_pixel: int = 4):
    """(wrong fraction, its interval by :func:`study.stats.fraction_cis`, None): ``rays_per_pixel`` rays
    per pixel of ``mask``, each wrong with probability Φ(``probit``) of its pixel."""
    p = sps.norm.cdf(probit)[mask]
    pix = np.repeat(np.flatnonzero(mask), rays_per_pixel)
    wrong = rng.random(pix.size) < np.repeat(p, rays_per_pixel)
    ((now,), _) = stats.fraction_cis([wrong], pix, mask.shape)
    return float(wrong.mean()), now, None


def _field_fraction(rng, before: bool, sigma, mask):
    """The ray-fraction row's design on another field (filter ``sigma``, a random axis) or object ``mask``."""
    z = correlated_field(rng, sigma=sigma)
    return _rays_wrong(rng, -1.5 + (z if rng.random() < 0.5 else z.T), mask)


def _study_wrong(rng, before: bool):
    """The ray-fraction design on the wrong-hit template (:func:`study.stats.fields.study_wrong_probit`)."""
    return _rays_wrong(rng, study_wrong_probit(rng), _disc())


#: The designs on study's own error maps (also measured, with a simulated check of their truths, by
#: scripts/measure_study_fields.py); the last rows of :data:`ROWS`.
STUDY_ROWS = {
    "RMSE, study's reflected-edge map": (
        lambda r, b: _field_rmse(r, b, _study_edge, _disc(), squared=True),
        math.sqrt(EDGE_MSE),
        "pixels of a 40 px disc",
        True,
    ),
    "ray fraction, study's wrong-hit map": (_study_wrong, study_wrong_truth, "4 rays × 5024 pixels", True),
}


#: The truth, n and band of the RMSE rows on the 40 px disc (per-pixel error 0.5 + a unit-variance field) and
#: of the ray-fraction rows on it (probit −1.5 + a unit-variance field).
_DISC_RMSE = (math.sqrt(1.25), "pixels of a 40 px disc", True)
_DISC_RAYS = (float(sps.norm.cdf(-1.5 / math.sqrt(2))), "4 rays × 5024 pixels", True)

#: name → (draw(rng, with_before) → (estimate, now, before or None), truth (or a function giving it), n in words,
#: whether the band applies)
ROWS = {
    "pixel error (RMSE)": (lambda r, b: _pixel_error(r, b, False), *_DISC_RMSE),
    "debiased RMSE": (lambda r, b: _pixel_error(r, b, True), math.sqrt(1.25), "pixels of a 40 px disc", True),
    "split term (signed)": (_split_term, 1.0, "pixels of a 40 px disc", True),
    "ray fraction": (_ray_fraction, float(sps.norm.cdf(-1.5 / math.sqrt(2))), "4 rays × 5024 pixels", True),
    "ray percentile (p95)": (_ray_percentile, float(sps.norm.ppf(0.95)), "4 rays × 5024 pixels", True),
    "case median": (lambda r, b: _case_median(r, b, 12), 1.0, "12 cases", True),
    "case range (n < 10)": (lambda r, b: _case_median(r, False, 3), 1.0, "3 cases", False),
    "paired difference": (lambda r, b: _paired(r, 12), 0.0, "12 cases", True),
    "JOD over segments": (_jod, 0.0, "4 segments", True),
    "RMSE, long correlation (σ 8 px)": (
        lambda r, b: _field_rmse(r, b, lambda g: correlated_field(g, sigma=LONG_SIGMA), _disc()),
        *_DISC_RMSE,
    ),
    "RMSE, streaks (σ 0.8 × 12 px)": (lambda r, b: _field_rmse(r, b, _streaks, _disc()), *_DISC_RMSE),
    "RMSE, sparse heavy-tailed blobs": (
        lambda r, b: _field_rmse(r, b, _blobs, _disc(), squared=True),
        math.sqrt(BLOB_MSE),
        "pixels of a 40 px disc",
        True,
    ),
    "RMSE, ≈ 200-pixel object": (
        lambda r, b: _field_rmse(r, b, correlated_field, _small_disc()),
        math.sqrt(1.25),
        "pixels of an 8 px disc",
        True,
    ),
    "RMSE, ≈ 200 pixels with blobs": (
        _small_blobs_shown,
        math.sqrt(SMALL_BLOB_MSE),
        "pixels of an 8 px disc that show error",
        True,
    ),
    "ray fraction, long correlation (σ 8 px)": (
        lambda r, b: _field_fraction(r, b, LONG_SIGMA, _disc()),
        *_DISC_RAYS,
    ),
    "ray fraction, streaks (σ 0.8 × 12 px)": (
        lambda r, b: _field_fraction(r, b, STREAK_SIGMA, _disc()),
        *_DISC_RAYS,
    ),
    "ray fraction, ≈ 200-pixel object": (
        lambda r, b: _field_fraction(r, b, FIELD_SIGMA, _small_disc()),
        float(sps.norm.cdf(-1.5 / math.sqrt(2))),
        "4 rays × 200 pixels",
        True,
    ),
    **STUDY_ROWS,
    # the streaks turned by 45° (study.stats.fields.streaks_diagonal), last: a row's seed is its place in ROWS
    "RMSE, streaks at 45°": (lambda r, b: _field_rmse(r, b, _diagonal, _disc()), *_DISC_RMSE),
    "ray fraction, streaks at 45°": (lambda r, b: _rays_wrong(r, -1.5 + _diagonal(r), _disc()), *_DISC_RAYS),
    # every draw of the small object with blobs, those that show no error included: no interval can hold there
    "RMSE, ≈ 200 pixels with blobs, every draw": (
        lambda r, b: _field_rmse(r, b, _blobs, _small_disc(), squared=True),
        math.sqrt(BLOB_MSE),
        "pixels of an 8 px disc",
        False,
    ),
}


@dataclass
class Row:
    interval: str
    variant: str  # "now" or "before"
    n: str
    replicates: int
    coverage: float
    width_ratio: float
    contains_estimate: float
    banded: bool

    def flagged(self, band: tuple[float, float]) -> bool:
        """True where a banded row's coverage lies outside ``band``."""
        return self.banded and not band[0] <= self.coverage <= band[1]


def _summary(name, variant, n, est, cis, truth, banded) -> Row:
    lo, hi = np.array([c[0] for c in cis], float), np.array([c[1] for c in cis], float)
    cover = np.mean((lo <= truth) & (truth <= hi))
    tol = 1e-12 * np.abs(est)
    contains = np.mean((lo <= est + tol) & (est - tol <= hi)) if np.isfinite(lo).all() else math.nan
    spread = float(np.std(est))
    finite = np.isfinite(lo) & np.isfinite(hi)
    width = float(np.mean(hi[finite] - lo[finite])) if finite.any() else math.nan
    ratio = width / (2 * sps.norm.ppf(0.5 + stats.LEVEL / 2) * spread) if spread > 0 else math.nan
    return Row(name, variant, n, len(est), float(cover), ratio, float(contains), banded)


def _shrunk(est: float, ci, f: float):
    return est - f * (est - ci[0]), est + f * (ci[1] - est)


def coverage(
    name: str, replicates: int = FAST, seed: int = 0, shrink: float = 1.0, before: int | None = None
) -> list[Row]:
    """The *now* row of one interval type of :data:`ROWS` over ``replicates`` draws, and its *before* row (where
    there is one) over the first ``before`` of them (default min(replicates, :data:`BEFORE_REPLICATES`); 0: none).
    ``shrink``: narrow every *now* interval about its estimate by this factor (a planted error)."""
    draw, truth, n, banded = ROWS[name]
    truth = truth() if callable(truth) else truth
    rng = np.random.default_rng([seed, list(ROWS).index(name)])
    before = min(replicates, BEFORE_REPLICATES) if before is None else before
    est, now, old = [], [], []
    for i in range(replicates):
        e, a, b = draw(rng, i < before)
        est.append(e)
        now.append(_shrunk(e, a, shrink) if shrink != 1 and np.isfinite(a).all() else a)
        old.append(b)
    est = np.array(est, float)
    rows = [_summary(name, "now", n, est, now, truth, banded)]
    if before and old[0] is not None:
        rows.append(_summary(name, "before", n, est[:before], old[:before], truth, banded))
    return rows


def power(n: int, replicates: int = FAST, seed: int = 0) -> float:
    """The share of ``replicates`` draws of n paired normal differences shifted by
    :func:`study.stats.detectable_shift`(n) standard deviations that the Wilcoxon test finds at 5 %."""
    shift = stats.detectable_shift(n)
    rng = np.random.default_rng([seed, 1000 + n])
    return float(np.mean([math.isnan(_paired(rng, n, shift)[1][0]) for _ in range(replicates)]))


def coverage_table(replicates: int = FAST, seed: int = 0) -> tuple[list[Row], dict[int, float]]:
    """Every row of :data:`ROWS` (now and before) and the power at the smallest detectable shift for 6, 12 and
    36 cases."""
    rows = [
        r
        for name in ROWS
        for r in coverage(name, replicates, seed, before=0 if name.startswith("case range") else None)
    ]
    return rows, {n: power(n, replicates, seed) for n in (6, 12, 36)}
