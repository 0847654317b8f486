"""Error metrics: geometric (angular error, distance) and image error (RMSE, PSNR, SSIM, FLIP) over a mask.

Images are linear RGB radiance (H, W, 3). RMSE is taken on linear radiance. PSNR, SSIM and FLIP are taken on
LDR images: ``to_ldr`` clips linear radiance to [0, 1] (exposure 1) and encodes sRGB; FLIP runs in its "LDR"
mode on these sRGB images. Image metrics are averaged over the masked pixels only (the object's pixels), so each is
computed on what the masked pixels' values depend on and no more (:func:`_crop`): PSNR on the masked pixels, SSIM
on the mask's bounding box + 8 px (its 7×7 window reaches 3 px), FLIP on the bounding box + 24 px (its filters
reach < 12 px at 67 ppd). The values are those of the whole frame (FLIP bit for bit, SSIM to float64 rounding,
tests/test_bench.py), at a fraction of the cost of a sweep's case.
"""

from __future__ import annotations

import numpy as np


def angular_error(x: np.ndarray, shown: np.ndarray, exact: np.ndarray) -> np.ndarray:
    """Angle in degrees at shading points x between (shown − x) and (exact − x).

    x, shown, exact: (N, 3). NaN where a point is NaN."""
    a, b = shown - x, exact - x
    cos = np.sum(a * b, axis=-1) / (np.linalg.norm(a, axis=-1) * np.linalg.norm(b, axis=-1))
    # arctan2 of |a×b| and a·b keeps precision for tiny angles
    sin = np.linalg.norm(np.cross(a, b), axis=-1) / (np.linalg.norm(a, axis=-1) * np.linalg.norm(b, axis=-1))
    return np.degrees(np.arctan2(sin, cos))


def value_stats(values: np.ndarray, prefix: str, unit: str = "") -> dict[str, float]:
    """``{prefix}_median{unit}``, ``_p95``, ``_max`` of the finite values (NaN if none).

    Rays without a finite value (no hit) are left out here; the share left out is the ``angle_dropped`` column of
    :func:`study.measure.case_columns.ray_columns`, and ``angle_p95_all_deg`` counts them as infinite error."""
    v = np.asarray(values, float)
    v = v[np.isfinite(v)]
    stats = (np.median(v), np.percentile(v, 95), v.max()) if v.size else (np.nan,) * 3
    return {f"{prefix}_{s}{unit}": float(x) for s, x in zip(("median", "p95", "max"), stats)}


def to_ldr(img: np.ndarray) -> np.ndarray:
    """Linear radiance → sRGB-encoded [0, 1] (clip at 1, exposure 1)."""
    c = np.clip(np.asarray(img, np.float64), 0, 1)
    return np.where(c <= 0.0031308, 12.92 * c, 1.055 * np.power(c, 1 / 2.4) - 0.055)


def masked_rows(images, mask) -> np.ndarray:
    """(M, P, C) the masked pixels of a stack of images (M, H, W, C), each image's P pixels contiguous. Boolean
    indexing lays them out pixel-major (strides (C, P·C, 1) items), and a mean over a strided image sums in another
    order than over the same image alone: the last bit of a column would depend on how many images were measured
    together (the columns' threads cut the stack into parts, study.measure.workers)."""
    return np.ascontiguousarray(np.asarray(images)[:, mask])


def rmse(ref: np.ndarray, test: np.ndarray, *, mask: np.ndarray) -> float:
    """Root mean squared error of linear radiance over the masked pixels (all channels)."""
    # the masked pixels first, then float64 (not whole 1024² frames)
    d = np.asarray(test)[mask].astype(float) - np.asarray(ref)[mask].astype(float)
    return float(np.sqrt(np.mean(d * d))) if d.size else np.nan


def _crop(mask: np.ndarray, margin: int, *images):
    """The mask's bounding box grown by ``margin`` pixels (clipped to the frame), cut from mask and images."""
    ys, xs = np.nonzero(mask)
    y0, y1 = max(ys.min() - margin, 0), ys.max() + margin + 1
    x0, x1 = max(xs.min() - margin, 0), xs.max() + margin + 1
    return [a[y0:y1, x0:x1] for a in (mask, *images)]


