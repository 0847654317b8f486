"""Every image column of a case's methods in one pass per reference: the methods' images stacked (M, H, W, 3) and
measured together, what depends only on a reference and the case computed once.

A case measures each method's image against the oracle, the truth and Mitsuba (:mod:`study.measure.metrics`,
:mod:`study.measure.truth`, :mod:`study.measure.split`). Per method that is RMSE, PSNR, SSIM, FLIP, relMSE, the
truth's noise-debiased errors and the error split's per-pixel terms; per reference and case it is the masked
pixels and their LDR encoding, SSIM's crop and the reference's window means, the FLIP reference's filtered colour
and features (on a Dr.Jit backend: :func:`study.measure.flip.flip_stack`), the truth's noise σ, Mitsuba's noise
and its fireflies. :func:`method_columns` computes the latter once and the former over the stack:

* RMSE, PSNR, relMSE and the split's terms are means over the masked pixels of the stack, in numpy (float64);
* SSIM is scikit-image's (``structural_similarity`` with a 7 × 7 uniform window, sample covariance, as
  :func:`study.measure.metrics.ssim` calls it) written over the stack: ``scipy.ndimage.uniform_filter`` with size
  1 along the stack's axis filters each image alone, exactly as scikit-image filters one;
* FLIP runs where :func:`study.measure.metrics.flip_map` runs it: flip-evaluator for ``numpy`` (one call per
  image, on the crop where the images differ), the array code over the whole stack for ``llvm`` and ``cuda``.

The pixel intervals (:func:`study.stats.spatial.mean_intervals` through
:func:`study.measure.case_columns.pixel_columns_stack`, the exposed relMSE's and the split's) take every method's
samples in one call per column group: the mask's own work (its box, pair counts per lag, lag geometry) once per case
(:mod:`study.stats.region`), the samples' FFTs batched, a sample no method changes measured once; each sample's
values are those of a call of its own. The values are those of the per-method path
(``case._image_columns``, kept for the references' rows): ``tests/measure/test_batched_columns.py`` compares them
column by column (on ``numpy`` bit for bit: each image's means are summed as one image's; on ``llvm`` where the
per-method path measured RMSE, PSNR and SSIM with :mod:`study.measure.pixels`, within its 1e-12 of numpy, and FLIP
within float32 rounding of the per-pair array code).
"""

from __future__ import annotations

import numpy as np

from study.measure import bias, case_columns, exposure, metrics, split, truth, workers
from study.measure.metrics import _crop, masked_rows, to_ldr
from study.measure.pixels import K1, K2, WIN  # scikit-image's SSIM: window size, K₁, K₂
from study.stats import spatial
from study.stats.intervals import LEVEL


# ---------------------------------------------------------------------------------------------- one reference
def _rmse(ref_px: np.ndarray, tests_px: np.ndarray) -> np.ndarray:
    """(M,) RMSE of linear radiance: ``ref_px`` (P, 3) the reference's masked pixels, ``tests_px`` (M, P, 3)."""
    if ref_px.size == 0:
        return np.full(len(tests_px), np.nan)
    d = tests_px.astype(float) - ref_px.astype(float)
    return np.sqrt([np.mean(q) for q in d * d])  # each image's (P, 3) summed as one image's: the same bits


def _psnr(ref_ldr: np.ndarray, tests_ldr: np.ndarray) -> np.ndarray:
    """(M,) PSNR (dB, data range 1) of LDR pixels, as scikit-image's ``peak_signal_noise_ratio`` (inf if equal)."""
    if ref_ldr.size == 0:
        return np.full(len(tests_ldr), np.nan)
    mse = np.array([np.mean(q, dtype=np.float64) for q in (ref_ldr - tests_ldr) ** 2])
    with np.errstate(divide="ignore"):
        return np.where(mse == 0, np.inf, 10 * np.log10(1.0 / np.where(mse == 0, 1.0, mse)))


def _window(a: np.ndarray) -> np.ndarray:
    """The 7 × 7 uniform window means of (…, h, w, C) images, each image and channel alone (scipy's reflect)."""
    from scipy.ndimage import uniform_filter

    size = (1,) * (a.ndim - 3) + (WIN, WIN, 1)
    return uniform_filter(a, size=size)


