"""Exact first hits with Embree (embreex) on the very triangles Mitsuba renders (:func:`study.scene.room_mesh`)."""

from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from study.scene import RoomMesh


class Tracer:
    """Embree scene of a :class:`RoomMesh`. ``intersect`` releases the GIL; float32 inside, as Embree is.

    ``threads`` (default: ``$STUDY_THREADS``, which a sweep's worker processes set to their share of the cores,
    else every core) is how many chunks :meth:`distance` casts at once."""

    def __init__(self, mesh: RoomMesh, *, threads: int | None = None):
        from embreex import rtcore_scene as rtcs
        from embreex.mesh_construction import TriangleMesh

        self.mesh = mesh
        self.scene = rtcs.EmbreeScene()
        TriangleMesh(self.scene, mesh.vertices.astype(np.float32), mesh.faces.astype(np.int32))
        self.threads = max(1, threads or int(os.environ.get("STUDY_THREADS") or 0) or os.cpu_count() or 1)
        self._pool: tuple[int, ThreadPoolExecutor] | None = None  # (pid, pool), made on first use

    @classmethod
    def from_triangles(cls, V: np.ndarray, F: np.ndarray, *, threads: int | None = None) -> Tracer:
        """A tracer of raw triangles (V, 3), (F, 3): one untextured surface (uv and surface ids all zero)."""
        V = np.ascontiguousarray(V, np.float32).reshape(-1, 3)
        F = np.ascontiguousarray(F, np.int32).reshape(-1, 3)
        mesh = RoomMesh(V, F, np.zeros((len(V), 2), np.float32), np.zeros(len(F), np.int32), ("triangles",))
        return cls(mesh, threads=threads)

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
            res = self.scene.run(o[s : s + chunk], d[s : s + chunk], output=1)
            hit = res["geomID"] != -1
            t[s : s + chunk] = np.where(hit, res["tfar"], np.inf)
            prim[s : s + chunk] = np.where(hit, res["primID"], -1)
            bu[s : s + chunk], bv[s : s + chunk] = res["u"], res["v"]
        hit = prim >= 0
        point = o.astype(np.float64) + d.astype(np.float64) * np.where(hit, t, np.nan)[:, None]
        surface = np.where(hit, self.mesh.surface[np.maximum(prim, 0)], -1)
        tri_uv = self.mesh.uv[self.mesh.faces[np.maximum(prim, 0)]]  # (N, 3, 2)
        uv = (1 - bu - bv)[:, None] * tri_uv[:, 0] + bu[:, None] * tri_uv[:, 1] + bv[:, None] * tri_uv[:, 2]
        return {
            "t": t,
            "point": point,
            "prim": prim,
            "surface": surface,
            "uv": np.where(hit[:, None], uv, np.nan),
        }

    def distance(self, o: np.ndarray, d: np.ndarray) -> np.ndarray:
        """|hit − o| for unit directions d (inf on a miss): (N,) float64, the ``t`` of :meth:`intersect`.

        Only the hit distance is asked of Embree; batches of 4096 rays or more are cut into ``threads`` chunks
        cast at once (embreex releases the GIL)."""
        return self._cast(o, d, False)[0]

    def hits(self, o: np.ndarray, d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(t, prim): :meth:`intersect`'s ``t`` and ``prim`` alone (inf and −1 on a miss), cast in chunks at once
        as :meth:`distance` is."""
        return self._cast(o, d, True)

    def _cast(self, o: np.ndarray, d: np.ndarray, prims: bool) -> tuple[np.ndarray, np.ndarray | None]:
        o = np.ascontiguousarray(o, np.float32).reshape(-1, 3)
        d = np.ascontiguousarray(d, np.float32).reshape(-1, 3)
        t = np.empty(len(o))
        prim = np.empty(len(o), np.int64) if prims else None

        def cast(a: int, b: int) -> None:
            res = self.scene.run(o[a:b], d[a:b], output=1)
            hit = res["geomID"] != -1
            t[a:b] = np.where(hit, res["tfar"], np.inf)
            if prim is not None:
                prim[a:b] = np.where(hit, res["primID"], -1)

        if self.threads == 1 or len(o) < 4096:
            cast(0, len(o))
            return t, prim
        cuts = np.linspace(0, len(o), self.threads + 1).astype(int)
        list(self._executor().map(cast, cuts[:-1], cuts[1:]))  # list(): wait, and raise a chunk's error
        return t, prim

    def _executor(self) -> ThreadPoolExecutor:
        # made lazily and again in a forked child (a parent's pool has no threads there)
        if self._pool is None or self._pool[0] != os.getpid():
            self._pool = (os.getpid(), ThreadPoolExecutor(self.threads, thread_name_prefix="embree"))
        return self._pool[1]
