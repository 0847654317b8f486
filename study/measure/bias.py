"""The signed radiance bias of an image against truth_at_hit: how much brighter (or darker) a method's image is over
the pixels where it can be right, as one number.

``radiance_bias_truth`` = Σ img / Σ truth − 1, summed over the RGB channels of the held object pixels (those whose
every hit the views hold: :func:`study.measure.split.held_pixels`): 0 for an image with the truth's brightness, +0.03
for one 3 % too bright. Where the error columns (RMSE, relMSE) are squares that noise and a wrong search fill, a
uniform gain moves this one linearly and with its sign; the truth's Monte Carlo noise averages over the pixels, so
it is tight from seed to seed (``study check`` holds it in its baseline).
"""

from __future__ import annotations

import numpy as np


def radiance_bias(img: np.ndarray, truth: np.ndarray, mask: np.ndarray) -> float:
    """Σ ``img`` / Σ ``truth`` − 1 over the ``mask``'s pixels and their channels (float64 sums).

    Parameters
    ----------
    img, truth : (H, W, 3) arrays
        The image and truth_at_hit, linear RGB.
    mask : (H, W) bool array
        The pixels summed (the held object pixels).

    Returns
    -------
    float
        The signed relative bias; NaN without pixels or where the truth sums to 0 or is not finite.
    """
    m = np.asarray(mask, bool)
    a = float(np.asarray(img)[m].astype(np.float64).sum())  # the masked pixels first, then float64
    b = float(np.asarray(truth)[m].astype(np.float64).sum())
    if not m.any() or not (np.isfinite(a) and np.isfinite(b)) or b <= 0:
        return float("nan")
    return a / b - 1.0


def bias_columns(img: np.ndarray, truth: np.ndarray, mask: np.ndarray) -> dict:
    """``{"radiance_bias_truth": ...}`` (:func:`radiance_bias`) for one image's row."""
    return {"radiance_bias_truth": radiance_bias(img, truth, mask)}
