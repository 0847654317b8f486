"""Placement checks for any environment, by ray casting against its triangles (not by box bounds).

* a point (the reference point, the light) must lie in free space: of the rays cast from it in 128 directions,
  most that hit something must hit the *front* of a surface (normals face free space: a room's walls face in,
  a column's or a cube's faces out); a point inside a solid sees back faces;
* the reference point must see the environment: at least one of those rays must hit a surface (open scenes are
  fine: a ray that leaves the scene sees the sky, :mod:`study.scene.sky`); probes must be enclosed (at least half
  of them hit);
* the object (its bounding sphere) must not touch the environment: the nearest triangle is farther than its radius.

Rays are cast by Embree (embreex, as in :mod:`study.reference.embree`), so that placement stays fast on meshes of
hundreds of thousands of triangles; the camera's view of the object is checked per case as well
(:func:`study.optics.shading.object_rays`).
"""

from __future__ import annotations

import numpy as np

from study.scene.room import RoomMesh
from study.validation import KeyedError

N_DIRS = 128  # rays cast from a point
ENCLOSED = 0.5  # fraction of them that must hit a surface around the reference point


def directions(n: int = N_DIRS) -> np.ndarray:
    """(n, 3) unit directions spread evenly over the sphere (Fibonacci lattice)."""
    i = np.arange(n) + 0.5
    z = 1 - 2 * i / n
    phi = np.pi * (1 + 5**0.5) * i
    r = np.sqrt(1 - z * z)
    return np.stack([r * np.cos(phi), z, r * np.sin(phi)], -1)


class _Rays:
    """An Embree scene of a mesh's triangles (embreex, as :mod:`study.reference.embree`; that layer sits above
    this one) and the per-triangle data that placement asks about."""

    def __init__(self, mesh: RoomMesh):
        from embreex import rtcore_scene as rtcs
        from embreex.mesh_construction import TriangleMesh

        self.scene = rtcs.EmbreeScene()
        V = np.ascontiguousarray(mesh.vertices, np.float32)
        F = np.ascontiguousarray(mesh.faces, np.int32)
        TriangleMesh(self.scene, V, F)
        tri = V.astype(np.float64)[F]
        self.tri = tri
        self.normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        self.lo, self.hi = tri.min(1), tri.max(1)


_RAYS: dict[int, tuple[RoomMesh, _Rays]] = {}


def _rays(mesh: RoomMesh) -> _Rays:
    hit = _RAYS.get(id(mesh))
    if hit is None or hit[0] is not mesh:
        if len(_RAYS) >= 4:
            _RAYS.pop(next(iter(_RAYS)))
        hit = _RAYS[id(mesh)] = (mesh, _Rays(mesh))
    return hit[1]


