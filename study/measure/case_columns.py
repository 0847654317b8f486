"""A case's per-ray and per-pixel columns with their intervals (the statistics themselves live in :mod:`study.stats`),
and the wrong fraction at tolerances with one meaning.

Units of uncertainty (what a column averages, and what is correlated within it); each interval's coverage is
measured by simulation with a known truth (:mod:`study.stats.calibration`, ``reports/calibration.md``):

* **rays** for per-ray columns (``wrong_fraction*``, ``angle_*``, ``dist_*``): the object's secondary rays of one
  case. Neighbouring rays share texels and surfaces, so they are not independent draws: fractions get a Wilson
  score interval at the effective number of rays, n over the design effect measured from the per-pixel counts'
  spatial autocovariance (:func:`fraction_cis`, :func:`study.stats.spatial.fraction_intervals`; it stays honest
  at 0 % and 100 %); percentiles get a distribution-free order-statistic interval over the rays
  (:func:`quantile_ci`, exact for independent rays).
* **pixels** for image columns (``rmse_*``, ``relmse_*``, ``flip_*``, the error split's ``dec_*``): the object's
  pixels of one case, spatially correlated (a wrong reflection is a blob of pixels, not independent evidence per
  pixel): the mean ± t·√variance, the variance summed from the image's own autocovariance over a lag window sized
  by its measured correlation length (:func:`study.stats.spatial.mean_intervals`; ``corr_px``). RMSE-like
  columns take the interval of the mean squared error and transform its ends, so each interval contains its
  estimate.
* **cases** for a table's summary: the median over cases with the interpolated order-statistic interval
  (:func:`median_ci`) from :data:`MIN_CASES_CI` cases on, else their range (:func:`case_interval`), and paired
  comparisons of two methods over the same cases (:func:`paired`: Wilcoxon signed-rank), with the smallest shift
  such a comparison detects (:func:`detectable_shift`).

A bootstrap (:func:`bootstrap_ci`, for statistics without a closed form) is percentile, :data:`N_RESAMPLES`
resamples, seed :data:`SEED` (deterministic), level :data:`LEVEL`.
"""

from __future__ import annotations

import math

import numpy as np

from study.measure.metrics import masked_rows
from study.stats import spatial
from study.stats.intervals import LEVEL, debiased_root, fraction_cis, quantile_ci, root_bounds

#: The fixed absolute tolerances of ``wrong_fraction_<tol>`` (metres, name suffix): the same distance at every
#: cube resolution, unlike the texel-relative ``wrong_fraction_texel``. They also sample the wrong-versus-tolerance
#: curve (:func:`tolerance_curve`).
TOLERANCES = {"1mm": 0.001, "3mm": 0.003, "1cm": 0.01, "3cm": 0.03, "10cm": 0.1, "30cm": 0.3}
#: The tolerances whose wrong fraction gets an interval (``_lo``/``_hi``).
TOLERANCES_CI = ("1cm", "3cm", "10cm")
#: The angular tolerance of ``wrong_fraction_0p5deg``: the shown point is wrong when |shown − exact| subtends more
#: than this angle seen from the shading point x (|shown − exact| > |exact − x|·tan θ), degrees.
ANGLE_TOL_DEG = 0.5
#: The share of worst pixels ``*_trim`` columns leave out (0.1 %, at least one pixel).
TRIM = 0.001


# ---------------------------------------------------------------------------------------------- per ray
def error_distance(outcomes, x, exact) -> np.ndarray:
    """Per ray, the distance |shown − exact| that fixed tolerances are compared with (m): ``inf`` for NO_HIT and
    for a point at infinity that the texel-relative classification did not call correct, 0 for one it did (both
    at infinity, same direction within one texel), else :attr:`Outcomes.dist`."""
    from study.measure.outcomes import CORRECT, NO_HIT

    c, d = np.asarray(outcomes.cls), np.asarray(outcomes.dist, float)
    return np.where(c == NO_HIT, np.inf, np.where(np.isnan(d), np.where(c == CORRECT, 0.0, np.inf), d))


def tolerance_curve(err: np.ndarray, tolerances=tuple(TOLERANCES.values())) -> np.ndarray:
    """The wrong fraction at each fixed tolerance (m): the share of rays with ``err`` > tolerance (no hit counts
    as wrong at every tolerance)."""
    e = np.asarray(err, float)
    return np.array([np.mean(e > t) if e.size else math.nan for t in tolerances])