def psnr(ref: np.ndarray, test: np.ndarray, *, mask: np.ndarray) -> float:
    """PSNR (dB) of the LDR images over the masked pixels (scikit-image, data_range 1)."""
    from skimage.metrics import peak_signal_noise_ratio

    a, b = to_ldr(np.asarray(ref)[mask]), to_ldr(np.asarray(test)[mask])
    if a.size == 0:
        return np.nan
    if np.array_equal(a, b):
        return float("inf")
    return float(peak_signal_noise_ratio(a, b, data_range=1.0))


def ssim(ref: np.ndarray, test: np.ndarray, *, mask: np.ndarray) -> float:
    """Mean SSIM of the LDR images over the masked pixels (scikit-image's SSIM map, 7×7 window)."""
    from skimage.metrics import structural_similarity

    if not mask.any():
        return np.nan
    mask, test, ref = _crop(mask, 8, test, ref)
    _, smap = structural_similarity(to_ldr(ref), to_ldr(test), channel_axis=-1, data_range=1.0, full=True)
    return float(smap.mean(axis=-1)[mask].mean())


#: FLIP's filters reach fewer pixels than this (< 12 px at 67 ppd): a pixel farther from every pixel where two
#: images differ has error 0, and a crop this much larger than a region gives the region's errors bit for bit.
FLIP_MARGIN = 24


def differing(ref: np.ndarray, test: np.ndarray) -> np.ndarray:
    """(H, W) bool: the pixels where two images differ in some channel (NaN compared as a value)."""
    a, b = np.asarray(ref), np.asarray(test)
    return np.any((a != b) & ~(np.isnan(a) & np.isnan(b)), axis=-1)


def flip_map(ref: np.ndarray, test: np.ndarray, backend: str = "numpy") -> np.ndarray:
    """Per-pixel LDR-FLIP error map of two linear-radiance images.

    Parameters
    ----------
    test, ref : (H, W, 3) array
        Linear RGB radiance; both are turned into sRGB LDR images first (:func:`to_ldr`).
    backend : str
        'numpy': flip-evaluator (NVIDIA's C++ code, the reference); 'llvm' or 'cuda': the array implementation
        :mod:`study.measure.flip` on that Dr.Jit backend (within 1e-4 of the reference, ``tests/measure/test_flip.py``).

    Returns
    -------
    (H, W) float32 array
        FLIP error per pixel, in [0, 1] (0: indistinguishable). Only the bounding box of the pixels where the
        images differ, grown by :data:`FLIP_MARGIN`, is filtered: every other pixel's error is 0, as the whole
        frame's (bit for bit, ``tests/measure/test_batched_columns.py``).
    """
    ref, test = np.asarray(ref), np.asarray(test)
    diff = differing(ref, test)
    out = np.zeros(ref.shape[:2], np.float32)
    if not diff.any():  # identical images: FLIP is 0 everywhere
        return out
    ys, xs = np.nonzero(diff)
    y0, y1 = max(ys.min() - FLIP_MARGIN, 0), ys.max() + FLIP_MARGIN + 1
    x0, x1 = max(xs.min() - FLIP_MARGIN, 0), xs.max() + FLIP_MARGIN + 1
    out[y0:y1, x0:x1] = _flip_frame(ref[y0:y1, x0:x1], test[y0:y1, x0:x1], backend)
    return out


def _flip_frame(ref: np.ndarray, test: np.ndarray, backend: str) -> np.ndarray:
    """:func:`flip_map` of the whole frame given."""
    if (
        backend != "numpy"
    ):  # the sRGB encoding on the device too (float32; within 1e-4, tests/measure/test_flip.py)
        from study.measure.flip import ldr_flip_image

        return ldr_flip_image(ref, test, backend, linear=True)
    a, b = (np.ascontiguousarray(to_ldr(x), np.float32) for x in (ref, test))
    import flip_evaluator

    emap, _, _ = flip_evaluator.evaluate(a, b, "LDR", applyMagma=False)
    return np.asarray(emap, np.float32)[..., 0]


