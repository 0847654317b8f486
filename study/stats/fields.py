"""The synthetic error fields of the calibration harness (study.stats.calibration): a stationary Gaussian field,
the designs beyond the one the intervals were tuned on (long correlation, streaks, heavy-tailed blobs, a small
object) and the mosaics (dead leaves) of study's own error maps (a reflected edge, a wrong-hit region) with their
analytic truths.
"""

from __future__ import annotations

import functools
import math
from pathlib import Path

import numpy as np
from scipy import integrate, ndimage
from scipy import stats as sps

#: The synthetic images: a (SIZE, SIZE) frame, the object a disc of DISC px radius, fields filtered at FIELD_SIGMA.
SIZE, DISC, FIELD_SIGMA = 96, 40, 2.0


def disc() -> np.ndarray:
    yy, xx = np.mgrid[:SIZE, :SIZE]
    c = (SIZE - 1) / 2
    return (yy - c) ** 2 + (xx - c) ** 2 < DISC**2


def correlated_field(rng, shape=None, sigma: float = FIELD_SIGMA) -> np.ndarray:
    """A stationary Gaussian field of unit variance: white noise filtered by a Gaussian of ``sigma`` px
    (periodic), rescaled by the filter's norm; ``shape`` default (:data:`SIZE`, :data:`SIZE`)."""
    shape = (SIZE, SIZE) if shape is None else shape
    delta = np.zeros(shape)
    delta[shape[0] // 2, shape[1] // 2] = 1
    norm = np.sqrt(np.sum(ndimage.gaussian_filter(delta, sigma, mode="wrap") ** 2))
    return ndimage.gaussian_filter(rng.normal(size=shape), sigma, mode="wrap") / norm


# ------------------------------------------------------------------------------- error fields beyond the tuned one
#: The error fields the pixel and ray intervals were not tuned on: long correlation (filter σ 8 px),
#: anisotropic streaks (filter σ 0.8 × 12 px, along a random axis: a reflected edge smeared along the edge), sparse
#: heavy-tailed blobs (squared error exp(g) where a σ 3 px field g passes BLOB_LEVEL, 0 elsewhere), and a small
#: object (a disc of SMALL_DISC px radius, ≈ 200 pixels).
LONG_SIGMA, STREAK_SIGMA, BLOB_SIGMA, BLOB_LEVEL, SMALL_DISC = 8.0, (0.8, 12.0), 3.0, 2.0, 8.0
#: E[exp(g); g > BLOB_LEVEL] for a standard normal g: the blob design's true mean squared error.
BLOB_MSE = math.exp(0.5) * float(sps.norm.cdf(1.0 - BLOB_LEVEL))


def small_disc() -> np.ndarray:
    yy, xx = np.mgrid[:SIZE, :SIZE]
    c = (SIZE - 1) / 2
    return (yy - c) ** 2 + (xx - c) ** 2 < SMALL_DISC**2


#: The share of the blob design's draws in which some pixel of the small disc shows an error (a blob reaches into
#: the ≈ 200-pixel object; in the others every pixel's error is 0): :func:`blob_shown_share` over 20,000 fields
#: (seed 0; standard error 0.0006), ``python -c "from study.stats.fields import blob_shown_share as f; print(f())"``.
SMALL_BLOB_SHOWN = 0.2945
#: The blob design's true mean squared error over the small objects that show one: E[S | S > 0] = E[S] / P(S > 0)
#: for the disc's mean S ≥ 0 (0 exactly where no blob reaches in).
SMALL_BLOB_MSE = BLOB_MSE / SMALL_BLOB_SHOWN


def blob_shown_share(fields: int = 20_000, seed: int = 0) -> float:
    """P(some pixel of :func:`small_disc` lies in a blob of :func:`blobs`), estimated over ``fields`` draws of the
    field, each at every placement of the disc: the field is periodic and stationary, so every placement has the
    same probability, and the share of placements where the disc's footprint meets a blob (a maximum filter over
    the footprint, wrapped) is an unbiased estimate of it from one field."""
    ys, xs = np.nonzero(small_disc())
    foot = np.zeros((np.ptp(ys) + 1, np.ptp(xs) + 1), bool)
    foot[ys - ys.min(), xs - xs.min()] = True
    rng = np.random.default_rng(seed)
    return float(
        np.mean(
            [
                ndimage.maximum_filter(
                    correlated_field(rng, sigma=BLOB_SIGMA) > BLOB_LEVEL, footprint=foot, mode="wrap"
                ).mean()  # fmt: skip
                for _ in range(fields)
            ]
        )
    )


def streaks(rng) -> np.ndarray:
    f = correlated_field(rng, sigma=STREAK_SIGMA)
    return f if rng.random() < 0.5 else f.T


#: The streaks turned by 45° (a reflected edge runs at any angle, not only along the pixel axes).
STREAK_ANGLE = 45.0


@functools.cache
def _diagonal_transfer() -> np.ndarray:
    """The periodic transfer function of the anisotropic Gaussian filter of :data:`STREAK_SIGMA` (across, along)
    with its long axis at :data:`STREAK_ANGLE` to the rows, sampled at the periodic pixel displacements and scaled
    to unit L2 norm (so the filtered white noise has unit variance)."""
    d = (np.arange(SIZE) + SIZE // 2) % SIZE - SIZE // 2  # displacements on the torus, −SIZE/2 … SIZE/2 − 1
    dy, dx = np.meshgrid(d, d, indexing="ij")
    a = math.radians(STREAK_ANGLE)
    along, across = dx * math.cos(a) + dy * math.sin(a), -dx * math.sin(a) + dy * math.cos(a)
    k = np.exp(-0.5 * ((across / STREAK_SIGMA[0]) ** 2 + (along / STREAK_SIGMA[1]) ** 2))
    return np.fft.rfft2(k / np.sqrt(np.sum(k**2)))


def streaks_diagonal(rng) -> np.ndarray:
    """The streaks of :func:`streaks` with their long axis at :data:`STREAK_ANGLE` (or its mirror, 180° − it,
    with probability ½): white noise convolved (periodic, by FFT) with the turned anisotropic Gaussian kernel
    sampled on the pixel grid, unit variance (the kernel's L2 norm 1)."""
    f = np.fft.irfft2(np.fft.rfft2(rng.normal(size=(SIZE, SIZE))) * _diagonal_transfer(), s=(SIZE, SIZE))
    return f if rng.random() < 0.5 else f[:, ::-1]


def blobs(rng) -> np.ndarray:
    g = correlated_field(rng, sigma=BLOB_SIGMA)
    return np.where(g > BLOB_LEVEL, np.exp(g), 0.0)


# ------------------------------------------------------------------------------ study's own error maps as templates
#: study/stats/data/study_fields.npz (scripts/make_study_fields.py): the per-pixel error of classical on a small
#: room case (a reflected edge, ``edge``) and the wrong-hit mask of localized(iterations=0) (``wrong``), each on the
#: object's square bounding box (0 off the object).
STUDY_FIELDS = Path(__file__).resolve().parent / "data" / "study_fields.npz"
#: Per placed copy: the amplitude of the edge template, uniform on EDGE_AMPLITUDE (so E[a²] = 13/12), and the level
#: of the wrong-hit template's probit inside its wrong region, uniform on WRONG_LEVEL (WRONG_BACKGROUND outside).
EDGE_AMPLITUDE, WRONG_LEVEL, WRONG_BACKGROUND = (0.5, 1.5), (-0.5, 1.5), -2.5
#: The σ of the correlated noise (filter :data:`FIELD_SIGMA`) added to the edge template's error.
EDGE_NOISE = 0.3
#: The edge design's true mean squared error: E[a²] (a uniform on EDGE_AMPLITUDE) + EDGE_NOISE².
EDGE_MSE = (
    EDGE_AMPLITUDE[0] ** 2 + EDGE_AMPLITUDE[0] * EDGE_AMPLITUDE[1] + EDGE_AMPLITUDE[1] ** 2
) / 3 + EDGE_NOISE**2


@functools.cache
def study_templates() -> tuple[np.ndarray, np.ndarray]:
    """(edge, wrong): the edge error template scaled to unit mean square over its square, and the wrong-hit mask
    (0/1 floats), from :data:`STUDY_FIELDS`."""
    with np.load(STUDY_FIELDS) as f:
        edge, wrong = f["edge"].astype(float), f["wrong"].astype(float)
    return edge / math.sqrt(float(np.mean(edge**2))), wrong


def mosaic(rng, tile: np.ndarray, level) -> np.ndarray:
    """A (:data:`SIZE`, :data:`SIZE`) frame covered by copies of the square ``tile`` at independent uniform
    positions (dead leaves: the first copy drawn lies on top, each later one fills only the pixels still bare, until
    none is), each turned by a random multiple of 90°, mirrored with probability ½ and mapped by ``level(copy,
    rng)``. A copy's corner is uniform over the positions where it meets the frame, so the top copy over a pixel
    holds it at a uniform place of the tile: every pixel sees a uniform draw of the tile's pixels (its expectation
    is the tile's mean), and pixels under different copies are independent.

    Not a lattice of copies (one per tile-sized square at a random offset): a lattice is periodic, its field never
    mixes, and the copies in a region are fixed in number and place by the lattice, not by the errors. On a lattice
    the mean over the 40 px disc varies half as much as the lag window measures (ensemble covariance summed to 8 px
    2.0 × the mean's variance, back to 1.0 by 30 px; the estimate 2.05 × for the edge, 2.30 × for the wrong-hit
    region: ``scripts/diagnose_study_fields.py --lattice``), a regularity no single draw, which spans under two
    periods, can show; copies placed independently leave the pixels' distribution, and so the truths, as they
    were."""
    s = tile.shape[0]
    out, bare = np.zeros((SIZE, SIZE)), np.ones((SIZE, SIZE), bool)
    while bare.any():
        y, x = rng.integers(1 - s, SIZE, size=2)  # the copy's corner: it meets the frame
        t = np.rot90(tile, int(rng.integers(4)))
        t = level(t[:, ::-1] if rng.random() < 0.5 else t, rng)
        ys, xs = slice(max(y, 0), min(y + s, SIZE)), slice(max(x, 0), min(x + s, SIZE))
        inside = t[ys.start - y : ys.stop - y, xs.start - x : xs.stop - x]
        fill = bare[ys, xs]
        out[ys, xs][fill] = inside[fill]
        bare[ys, xs] = False
    return out


def study_edge(rng) -> np.ndarray:
    """The squared error: the edge template's mosaic (amplitude per copy) plus correlated noise of σ
    :data:`EDGE_NOISE` (truth E[a²] + :data:`EDGE_NOISE`²)."""
    edge, _ = study_templates()
    field = mosaic(rng, edge, lambda t, r: r.uniform(*EDGE_AMPLITUDE) * t)
    return (field + EDGE_NOISE * correlated_field(rng)) ** 2


def study_wrong_truth() -> float:
    """The wrong-hit design's true ray fraction: the template's wrong share × E_u[Φ(u/√2)] over the uniform level u
    (by quadrature) + the rest × Φ(:data:`WRONG_BACKGROUND`/√2)."""
    share = float(np.mean(study_templates()[1]))
    lo, hi = WRONG_LEVEL
    inside = integrate.quad(lambda u: sps.norm.cdf(u / math.sqrt(2)), lo, hi)[0] / (hi - lo)
    return share * inside + (1 - share) * float(sps.norm.cdf(WRONG_BACKGROUND / math.sqrt(2)))


def study_wrong_probit(rng) -> np.ndarray:
    """The wrong-hit design's probit of each pixel's wrong-ray probability: the wrong-hit template's mosaic (a
    level uniform on :data:`WRONG_LEVEL` per copy inside the wrong region, :data:`WRONG_BACKGROUND` outside) plus
    the unit-variance correlated field."""
    _, wrong = study_templates()
    level = mosaic(rng, wrong, lambda t, r: np.where(t > 0, r.uniform(*WRONG_LEVEL), WRONG_BACKGROUND))
    return level + correlated_field(rng)
