"""The image columns as array code on a Dr.Jit backend (``llvm`` on the CPU, ``cuda`` on a GPU), so that a case
measures its images where its methods ran, as :mod:`study.measure.flip` does FLIP.

Each function here has a twin that stays the reference and the path of backend ``numpy``: RMSE, PSNR and SSIM of
:mod:`study.measure.metrics` (PSNR and SSIM by scikit-image) and the truth's columns of
:mod:`study.measure.truth` (relMSE, the noise RMS, the debiased RMSE). The array code follows them step by step
in float64, over the very pixels they use, so the values agree to float64 rounding (``tests/measure/test_pixels.py``:
within 1e-5, seen ≤ 1e-12):

* RMSE of linear radiance and the LDR MSE behind PSNR (:func:`study.measure.metrics.to_ldr`: clip to [0, 1],
  sRGB) are means over the masked pixels and their channels.
* SSIM is scikit-image's ``structural_similarity`` as :func:`study.measure.metrics.ssim` calls it: per channel a
  7×7 uniform window (separated, one pass along x, one along y), sample covariance (``NP / (NP − 1)``, NP = 49),
  K₁ = 0.01, K₂ = 0.03, data range 1; the map averaged over channels, then over the masked pixels. It is computed
  on the same crop (:func:`study.measure.metrics._crop`: the mask's bounding box + 8 px, clipped to the frame, cut
  by the caller), and the crop's borders are reflected as ``scipy.ndimage.uniform_filter`` reflects them
  (``d c b a | a b c d``): the crop is padded by the window's reach in numpy (``np.pad`` ``symmetric`` is that
  reflection) before it is uploaded.

Images are (H, W, 3) numpy arrays of linear radiance; only their crop travels to the backend, as float64.
"""

from __future__ import annotations

import math

import numpy as np

from study import backend as backends

#: scikit-image's SSIM constants: window size, K₁, K₂ (data range 1).
WIN, K1, K2 = 7, 0.01, 0.03
#: How far the SSIM window reaches on either side of a pixel.
REACH = (WIN - 1) // 2


class _Frame:
    """A crop of several images and the mask on one Dr.Jit backend: flat row-major float64 channels."""

    def __init__(self, B, mask: np.ndarray, images: list[np.ndarray], *, pad: int = 0):
        self.B, self.dr, self.m = B, B.dr, B.m
        if pad:  # scipy's 'reflect' border (d c b a | a b c d) is numpy's 'symmetric'
            mask = np.pad(mask, pad)
            images = [
                np.pad(np.asarray(a), ((pad, pad), (pad, pad), (0, 0)), mode="symmetric") for a in images
            ]
        self.h, self.w = mask.shape
        self.count = int(mask.sum())
        self.mask = self.m.Bool(np.ascontiguousarray(mask.reshape(-1)))
        self.images = [
            [
                self.m.Float64(np.ascontiguousarray(np.asarray(a)[..., c].reshape(-1), np.float64))
                for c in range(3)
            ]
            for a in images
        ]

    def mean(self, values) -> float:
        """Mean over the masked pixels of one or several per-pixel arrays (summed per pixel first: one
        reduction)."""
        dr = self.dr
        return float(dr.sum(dr.select(self.mask, sum(values[1:], values[0]), 0.0))[0]) / (
            self.count * len(values)
        )

    def shifted(self, a, k: int, axis: int):
        """``a`` moved by k pixels along ``axis`` (1: x, 0: y) as a flat array (index + k or + k·width, clamped to
        the array): right wherever the window stays inside the padded crop, which is everywhere a masked pixel's
        window reads (no division per pixel)."""
        dr, m = self.dr, self.m
        n = self.w * self.h
        step = dr.opaque(m.Int32, k if axis == 1 else k * self.w)  # one kernel for every size and shift
        i = dr.clip(dr.arange(m.Int32, n) + step, 0, dr.opaque(m.Int32, n - 1))
        return dr.gather(type(a), a, m.UInt32(i))

    def windows(self, x: list, y: list) -> list:
        """The 7×7 uniform window's means of x, y, x², y² and xy for each channel pair of ``x`` and ``y`` (one pass
        along x over the images themselves, the products formed there, then one pass along y): 5 per channel."""
        sums = []
        for xc, yc in zip(x, y):
            s = [0.0] * 5
            for k in range(-REACH, REACH + 1):
                a, b = (self.shifted(c, k, 1) if k else c for c in (xc, yc))
                s = [s[0] + a, s[1] + b, s[2] + a * a, s[3] + b * b, s[4] + a * b]
            sums += s
        self.dr.eval(*sums)
        out = []
        for a in sums:
            t = a
            for k in range(-REACH, REACH + 1):
                if k:
                    t = t + self.shifted(a, k, 0)
            out.append(t * (1.0 / (WIN * WIN)))
        self.dr.eval(*out)
        return out


