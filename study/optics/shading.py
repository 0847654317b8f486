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
        """Scatter per-ray values (M, ...) to pixels (H, W, ...), averaging the sub-pixel rays that hit."""
        H, W, S = self.hit.shape
        values = self.per_camera_ray(values)
        if S == 1:  # one ray per pixel (paper quality): its value; a NaN mean over one sample costs 10× more
            out = np.full((H, W) + values.shape[1:], np.nan)
            out[self.hit[..., 0]] = values
            return np.where(np.isnan(out), fill, out)
        if (
            reduce == "mean"
        ):  # np.nanmean's own sum / count, without its NaN-filled copy: bit for bit, 2x faster
            ok = ~np.isnan(values)
            tot = np.zeros((H, W, S) + values.shape[1:])
            cnt = np.zeros(tot.shape, np.intp)
            tot[self.hit], cnt[self.hit] = np.where(ok, values, 0.0), ok
            with np.errstate(invalid="ignore", divide="ignore"):
                red = np.sum(tot, axis=2) / np.sum(cnt, axis=2)
            return np.where(np.isnan(red), fill, red)
        out = np.full((H, W, S) + values.shape[1:], np.nan)
        out[self.hit] = values
        with np.errstate(invalid="ignore"), warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)  # all-NaN pixels: filled below
            red = np.nanmean(out, axis=2) if reduce == "mean" else np.nanmax(out, axis=2)
        return np.where(np.isnan(red), fill, red)


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
    """Image (H, W, 3): sub-pixel rays on the object show ``reflected`` (M, 3), the others the background."""
    H, W, S = rays.hit.shape
    sub = np.broadcast_to(background[:, :, None, :], (H, W, S, 3)).copy()
    sub[rays.hit] = rays.per_camera_ray(reflected, total=True)
    return sub.mean(axis=2).astype(np.float32)
