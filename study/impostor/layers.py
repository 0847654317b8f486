"""Layered distance impostors: several depth layers seen from the reference point (depth peeling).

For every texel-centre direction ω of the cube map (:mod:`study.impostor.cubemap`), layer k holds the (k+1)-th surface
that the ray o + t ω crosses (Embree, each ray restarted just beyond the previous hit). Where a ray has fewer
surfaces (it left the room), the layer repeats the last one (a ray that meets no surface at all holds FAR),
so every layer is a complete environment
surface that a search can run on. Channels per texel: (R, G, B, jump, distance):

- radiance: layer 0 is the ordinary impostor's radiance (so the first layer is exactly what ``localized`` sees);
  deeper layers are path traced by Mitsuba (``integrator.sample``) on rays that arrive at the texel's surface
  point from its free side (origin p + ε n, direction −n, n the mesh normal, which faces free space: room
  inward, columns outward). Surfaces are diffuse, so this is the radiance a reflected ray from any direction
  on that side sees; a ray through o would instead see the inside of a column (dark), which no reflected ray does.
- jump: max over the 4 in-face neighbour texels of |d − d_n| / min(d, d_n), the relative depth jump. Bilinear
  lookups between texels across a depth discontinuity (the "skin" that joins a silhouette to what lies behind it)
  read a large jump; a smooth wall at the steepest angle seen in a box room stays below ~0.01 at 256².
- distance: |hit − o|.
"""

from __future__ import annotations

import numpy as np

from study import progress
from study.cache import Cache, content_key
from study.impostor import cubemap
from study.impostor.capture import impostor_key
from study.reference.embree import Tracer
from study.reference.mitsuba import radiance_along
from study.reference.tracer import make_tracer
from study.scene import Scene

RESTART_EPS = 1e-4  # restart offset along the ray beyond a hit (m)


def peel(tracer: Tracer, o: np.ndarray, dirs: np.ndarray, layers: int):
    """The first ``layers`` surfaces along rays o + t·dirs.

    Returns
    -------
    dist : (K, N) float64, |hit − o| (the last real hit repeated where a ray has fewer surfaces)
    point : (K, N, 3) hit points
    normal : (K, N, 3) unit mesh normals (facing free space)
    new : (K, N) bool, True where layer k is a real (k+1)-th hit rather than a repeat
    """
    V, F = tracer.mesh.vertices.astype(float), tracer.mesh.faces
    fn = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
    length = np.linalg.norm(fn, axis=1, keepdims=True)  # 0 for a degenerate triangle (never hit): normal 0
    fn = np.divide(fn, length, out=np.zeros_like(fn), where=length > 0)
    n = len(dirs)
    start = np.broadcast_to(np.asarray(o, float), (n, 3)).copy()
    dist, point, normal, new = (
        np.zeros((layers, n)),
        np.zeros((layers, n, 3)),
        np.zeros((layers, n, 3)),
        np.zeros((layers, n), bool),
    )
    for k in range(layers):
        h = tracer.intersect(start, dirs)
        hit = h["prim"] >= 0
        p = np.where(
            hit[:, None], h["point"], point[k - 1] if k else o + dirs * cubemap.FAR
        )  # no surface: FAR
        point[k], new[k] = p, hit
        dist[k] = np.where(hit, np.linalg.norm(p - o, axis=1), dist[k - 1] if k else cubemap.FAR)
        normal[k] = np.where(hit[:, None], fn[np.maximum(h["prim"], 0)], normal[k - 1] if k else 0.0)
        start = np.where(hit[:, None], p + dirs * RESTART_EPS, start)
    return dist, point, normal, new


def depth_jump(dist: np.ndarray) -> np.ndarray:
    """(…, 6, R, R) distances → relative depth jump to the 4 in-face neighbours, same shape."""
    d = np.asarray(dist, float)
    pad = np.pad(d, [(0, 0)] * (d.ndim - 2) + [(1, 1), (1, 1)], mode="edge")
    jump = np.zeros_like(d)
    for di, dj in ((-1, 0), (1, 0), (0, -1), (0, 1)):
        nb = pad[..., 1 + di : pad.shape[-2] - 1 + di, 1 + dj : pad.shape[-1] - 1 + dj]
        jump = np.maximum(jump, np.abs(d - nb) / np.minimum(d, nb))
    return jump


def surface_radiance(
    scene: Scene, point: np.ndarray, normal: np.ndarray, spp: int, *, seed: int = 0
) -> np.ndarray:
    """Radiance leaving surface points towards their free side, path traced by Mitsuba: (N, 3) float32.

    Each point is seen by ``spp`` rays from p + 1e-3 n along −n (:func:`study.reference.mitsuba.radiance_along`)."""
    return radiance_along(scene, point + 1e-3 * normal, -normal, spp=spp, seed=seed)


def capture_layers(
    scene: Scene,
    layers: int,
    radiance0: np.ndarray,
    *,
    res: int | None = None,
    spp: int | None = None,
    tracer: Tracer | None = None,
) -> np.ndarray:
    """The layered impostor: (K, 6, R, R, 5) float32 with channels (R, G, B, jump, distance).

    ``radiance0`` (6, R, R, 3) is the ordinary impostor's radiance, used for layer 0."""
    res = res or scene.render.cube_res
    spp = spp or scene.render.cube_spp
    tracer = tracer or make_tracer(scene.mesh())
    o = np.asarray(scene.reference.point, float)
    dirs = cubemap.texel_directions(res).reshape(-1, 3)
    dist, point, normal, new = peel(tracer, o, dirs, layers)
    rgb = np.zeros((layers, len(dirs), 3), np.float32)
    rgb[0] = np.asarray(radiance0, np.float32).reshape(-1, 3)
    for k in range(1, layers):
        rgb[k] = rgb[k - 1]
        if new[k].any():
            progress.note(f"layer {k + 1}/{layers}: path tracing {int(new[k].sum())} texels")
            rgb[k][new[k]] = surface_radiance(
                scene, point[k][new[k]], normal[k][new[k]], spp, seed=scene.render.seed + 1000 * k
            )
    dist = dist.reshape(layers, 6, res, res)
    out = np.concatenate(
        [rgb.reshape(layers, 6, res, res, 3), depth_jump(dist)[..., None], dist[..., None]], -1
    )
    return out.astype(np.float32)


def layers_key(scene: Scene, layers: int) -> str:
    """Cache key: the impostor's key (room, columns, light, reference, res, spp, ...) and the layer count."""
    return content_key(impostor_key(scene), layers, "layers-v1")


def layered_impostor(
    scene: Scene, cache: Cache, layers: int, radiance0: np.ndarray, tracer: Tracer | None = None
) -> np.ndarray:
    """:func:`capture_layers` through the cache: (K, 6, R, R, 5)."""
    r = scene.render.cube_res
    a = cache.get(
        "layers",
        layers_key(scene, layers),
        lambda: capture_layers(scene, layers, radiance0, tracer=tracer),
        code=capture_layers,
    )
    return a.reshape(layers, 6, r, r, 5)
