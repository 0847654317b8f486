"""Many short runs where something is stochastic (Celarek et al. 2019): the error of an image over seeds, and
whether two stochastic renders agree pixel by pixel (Jung et al. 2020).

One run at one seed gives one MSE; the seed moves it. Over S runs (images (S, H, W, 3) of the same case at seeds
0 … S − 1) :func:`mse_over_seeds` gives E[MSE] and Var[MSE] over the seeds and splits E[MSE] into the image's
own variance (the mean over pixels of the per-pixel variance over seeds) and its squared bias (what stays when
the seeds' mean is compared, less the variance the S-run mean still holds). A reference's own noise is measured
the same way against the mean of its other runs (``ref`` None: leave one out).

:func:`welch_map` tests, per tile of :data:`TILE` × :data:`TILE` pixels, whether two renders have the same mean
over their seeds (Welch's unequal variance t-test, ``scipy.stats.ttest_ind(equal_var=False)``, on the channel
mean); under the null the p-values are uniform on [0, 1], so their histogram is flat and :func:`uniformity`
(Kolmogorov–Smirnov against the uniform law, ``scipy.stats.kstest``) keeps it; a bias between the renders piles
them up near 0.
"""

from __future__ import annotations

import math

import numpy as np
from scipy import stats as sps


def _stack(images) -> np.ndarray:
    x = np.asarray(images, float)
    return x[..., None] if x.ndim == 3 else x  # (S, H, W) grey → one channel


def mse_over_seeds(images, ref, mask) -> dict[str, float]:
    """E[MSE], Var[MSE] (sample variance over the seeds), the variance and squared-bias parts of E[MSE], and S,
    of ``images`` (S, H, W[, 3]) against ``ref`` (H, W[, 3]) over ``mask`` (H, W). ``ref`` None: each run against
    the mean of the others (a reference's own noise: E[MSE] = (1 + 1/(S − 1)) × its variance). S < 2: NaN."""
    x = _stack(images)[:, np.asarray(mask, bool)]  # (S, P, C)
    s = len(x)
    if s < 2 or x.shape[1] == 0:
        return dict.fromkeys(("mse_mean", "mse_var", "variance", "bias2"), math.nan) | {"seeds": float(s)}
    if ref is None:
        total = x.sum(axis=0)
        mse = np.array([np.mean((x[i] - (total - x[i]) / (s - 1)) ** 2) for i in range(s)])
        bias2 = 0.0
    else:
        r = _stack(np.asarray(ref, float)[None])[0][np.asarray(mask, bool)]
        mse = np.mean((x - r) ** 2, axis=(1, 2))
    variance = float(np.mean(np.var(x, axis=0, ddof=1)))
    if ref is not None:
        bias2 = float(np.mean((x.mean(axis=0) - r) ** 2)) - variance / s
    return {
        "mse_mean": float(mse.mean()),
        "mse_var": float(mse.var(ddof=1)),
        "variance": variance,
        "bias2": float(bias2),
        "seeds": float(s),
    }


#: Pixels per side of the tiles Welch's test compares: the mean of 2 × 2 pixels is near enough normal for the
#: t-test's p-values to be uniform (per pixel, renders of 16 heavy-tailed samples at 12 seeds each: the
#: Kolmogorov–Smirnov test rejected uniformity in 10 % of 20 simulations, per 2 × 2 tile in 5 %).
TILE = 2


def tiles(images, mask, tile: int = TILE) -> tuple[np.ndarray, np.ndarray]:
    """(runs (S, H // tile, W // tile, C), whole (H // tile, W // tile) bool): the mean over each tile × tile
    tile of ``images`` (S, H, W[, C]) and which tiles lie wholly inside ``mask`` (H, W)."""
    x, mask = _stack(images), np.asarray(mask, bool)
    h, w = (d // tile * tile for d in mask.shape)
    s, c = len(x), x.shape[-1]
    runs = x[:, :h, :w].reshape(s, h // tile, tile, w // tile, tile, c).mean(axis=(2, 4))
    whole = mask[:h, :w].reshape(h // tile, tile, w // tile, tile).all(axis=(1, 3))
    return runs, whole


def welch_map(a, b, mask, tile: int = TILE) -> np.ndarray:
    """(H // tile, W // tile) the two-sided p-value of Welch's t-test per tile (:func:`tiles`; ``tile`` 1: per
    pixel) between the runs of ``a`` (S, H, W[, C]) and of ``b`` (S', H, W[, C]), on their channel means; NaN
    for a tile not wholly in ``mask``, and where both runs are constant."""
    (xa, whole), (xb, _) = tiles(a, mask, tile), tiles(b, mask, tile)
    out = np.full(whole.shape, np.nan)
    with np.errstate(invalid="ignore", divide="ignore"):
        out[whole] = sps.ttest_ind(
            xa.mean(axis=-1)[:, whole], xb.mean(axis=-1)[:, whole], axis=0, equal_var=False
        ).pvalue
    return out


def uniformity(p) -> float:
    """The Kolmogorov–Smirnov p-value of the finite ``p`` against the uniform law on [0, 1] (NaN if none): small
    where the per-pixel p-values are not uniform, i.e. the two renders differ somewhere."""
    v = np.asarray(p, float).reshape(-1)
    v = v[np.isfinite(v)]
    return float(sps.kstest(v, "uniform").pvalue) if v.size else math.nan
