"""Shading the object: camera rays → object hit → normal → reflection → method → radiance → Fresnel.

The object's pixels are composited over a Mitsuba render of the room without the object. Each pixel is shaded
from ``supersample²`` stratified sub-pixel rays; a sub-pixel ray that misses the object shows the background.
"""
from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from study.scene import Scene, camera_rays


@dataclass
class ObjectRays:
    """The secondary rays leaving the object, one per sub-pixel ray that hits it (M of them)."""
    hit: np.ndarray        # (H, W, S) bool: sub-pixel ray hits the object
    x: np.ndarray          # (M, 3) shading points, world space
    N: np.ndarray          # (M, 3) unit normals
    V: np.ndarray          # (M, 3) unit view directions (camera → x)
    R: np.ndarray          # (M, 3) unit reflected directions

    @property
    def full(self) -> np.ndarray:
        """(H, W) pixels covered by the object in every sub-pixel ray: where image metrics are taken."""
        return self.hit.all(axis=-1)

    def per_pixel(self, values: np.ndarray, fill=np.nan, reduce="mean") -> np.ndarray:
        """Scatter per-ray values (M, ...) to pixels (H, W, ...), averaging the sub-pixel rays that hit."""
        H, W, S = self.hit.shape
        out = np.full((H, W, S) + values.shape[1:], np.nan)
        out[self.hit] = values
        with np.errstate(invalid="ignore"), warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)         # all-NaN pixels: filled below
            red = np.nanmean(out, axis=2) if reduce == "mean" else np.nanmax(out, axis=2)
        return np.where(np.isnan(red), fill, red)


def reflect(V: np.ndarray, N: np.ndarray) -> np.ndarray:
    return V - 2 * np.sum(V * N, axis=-1, keepdims=True) * N


def intersect_sphere(o, d, center, radius) -> np.ndarray:
    """Nearest positive ray parameter of rays (o, unit d) with a sphere, inf on a miss: (N,)."""
    L = o - np.asarray(center, float)
    b = np.sum(L * d, axis=-1)
    c = np.sum(L * L, axis=-1) - radius * radius
    disc = b * b - c
    s = np.sqrt(np.maximum(disc, 0))
    t0, t1 = -b - s, -b + s
    t = np.where(t0 > 1e-9, t0, np.where(t1 > 1e-9, t1, np.inf))
    return np.where(disc >= 0, t, np.inf)


def object_rays(scene: Scene) -> ObjectRays:
    o, d = camera_rays(scene.camera, scene.render.supersample)
    H, W, S, _ = d.shape
    t = intersect_sphere(o.reshape(-1, 3), d.reshape(-1, 3), scene.object.center, scene.object.radius)
    hit = np.isfinite(t)
    V = d.reshape(-1, 3)[hit]
    x = o.reshape(-1, 3)[hit] + V * t[hit, None]
    N = (x - np.asarray(scene.object.center)) / scene.object.radius
    N /= np.linalg.norm(N, axis=-1, keepdims=True)
    R = reflect(V, N)
    R /= np.linalg.norm(R, axis=-1, keepdims=True)
    return ObjectRays(hit.reshape(H, W, S), x, N, V, R)


# ---------------------------------------------------------------------------------------------- Fresnel
def fresnel_approx(n, k, cos_theta) -> np.ndarray:
    """The paper's (Lazányi and Szirmay-Kalos) approximation: ((n−1)² + k² + 4n(1 − cos)⁵) / ((n+1)² + k²).

    n, k: (3,) per RGB channel; cos_theta: (M,) = N·R. Returns (M, 3)."""
    n, k = np.asarray(n, float), np.asarray(k, float)
    c = np.clip(np.asarray(cos_theta, float), 0, 1)[:, None]
    return ((n - 1) ** 2 + k ** 2 + 4 * n * (1 - c) ** 5) / ((n + 1) ** 2 + k ** 2)


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
    """Fresnel reflectance (M, 3) of the object's material for the object's rays."""
    mat = scene.object.material
    cos = np.sum(rays.N * rays.R, axis=-1)
    if mat.type == "mirror":
        return np.ones((len(cos), 3))
    if mat.type != "conductor":
        from study.errors import StudyError
        raise StudyError(f"shading of {mat.type!r} objects is not implemented yet", key="object.material")
    f = fresnel_conductor if scene.render.fresnel == "exact" else fresnel_approx
    return f(mat.n, mat.k, cos)


def composite(rays: ObjectRays, reflected: np.ndarray, background: np.ndarray) -> np.ndarray:
    """Image (H, W, 3): sub-pixel rays on the object show ``reflected`` (M, 3), the others the background."""
    H, W, S = rays.hit.shape
    sub = np.broadcast_to(background[:, :, None, :], (H, W, S, 3)).copy()
    sub[rays.hit] = reflected
    return sub.mean(axis=2).astype(np.float32)
