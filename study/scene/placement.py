"""Placement checks for any environment, by ray casting against its triangles (not by box bounds).

* a point (the reference point, the light) must lie in free space: of the rays cast from it in 128 directions,
  most that hit something must hit the *front* of a surface (normals face free space: a room's walls face in,
  a column's or a cube's faces out); a point inside a solid sees back faces;
* the reference point must be enclosed: at least half of those rays must hit a surface (an open side such as the
  Cornell box's front is fine; a point outside the model is not);
* the object (its bounding sphere) must not touch the environment: the nearest triangle is farther than its radius.

The ray caster is numpy Möller–Trumbore, slow and obvious (placement casts a few hundred rays); the camera's view
of the object is checked per case with Embree (:func:`study.optics.shading.object_rays`).
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


def cast(mesh: RoomMesh, o: np.ndarray, d: np.ndarray, chunk: int = 1 << 20) -> tuple[np.ndarray, np.ndarray]:
    """Nearest hits of rays (o, d), (N, 3) each: ``t`` (N,) (inf on a miss) and ``front`` (N,) bool, True where the
    ray meets the side the triangle's normal (counter-clockwise winding) points to."""
    V = mesh.vertices.astype(np.float64)
    A, B, C = (V[mesh.faces[:, k]] for k in range(3))
    e1, e2 = B - A, C - A
    n = np.cross(e1, e2)
    o, d = np.broadcast_to(o, d.shape).astype(float), d.astype(float)
    best, front = np.full(len(d), np.inf), np.zeros(len(d), bool)
    per = max(1, chunk // max(1, len(A)))
    for s in range(0, len(d), per):
        oo, dd = o[s : s + per, None], d[s : s + per, None]
        p = np.cross(dd, e2)
        det = np.sum(e1 * p, -1)
        with np.errstate(divide="ignore", invalid="ignore"):
            inv = 1 / det
            tv = oo - A
            u = np.sum(tv * p, -1) * inv
            q = np.cross(tv, e1)
            v = np.sum(dd * q, -1) * inv
            t = np.sum(e2 * q, -1) * inv
            ok = (np.abs(det) > 1e-12) & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 1e-6)
        t = np.where(ok, t, np.inf)
        k = np.argmin(t, axis=1)
        best[s : s + per] = t[np.arange(len(k)), k]
        front[s : s + per] = np.sum(n[k] * d[s : s + per], -1) < 0
    return best, front


def clearance(mesh: RoomMesh, p) -> float:
    """Distance from the point ``p`` to the nearest triangle of ``mesh``."""
    from trimesh.triangles import closest_point

    tri = mesh.vertices[mesh.faces].astype(np.float64)
    q = closest_point(tri, np.broadcast_to(np.asarray(p, float), (len(tri), 3)))
    return float(np.min(np.linalg.norm(q - np.asarray(p, float), axis=-1)))


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
    check_free(mesh, scene.reference.point, "reference.point", enclosed=True)
    check_object(mesh, obj.center, r, what)
    if scene.environment.type == "mesh":  # the point light lights mesh environments
        check_free(mesh, scene.light.position, "light.position")
    for key, p in (("light.position", scene.light.position), ("camera.eye", scene.camera.eye)):
        if (key == "camera.eye" or scene.environment.type == "mesh") and float(
            np.linalg.norm(np.subtract(p, obj.center))
        ) <= r:
            raise KeyedError(key, "lies inside the object")
    if np.linalg.norm(np.cross(np.subtract(scene.camera.target, scene.camera.eye), scene.camera.up)) < 1e-9:
        raise KeyedError("camera.up", "must not be parallel to the viewing direction")
