"""Shading the object: camera rays → object hit → normal → reflection → method → radiance → Fresnel.

The object's pixels are composited over a Mitsuba render of the room without the object. Each pixel is shaded
from ``supersample²`` stratified sub-pixel rays; a sub-pixel ray that misses the object shows the background.

Dielectric objects (``material.type = "dielectric"``) hand the methods two secondary rays per camera ray: the
reflected ray at the entry point (weight F_in) and the transmitted ray (weight (1 − F_in)(1 − F_out)). With
``render.refraction = "single"`` (the paper) the transmitted ray is the refracted ray at the entry point, looked up
from there; with ``"double"`` it is the ray leaving the object's far side
(:func:`study.optics.interfaces.through_object`),
found exactly (sphere: closed form; mesh: Embree) or through the object's own distance map
(:class:`study.optics.distance_map.DistanceMap`), after at most ``render.internal_bounces`` total internal
reflections. Rays
still inside after that, or whose exit was not found, are dropped from the secondary rays (so no NaN reaches the
metrics) and counted (``dropped_fraction``); their energy is lost, as is the part reflected back inside at a
transmitting exit. The exact reference (Embree) traces the exact outgoing ray: where the methods get the ray from
the distance map, ``exact_x``/``exact_R`` hold the exactly traced one.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field

import numpy as np

from study.errors import StudyError
from study.impostor import ggx
from study.optics import interfaces as optics
from study.optics.distance_map import DistanceMap
from study.scene import Scene, camera_rays, objects


@dataclass
class ObjectRays:
    """The secondary rays leaving the object, one per sub-pixel ray that hits it (M of them)."""

    hit: np.ndarray  # (H, W, S) bool: sub-pixel ray hits the object
    x: np.ndarray  # (M, 3) shading points, world space
    N: np.ndarray  # (M, 3) unit normals
    V: np.ndarray  # (M, 3) unit view directions (camera → x)
    R: np.ndarray  # (M, 3) unit reflected directions
    # ----- dielectrics: K secondary rays (x, R above are then (K, 3)), several per camera ray
    src: np.ndarray | None = None  # (K,) index of the camera ray (among the M hits) each ray belongs to
    weight: np.ndarray | None = None  # (K, 3) Fresnel weight of each secondary ray
    exact_x: np.ndarray | None = None  # (K, 3) exactly traced outgoing rays for Embree (default x, R)
    exact_R: np.ndarray | None = None
    stats: dict = field(default_factory=dict)  # extra per-case numbers for the metrics table

    def exact_rays(self) -> tuple[np.ndarray, np.ndarray]:
        """The exact outgoing rays (origins, directions), one per secondary ray, for the exact reference."""
        return (self.x if self.exact_x is None else self.exact_x), (
            self.R if self.exact_R is None else self.exact_R
        )

    def per_camera_ray(self, values: np.ndarray, *, total: bool = False) -> np.ndarray:
        """Secondary-ray values (K, ...) → camera-ray values (M, ...): the sum (``total``) or the weighted mean
        (Fresnel weight, NaN ignored) of the secondary rays of each camera ray. Identity without ``src``."""
        if self.src is None:
            return values
        M = int(self.hit.sum())
        v = np.asarray(values, float)
        out = np.zeros((M,) + v.shape[1:])
        if total:
            np.add.at(out, self.src, v)
            return out
        w = self.weight.mean(axis=1).reshape((-1,) + (1,) * (v.ndim - 1)) * np.isfinite(v)
        den = np.zeros_like(out)
        np.add.at(out, self.src, np.nan_to_num(v) * w)
        np.add.at(den, self.src, np.broadcast_to(w, v.shape))
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.where(den > 0, out / den, np.nan)

    @property
    def full(self) -> np.ndarray:
        """(H, W) pixels covered by the object in every sub-pixel ray: where image metrics are taken."""
        return self.hit.all(axis=-1)

    def per_pixel(self, values: np.ndarray, fill=np.nan, reduce="mean") -> np.ndarray:
        """Scatter per-ray values (M, ...) to pixels (H, W, ...), averaging the sub-pixel rays that hit.

        Bit for bit ``np.nanmean`` (``reduce="mean"``) or ``np.nanmax`` (else) over the sub-pixel axis of the
        NaN-filled (H, W, S, ...) rays, ``fill`` where a pixel has no finite value: only the P pixels with a hit
        ray are reduced (:class:`_Slots`), in the order numpy reduces the (H, W, S, ...) array."""
        H, W, S = self.hit.shape
        values = self.per_camera_ray(values)
        tail = values.shape[1:]
        if S == 1:  # one ray per pixel (paper quality): its value; a NaN mean over one sample costs 10× more
            v = np.asarray(values, float)
            red = np.where(np.isnan(v), fill, v)
            out = np.full((H, W) + tail, fill, red.dtype)
            _scatter(out, self.hit[..., 0], red)
            return out
        slots = _Slots(self.hit, len(values))
        if reduce == "mean":  # np.nanmean's own sum / count, without its NaN-filled copy
            with np.errstate(invalid="ignore", divide="ignore"):
                red = slots.nanmean(np.asarray(values, float))
        else:
            full = slots.gather(values)  # (P, S, ...) NaN-filled: the rows of the (H, W, S, ...) layout
            with np.errstate(invalid="ignore"), warnings.catch_warnings():
                warnings.simplefilter("ignore", RuntimeWarning)  # all-NaN pixels: filled below
                red = np.nanmax(full, axis=1)
        red = np.where(np.isnan(red), fill, red)
        out = np.full((H, W) + tail, fill, red.dtype)
        _scatter(out, slots.on, red)
        return out


class _Slots:
    """The S sub-pixel slots of the P pixels that at least one of the M rays hits.

    ``on`` (H, W): those pixels; ``index`` (P, S): the ray in each slot (the rays fill the True entries of the
    (H, W, S) ``hit`` in C order, so a pixel's rays are consecutive), 0 where the slot's ray misses;
    ``missing[k]``: the pixels whose slot k misses (few: the object's outline)."""

    def __init__(self, hit: np.ndarray, M: int):
        H, W, S = hit.shape
        h = np.ascontiguousarray(hit, dtype=bool).reshape(H * W, S)
        width = next(w for w in (8, 4, 2, 1) if S % w == 0)  # a pixel's S flags as S / width unsigned words
        words = h.view(np.dtype(f"u{width}"))
        any_word = words[:, 0].copy()
        for k in range(1, words.shape[1]):
            any_word |= words[:, k]
        on = any_word != 0
        rows = h.view(np.dtype((np.void, S)))[:, 0][on].view(bool).reshape(-1, S)  # (P, S) hit flags
        self.on, self.S, self.rows = on.reshape(H, W), S, rows
        if np.count_nonzero(rows) != M:
            raise ValueError(f"{M} ray values for {np.count_nonzero(rows)} sub-pixel rays that hit")
        self.index = np.zeros(rows.shape, np.intp)
        self.index[rows] = np.arange(M)
        self.missing = [np.flatnonzero(~rows[:, k]) for k in range(S)]

    def slot(self, values: np.ndarray, k: int, missing) -> np.ndarray:
        """(P, ...) the values (M, ...) of slot k of each pixel; where it misses ``missing``: a scalar, or one
        value per pixel of ``self.missing[k]``."""
        out = values.take(self.index[:, k], axis=0)
        out[self.missing[k]] = missing
        return out

    def gather(self, values: np.ndarray) -> np.ndarray:
        """(P, S, ...) float64 every slot of each pixel, NaN where its ray misses."""
        out = np.asarray(values, float).take(self.index, axis=0)
        out[~self.rows] = np.nan
        return out

    def nanmean(self, values: np.ndarray) -> np.ndarray:
        """(P, ...) the mean of the finite values (M, ...) float64 of each pixel's rays, NaN where none: bit for
        bit ``np.sum(tot, axis=2) / np.sum(cnt, axis=2)`` of the zero-filled (H, W, S, ...) values ``tot`` and
        their counts ``cnt``. Numpy reduces onto 0.0: with C = prod(...) > 1 values per ray the C channels are its
        inner loop and it adds the S slots one after another, ((0 + v₀) + v₁) + …; with one value per ray the S
        slots of a pixel are contiguous and it adds their pairwise sum (:func:`_pairwise_sum`). Here slot by slot
        over (P, ...) arrays, without numpy's inner loop of C (or S) elements per pixel; the counts are integers
        (exact in any order)."""
        P, tail = len(self.index), values.shape[1:]
        nan_count = np.zeros((P,) + tail, np.min_scalar_type(self.S))
        cols = []
        for k in range(self.S):
            v = self.slot(values, k, np.nan)
            nan = np.isnan(v)
            np.putmask(v, nan, 0.0)
            nan_count += nan
            cols.append(v)
        if math.prod(tail) > 1:
            tot = np.zeros((P,) + tail)
            for v in cols:
                tot += v
        else:
            tot = 0.0 + _pairwise_sum(cols)
        return tot / (self.S - nan_count)


def _pairwise_sum(cols: list) -> np.ndarray:
    """Elementwise sum of the arrays ``cols`` as numpy's ``pairwise_sum`` (``loops_utils.h``) adds a contiguous
    run of n values: below 8 one after another from -0.0; up to 128 in 8 accumulators over strides of 8, combined
    as ((r₀ + r₁) + (r₂ + r₃)) + ((r₄ + r₅) + (r₆ + r₇)), then the rest one by one; above 128 the two halves
    (the first a multiple of 8 long) separately."""
    n = len(cols)
    if n < 8:
        res = np.full(cols[0].shape, -0.0)
        for c in cols:
            res += c
        return res
    if n <= 128:
        r = [c.copy() for c in cols[:8]]
        i = 8
        while i < n - n % 8:
            for j in range(8):
                r[j] += cols[i + j]
            i += 8
        res = ((r[0] + r[1]) + (r[2] + r[3])) + ((r[4] + r[5]) + (r[6] + r[7]))
        for c in cols[i:]:
            res += c
        return res
    half = n // 2
    half -= half % 8
    return _pairwise_sum(cols[:half]) + _pairwise_sum(cols[half:])


def _scatter(out: np.ndarray, on: np.ndarray, rows: np.ndarray) -> None:
    """``out[on] = rows`` for C-contiguous ``out`` (H, W, ...), each pixel's values copied as one item."""
    n = math.prod(out.shape[2:])
    if n <= 1 or not out.flags.c_contiguous:
        out[on] = rows
        return
    item = np.dtype((np.void, out.itemsize * n))
    src = np.ascontiguousarray(rows, out.dtype).reshape(-1, n).view(item)[:, 0]
    out.reshape(-1, n).view(item)[:, 0][on.reshape(-1)] = src


def object_rays(scene: Scene, occluder=None) -> ObjectRays:
    """The camera's sub-pixel rays that hit the object, and their reflected rays. ``occluder(o, d) → t`` (the
    environment's nearest-hit distance, e.g. :meth:`study.reference.embree.Tracer.distance`) drops camera rays
    that meet the environment before the object (a wall between a camera anywhere and the object)."""
    o, d = camera_rays(scene.camera, scene.render.supersample)
    H, W, S, _ = d.shape
    geom = objects.object_geometry(scene)
    t, n = geom.intersect(o.reshape(-1, 3), d.reshape(-1, 3))
    hit = np.isfinite(t)
    if occluder is not None and hit.any():
        o_all = np.broadcast_to(o, d.shape).reshape(-1, 3)
        hit[hit] = t[hit] < np.asarray(occluder(o_all[hit], d.reshape(-1, 3)[hit]))
    V = d.reshape(-1, 3)[hit]
    x = o.reshape(-1, 3)[hit] + V * t[hit, None]
    N = n[hit]
    N = np.where(
        (np.sum(N * V, -1) < 0)[:, None], N, N - 2 * np.sum(N * V, -1, keepdims=True) * V
    )  # face the eye
    N /= np.linalg.norm(N, axis=-1, keepdims=True)
    R = optics.reflect(V, N)
    R /= np.linalg.norm(R, axis=-1, keepdims=True)
    rays = ObjectRays(hit.reshape(H, W, S), x, N, V, R)
    if scene.object.material.type == "dielectric":
        rays = dielectric_rays(scene, rays, geom)
    return rays


def dielectric_rays(scene: Scene, rays: ObjectRays, geom) -> ObjectRays:
    """The secondary rays of a dielectric object: reflected (weight F_in) and transmitted (module docstring)."""
    r, ior = scene.render, scene.object.material.ior
    x, N, V, R = rays.x, rays.N, rays.V, rays.R
    M = len(x)
    F_in = optics.fresnel_dielectric(-np.sum(V * N, axis=-1), 1.0 / ior)
    stats = {"refraction": r.refraction}
    # ----- transmitted rays: single refraction (paper) or through the far side
    if r.refraction == "single":
        T, _ = optics.refract(V, N, 1.0 / ior)
        tx, tR, tw, ok = x, T, 1 - F_in, np.ones(M, bool)
        ex, eR = tx, tR
        stats["exit"] = "none"
    else:
        mode = r.exit if r.exit != "auto" else ("exact" if scene.object.shape == "sphere" else "distance_map")
        exact = optics.through_object(x, V, N, ior, geom.exit, max_bounces=r.internal_bounces)
        if mode == "exact":
            path = exact
        else:
            dmap = DistanceMap(geom, r.object_res)
            path = optics.through_object(x, V, N, ior, dmap.exit, max_bounces=r.internal_bounces)
            stats["exit_lookups_per_ray"] = dmap.lookups_per_ray()
        ok = path.ok & exact.ok
        tx, tR, tw, ex, eR = path.origin, path.out, path.transmittance, exact.origin, exact.out
        stats.update(exit=mode, tir_fraction=float(np.mean(path.bounces[ok] > 0)) if ok.any() else np.nan)
    stats["dropped_fraction"] = float(1 - ok.mean()) if M else 0.0
    # ----- secondary rays: all reflected rays, then the transmitted rays that left the object
    keep = np.nonzero(ok)[0]
    src = np.concatenate([np.arange(M), keep])
    w = np.concatenate([F_in, tw[keep]])
    cat = lambda a, b: np.concatenate([a, b[keep]])  # noqa: E731
    return ObjectRays(
        rays.hit,
        cat(x, tx),
        cat(N, N),
        cat(V, V),
        cat(R, tR),
        src=src,
        weight=np.repeat(w[:, None], 3, axis=1),
        exact_x=cat(x, ex),
        exact_R=cat(R, eR),
        stats=stats,
    )


# ---------------------------------------------------------------------------------------------- Fresnel
def fresnel_approx(n, k, cos_theta) -> np.ndarray:
    """The paper's (Lazányi and Szirmay-Kalos) approximation: ((n−1)² + k² + 4n(1 − cos)⁵) / ((n+1)² + k²).

    n, k: (3,) per RGB channel; cos_theta: (M,) = N·R. Returns (M, 3)."""
    n, k = np.asarray(n, float), np.asarray(k, float)
    c = np.clip(np.asarray(cos_theta, float), 0, 1)[:, None]
    return ((n - 1) ** 2 + k**2 + 4 * n * (1 - c) ** 5) / ((n + 1) ** 2 + k**2)


def fresnel_conductor(n, k, cos_theta) -> np.ndarray:
    """Exact unpolarised Fresnel reflectance of a conductor with complex index n + ik (outside index 1), as
    Mitsuba's ``fresnel_conductor``. Returns (M, 3)."""
    eta, kk = np.asarray(n, float), np.asarray(k, float)
    c = np.clip(np.asarray(cos_theta, float), 1e-12, 1)[:, None]
    c2, s2 = c * c, 1 - c * c
    t0 = eta * eta - kk * kk - s2
    a2pb2 = np.sqrt(np.maximum(t0 * t0 + 4 * eta * eta * kk * kk, 0))
    a = np.sqrt(np.maximum(0.5 * (a2pb2 + t0), 0))
    t1, t2 = a2pb2 + c2, 2 * c * a
    rs = (t1 - t2) / (t1 + t2)
    t3, t4 = c2 * a2pb2 + s2 * s2, t2 * s2
    rp = rs * (t3 - t4) / (t3 + t4)
    return 0.5 * (rs + rp)


def fresnel(scene: Scene, rays: ObjectRays) -> np.ndarray:
    """Fresnel reflectance (M, 3) of the object's material for the object's rays. A rough object (``object.alpha``
    > 0) gets its GGX directional albedo E = ∫ F D G / (4 n·v) dl instead (:func:`study.impostor.ggx.albedo`,
    Fresnel at v·h): the methods' radiance is then the lobe's average, and E × average its reflection."""
    mat = scene.object.material
    alpha = scene.object.alpha
    if alpha > 0 and (rays.weight is not None or mat.type == "dielectric"):
        raise StudyError(
            "the methods shade rough conductors and mirrors only; a rough dielectric is rendered by Mitsuba "
            "alone (set object.alpha = 0 or a conductor material)",
            key="object.alpha",
        )
    if rays.weight is not None:
        return rays.weight
    cos = np.sum(rays.N * rays.R, axis=-1)
    if mat.type == "mirror":
        ones = lambda c: np.ones((len(c), 3))  # noqa: E731
        return ggx.albedo(rays.N, -rays.V, alpha, ones, seed=scene.render.seed) if alpha > 0 else ones(cos)
    if mat.type != "conductor":
        raise StudyError(f"shading of {mat.type!r} objects is not implemented yet", key="object.material")
    f = fresnel_conductor if scene.render.fresnel == "exact" else fresnel_approx
    if alpha > 0:
        return ggx.albedo(rays.N, -rays.V, alpha, lambda c: f(mat.n, mat.k, c), seed=scene.render.seed)
    return f(mat.n, mat.k, cos)


def composite(rays: ObjectRays, reflected: np.ndarray, background: np.ndarray) -> np.ndarray:
    """Image (H, W, 3): sub-pixel rays on the object show ``reflected`` (M, 3), the others the background.

    Bit for bit ``sub.mean(axis=2).astype(np.float32)`` of the (H, W, S, 3) sub-pixel image ``sub`` (in the
    background's dtype): numpy's mean adds the S sub-pixels onto 0 one after another (the 3 channels are the
    inner loop), then divides by ``np.intp(S)``. A pixel without a hit ray adds S copies of its background; the
    P pixels with one take their slots (:class:`_Slots`, a missing ray's slot reads the pixel's background)."""
    H, W, S = rays.hit.shape
    values = rays.per_camera_ray(reflected, total=True)
    bg = np.asarray(background)
    if bg.shape != (H, W, 3) or bg.dtype not in (np.dtype(np.float32), np.dtype(np.float64)):
        sub = np.broadcast_to(bg[:, :, None, :], (H, W, S, 3)).copy()
        sub[rays.hit] = values
        return sub.mean(axis=2).astype(np.float32)
    slots = _Slots(rays.hit, len(values))
    values = np.asarray(values).astype(bg.dtype, copy=False)  # as sub[rays.hit] = values casts
    pixels, bg_rows = np.flatnonzero(slots.on), bg.reshape(-1, 3)
    hits = np.zeros((len(pixels), 3), bg.dtype)
    for k in range(S):
        hits += slots.slot(values, k, bg_rows[pixels[slots.missing[k]]])
    divide = lambda a: np.true_divide(a, np.intp(S), out=a, casting="unsafe")  # noqa: E731  as np.mean divides
    out = np.empty((H, W, 3), bg.dtype)
    for i in range(0, H, 64):  # S copies of the background, a band of rows at a time (in cache)
        band = out[i : i + 64]
        band[...] = 0
        for _ in range(S):
            band += bg[i : i + 64]
        divide(band)
    _scatter(out, slots.on, divide(hits))
    return out if out.dtype == np.float32 else out.astype(np.float32)
