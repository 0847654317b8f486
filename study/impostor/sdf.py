"""A signed distance field of the environment on a 3D grid (the global distance field engines trace reflections
through, e.g. Lumen), built from the very triangles Embree intersects and Mitsuba renders, and :class:`SdfGrid`,
the field bound to one backend.

Grid (:func:`grid_frame`): N = ``SdfSpec.res`` nodes along each axis of a cube that holds the environment's bounds
with a margin of ``band`` + 2 voxels, node (i, j, k) at lo + h·(i, j, k) (x, y, z; stored as [k, j, i], the layout
Dr.Jit's ``Texture3f`` and Mitsuba's ``sdfgrid`` read). Distances are metres.

Values (:func:`build_grid`):

* **narrow band**, nodes within ``band`` voxels of a triangle: the exact distance to the nearest triangle (each
  triangle measured against the nodes of its bounding box grown by the band; closest point on the plane when its
  projection falls inside the triangle, else on the nearest edge), with the **sign rule**: + on the side the
  nearest triangle's normal (counter-clockwise winding, :func:`study.scene.placement.cast`) points to, the free
  side, − behind it; among triangles at the same distance (an edge or corner) the one the point lies most squarely
  in front of or behind decides.
* **outside the band**: a lower bound of the distance, so a sphere trace never steps through a surface:
  max(band·h, e + band·h − √3·h), e the Euclidean distance to the nearest band node (``scipy.ndimage``'s exact
  EDT), with that node's sign.

Trilinear interpolation of the nodes reproduces a plane's signed distance exactly, so walls are exact up to float32
rounding; edges and corners are rounded off within about a voxel.

The grid is cached like an impostor (:func:`sdf_grid`: key = the triangles, the spec and this module's code).
Without the scene's triangles (a bare impostor, the bench) :func:`box_grid` gives the field of a room box.
"""

from __future__ import annotations

import hashlib
import math

import numpy as np

from study.backend import V3, Backend
from study.cache import Cache, content_key
from study.impostor.views import SdfSpec

# ---------------------------------------------------------------------------------------------- the grid's frame


def grid_frame(bounds, spec: SdfSpec) -> tuple[np.ndarray, float]:
    """(lo, h): the world position of node (0, 0, 0) and the voxel size of a cube of ``spec.res`` nodes per axis
    centred on ``bounds`` = (min, max), with ``spec.band`` + 2 voxels of margin on every side."""
    lo, hi = (np.asarray(b, float) for b in bounds)
    pad = math.ceil(spec.band) + 2
    ext = float(np.max(hi - lo))
    h = ext / (spec.res - 1 - 2 * pad)
    side = h * (spec.res - 1)
    return (lo + hi) / 2 - side / 2, h


def _closest(p: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray):
    """Distance from points ``p`` (M, 3) to the triangle (a, b, c), and the cosine between p − q and the
    triangle's unit normal (q the closest point): (M,) each."""
    n = np.cross(b - a, c - a)
    n = n / np.linalg.norm(n)
    ap = p - a
    dp = ap @ n
    proj = p - dp[:, None] * n
    inside = np.ones(len(p), bool)
    for u, v in ((a, b), (b, c), (c, a)):
        inside &= np.cross(v - u, proj - u) @ n >= 0
    best = np.where(inside, np.abs(dp), np.inf)
    q = np.where(inside[:, None], proj, 0.0)
    for u, v in ((a, b), (b, c), (c, a)):
        e = v - u
        t = np.clip((p - u) @ e / (e @ e), 0.0, 1.0)
        qe = u + t[:, None] * e
        de = np.linalg.norm(p - qe, axis=1)
        closer = de < best
        best = np.where(closer, de, best)
        q = np.where(closer[:, None], qe, q)
    cos = ((p - q) @ n) / np.maximum(best, 1e-30)
    return best, np.where(best > 0, cos, 1.0)


def build_grid(V: np.ndarray, F: np.ndarray, bounds, spec: SdfSpec) -> tuple[np.ndarray, np.ndarray, float]:
    """The signed distance grid of the triangles (V, F) (module docstring): ((N, N, N) float32 as [z, y, x], lo,
    h)."""
    from scipy import ndimage

    lo, h = grid_frame(bounds, spec)
    N = spec.res
    band = spec.band * h
    best = np.full((N, N, N), np.inf)  # [x, y, z] while building
    cos = np.ones((N, N, N))
    tri = np.asarray(V, float)[np.asarray(F, np.int64)]
    for a, b, c in tri:
        if np.linalg.norm(np.cross(b - a, c - a)) < 1e-14:
            continue  # degenerate: its edges belong to neighbours
        tmin, tmax = np.minimum(np.minimum(a, b), c) - band, np.maximum(np.maximum(a, b), c) + band
        i0 = np.clip(np.ceil((tmin - lo) / h).astype(int), 0, N - 1)
        i1 = np.clip(np.floor((tmax - lo) / h).astype(int), 0, N - 1)
        if np.any(i1 < i0):
            continue
        ax = [lo[d] + h * np.arange(i0[d], i1[d] + 1) for d in range(3)]
        P = np.stack(np.meshgrid(*ax, indexing="ij"), -1).reshape(-1, 3)
        d, cs = _closest(P, a, b, c)
        sl = tuple(slice(i0[k], i1[k] + 1) for k in range(3))
        old, old_cos = best[sl].reshape(-1), cos[sl].reshape(-1)
        tie = np.abs(d - old) <= 1e-9 * max(h, 1.0)
        take = (d < old) & ~tie | tie & (np.abs(cs) > np.abs(old_cos))
        best[sl] = np.where(take, d, old).reshape(best[sl].shape)
        cos[sl] = np.where(take, cs, old_cos).reshape(cos[sl].shape)
    sign = np.where(cos < 0, -1.0, 1.0)
    inband = best < band
    if not inband.any():
        out = np.full((N, N, N), band)
    else:
        e, idx = ndimage.distance_transform_edt(~inband, sampling=h, return_indices=True)
        far = np.maximum(band, e + band - math.sqrt(3) * h) * sign[tuple(idx)]
        out = np.where(inband, best * sign, far)
    return np.ascontiguousarray(out.transpose(2, 1, 0), np.float32), lo, h