def srgb(dr, c):
    """:func:`study.measure.metrics.to_ldr` of one float64 channel: clip to [0, 1], encode sRGB."""
    c = dr.clip(c, 0.0, 1.0)
    return dr.select(c <= 0.0031308, 12.92 * c, 1.055 * dr.power(dr.maximum(c, 1e-300), 1 / 2.4) - 0.055)


def _squares(a: list, b: list) -> list:
    return [(p - q) * (p - q) for p, q in zip(a, b)]


def ssim_map(F: _Frame, x: list, y: list):
    """The per-pixel SSIM of two LDR images (three float64 channels each), averaged over the channels."""
    cov = WIN * WIN / (WIN * WIN - 1.0)
    c1, c2 = K1 * K1, K2 * K2
    out, means = None, F.windows(x, y)
    for c in range(len(x)):  # per channel, as scikit-image with channel_axis
        ux, uy, uxx, uyy, uxy = means[5 * c : 5 * c + 5]
        vx, vy, vxy = cov * (uxx - ux * ux), cov * (uyy - uy * uy), cov * (uxy - ux * uy)
        s = ((2 * ux * uy + c1) * (2 * vxy + c2)) / ((ux * ux + uy * uy + c1) * (vx + vy + c2))
        out = s if out is None else out + s
    out = out * (1.0 / len(x))
    F.dr.eval(out)
    return out


def errors_on(ref: np.ndarray, test: np.ndarray, *, mask: np.ndarray, backend: str) -> tuple[float, ...]:
    """(RMSE, PSNR, SSIM) of ``test`` against ``ref`` over ``mask`` on ``backend`` ('llvm' or 'cuda'): the twins of
    :func:`study.measure.metrics.rmse`, :func:`~study.measure.metrics.psnr` and
    :func:`~study.measure.metrics.ssim` (NaN without pixels; PSNR inf where the LDR images are equal). SSIM is taken
    on the frame given, its borders reflected: the caller hands over the crop (:func:`study.measure.metrics._crop`,
    the mask's bounding box + 8 px), as :func:`~study.measure.metrics.ssim` takes it."""
    if not mask.any():
        return np.nan, np.nan, np.nan
    F = _Frame(backends.get(backend), mask, [ref, test], pad=REACH)
    a, b = F.images
    dr = F.dr
    la, lb = [srgb(dr, c) for c in a], [srgb(dr, c) for c in b]
    dr.eval(*la, *lb)
    rmse = math.sqrt(F.mean(_squares(a, b)))
    mse = F.mean(_squares(la, lb))
    psnr = float("inf") if mse == 0 else 10.0 * math.log10(1.0 / mse)
    return rmse, psnr, F.mean([ssim_map(F, la, lb)])


def truth_errors(images: dict[str, np.ndarray], *, mask: np.ndarray, backend: str, rel_eps: float) -> dict:
    """The means over ``mask`` that :func:`study.measure.truth.columns` takes, on ``backend``: ``images`` holds
    ``image``, ``truth``, ``mitsuba``, ``truth_noise`` and ``mitsuba_noise``; returns the mean squares
    ``truth`` (image − truth), ``mitsuba`` (image − mitsuba), ``truth_noise`` and ``mitsuba_noise``, and
    ``relmse`` (mean of (image − truth)² / (truth² + rel_eps)). NaN without pixels. Only the masked pixels count:
    the caller may hand over the mask's bounding box alone."""
    keys = ("image", "truth", "mitsuba", "truth_noise", "mitsuba_noise")
    if not mask.any():
        return dict.fromkeys(("truth", "mitsuba", "truth_noise", "mitsuba_noise", "relmse"), np.nan)
    F = _Frame(backends.get(backend), mask, [images[k] for k in keys])
    img, tru, mit, tn, mn = F.images
    d = _squares(img, tru)
    return {
        "truth": F.mean(d),
        "mitsuba": F.mean(_squares(img, mit)),
        "truth_noise": F.mean([c * c for c in tn]),
        "mitsuba_noise": F.mean([c * c for c in mn]),
        "relmse": F.mean([q / (r * r + rel_eps) for q, r in zip(d, tru)]),
    }