def ssim_moments(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(window mean, window mean of the square) of an LDR reference crop (h, w, C): what SSIM needs of it alone."""
    x = np.asarray(x, np.float64)
    return _window(x), _window(x * x)


def _ssim(x, y, mask, moments=None, y_moments=None) -> np.ndarray:
    """(M,) mean SSIM over ``mask`` (h, w) of LDR crops ``y`` (M, h, w, C) against ``x`` ((h, w, C) with its
    :func:`ssim_moments` given or not, or (M, h, w, C)): scikit-image's map per channel, averaged over channels.
    ``y_moments``: ``y``'s :func:`ssim_moments`, when already computed against another reference."""
    y = np.asarray(y, np.float64)
    x = np.asarray(x, np.float64)
    if moments is not None:
        ux, uxx = moments
    else:
        ux, uxx = _window(x), _window(x * x)
    uy, uyy = y_moments if y_moments is not None else ssim_moments(y)
    uxy = _window(x * y)
    np_ = WIN * WIN
    cov = np_ / (np_ - 1)
    vx, vy, vxy = cov * (uxx - ux * ux), cov * (uyy - uy * uy), cov * (uxy - ux * uy)
    c1, c2 = K1**2, K2**2
    s = ((2 * ux * uy + c1) * (2 * vxy + c2)) / ((ux**2 + uy**2 + c1) * (vx + vy + c2))
    return np.array([float(m.mean(axis=-1)[mask].mean()) for m in s])


def _flip_values(ref, tests, mask, backend: str, refs=None) -> list[np.ndarray]:
    """Per image, the FLIP errors (P,) of its masked pixels against ``ref`` (H, W, 3) or ``refs[i]``, on the crop
    of :func:`study.measure.metrics.flip_values` (the mask's bounding box + FLIP's margin)."""
    if not mask.any():
        return [np.zeros(0, np.float32) for _ in tests]
    cut = _crop(mask, metrics.FLIP_MARGIN, *([ref] if refs is None else []), *tests)
    m, parts = cut[0], cut[1:]
    r, t = (parts[0], np.stack(parts[1:])) if refs is None else (None, np.stack(parts))
    rs = None if refs is None else np.stack(_crop(mask, metrics.FLIP_MARGIN, *refs)[1:])
    maps = flip_maps(r, t, backend, refs=rs)
    return [e[m] for e in maps]


def _differing_any(ref, tests) -> np.ndarray:
    """(H, W) bool: the pixels where some image of ``tests`` (M, H, W, 3) differs from ``ref`` ((H, W, 3) or
    (M, H, W, 3), one per test) in some channel, NaN compared as a value: the union of
    :func:`study.measure.metrics.differing` over the stack, in one pass over the frames (NaN looked at only
    where the values compare unequal)."""
    ref, tests = np.asarray(ref), np.asarray(tests)
    every = np.broadcast_to(ref, tests.shape)
    acc = np.zeros(tests.shape[1:], bool)
    for a, b in zip(every, tests):  # image by image (no (M, H, W, 3) temporary), channels last
        acc |= a != b
    hit = np.logical_or.reduce([acc[..., c] for c in range(acc.shape[-1])])
    ys, xs = np.nonzero(hit)
    a, b = every[:, ys, xs], tests[:, ys, xs]  # (M, K, 3)
    hit[ys, xs] = np.any((a != b) & ~(np.isnan(a) & np.isnan(b)), axis=(0, -1))
    return hit


def flip_maps(ref, tests, backend: str, refs=None) -> np.ndarray:
    """(M, H, W) FLIP maps of ``tests`` (M, H, W, 3) against ``ref`` (H, W, 3) or ``refs`` (M, H, W, 3), as
    :func:`study.measure.metrics.flip_map` makes each (flip-evaluator per image for ``numpy``; for ``llvm`` and
    ``cuda`` one pass of the array code over the stack, the reference's terms once, on the crop where the images
    differ, grown by FLIP's margin)."""
    tests = np.asarray(tests)
    if backend == "numpy":
        return np.stack([metrics.flip_map(ref if refs is None else refs[i], t) for i, t in enumerate(tests)])
    from study.measure import flip

    diff = _differing_any(ref if refs is None else refs, tests) if len(tests) else None
    out = np.zeros(tests.shape[:3], np.float32)
    if diff is None or not diff.any():
        return out
    ys, xs = np.nonzero(diff)
    g = metrics.FLIP_MARGIN
    y0, y1, x0, x1 = max(ys.min() - g, 0), ys.max() + g + 1, max(xs.min() - g, 0), xs.max() + g + 1
    box = (slice(None), slice(y0, y1), slice(x0, x1))
    out[box] = flip.flip_stack(
        None if ref is None or refs is not None else np.asarray(ref)[y0:y1, x0:x1],
        tests[box],
        backend,
        refs=None if refs is None else np.asarray(refs)[box],
    )
    return out


def _tests_of(tests, mask, shared: dict | None) -> dict:
    """What :func:`errors` needs of the test images alone over ``mask``: their masked pixels (``px``), those
    pixels' LDR (``ldr``), SSIM's LDR crop (``crop``) and its :func:`ssim_moments` (``moments``); kept in
    ``shared`` (when given) for the next reference over the same images and mask (the truth, then Mitsuba)."""
    if shared is not None and shared:
        return shared
    px = masked_rows(tests, mask)
    out = {"px": px, "ldr": to_ldr(px)}
    if mask.any():
        crop = to_ldr(np.stack(_crop(mask, 8, *tests)[1:]))
        out |= {"crop": crop, "moments": ssim_moments(crop)}
    if shared is not None:
        shared.update(out)
    return out


def errors(
    ref, tests, *, mask, suffix: str, backend: str, with_flip: bool, fvals=None, refs=None, shared=None
) -> list[dict]:
    """Per test image, :func:`study.measure.metrics.image_errors`'s columns (``rmse_<suffix>``, ``psnr_``,
    ``ssim_``, ``flip_``, ``flip_<suffix>_p95``) against ``ref`` (H, W, 3), or against ``refs`` (M, H, W, 3)
    where each test has its own reference that equals ``ref`` on ``mask`` (the oracle: its unheld pixels take
    the image's value); ``fvals``: the FLIP values over ``mask`` already measured, per image; ``shared``: a dict
    that carries the test images' own terms (:func:`_tests_of`) from one reference to the next over the same
    ``tests`` and ``mask`` (start it empty)."""
    M = len(tests)
    if fvals is None:
        fvals = _flip_values(ref, tests, mask, backend, refs) if with_flip else [np.zeros(0)] * M
    own = _tests_of(tests, mask, shared if refs is None else None)
    ref_px, tests_px = np.asarray(ref)[mask], own["px"]
    e_rmse = _rmse(ref_px, tests_px)
    e_psnr = _psnr(to_ldr(ref_px), own["ldr"])
    if mask.any():
        m, *xs = _crop(mask, 8, *([ref] if refs is None else refs))  # the tests' crop: own["crop"]
        x = to_ldr(xs[0] if refs is None else np.stack(xs))
        e_ssim = _ssim(x, own["crop"], m, ssim_moments(x) if refs is None else None, own["moments"])
    else:
        e_ssim = np.full(M, np.nan)
    return [
        {
            f"rmse_{suffix}": float(e_rmse[i]),
            f"psnr_{suffix}": float(e_psnr[i]),
            f"ssim_{suffix}": float(e_ssim[i]),
            f"flip_{suffix}": float(fv.mean()) if fv.size else np.nan,
            f"flip_{suffix}_p95": float(np.percentile(fv, 95)) if fv.size else np.nan,
        }
        for i, fv in enumerate(fvals)
    ]


# ---------------------------------------------------------------------------------------------- the truth's columns
def truth_columns(
    tests, t: truth.Truth, mitsuba, *, mask, rmse_truth, rmse_mitsuba, terms=None
) -> list[dict]:
    """Per test image, :func:`study.measure.truth.columns` (its numpy path), with the RMSEs already measured by
    :func:`errors`; the noise σ, Mitsuba's noise and fireflies once for all. ``terms``: what
    :func:`truth_terms` gave for the same arguments (else computed here)."""
    sigma, sigma_m, frame, fireflies, rel, exposed = terms or truth_terms(tests, t, mitsuba, mask=mask)
    out = []
    for i in range(len(tests)):
        deb, deb_m = truth.debiased(rmse_truth[i], sigma), truth.debiased(rmse_mitsuba[i], sigma_m)
        out.append({
            "rmse_truth": rmse_truth[i],
            "rmse_truth_debiased": deb,
            "relmse_truth": float(rel[i]),
            "truth_noise_rmse": sigma,
            "truth_noise_flag": truth.noise_flag(sigma, deb),
            "rmse_mitsuba_debiased": deb_m,
            "mitsuba_noise_rmse": sigma_m,
            "mitsuba_noise_flag": truth.noise_flag(sigma_m, deb_m),
            "mitsuba_noise_frame": frame,
            **exposed[i],
            "firefly_fraction": fireflies,
        })  # fmt: skip
    return out


def truth_terms(tests, t: truth.Truth, mitsuba, *, mask, exposed=None) -> tuple:
    """What :func:`truth_columns` needs besides the RMSEs: (σ, Mitsuba's σ, its frame noise, fireflies, relMSE per
    image, the exposed relMSE's columns per image: :func:`exposed_of`, or ``exposed()`` when given)."""
    sigma, sigma_m = truth.noise_rms(t.noise, mask), truth.noise_rms(t.mitsuba_noise, mask)
    frame, fireflies = truth.frame_terms(t, mitsuba)
    ref_px = t.image[mask]
    den = ref_px * ref_px + truth.REL_EPS
    d = masked_rows(tests, mask) - ref_px
    rel = (
        [np.mean(q) for q in d * d / den] if ref_px.size else [np.nan] * len(tests)
    )  # in the images' float32
    exposed = exposed_of(tests, t, mask=mask) if exposed is None else exposed()
    return sigma, sigma_m, frame, fireflies, rel, exposed


def exposed_of(tests, t: truth.Truth, *, mask) -> list[dict]:
    """The exposed relMSE's columns of each image of ``tests`` (truth._interval's, every image in one pass over
    the mask)."""
    return exposure.exposed_stack(
        tests, t.image, t.noise, mask=mask, ev=t.ev,
        intervals=lambda s: [ci[0] for ci, _ in spatial.grouped_intervals(s[:, None], mask, LEVEL)],
    )  # fmt: skip


# ---------------------------------------------------------------------------------------------- a case's methods
def _against_oracle(imgs, r, backend: str):
    """:func:`errors` against the oracle over its held pixels, each image with its own reference (the oracle where
    it holds a value, the image elsewhere), all cut to the held pixels' box + FLIP's margin first: SSIM's and FLIP's
    crops lie inside it, so the values are those of the whole frames. FLIP runs here, the rest in parts
    (:func:`_chunked`); returns the function that gives the columns."""
    on, flips = r.on_held, "oracle" in r.against
    if not on.any():
        return _chunked(
            _errors_of, imgs, r.oracle, mask=on, suffix="oracle", backend=backend, with_flip=flips
        )
    m, keep, oracle, *cut = _crop(on, metrics.FLIP_MARGIN, r.held_px | ~r.mask, r.oracle, *imgs)
    cut = np.stack(cut)
    refs = np.where(keep[..., None], oracle, cut)
    fvals = _flip_values(oracle, cut, m, backend, refs) if flips else None
    return _chunked(_errors_of, cut, oracle, each={"refs": refs, "fvals": fvals}, mask=m, suffix="oracle",
                    backend=backend, with_flip=flips)  # fmt: skip


def _errors_of(tests, ref, **kwargs) -> list[dict]:
    """:func:`errors` with the test images first (for :func:`_chunked`)."""
    return errors(ref, tests, **kwargs)


def _against_both(
    tests, t_img, mitsuba, *, mask, backend: str, against, tflip=None
) -> list[tuple[dict, dict]]:
    """(columns against the truth, against Mitsuba) of each image of ``tests``: :func:`errors` for both, the
    images' own terms (:func:`_tests_of`) computed once; ``tflip``: the FLIP values against the truth."""
    shared: dict = {}
    tr = errors(t_img, tests, mask=mask, suffix="truth", backend=backend, with_flip="truth" in against, fvals=tflip,
                shared=shared)  # fmt: skip
    mi = errors(mitsuba, tests, mask=mask, suffix="mitsuba", backend=backend, with_flip="mitsuba" in against,
                shared=shared)  # fmt: skip
    return list(zip(tr, mi))


def _chunked(fn, imgs, *args, each: dict | None = None, **kwargs):
    """``fn`` (a function of a stack of images returning one entry per image) over parts of ``imgs``, side by side
    on the columns' threads (one part per thread); ``each``: keyword arguments given per image (a list each, or
    None). Returns a function that waits and gives the entries in order: the values of one call over the whole
    stack, as every image's are its own (its means over its pixels, its intervals: a call of its own)."""
    cut = np.linspace(0, len(imgs), min(len(imgs), workers.threads()) + 1).astype(int)
    parts = [
        workers.submit(fn, imgs[a:b], *args, **kwargs,
                       **{k: None if v is None else v[a:b] for k, v in (each or {}).items()})
        for a, b in zip(cut[:-1], cut[1:]) if b > a
    ]  # fmt: skip
    return lambda: [x for p in parts for x in p.result()]


def method_columns(images, r, *, backend: str, intervals: bool) -> tuple[list[dict], list]:
    """(columns, FLIP maps): per method image of ``images`` (M, H, W, 3), the image columns of
    ``case._image_columns`` (a trace over every object pixel), and with ``intervals`` its whole-frame FLIP map
    against the truth (else None); ``r`` the case's references (``case._Refs``). FLIP runs here (on the GPU with
    ``cuda``); every other group runs on the columns' threads (:mod:`study.measure.workers`), in parts of the stack
    (:func:`_chunked`); the values are those of one group after the other over the whole stack."""
    columns, fmaps = method_columns_later(images, r, backend=backend, intervals=intervals)
    return columns(), fmaps


def method_columns_later(images, r, *, backend: str, intervals: bool):
    """:func:`method_columns` that returns once its FLIP ran: (a function that waits for the columns' threads and
    gives the columns, the FLIP maps)."""
    imgs = np.asarray(images)
    M = len(imgs)
    if M == 0:
        return list, []
    mask = r.mask
    # ------------------------------------------------------------------ what needs no FLIP: started first
    sp = _chunked(split.split_stack, imgs, r.truth.image, r.truth.noise, r.oracle, r.oracle_seed, r.oracle_coarse,
                  mask=mask, held_px=r.held_px, intervals=intervals)  # fmt: skip
    bias_cols = _chunked(
        lambda ims: [bias.bias_columns(im, r.truth.image, mask=mask & r.held_px) for im in ims], imgs
    )
    exposed = _chunked(exposed_of, imgs, r.truth, mask=mask)
    terms = workers.submit(truth_terms, imgs, r.truth, r.mitsuba, mask=mask, exposed=exposed)
    # ------------------------------------------------------------------ FLIP against the truth, then its users
    fmaps = list(flip_maps(r.truth.image, imgs, backend)) if intervals else [None] * M
    pxs = _chunked(case_columns.pixel_columns_stack, imgs, r.truth.image, mask=mask, sigma=r.sigma,
                   rel_eps=truth.REL_EPS, each={"emaps": fmaps if intervals else None})  # fmt: skip
    tflip = (
        [np.asarray(f)[mask] for f in fmaps] if intervals and "truth" in r.against
        else None if "truth" in r.against else [np.zeros(0)] * M
    )  # fmt: skip
    here = backend != "numpy" and (tflip is None or "mitsuba" in r.against)  # FLIP left to run on Dr.Jit
    both = (workers.here(_against_both, imgs, r.truth.image, r.mitsuba, mask=mask, backend=backend,
                         against=r.against, tflip=tflip).result if here
            else _chunked(_against_both, imgs, r.truth.image, r.mitsuba, mask=mask, backend=backend,
                          against=r.against, each={"tflip": tflip}))  # fmt: skip
    oracle = _against_oracle(imgs, r, backend)  # its FLIP here, the rest in parts

    def columns() -> list[dict]:
        tr, mi = zip(*both())
        tc = truth_columns(imgs, r.truth, r.mitsuba, mask=mask, rmse_truth=[c["rmse_truth"] for c in tr],
                           rmse_mitsuba=[c["rmse_mitsuba"] for c in mi], terms=terms.result())  # fmt: skip
        cols = zip(oracle(), tr, mi, tc, pxs(), sp(), bias_cols())
        return [{k: v for part in c for k, v in part.items()} for c in cols]

    return columns, fmaps