def box_grid(box, spec: SdfSpec) -> tuple[np.ndarray, np.ndarray, float]:
    """The signed distance grid of a room box (min, max) seen from inside (+ inside, − outside), analytic."""
    lo_b, hi_b = (np.asarray(b, float) for b in box)
    lo, h = grid_frame(box, spec)
    ax = [lo[d] + h * np.arange(spec.res) for d in range(3)]
    z, y, x = np.meshgrid(ax[2], ax[1], ax[0], indexing="ij")
    p = np.stack([x, y, z], -1)
    inner = np.min(np.minimum(p - lo_b, hi_b - p), -1)  # distance to the nearest wall from inside
    outer = np.linalg.norm(np.maximum(np.maximum(lo_b - p, p - hi_b), 0.0), axis=-1)
    return np.where(inner >= 0, inner, -outer).astype(np.float32), lo, h


def sdf_grid(scene, spec: SdfSpec, cache: Cache) -> tuple[np.ndarray, np.ndarray, float]:
    """:func:`build_grid` of the environment of ``scene`` (``scene.mesh()``, the triangles Embree and Mitsuba
    use), cached under the triangles' hash, the spec and the code."""
    mesh = scene.mesh()
    bounds = scene.bounds()
    V = np.ascontiguousarray(mesh.vertices, np.float32)
    F = np.ascontiguousarray(mesh.faces, np.int32)
    tris = hashlib.sha256(V.tobytes() + F.tobytes()).hexdigest()[:20]
    key = content_key("sdf-v1", tris, [list(map(float, b)) for b in bounds], spec.res, spec.band)
    grid = cache.get("sdf", key, lambda: build_grid(V, F, bounds, spec)[0], code=build_grid)
    lo, h = grid_frame(bounds, spec)
    return grid, lo, h


# ---------------------------------------------------------------------------------------------- the field on a backend


class SdfGrid:
    """A distance grid on one backend. ``grid`` (N, N, N) [z, y, x] float32, ``lo`` world position of node 0,
    ``h`` voxel size, ``origin`` the reference point o (world): :meth:`distance` takes points relative to o, as
    methods do. On Dr.Jit the grid is a ``Texture3f`` (hardware-filtered on CUDA); on numpy the same trilinear
    filter is computed; both clamp outside the grid."""

    def __init__(self, grid: np.ndarray, lo, h: float, origin, B: Backend):
        self.B, self.h, self.res = B, float(h), grid.shape[0]
        self.grid = np.ascontiguousarray(grid, np.float32)
        self.lo = np.asarray(lo, float)
        self.origin = np.asarray(origin, float)
        self.shift = self.lo - self.origin  # node 0 relative to o
        if B.name == "numpy":
            self.tex = self.grid
        else:
            self.tex = B.m.Texture3f(
                B.m.TensorXf(self.grid[..., None]),
                filter_mode=B.dr.FilterMode.Linear,
                wrap_mode=B.dr.WrapMode.Clamp,
                use_accel=B.name == "cuda",
            )

    @property
    def extent(self) -> float:
        """Side of the grid's cube, metres."""
        return self.h * (self.res - 1)

    def distance(self, p: V3):
        """Trilinear signed distance at points ``p`` relative to o (one 3D fetch)."""
        B, N = self.B, self.res
        gx = (p.x - float(self.shift[0])) / self.h  # continuous node coordinates
        gy = (p.y - float(self.shift[1])) / self.h
        gz = (p.z - float(self.shift[2])) / self.h
        if B.name != "numpy":
            pos = B.m.Array3f((gx + 0.5) / N, (gy + 0.5) / N, (gz + 0.5) / N)
            return self.tex.eval(pos)[0]
        c = [np.clip(np.nan_to_num(g, nan=0.0), 0.0, N - 1.0) for g in (gx, gy, gz)]
        i0 = [np.minimum(g.astype(np.int64), N - 2) for g in c]
        f = [g - i for g, i in zip(c, i0)]
        G = self.grid
        out = np.zeros_like(c[0])
        for dz in (0, 1):
            wz = f[2] if dz else 1 - f[2]
            for dy in (0, 1):
                wy = f[1] if dy else 1 - f[1]
                for dx in (0, 1):
                    wx = f[0] if dx else 1 - f[0]
                    out = out + wx * wy * wz * G[i0[2] + dz, i0[1] + dy, i0[0] + dx]
        return out.astype(np.float32)


def room_field(env, spec: SdfSpec) -> SdfGrid:
    """The field of the room box on the backend of ``env`` (a :class:`~study.impostor.views.Captured`): its
    ``room``, or where none is known a cube about o of the impostor's mean distance along the axes."""
    o = env.origin()
    box = env.room
    if box is None:
        r = float(np.mean(np.asarray(env.B.numpy(env.distance(env.B.vec(np.eye(3)))))))
        box = (o - r, o + r)
    return SdfGrid(*box_grid(box, spec), o, env.B)
