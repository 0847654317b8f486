"""Exposure from an image, and what is measured after it: errors that mean the same in a dark scene, and whether
a picture is mostly fireflies.

* :func:`auto_exposure` (:data:`FRAME_RULE`): the exposure a person (or tev) would set for an image as a whole;
  the run's PNG and viewer use it on Mitsuba's render (:mod:`study.outputs.run_files`).
* **relMSE after exposure** (:func:`exposed_columns`): both images × g, g = 2^EV with EV = :func:`auto_exposure`
  of the truth over the object's pixels (its median at middle grey), then mean((g·a − g·b)² / ((g·b)² + ε)) with
  ε = :data:`EXPOSED_EPS`. The rule is scale-equivariant (a scene 1000× darker gets log2 1000 EV more), so the
  column is the same number for a scene and that scene × k, for any k > 0, while RMSE scales by k. ε = 0.01 is the
  denoising literature's ε for images of order 1 (Rousselle et al. 2011, Bako et al. 2017) on the exposed image:
  √ε = 0.1, about half of middle grey, so a pixel darker than that (the noise-dominated corners) counts its error
  about as an absolute one and cannot dominate the mean, while pixels as bright as the scene's median and brighter
  count relatively. ``truth_noise_relmse``: the truth's own noise (half its two seeds' difference, the variance of
  their mean) in the same unit — the part of every row's relMSE the reference itself brings.
* **fireflies** (:func:`firefly_fraction`): the share of the frame's pixels whose displayed luminance (the
  picture's exposure, :func:`auto_exposure` of the render, clipped at 1) differs between Mitsuba's two seeds by
  more than :data:`FIREFLY_STEP` of the display range. A firefly is a pixel one seed lights and the other does
  not; a converged render repeats itself. A picture over :data:`FIREFLY_LIMIT` is labelled (measured: the McGuire
  Cornell box at 16 spp, 64², 0.7 %; the same box lit by a 1/100-area light and study's point light 3.8 %).
"""

from __future__ import annotations

import math

import numpy as np

from study.measure.metrics import masked_rows

#: Exposure from an image as a whole, as a person (or tev) would set it: the median of its visible luminance (the
#: pixels that show any light) at middle grey, unless that puts more than 5 % of them above 1 (then their 95th
#: percentile at 1).
MIDDLE_GREY, HIGH_PERCENTILE = 0.18, 95.0
FRAME_RULE = f"median of the visible luminance → {MIDDLE_GREY:g}, its p{HIGH_PERCENTILE:g} ≤ 1"
REC709 = (0.2126, 0.7152, 0.0722)
#: ε of the relMSE after exposure (exposed units², module docstring)
EXPOSED_EPS = 1e-2
#: A pixel's displayed luminance differing between the two seeds by more than this (of the [0, 1] display range)
#: is a firefly; a picture with more than FIREFLY_LIMIT of its pixels so is labelled FIREFLIES.
FIREFLY_STEP, FIREFLY_LIMIT = 0.25, 0.02


def luminance(rgb) -> np.ndarray:
    """Rec. 709 luminance of an (..., 3) linear image; an (H, W) or (H, W, 1) image is its own luminance."""
    a = np.asarray(rgb, np.float64)
    return a @ np.asarray(REC709) if a.ndim == 3 and a.shape[-1] == 3 else a.reshape(a.shape[:2])


def auto_exposure(rgb: np.ndarray | None) -> float | None:
    """The exposure (EV: image × 2^EV) of :data:`FRAME_RULE` for an (H, W, 3) or (H, W) linear image; None where
    no pixel shows light."""
    if rgb is None:
        return None
    lum = luminance(rgb)
    lum = lum[np.isfinite(lum) & (lum > 0)]
    if lum.size == 0:
        return None
    mid, high = np.percentile(lum, [50.0, HIGH_PERCENTILE])
    return float(min(np.log2(MIDDLE_GREY / mid), np.log2(1.0 / high)))