def flip_values(
    ref: np.ndarray,
    test: np.ndarray,
    *,
    mask: np.ndarray,
    emap: np.ndarray | None = None,
    backend: str = "numpy",
) -> np.ndarray:
    """LDR-FLIP error (:func:`flip_map` on ``backend``) of each masked pixel of two linear-radiance images, (P,).

    ``emap``: the (H, W) map of :func:`flip_map` for these two images, when the caller already has it (it is then
    not computed again)."""
    if not mask.any():
        return np.zeros(0, np.float32)
    if emap is None:  # only the mask's bounding box + 24 px: FLIP's filters reach < 12 px (67 ppd), so the
        mask, test, ref = _crop(mask, FLIP_MARGIN, test, ref)  # masked pixels' errors are bit-identical
        emap = flip_map(ref, test, backend)
    return np.asarray(emap)[mask]


def flip(
    ref: np.ndarray,
    test: np.ndarray,
    *,
    mask: np.ndarray,
    emap: np.ndarray | None = None,
    backend: str = "numpy",
) -> float:
    """Mean LDR-FLIP error over the masked pixels (:func:`flip_values`; NaN without pixels)."""
    v = flip_values(ref, test, mask=mask, emap=emap, backend=backend)
    return float(v.mean()) if v.size else np.nan


#: Where a case on the CPU's Dr.Jit backend (``llvm``) measures RMSE, PSNR, SSIM and the truth's columns: its array
#: code (:mod:`study.measure.pixels`) or numpy (scikit-image), the faster on the CPU as measured side by side by
#: ``scripts/bench_image_columns.py`` (reports/performance/image-columns-cpu.md): LLVM from crops of
#: :data:`LLVM_MIN_PIXELS` pixels (0.6× numpy's time at 1024² frames' 221² crops, 0.6–0.85× at 93²), numpy below
#: (0.6–2.1× numpy's time over six runs at 256² frames' 67² crops: LLVM's fixed cost per kernel, 2 busy cores).
LLVM_IMAGES = "llvm"
LLVM_MIN_PIXELS = 10_000


def image_backend(backend: str, pixels: int | None = None) -> str:
    """Where a case on ``backend`` measures its image columns over a crop of ``pixels`` pixels: numpy
    (scikit-image, the reference) for ``numpy``, the GPU for ``cuda``, for ``llvm`` :data:`LLVM_IMAGES` from
    :data:`LLVM_MIN_PIXELS` on (or without ``pixels``) and numpy below."""
    if backend == "llvm":
        return LLVM_IMAGES if pixels is None or pixels >= LLVM_MIN_PIXELS else "numpy"
    return backend


def image_errors(
    ref: np.ndarray,
    test: np.ndarray,
    *,
    mask: np.ndarray,
    suffix: str,
    flip_emap: np.ndarray | None = None,
    backend: str = "numpy",
    with_flip: bool = True,
) -> dict[str, float]:
    """``rmse_<suffix>``, ``psnr_<suffix>``, ``ssim_<suffix>``, ``flip_<suffix>`` (mean) and ``flip_<suffix>_p95``
    (the 95th percentile over the pixels: the tail a viewer notices) of ``test`` against ``ref`` over ``mask``
    (``flip_emap``: the FLIP map of the two images, if already computed; ``backend``: the case's backend, where FLIP
    runs, :func:`flip_map`, and RMSE, PSNR and SSIM on :func:`image_backend` of SSIM's crop; ``with_flip`` False:
    the FLIP columns are NaN, not measured)."""
    fv = flip_values(ref, test, mask=mask, emap=flip_emap, backend=backend) if with_flip else np.zeros(0)
    cut = _crop(mask, 8, ref, test) if mask.any() and backend != "numpy" else None  # SSIM's crop
    on = image_backend(backend, None if cut is None else cut[0].size)
    if on == "numpy" or cut is None:
        e = rmse(ref, test, mask=mask), psnr(ref, test, mask=mask), ssim(ref, test, mask=mask)
    else:  # the same three as array code where the images are (study.measure.pixels), on ssim's crop
        from study.measure import pixels

        e = pixels.errors_on(cut[1], cut[2], mask=cut[0], backend=on)
    return {
        f"rmse_{suffix}": e[0],
        f"psnr_{suffix}": e[1],
        f"ssim_{suffix}": e[2],
        f"flip_{suffix}": float(fv.mean()) if fv.size else np.nan,
        f"flip_{suffix}_p95": float(np.percentile(fv, 95)) if fv.size else np.nan,
    }
