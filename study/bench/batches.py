"""The bench's inputs: ray batches, the room's triangles (optionally with a heightfield) and the impostor texels.

Batches
    fig4      : the secondary rays of the fig4 scene with the object at one position (``shading.object_rays``,
                camera res², 1 sample per pixel);
    close-up  : the same with the camera zoomed onto the object (every pixel sees it: a full frame of coherent
                secondary rays);
    synthetic : origins uniform in a cube of ±``extent`` m around the reference point, uniform unit directions,
                fixed seed; and the same rays sorted by direction (:func:`direction_sorted`, ray reordering).
Each batch names the camera whose depth buffer the screen-space methods search (``ssr``, ``ssr_hiz``): the frame
its rays were made in (the synthetic batches: the scene's camera at the fig4 batch's resolution).
Impostor: exact distances from the reference point through every texel centre (:func:`study.impostor.capture.
distances_from`, Embree on the same triangles); the RGB channels are a stand-in (|direction|): what a lookup
costs does not depend on texel values.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from study import backend as backends
from study.impostor import analytic, cubemap
from study.impostor.capture import distances_from
from study.optics.shading import object_rays
from study.reference.embree import Tracer
from study.scene import Scene


@dataclass
class Batch:
    name: str
    x: np.ndarray  # (N, 3) world-space origins
    R: np.ndarray  # (N, 3) unit directions
    camera: Any = None  # the camera of the screen buffer (study.scene camera), None: none


def scene_rays(scene: Scene, position, res: int) -> Batch:
    """Secondary (reflected) rays of ``scene`` with the object at ``position``, camera res² and 1 sample/pixel."""
    sc = scene.with_updates(
        {"object.center": list(position), "camera.width": res, "camera.height": res, "render.supersample": 1}
    )
    r = object_rays(sc)
    p = ", ".join(f"{c:g}" for c in position)
    return Batch(f"fig4 ({p}) {res}²", r.x, r.R, sc.camera)


def closeup_rays(scene: Scene, position, res: int) -> Batch:
    """As :func:`scene_rays`, with the camera aimed at the object and zoomed so that every pixel of the res²
    frame sees it: a full frame (res² rays) of coherent secondary rays, as when the mirror fills the screen."""
    c = np.asarray(position, float)
    eye = np.asarray(scene.camera.eye, float)
    a = math.asin(min(scene.object.radius / np.linalg.norm(c - eye), 1.0))  # angular radius of the sphere
    fov = math.degrees(2 * math.atan(math.tan(a) / math.sqrt(2))) * 0.98  # square frame inside the disc
    sc = scene.with_updates(
        {
            "object.center": list(position),
            "camera.target": list(position),
            "camera.fov": fov,
            "camera.width": res,
            "camera.height": res,
            "render.supersample": 1,
        }
    )
    r = object_rays(sc)
    p = ", ".join(f"{v:g}" for v in position)
    return Batch(f"fig4 close-up ({p}) {res}²", r.x, r.R, sc.camera)


def synthetic_rays(scene: Scene, n: int, *, extent: float = 0.6, seed: int = 0, camera=None) -> Batch:
    x, d = analytic.random_rays(n, extent=extent, seed=seed)
    return Batch(f"synthetic {n}", x + np.asarray(scene.reference.point), d, camera)


def direction_sorted(b: Batch, res: int = 64) -> Batch:
    """``b``'s rays reordered by the cube-map texel (of a res² cube) their direction points at — ray reordering, as a
    renderer sorts incoherent rays so that neighbouring lanes fetch neighbouring texels. The sort is not timed."""
    face, u, v = cubemap.face_uv(backends.get("numpy"), *np.asarray(b.R, np.float64).T)
    key = (face.astype(np.int64) * res + np.minimum(v * res, res - 1).astype(np.int64)) * res + np.minimum(
        u * res, res - 1
    ).astype(np.int64)
    order = np.argsort(key, kind="stable")
    return Batch(f"{b.name} sorted by direction", b.x[order], b.R[order], b.camera)


def heightfield(scene: Scene, triangles: int) -> tuple[np.ndarray, np.ndarray]:
    """A displaced grid over the floor with about ``triangles`` triangles (≥ 2): (V, 3), (F, 3).

    Height 2…10 cm above the floor (bumps of a few cm), inset 5 cm from the walls; below every batch's origins."""
    k = max(1, int(round(math.sqrt(triangles / 2))))
    lo, hi = np.asarray(scene.room.min, float), np.asarray(scene.room.max, float)
    s = np.linspace(0, 1, k + 1)
    gx = lo[0] + 0.05 + s * (hi[0] - lo[0] - 0.1)
    gz = lo[2] + 0.05 + s * (hi[2] - lo[2] - 0.1)
    X, Z = np.meshgrid(gx, gz, indexing="ij")
    Y = lo[1] + 0.06 + 0.04 * np.sin(7.3 * X) * np.cos(5.1 * Z)
    V = np.stack([X, Y, Z], -1).reshape(-1, 3)
    i, j = np.meshgrid(np.arange(k), np.arange(k), indexing="ij")
    a = (i * (k + 1) + j).ravel()
    b, c, d = a + 1, a + k + 1, a + k + 2
    F = np.concatenate([np.stack([a, b, d], -1), np.stack([a, d, c], -1)])
    return V.astype(np.float32), F.astype(np.int32)


def room_triangles(scene: Scene, extra: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """The scene's triangles plus, if ``extra`` > 0, a heightfield of about that many triangles."""
    m = scene.mesh()
    V, F = m.vertices.astype(np.float32), m.faces.astype(np.int32)
    if extra > 0:
        hV, hF = heightfield(scene, extra)
        V, F = np.concatenate([V, hV]), np.concatenate([F, hF + len(V)])
    return V, F


def distance_texels(tracer: Tracer, o, res: int) -> np.ndarray:
    """(6, R, R, 4) impostor texels: exact distance from o through texel centres (``tracer``), RGB = |direction|."""
    dirs = cubemap.texel_directions(res)
    return np.concatenate([np.abs(dirs), distances_from(tracer, o, res)[..., None]], -1).astype(np.float32)
