"""Exact first hits through Mitsuba's ray queries (OptiX on ``cuda_ad_rgb``, Embree inside Mitsuba on
``llvm_ad_rgb``), with the interface of :class:`study.reference.embree.Tracer`: the exact side of a study run on
the GPU.

All the room's triangles are one Mitsuba mesh, so a hit's ``prim_index`` is the face index of the
:class:`~study.scene.RoomMesh`, and ``prim_uv`` are the barycentric weights of the face's second and third vertex,
as Embree's ``u``, ``v``. Only ``scene.ray_intersect_preliminary`` is asked (no SurfaceInteraction): the cheapest
query that answers "where is the first hit". float32 inside, as Embree is.
"""

from __future__ import annotations

import numpy as np

from study.reference import mitsuba as mitsuba_ref
from study.scene import RoomMesh


class MitsubaTracer:
    """Mitsuba scene of a :class:`RoomMesh` in ``variant`` (default: the render device's).

    ``intersect`` and ``distance`` return exactly what :class:`~study.reference.embree.Tracer`'s do."""

    def __init__(self, mesh: RoomMesh, *, variant: str | None = None, threads: int | None = None):
        self.mesh = mesh
        self.m, self.scene = mitsuba_ref.triangle_scene(mesh.vertices, mesh.faces, variant)
        self.variant = self.m.variant()
        self.threads = 1  # one device call per chunk; the device is parallel

    def _query(self, o: np.ndarray, d: np.ndarray):
        m = mitsuba_ref.mi(self.variant)
        ray = m.Ray3f(m.Point3f(np.ascontiguousarray(o.T)), m.Vector3f(np.ascontiguousarray(d.T)))
        pi = self.scene.ray_intersect_preliminary(ray)
        hit = pi.is_valid()
        return (
            np.where(np.asarray(hit), np.asarray(pi.t, np.float64), np.inf),
            np.where(np.asarray(hit), np.asarray(pi.prim_index).astype(np.int64), -1),
            np.asarray(pi.prim_uv, np.float64).reshape(2, -1),
        )

    def intersect(self, o: np.ndarray, d: np.ndarray, *, chunk: int = 1 << 22) -> dict[str, np.ndarray]:
        """First hits of rays o + t d (t > 0), (N, 3) each: ``t``, ``point``, ``prim``, ``surface``, ``uv`` as
        :meth:`study.reference.embree.Tracer.intersect`."""
        o = np.ascontiguousarray(o, np.float32).reshape(-1, 3)
        d = np.ascontiguousarray(d, np.float32).reshape(-1, 3)
        n = len(o)
        t, prim, bary = np.full(n, np.inf), np.full(n, -1, np.int64), np.zeros((2, n))
        for s in range(0, n, chunk):
            t[s : s + chunk], prim[s : s + chunk], bary[:, s : s + chunk] = self._query(
                o[s : s + chunk], d[s : s + chunk]
            )
        hit = prim >= 0
        point = o.astype(np.float64) + d.astype(np.float64) * np.where(hit, t, np.nan)[:, None]
        surface = np.where(hit, self.mesh.surface[np.maximum(prim, 0)], -1)
        tri_uv = self.mesh.uv[self.mesh.faces[np.maximum(prim, 0)]]  # (N, 3, 2)
        bu, bv = bary
        uv = (1 - bu - bv)[:, None] * tri_uv[:, 0] + bu[:, None] * tri_uv[:, 1] + bv[:, None] * tri_uv[:, 2]
        return {
            "t": t,
            "point": point,
            "prim": prim,
            "surface": surface,
            "uv": np.where(hit[:, None], uv, np.nan),
        }

    def hits(self, o: np.ndarray, d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(t, prim): :meth:`intersect`'s ``t`` and ``prim`` alone (inf and −1 on a miss), one device call."""
        o = np.ascontiguousarray(o, np.float32).reshape(-1, 3)
        d = np.ascontiguousarray(d, np.float32).reshape(-1, 3)
        if not len(o):
            return np.empty(0), np.empty(0, np.int64)
        t, prim, _ = self._query(o, d)
        return t, prim

    def distance(self, o: np.ndarray, d: np.ndarray) -> np.ndarray:
        """|hit − o| for unit directions d (inf on a miss): (N,) float64."""
        o = np.ascontiguousarray(o, np.float32).reshape(-1, 3)
        d = np.ascontiguousarray(d, np.float32).reshape(-1, 3)
        return self._query(o, d)[0] if len(o) else np.empty(0)
