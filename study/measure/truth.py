"""The references a method's image is measured against (truth_at_hit, Mitsuba's render) and their noise.

Three images of the object's pixels, all built from the very sub-pixel rays the methods shade (same pixel
sampling) and composited over the same object-free background:

* ``oracle_map`` — the exact hit shaded with what the reference point's views hold (:mod:`study.measure.split`:
  the impostor read towards a hit o sees, the background along an escaping ray, and no value — a marked pixel —
  where the hit is hidden from o).
* ``truth_at_hit`` — the radiance arriving along each exact secondary ray, path traced by Mitsuba in the scene
  *without* the object (:func:`study.reference.mitsuba.radiance_along`), with the impostor's bounce budget
  (``render.max_depth`` counted from the ray's origin, as the impostor's faces were from the reference point).
  Neither it nor the methods see the object's own shadow or interreflection. A rough object (``object.alpha``
  > 0): the GGX lobe's average radiance at each shading point, path traced along directions sampled from the
  lobe (:func:`lobe_at_hit`). Rendered with two seeds
  (``render.spp`` samples per ray each): the mean is the truth, half their difference its noise.
* ``mitsuba`` — Mitsuba's own camera render with the object (kept: the end-to-end comparison a user would make);
  it differs from the methods' setting by the object's shadow and interreflection and by one bounce on the
  reflected path. Also rendered with two seeds, so its noise is stated too.

Noise-debiased RMSE: √max(0, RMSE² − σ²), σ² the mean squared noise of the reference over the same pixels
(σ² of a two-seed mean from the seeds' half difference). relMSE: mean((a − b)² / (b² + ε)), ε = :data:`REL_EPS`
(absolute: in a dark scene it is the MSE / ε). The relMSE after exposure, the same in a scene and in that scene
× k, the truth's noise in its unit, and the picture's fireflies: :mod:`study.measure.exposure`.

The split of a method's error into search, visibility, representation and noise, over every object pixel, and
the oracle (``oracle_map``) are in :mod:`study.measure.split`.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass, field

import numpy as np

from study import backend as backends
from study import stats
from study.cache import Cache, content_key
from study.impostor import ggx
from study.measure import exposure
from study.measure.metrics import _crop, image_backend, rmse
from study.optics import shading
from study.reference.mitsuba import radiance_along
from study.scene import Scene
from study.scene.sources import key_fields
from study.stats import spatial

REL_EPS = 1e-2  # ε of relMSE, (W/m²/sr)²
SEED_OFFSET = 7919  # the second seed of every two-seed Mitsuba reference


@dataclass
class Truth:
    image: np.ndarray  # (H, W, 3) truth_at_hit composited: Fresnel-weighted, over the background
    noise: np.ndarray  # (H, W, 3) its noise: half the two seeds' difference (Fresnel-weighted)
    along: np.ndarray  # (K, 3) the radiance along each exact secondary ray (two seeds' mean, no Fresnel)
    mitsuba_noise: np.ndarray  # (H, W, 3) the same for Mitsuba's camera render with the object
    ev: float = 0.0  # the truth's exposure over the object's pixels (study.measure.exposure.object_exposure)
    #: :func:`frame_terms` once made (with the Mitsuba render they were made of): the same for every image
    made: list = field(default_factory=list, init=False, repr=False, compare=False)


def truth_at_hit(scene: Scene, cache: Cache, rays: shading.ObjectRays) -> tuple[np.ndarray, np.ndarray]:
    """Radiance along each exact secondary ray, (K, 3) twice: seeds ``render.seed`` and ``+ SEED_OFFSET``; for a
    rough object (``object.alpha`` > 0) the GGX lobe's average instead (:func:`lobe_at_hit`)."""
    origins, dirs = rays.exact_rays()
    s = key_fields(scene)  # files by their bytes (a rough object's alpha among them)
    s["render"] = {k: v for k, v in s["render"].items() if k not in ("cube_res", "cube_spp", "object_res")}
    rough = scene.object.alpha > 0
    out = []
    for seed in (scene.render.seed, scene.render.seed + SEED_OFFSET):
        key = content_key(s, seed, "truth-lobe-v1" if rough else "truth-at-hit-v1")
        make = (
            (lambda: lobe_at_hit(scene, rays, seed))  # noqa: B023
            if rough
            else (lambda: radiance_along(scene, origins, dirs, spp=scene.render.spp, seed=seed))  # noqa: B023
        )
        out.append(cache.get("truth_at_hit", key, make, code=(radiance_along, lobe_at_hit)).reshape(-1, 3))
    return out[0], out[1]


