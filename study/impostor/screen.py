"""The camera's own buffer as a view (screen-space ray tracing, McGuire and Mara 2014): z-depth and colour per pixel,
and the camera's perspective projection.

Depth: Embree through every pixel centre of the scene's camera (:mod:`study.scene.camera`, one ray per pixel) into
the environment *without* the object (the reflector is not in its own reflection), stored as z = (p − eye)·f, f
the view axis (inf where the ray leaves an open environment). Colour: the case's Mitsuba render of the environment
without the object (the ``background`` of :func:`study.measure.case.run_case`), what a renderer's colour buffer
holds before the reflective object is shaded.

Projection of a point p (relative to the reference point o; e = eye − o; f, r, u the camera's forward, right, up;
T = tan(fov/2) horizontally, T·H/W vertically): z = (p − e)·f, X = (p − e)·r, Y = (p − e)·u, and the continuous
pixel coordinates px = (X/(z T) + 1) W/2 (columns), py = (1 − Y/(z T H/W)) H/2 (rows); pixel (row i, column j)
covers [j, j+1) × [i, i+1), its centre is the camera ray of :func:`study.scene.camera.camera_rays`.
"""

from __future__ import annotations

import math

import numpy as np

from study.backend import V3, Backend
from study.reference.embree import Tracer
from study.scene import Scene
from study.scene.camera import camera_rays, look_at_basis


def buffers(scene: Scene, tracer: Tracer) -> tuple[np.ndarray, np.ndarray]:
    """(:func:`depth_buffer`, :func:`normal_buffer`) of ``scene``'s camera from one cast of its pixel rays."""
    o, d = camera_rays(scene.camera, 1)
    o, d = o.reshape(-1, 3), d.reshape(-1, 3)
    t, prim = tracer.hits(o, d)
    return _depth(scene, d, t), _normals(scene, tracer, d, prim)


def normal_buffer(scene: Scene, tracer: Tracer) -> np.ndarray:
    """Unit geometric normals of the environment (no object) through every pixel centre, turned towards the camera
    (a surface the camera sees faces it): (H, W, 3) float32, world axes (0 where nothing is hit) — a G-buffer's."""
    o, d = camera_rays(scene.camera, 1)
    o, d = o.reshape(-1, 3), d.reshape(-1, 3)
    return _normals(scene, tracer, d, tracer.hits(o, d)[1])


def _normals(scene: Scene, tracer: Tracer, d: np.ndarray, prim: np.ndarray) -> np.ndarray:
    tri = tracer.mesh.vertices[tracer.mesh.faces].astype(np.float64)  # each triangle's unit normal, once
    n_tri = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    n_tri /= np.maximum(np.linalg.norm(n_tri, axis=1, keepdims=True), 1e-30)
    n = n_tri[np.maximum(prim, 0)]
    n *= np.where(np.sum(n * d, axis=1) > 0, -1.0, 1.0)[:, None]
    n[prim < 0] = 0.0
    return n.reshape(scene.camera.height, scene.camera.width, 3).astype(np.float32)


def depth_buffer(scene: Scene, tracer: Tracer) -> np.ndarray:
    """z-depth of the environment (no object) through every pixel centre: (H, W) float32 (inf: nothing hit)."""
    o, d = camera_rays(scene.camera, 1)
    o, d = o.reshape(-1, 3), d.reshape(-1, 3)
    return _depth(scene, d, tracer.distance(o, d))


def _depth(scene, d: np.ndarray, t: np.ndarray) -> np.ndarray:
    f, _, _ = look_at_basis(scene.camera.eye, scene.camera.target, scene.camera.up)
    return (t * (d @ f)).reshape(scene.camera.height, scene.camera.width).astype(np.float32)


class ScreenView:
    """The camera's depth and colour buffer bound to a backend (module docstring for the projection).

    ``project(p)`` → (px, py, z) of points p relative to o; ``fetch(j, i)`` → [r, g, b, z] of pixel (row i, column j)
    (integer-valued float arrays, on screen); ``eye``, ``forward``, ``right``, ``up`` (numpy, relative to o),
    ``width``, ``height``. The buffer is one square face of side max(W, H) (padding never read), sampled at texel
    centres, so a fetch returns the stored values. ``normals`` (optional, (H, W, 3), :func:`normal_buffer`): a
    G-buffer's normals, read by ``fetch_normal(j, i)``; ``has_normals`` says whether there are any."""

    def __init__(self, depth: np.ndarray, colour: np.ndarray, camera, reference, B: Backend, normals=None):
        self.B, self.height, self.width = B, depth.shape[0], depth.shape[1]
        f, r, u = look_at_basis(camera.eye, camera.target, camera.up)
        self.eye = np.asarray(camera.eye, float) - np.asarray(reference, float)
        self.forward, self.right, self.up = f, r, u
        self.tan_x = math.tan(math.radians(camera.fov) / 2)
        self.tan_y = self.tan_x * self.height / self.width
        self.side = max(self.width, self.height)
        buf = np.zeros((1, self.side, self.side, 4), np.float32)
        buf[0, : self.height, : self.width, :3] = colour
        buf[0, : self.height, : self.width, 3] = np.where(np.isfinite(depth), depth, 3e38)
        self.tex = B.texture(buf)
        self.has_normals = normals is not None
        if normals is not None:
            nb = np.zeros((1, self.side, self.side, 3), np.float32)
            nb[0, : self.height, : self.width] = normals
            self.normal_tex = B.texture(nb)

    @classmethod
    def of_scene(cls, scene: Scene, colour: np.ndarray, tracer: Tracer, B: Backend) -> ScreenView:
        """The buffer of ``scene``'s camera: depth by :func:`depth_buffer`, ``colour`` (H, W, 3) the background,
        normals by :func:`normal_buffer` (both from one cast: :func:`buffers`)."""
        depth, normals = buffers(scene, tracer)
        return cls(depth, colour, scene.camera, scene.reference.point, B, normals=normals)

    def camera_space(self, p: V3):
        """(X, Y, z) of points p relative to o."""
        e = self.eye
        c = V3(p.x - float(e[0]), p.y - float(e[1]), p.z - float(e[2]))
        return tuple(
            c.x * float(a[0]) + c.y * float(a[1]) + c.z * float(a[2])
            for a in (self.right, self.up, self.forward)
        )

    def project(self, p: V3):
        X, Y, z = self.camera_space(p)
        return (
            (X / (z * self.tan_x) + 1.0) * (0.5 * self.width),
            (1.0 - Y / (z * self.tan_y)) * (0.5 * self.height),
            z,
        )

    def fetch(self, j, i) -> list:
        s = float(self.side)
        return self.B.sample(self.tex, j * 0.0, (j + 0.5) / s, (i + 0.5) / s)

    def fetch_normal(self, j, i) -> list:
        """[nx, ny, nz] (world axes) of pixel (row i, column j): one fetch."""
        s = float(self.side)
        return self.B.sample(self.normal_tex, j * 0.0, (j + 0.5) / s, (i + 0.5) / s)

    def on_screen(self, px, py):
        return (px >= 0.0) & (px < float(self.width)) & (py >= 0.0) & (py < float(self.height))