def object_exposure(ref: np.ndarray, mask: np.ndarray) -> float:
    """EV of :func:`auto_exposure` over the masked pixels of ``ref`` (0 where none shows light)."""
    ev = auto_exposure(np.asarray(ref, np.float64)[np.asarray(mask, bool)][None]) if np.any(mask) else None
    return 0.0 if ev is None else ev


def exposed_columns(img, ref, noise, *, mask, ev: float, interval=None) -> dict[str, float]:
    """``relmse_truth_exposed`` (and its ``_lo``/``_hi`` where ``interval``, a function of the per-pixel samples
    returning (lo, hi), is given) and ``truth_noise_relmse`` of ``img`` against ``ref`` over ``mask``, both
    exposed by ``ev`` (module docstring); ``truth_exposure_ev`` = ``ev``."""
    mask = np.asarray(mask, bool)
    g = 2.0**ev
    r = g * np.asarray(ref, np.float64)[mask]
    den = r * r + EXPOSED_EPS
    d = g * (np.asarray(img, np.float64)[mask] - np.asarray(ref, np.float64)[mask])
    n = g * np.asarray(noise, np.float64)[mask]
    per_pixel = np.mean(d * d / den, axis=-1)
    out = {
        "relmse_truth_exposed": float(per_pixel.mean()) if per_pixel.size else math.nan,
        "truth_noise_relmse": float(np.mean(n * n / den)) if n.size else math.nan,
        "truth_exposure_ev": float(ev),
    }
    if interval is not None:
        out["relmse_truth_exposed_lo"], out["relmse_truth_exposed_hi"] = (
            interval(per_pixel) if per_pixel.size else (math.nan, math.nan)
        )
    return out


def exposed_stack(
    images, ref, noise, *, mask, ev: float, interval=None, intervals=None
) -> list[dict[str, float]]:
    """:func:`exposed_columns` of each image of ``images`` (M, H, W, 3) against one ``ref``: the reference's
    exposed pixels and its noise's relMSE once, the images' per-pixel relMSE over the stack, ``interval`` per
    image, or ``intervals`` (a function of the (M, P) per-pixel samples returning M (lo, hi)) once for all."""
    mask = np.asarray(mask, bool)
    g = 2.0**ev
    # the masked pixels first, then float64 (not a stack of whole frames: the same values)
    r_px = np.asarray(ref)[mask].astype(np.float64)
    r = g * r_px
    den = r * r + EXPOSED_EPS
    n = g * np.asarray(noise)[mask].astype(np.float64)
    noise_rel = float(np.mean(n * n / den)) if n.size else math.nan
    d = g * (masked_rows(images, mask).astype(np.float64) - r_px)
    per_pixel = np.mean(d * d / den, axis=-1)  # (M, P)
    cis = intervals(per_pixel) if intervals is not None and per_pixel.shape[-1] else None
    out = []
    for i, pp in enumerate(per_pixel):
        row = {
            "relmse_truth_exposed": float(pp.mean()) if pp.size else math.nan,
            "truth_noise_relmse": noise_rel,
            "truth_exposure_ev": float(ev),
        }
        if interval is not None or intervals is not None:
            row["relmse_truth_exposed_lo"], row["relmse_truth_exposed_hi"] = (
                (math.nan, math.nan) if not pp.size else cis[i] if cis is not None else interval(pp)
            )
        out.append(row)
    return out


def firefly_fraction(picture: np.ndarray, noise: np.ndarray) -> float:
    """The share of pixels of ``picture`` (the two seeds' mean, linear RGB) whose displayed luminance differs
    between the seeds (``picture`` ± ``noise``, ``noise`` = half their difference) by more than
    :data:`FIREFLY_STEP` at the picture's own exposure (:func:`auto_exposure`, clipped at 1); NaN without light."""
    ev = auto_exposure(picture)
    if ev is None:
        return math.nan
    g = 2.0**ev
    a, b = (np.clip(g * luminance(picture + s * noise), 0.0, 1.0) for s in (1.0, -1.0))
    return float(np.mean(np.abs(a - b) > FIREFLY_STEP))