#: GGX directions per ray of the rough truth (each path traced with render.spp / LOBE_SAMPLES samples)
LOBE_SAMPLES = 16


def lobe_at_hit(scene: Scene, rays: shading.ObjectRays, seed: int) -> np.ndarray:
    """The truth of a rough object, (M, 3): per shading point, ``LOBE_SAMPLES`` directions importance-sampled
    from its GGX lobe (:mod:`study.impostor.ggx`, seeded), the radiance along each path traced by Mitsuba in the
    scene without the object (``render.spp`` / ``LOBE_SAMPLES`` samples each, so as many paths as the mirror
    truth), averaged with the weights G (v·h)/((n·h)(n·v)): the lobe's average radiance, which the case multiplies
    by the albedo E as it does the methods'. Like the mirror truth it leaves out the object's shadow and
    interreflection — and the highlight of the point light (a delta light no image of the room holds), which
    Mitsuba's camera render of a rough object shows."""
    B = backends.get("numpy")
    alpha, K = scene.object.alpha, min(LOBE_SAMPLES, scene.render.spp)
    n, v = B.vec(rays.N), B.vec(-rays.V)
    u = np.random.default_rng((seed, 1)).random((K, 2, len(rays.x)))  # not the methods' stream of seed
    d, W = ggx.lobe_samples(B, n, v, alpha, u)
    spp = max(1, scene.render.spp // K)
    L = radiance_along(scene, np.tile(rays.x, (K, 1)), d, spp=spp, seed=seed).reshape(K, -1, 3)
    num, den = (L * W).sum(0), W.sum(0)
    along_R = radiance_along(scene, rays.x, rays.R, spp=spp, seed=seed) if (den == 0).any() else None
    return np.where(den > 0, num / np.maximum(den, 1e-30), along_R if along_R is not None else 0.0)


@dataclass
class TruthPair:
    """:func:`truth_at_hit`'s two seeds of a case, computed on the first call only (the truth and exact shading,
    :func:`study.measure.inputs.exact_shading`, read them)."""

    scene: Scene
    cache: Cache
    rays: shading.ObjectRays
    seeds: tuple | None = None

    def __call__(self) -> tuple[np.ndarray, np.ndarray]:
        if self.seeds is None:
            self.seeds = truth_at_hit(self.scene, self.cache, self.rays)
        return self.seeds

    def along(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The exact rays (origins, directions) and the radiance along them (the two seeds' mean)."""
        t1, t2 = self()
        return (*self.rays.exact_rays(), (t1 + t2) / 2)


#: Two rays are one ray when their origins lie within this share of the scene's size and their unit directions
#: within this distance (the methods' rays are float32 copies of the exact rays relative to the reference point:
#: their rounding, ~1e-7, is a hundredth of it).
SAME_RAY = 1e-5


def same_rays(
    ref_o: np.ndarray, ref_d: np.ndarray, origins: np.ndarray, dirs: np.ndarray, size: float
) -> np.ndarray:
    """(N,) bool: which of (``origins``, ``dirs``) are the rays of (``ref_o``, ``ref_d``) in the same order, within
    :data:`SAME_RAY` (origins over ``size``, the scene's extent); none where the two sets differ in length (a
    method hands the case's rays in the case's order, or other rays)."""
    o, d = np.asarray(origins, float), np.asarray(dirs, float)
    if o.shape != np.shape(ref_o) or d.shape != np.shape(ref_d):
        return np.zeros(len(o), bool)
    with np.errstate(invalid="ignore"):
        return (np.abs(o - ref_o).max(-1) <= SAME_RAY * size) & (np.abs(d - ref_d).max(-1) <= SAME_RAY)


def build(
    scene: Scene,
    cache: Cache,
    rays: shading.ObjectRays,
    F: np.ndarray,
    background: np.ndarray,
    mitsuba: tuple[np.ndarray, np.ndarray],
    pair: tuple[np.ndarray, np.ndarray] | None = None,
) -> Truth:
    """The truth image and the noise images (module docstring); ``mitsuba`` = the camera render's two seeds,
    ``pair`` = :func:`truth_at_hit`'s two seeds where the case already has them."""
    t1, t2 = truth_at_hit(scene, cache, rays) if pair is None else pair
    zero = np.zeros_like(background)
    image = shading.composite(rays, (t1 + t2) / 2 * F, background)
    return Truth(
        image=image,
        noise=shading.composite(rays, (t1 - t2) / 2 * F, zero),
        along=(t1 + t2) / 2,
        mitsuba_noise=(mitsuba[0] - mitsuba[1]) / 2,
        ev=exposure.object_exposure(image, rays.full),
    )


def noise_rms(noise: np.ndarray, mask: np.ndarray) -> float:
    """σ: root mean square of a noise image over the masked pixels (NaN if none)."""
    d = noise[mask]
    return float(np.sqrt(np.mean(d * d))) if d.size else np.nan


def debiased(error: float, sigma: float) -> float:
    """√max(0, error² − σ²): the RMSE the reference's own noise σ does not explain; NaN where either is NaN
    (``max(0.0, nan)`` is 0.0: an unknown σ would read as no error)."""
    d = error * error - sigma * sigma
    return float("nan") if np.isnan(d) else float(np.sqrt(max(0.0, d)))


def relmse(a: np.ndarray, b: np.ndarray, mask: np.ndarray) -> float:
    """mean((a − b)² / (b² + ε)) over the masked pixels and channels, ε = REL_EPS."""
    d, r = (a - b)[mask], b[mask]
    return float(np.mean(d * d / (r * r + REL_EPS))) if d.size else np.nan


def columns(
    img: np.ndarray, truth: Truth, mitsuba: np.ndarray, *, mask: np.ndarray, backend: str = "numpy", made=None
) -> dict[str, float]:
    """The truth columns of one method's image (or the oracle's) over ``mask``: errors against truth_at_hit (raw,
    debiased, relMSE) and against Mitsuba debiased (module docstring); their means measured on
    :func:`study.measure.metrics.image_backend` of ``backend`` (numpy: the functions above), or ``made``: what
    :func:`means` gave for the same arguments. Then, on numpy, the columns of :mod:`study.measure.exposure`: relMSE
    after exposure with its pixel interval, the truth's noise in its unit, and the fireflies of Mitsuba's render."""
    sigma, rmse_truth, sigma_m, rmse_mitsuba, relmse_truth = made or means(
        img, truth, mitsuba, mask=mask, backend=backend
    )
    rmse_truth_debiased, rmse_mitsuba_debiased = debiased(rmse_truth, sigma), debiased(rmse_mitsuba, sigma_m)
    return {
        "rmse_truth": rmse_truth,
        "rmse_truth_debiased": rmse_truth_debiased,
        "relmse_truth": relmse_truth,
        "truth_noise_rmse": sigma,
        "truth_noise_flag": noise_flag(sigma, rmse_truth_debiased),
        "rmse_mitsuba_debiased": rmse_mitsuba_debiased,
        "mitsuba_noise_rmse": sigma_m,
        "mitsuba_noise_flag": noise_flag(sigma_m, rmse_mitsuba_debiased),
        "mitsuba_noise_frame": frame_terms(truth, mitsuba)[0],
        **exposure.exposed_columns(
            img, truth.image, truth.noise, mask=mask, ev=truth.ev, interval=_interval(mask)
        ),
        "firefly_fraction": frame_terms(truth, mitsuba)[1],
    }


def means(
    img: np.ndarray, truth: Truth, mitsuba: np.ndarray, *, mask: np.ndarray, backend: str = "numpy"
) -> tuple[float, float, float, float, float]:
    """(σ, RMSE against the truth, Mitsuba's σ, RMSE against Mitsuba, relMSE) of :func:`columns`: the part that
    runs on the backend's arrays (Dr.Jit on ``cuda`` and ``llvm``: on the thread that owns them)."""
    box = None  # only the mask's bounding box travels
    if backend != "numpy" and mask.any():
        box = _crop(mask, 0, img, truth.image, mitsuba, truth.noise, truth.mitsuba_noise)
    on = "numpy" if box is None else image_backend(backend, box[0].size)
    if on != "numpy":  # the same means as array code where the images are
        from study.measure import pixels

        names = ("image", "truth", "mitsuba", "truth_noise", "mitsuba_noise")
        m = pixels.truth_errors(dict(zip(names, box[1:])), mask=box[0], backend=on, rel_eps=REL_EPS)
        sigma, rmse_truth, sigma_m = (float(np.sqrt(m[k])) for k in ("truth_noise", "truth", "mitsuba_noise"))
        return sigma, rmse_truth, sigma_m, float(np.sqrt(m["mitsuba"])), m["relmse"]
    sigma, rmse_truth = noise_rms(truth.noise, mask), rmse(truth.image, img, mask=mask)
    sigma_m, rmse_mitsuba = noise_rms(truth.mitsuba_noise, mask), rmse(mitsuba, img, mask=mask)
    return sigma, rmse_truth, sigma_m, rmse_mitsuba, relmse(img, truth.image, mask)


_made = threading.Lock()


def frame_terms(truth: Truth, mitsuba: np.ndarray) -> tuple[float, float]:
    """(:func:`frame_noise` of Mitsuba's noise, :func:`study.measure.exposure.firefly_fraction` of its render):
    whole-frame numbers of the case, not of an image (each a few hundred ms at 1024²), made once and kept on
    ``truth`` for every image measured against it (its references' rows, each part of its methods' stack)."""
    with _made:
        for m, terms in truth.made:
            if m is mitsuba:
                return terms
        terms = frame_noise(truth.mitsuba_noise), exposure.firefly_fraction(mitsuba, truth.mitsuba_noise)
        truth.made.append((mitsuba, terms))
        return terms


def _interval(mask: np.ndarray):
    """The 95 % interval of the mean of per-pixel samples over ``mask`` (spatially correlated pixels)."""
    return lambda samples: spatial.mean_intervals([samples], mask, stats.LEVEL)[0][0]


#: A reference whose own noise σ exceeds this share of the error it debiases cannot resolve that error (Whittle
#: et al. 2017: a reference must be much less noisy than what it measures): the ``*_noise_flag`` columns.
NOISE_SHARE = 1 / 3
#: σ of a normal distribution over the median of its absolute values (the MAD's consistency constant).
MAD_TO_SIGMA = 1.4826


def noise_flag(sigma: float, error: float) -> float:
    """1.0 where a reference's noise σ exceeds :data:`NOISE_SHARE` of a method's (debiased) ``error`` against it,
    0.0 where not, NaN where either is unknown."""
    if not (np.isfinite(sigma) and np.isfinite(error)):
        return float("nan")
    return float(sigma > NOISE_SHARE * error)


def frame_noise(noise: np.ndarray) -> float:
    """A robust σ of a noise image (half two seeds' difference) over its whole frame and channels:
    :data:`MAD_TO_SIGMA` × the median absolute value. Over every pixel, not the object's few hundred, and blind
    to fireflies, so it moves little from seed to seed (1.1–1.6 % in ``study check``'s cases) and grows with fewer
    samples: × √2 for normal noise, +13 % for Mitsuba at half the check's 16 samples (its skewed noise's median
    moves less than its RMS), 9.7 of those seed-to-seed sd."""
    d = np.abs(np.asarray(noise, float)).reshape(-1)
    d = d[np.isfinite(d)]
    return float(MAD_TO_SIGMA * np.median(d)) if d.size else float("nan")