def ray_columns(outcomes, angle, hidden, x, exact, *, pixels=None, shape=None) -> dict[str, float]:
    """The columns with counts, intervals and fixed tolerances of one method in one case (resampling unit: rays).

    Parameters
    ----------
    outcomes : study.measure.outcomes.Outcomes
        The rays' classes against the exact hits (texel-relative tolerance ε).
    angle : (N,) array
        Angular error per ray, degrees (NaN where nothing is shown).
    hidden : (N,) bool array
        The exact hit is hidden from the reference point.
    x, exact : (N, 3) arrays
        The rays' origins (shading points) and exact hits.
    pixels, shape : (N,) int array and (H, W), optional
        Each ray's flat pixel index in the frame (:func:`study.stats.spatial.ray_pixels`): the fractions'
        intervals are then clustered by pixel (:func:`fraction_cis`; neighbouring rays share texels), else over
        independent rays.

    Returns
    -------
    dict
        ``n_rays``, ``n_hidden``, ``n_wrong`` (counts behind every fraction); ``rays_deff``: the design effect
        of ``wrong_fraction`` (its variance over the binomial one, NaN without ``pixels``);
        ``wrong_fraction_texel`` (= the texel-relative ``wrong_fraction``: ε = max(1 cm, one texel)) with
        ``_lo``/``_hi``, and ``_lo``/``_hi`` of
        ``wrong_fraction_visible``/``_hidden``; ``wrong_fraction_<tol>`` for each fixed tolerance of
        :data:`TOLERANCES` (no hit = wrong), with intervals for :data:`TOLERANCES_CI`; ``wrong_fraction_0p5deg``
        (angular tolerance :data:`ANGLE_TOL_DEG` seen from x); ``angle_dropped`` / ``dist_dropped``: the share of
        rays that ``angle_*`` / ``dist_*`` leave out (no hit; for dist also points at infinity);
        ``angle_p95_all_deg``: the 95th percentile of the angle with dropped rays as infinite error (inf when more
        than 5 % are dropped); ``angle_median_deg_lo``/``_hi``, ``angle_p95_deg_lo``/``_hi``,
        ``dist_p95_lo``/``_hi``: order-statistic intervals (:func:`quantile_ci`, clustered by pixel with
        ``pixels``) over the rays the statistic keeps.
    """
    from study.measure.outcomes import CORRECT

    c = np.asarray(outcomes.cls)
    hidden = np.asarray(hidden, bool)
    wrong = c != CORRECT
    err = error_distance(outcomes, x, exact)
    ang = np.asarray(angle, float)
    out = {"n_rays": int(c.size), "n_hidden": int(hidden.sum()), "n_wrong": int(wrong.sum())}
    reach = np.linalg.norm(np.asarray(exact, float) - np.asarray(x, float), axis=-1)
    with np.errstate(invalid="ignore"):
        flags = {
            "wrong_fraction_texel": wrong,
            **{f"wrong_fraction_{name}": err > tol for name, tol in TOLERANCES.items()},
            "wrong_fraction_0p5deg": ~(err <= reach * math.tan(math.radians(ANGLE_TOL_DEG))),
        }
    for name, f in flags.items():
        out[name] = float(f.mean()) if c.size else math.nan
    ci = ["wrong_fraction_texel", *(f"wrong_fraction_{t}" for t in TOLERANCES_CI), "wrong_fraction_0p5deg"]
    cis, deff = fraction_cis([flags[k] for k in ci], pixels, shape)
    out["rays_deff"] = float(deff[0])
    for part, sel in (("visible", ~hidden), ("hidden", hidden)):
        ci.append(f"wrong_fraction_{part}")
        cis += fraction_cis([wrong[sel]], None if pixels is None else np.asarray(pixels)[sel], shape)[0]
    for name, (lo, hi) in zip(ci, cis):
        out[f"{name}_lo"], out[f"{name}_hi"] = lo, hi
    fa, fd = np.isfinite(ang), np.isfinite(np.asarray(outcomes.dist, float))
    out["angle_dropped"] = float(1 - fa.mean()) if c.size else math.nan
    out["dist_dropped"] = float(1 - fd.mean()) if c.size else math.nan
    full = np.where(fa, ang, np.inf)
    out["angle_p95_all_deg"] = float(np.percentile(full, 95, method="inverted_cdf")) if c.size else math.nan
    px = (lambda sel: None) if pixels is None else (lambda sel: np.asarray(pixels)[sel])
    for name, v, p, sel in (
        ("angle_median_deg", ang[fa], 50, fa),
        ("angle_p95_deg", ang[fa], 95, fa),
        ("dist_p95", np.asarray(outcomes.dist)[fd], 95, fd),
    ):
        out[f"{name}_lo"], out[f"{name}_hi"] = quantile_ci(v, p, pixels=px(sel), shape=shape)
    return out


# ---------------------------------------------------------------------------------------------- per pixel
def _mean(x, axis=-1):
    return np.mean(x, axis=axis)


def trimmed_mean(values, trim: float = TRIM) -> float:
    """The mean of ``values`` without the largest ``trim`` share of them (at least one left out)."""
    return _trimmed_sorted(np.sort(np.asarray(values, float)), trim)


def _trimmed_sorted(v: np.ndarray, trim: float = TRIM) -> float:
    """:func:`trimmed_mean` of values ``v`` already sorted (ascending)."""
    drop = max(1, math.ceil(trim * v.size))
    return float(v[: v.size - drop].mean()) if v.size > drop else math.nan


