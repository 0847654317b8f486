"""Exact first hits with Embree (embreex) on the very triangles Mitsuba renders (:func:`study.scene.room_mesh`)."""
from __future__ import annotations

import numpy as np

from study.scene import RoomMesh


class Tracer:
    """Embree scene of a :class:`RoomMesh`. ``intersect`` releases the GIL; float32 inside, as Embree is."""

    def __init__(self, mesh: RoomMesh):
        from embreex import rtcore_scene as rtcs
        from embreex.mesh_construction import TriangleMesh
        self.mesh = mesh
        self.scene = rtcs.EmbreeScene()
        TriangleMesh(self.scene, mesh.vertices.astype(np.float32), mesh.faces.astype(np.int32))

    def intersect(self, o: np.ndarray, d: np.ndarray, *, chunk: int = 1 << 20) -> dict[str, np.ndarray]:
        """First hits of rays o + t d (t > 0): (N, 3) each.

        Returns ``t`` (N,) float64 ray parameter (inf on a miss; |d| need not be 1), ``point`` (N, 3) float64,
        ``prim`` (N,) int (−1 on a miss), ``surface`` (N,) texture id (−1 on a miss) and ``uv`` (N, 2).
        """
        o = np.ascontiguousarray(o, np.float32).reshape(-1, 3)
        d = np.ascontiguousarray(d, np.float32).reshape(-1, 3)
        n = len(o)
        t = np.full(n, np.inf)
        prim = np.full(n, -1, np.int64)
        bu, bv = np.zeros(n), np.zeros(n)
        for s in range(0, n, chunk):
            res = self.scene.run(o[s:s + chunk], d[s:s + chunk], output=1)
            hit = res["geomID"] != -1
            t[s:s + chunk] = np.where(hit, res["tfar"], np.inf)
            prim[s:s + chunk] = np.where(hit, res["primID"], -1)
            bu[s:s + chunk], bv[s:s + chunk] = res["u"], res["v"]
        hit = prim >= 0
        point = o.astype(np.float64) + d.astype(np.float64) * np.where(hit, t, np.nan)[:, None]
        surface = np.where(hit, self.mesh.surface[np.maximum(prim, 0)], -1)
        tri_uv = self.mesh.uv[self.mesh.faces[np.maximum(prim, 0)]]          # (N, 3, 2)
        uv = (1 - bu - bv)[:, None] * tri_uv[:, 0] + bu[:, None] * tri_uv[:, 1] + bv[:, None] * tri_uv[:, 2]
        return {"t": t, "point": point, "prim": prim, "surface": surface, "uv": np.where(hit[:, None], uv, np.nan)}

    def distance(self, o: np.ndarray, d: np.ndarray) -> np.ndarray:
        """|hit − o| for unit directions d (inf on a miss)."""
        return self.intersect(o, d)["t"]