def cast(mesh: RoomMesh, o: np.ndarray, d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Nearest hits of rays (o, d), (N, 3) each, by Embree: ``t`` (N,) (inf on a miss) and ``front`` (N,) bool,
    True where the ray meets the side the triangle's normal (counter-clockwise winding) points to."""
    r = _rays(mesh)
    d = np.ascontiguousarray(d, np.float32).reshape(-1, 3)
    o = np.ascontiguousarray(np.broadcast_to(np.asarray(o, np.float32).reshape(-1, 3), d.shape))
    res = r.scene.run(o, d, output=1)
    prim = np.asarray(res["primID"])
    hit = (np.asarray(res["geomID"]) != -1) & (np.asarray(res["tfar"]) > 1e-6)  # a point on a surface: no hit
    t = np.where(hit, res["tfar"], np.inf).astype(float)
    front = hit & (np.sum(r.normal[np.where(hit, prim, 0)] * d, -1) < 0)
    return t, front


def clearance(mesh: RoomMesh, p) -> float:
    """Distance from the point ``p`` to the nearest triangle of ``mesh``, exact: rays in 128 directions bound it
    from above (Embree), then only the triangles whose bounding boxes lie within that bound are measured."""
    from trimesh.triangles import closest_point

    r = _rays(mesh)
    p = np.asarray(p, float)
    t, _ = cast(mesh, p[None], directions())
    bound = float(t.min()) if np.isfinite(t).any() else np.inf
    gap = np.linalg.norm(np.maximum(np.maximum(r.lo - p, 0), p - r.hi), axis=1)  # point to box
    near = np.flatnonzero(gap <= bound * (1 + 1e-6) + 1e-9)
    if not len(near):
        return bound
    q = closest_point(r.tri[near], np.broadcast_to(p, (len(near), 3)))
    return float(np.min(np.linalg.norm(q - p, axis=-1)))


def sees(mesh: RoomMesh, eye, center, radius: float, n: int = 24) -> float:
    """Fraction of rays from ``eye`` towards ``center`` and points spread over the sphere (center, 0.8 radius)
    that reach it unblocked: the camera's view of the object."""
    eye, center = np.asarray(eye, float), np.asarray(center, float)
    pts = np.vstack([center, center + 0.8 * radius * directions(n)])
    d = pts - eye
    dist = np.linalg.norm(d, axis=1)
    t, _ = cast(mesh, np.broadcast_to(eye, d.shape), d / dist[:, None])
    front = np.einsum("ij,ij->i", pts - center, -d) >= 0  # the points on the side facing the eye
    front[0] = True
    return float(np.mean(t[front] >= dist[front] - radius * 0.8))


def check_free(mesh: RoomMesh, p, key: str, *, enclosed: bool = False) -> None:
    """``p`` lies in free space (and, with ``enclosed``, surfaces surround it); else a KeyedError on ``key``."""
    d = directions()
    t, front = cast(mesh, np.asarray(p, float)[None], d)
    hit = np.isfinite(t)
    if hit.any() and (~front[hit]).mean() > 0.5:
        raise KeyedError(
            key,
            f"lies inside geometry: {int((~front[hit]).sum())} of the {int(hit.sum())} surfaces "
            "seen from it face away from it; move it into the environment's free space",
        )
    if enclosed and hit.mean() < ENCLOSED:
        raise KeyedError(
            key,
            f"no closed region around it: {100 * (1 - hit.mean()):.0f} % of the directions from "
            f"it hit no surface (at most {100 * (1 - ENCLOSED):.0f} % may leave the scene); move it "
            "inside the environment",
        )


def check_reference(mesh: RoomMesh, p, key: str = "reference.point") -> None:
    """The reference point lies in free space and sees some surface (else its impostor holds nothing but sky)."""
    check_free(mesh, p, key)
    t, _ = cast(mesh, np.asarray(p, float)[None], directions())
    if not np.isfinite(t).any():
        raise KeyedError(
            key, "sees no surface: every direction from it leaves the scene; move it near the geometry"
        )


def enclosure(mesh: RoomMesh, p) -> float:
    """Share of the directions from ``p`` that hit a surface (1: enclosed; a room with an open side: less)."""
    t, _ = cast(mesh, np.asarray(p, float)[None], directions())
    return float(np.isfinite(t).mean())


def check_object(mesh: RoomMesh, center, radius: float, what: str) -> None:
    """The object's bounding sphere lies in free space and touches no triangle."""
    check_free(mesh, center, "object.center")
    gap = clearance(mesh, center)
    if gap <= radius:
        raise KeyedError(
            "object.center",
            f"the {what} intersects the environment: its nearest surface is "
            f"{gap:.3g} m from the centre; move it or make object.radius smaller",
        )


def check_scene(scene) -> None:
    """Every placement check of a scene in a mesh or Mitsuba environment (the box room's are in its schema)."""
    if scene.columns:
        raise KeyedError(
            "columns",
            "columns belong to the box room; with environment.type = "
            f"{scene.environment.type!r} put them in the mesh or scene instead",
        )
    mesh, obj = scene.mesh(), scene.object
    r = obj.radius
    what = f"{obj.shape} (bounding radius {r})" if obj.shape != "sphere" else f"sphere (radius {r})"
    check_reference(mesh, scene.reference.point)
    check_object(mesh, obj.center, r, what)
    lamp = scene.lamp()  # the point light lights the environment
    if lamp:
        check_free(mesh, scene.light.position, "light.position")
    for key, p in (("light.position", scene.light.position), ("camera.eye", scene.camera.eye)):
        if (key == "camera.eye" or lamp) and float(np.linalg.norm(np.subtract(p, obj.center))) <= r:
            raise KeyedError(key, "lies inside the object")
    if np.linalg.norm(np.cross(np.subtract(scene.camera.target, scene.camera.eye), scene.camera.up)) < 1e-9:
        raise KeyedError("camera.up", "must not be parallel to the viewing direction")