def pixel_columns(
    img, ref, *, mask, sigma: float, rel_eps: float, suffix: str = "truth", emap=None, shared=None
) -> dict:
    """Intervals and robust variants of one image's errors against ``ref`` over ``mask`` (pixels, spatially
    correlated: :mod:`study.stats.spatial`).

    Returns ``n_pixels``, ``corr_px`` (the squared error's correlation length, pixels); ``rmse_<suffix>_lo``/
    ``_hi`` (the interval of the mean squared error, :func:`study.stats.spatial.mean_intervals`, then √),
    ``rmse_<suffix>_debiased_lo``/``_hi`` (the same bounds debiased by the reference's noise σ, taken as known:
    √max(0, b² − σ²); σ must be measured over the same ``mask`` as the estimate's),
    ``relmse_<suffix>_lo``/``_hi`` (relMSE with ε = ``rel_eps``), ``flip_<suffix>_lo``/
    ``_hi`` (when the FLIP map ``emap`` is given); ``rmse_<suffix>_trim`` / ``rmse_<suffix>_debiased_trim``: the
    RMSE without the worst :data:`TRIM` of pixels (≥ 1 pixel); ``sqerr_top_share_<suffix>``: the share of the
    summed squared error that those worst pixels carry (near 1: the RMSE is decided by a handful of pixels).
    ``shared``: a dict the calls of one ``ref``, ``mask`` and ``rel_eps`` pass along (several images of a case),
    which keeps the reference's masked pixels and relMSE denominators for the next call."""
    return pixel_columns_stack(np.asarray(img)[None], ref, mask=mask, sigma=sigma, rel_eps=rel_eps, suffix=suffix,
                               emaps=None if emap is None else [emap], shared=shared)[0]  # fmt: skip


def pixel_columns_stack(
    imgs, ref, *, mask, sigma: float, rel_eps: float, suffix: str = "truth", emaps=None, shared=None
) -> list[dict]:
    """:func:`pixel_columns` of each image of ``imgs`` (M, H, W, 3) with its FLIP map of ``emaps`` (M maps, or
    None): the same values, every image's intervals in one call (:func:`study.stats.spatial.grouped_intervals`:
    one batched pass over the mask)."""
    mask = np.asarray(mask, bool)
    if shared is None or "r" not in shared:  # the masked pixels first, then float64 (not whole frames)
        r = np.asarray(ref)[mask].astype(float)
        shared = {} if shared is None else shared
        shared["r"], shared["den"] = r, r * r + rel_eps
    r, den = shared["r"], shared["den"]
    d = masked_rows(imgs, mask).astype(float) - r
    dd = d * d
    se = np.mean(dd, axis=-1)  # (M, P) per pixel, mean over channels: mean(se) = RMSE²
    rel = np.mean(dd / den, axis=-1)
    names = [f"rmse_{suffix}", f"relmse_{suffix}"] + ([] if emaps is None else [f"flip_{suffix}"])
    groups = [
        [se[i], rel[i]] + ([] if emaps is None else [np.asarray(emaps[i])[mask].astype(float)])
        for i in range(len(se))
    ]
    measured = (
        spatial.grouped_intervals(groups, mask, LEVEL) if r.shape[0]
        else [([(math.nan,) * 2] * 3, [math.nan])] * len(groups)
    )  # fmt: skip
    return [
        _pixel_row(se[i], names, cis, float(lengths[0]), suffix, sigma)
        for i, (cis, lengths) in enumerate(measured)
    ]


def _pixel_row(se: np.ndarray, names: list[str], intervals, length: float, suffix: str, sigma: float) -> dict:
    """:func:`pixel_columns`' columns of one image from its squared errors ``se`` (P,) and the intervals of the
    means of its samples ``names``."""
    out = {"n_pixels": int(se.size), "corr_px": length}
    cis = dict(zip(names, intervals))
    (lo, hi), (dlo, dhi) = root_bounds(*cis.pop(f"rmse_{suffix}"), sigma)  # the MSE's interval, rooted
    out[f"rmse_{suffix}_lo"], out[f"rmse_{suffix}_hi"] = lo, hi
    out[f"rmse_{suffix}_debiased_lo"], out[f"rmse_{suffix}_debiased_hi"] = dlo, dhi
    for name, (a, b) in cis.items():
        out[f"{name}_lo"], out[f"{name}_hi"] = a, b
    ranked = np.sort(se)  # sorted once: the trimmed mean and the worst pixels' share
    tm = _trimmed_sorted(ranked)
    out[f"rmse_{suffix}_trim"] = math.sqrt(tm) if tm == tm else math.nan
    out[f"rmse_{suffix}_debiased_trim"] = debiased_root(tm, sigma)
    total = float(se.sum())
    top = ranked[::-1][: max(1, math.ceil(TRIM * se.size))].sum() if se.size else math.nan
    out[f"sqerr_top_share_{suffix}"] = float(top / total) if total > 0 else math.nan
    return out
