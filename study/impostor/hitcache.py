"""A world-space radiance cache for hit lighting, the way engines shade a hit they found without tracing on: the
radiance leaving the surfaces is stored at low resolution and read at the hit (Lumen's surface cache, AMD GI-1.x's
world-space hash grid), so the shown colour carries a *hit lighting* error of its own beside the hit-finding
error of the search.

The cache here is a uniform grid over the environment's bounds with ``res`` cells along its longest side, each
cell split by the dominant axis of the surface normal (six bins: ±x, ±y, ±z, as GI-1.x keys its hash by normal
too), so the two sides of a wall and the faces meeting at a corner do not mix. It is filled from ``samples``
points spread over the environment's triangles by area, on both sides of each triangle; each point's radiance is
what leaves it along its normal (:func:`study.reference.mitsuba.radiance_along` on the ray p + δn → p, the same
path tracer as truth_at_hit; for the diffuse rooms studied, the radiance leaving towards any direction). A cell's
value is the mean of its samples; a query reads the cell of the hit point and the bin of the normal facing the
ray, and a cell no sample reached is a *miss*, shaded with the mean of its bin over the cache (counted).

What the cache costs: the grid's cells times six bins of RGB, and ``samples`` × ``spp`` paths to fill it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: surface points per side that fill a study's caches (all resolutions share them): 2 × 2¹⁶ path-traced rays
FILL_SAMPLES = 1 << 16
#: the offset of a fill ray's origin from its surface point along the normal (m): above float32 noise at 10 m
FILL_OFFSET = 1e-3


@dataclass
class GridCache:
    """Cell means of radiance, (cells × 6 normal bins, 3), with the grid's placement."""

    lo: np.ndarray  # (3,) the grid's corner
    cell: float  # cell edge (m)
    dims: np.ndarray  # (3,) cells along x, y, z
    sums: np.ndarray  # (C·6, 3) summed radiance per cell and bin
    counts: np.ndarray  # (C·6,) samples per cell and bin

    @classmethod
    def empty(cls, lo, hi, res: int) -> GridCache:
        """A grid over the box [lo, hi] with ``res`` cells along its longest side (≥ 1)."""
        lo, hi = np.asarray(lo, float), np.asarray(hi, float)
        cell = float(np.max(hi - lo)) / max(int(res), 1)
        dims = np.maximum(np.ceil((hi - lo) / cell - 1e-9).astype(int), 1)
        n = int(dims.prod()) * 6
        return cls(lo, cell, dims, np.zeros((n, 3)), np.zeros(n))

    def keys(self, points: np.ndarray, normals: np.ndarray) -> np.ndarray:
        """The flat index (cell, normal bin) of each point, (N,) int; points outside the grid are clamped."""
        ijk = np.clip(np.floor((np.asarray(points) - self.lo) / self.cell).astype(int), 0, self.dims - 1)
        cell = (ijk[:, 0] * self.dims[1] + ijk[:, 1]) * self.dims[2] + ijk[:, 2]
        return cell * 6 + normal_bin(normals)

    def add(self, points: np.ndarray, normals: np.ndarray, radiance: np.ndarray) -> None:
        """Accumulate samples: points and normals (N, 3), radiance (N, 3); non-finite radiance is skipped."""
        ok = np.isfinite(radiance).all(-1)
        k = self.keys(points[ok], normals[ok])
        np.add.at(self.sums, k, radiance[ok])
        self.counts += np.bincount(k, minlength=len(self.counts))

    def query(self, points: np.ndarray, normals: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(radiance (N, 3), miss (N,) bool): the mean of the cell and normal bin of each point; a miss (a cell no
        sample reached) reads the mean of all samples in its normal bin."""
        k = self.keys(points, normals)
        n = self.counts[k]
        by_bin = (
            self.sums.reshape(-1, 6, 3).sum(0) / np.maximum(self.counts.reshape(-1, 6).sum(0), 1)[:, None]
        )
        mean = self.sums[k] / np.maximum(n, 1)[:, None]
        miss = n == 0
        return np.where(miss[:, None], by_bin[k % 6], mean), miss

    @property
    def bytes(self) -> int:
        """What the cache holds: RGB half floats per cell and bin (as an engine would store it)."""
        return int(len(self.counts)) * 3 * 2


def normal_bin(normals: np.ndarray) -> np.ndarray:
    """0…5 for the dominant axis of each normal and its sign (+x, −x, +y, −y, +z, −z), (N,) int."""
    n = np.asarray(normals, float)
    axis = np.argmax(np.abs(n), axis=-1)
    sign = np.take_along_axis(n, axis[:, None], -1)[:, 0] < 0
    return axis * 2 + sign


def surface_samples(
    vertices: np.ndarray, faces: np.ndarray, n: int, seed: int
) -> tuple[np.ndarray, np.ndarray]:
    """``n`` points spread over the triangles by area, each with its triangle's unit normal, drawn once for each
    side (the first half facing along the winding's normal, the second against it): (2n, 3) twice."""
    V, F = np.asarray(vertices, float), np.asarray(faces)
    a, b, c = V[F[:, 0]], V[F[:, 1]], V[F[:, 2]]
    cross = np.cross(b - a, c - a)
    area = np.linalg.norm(cross, axis=-1)
    rng = np.random.default_rng((seed, 7))
    tri = rng.choice(len(F), size=n, p=area / area.sum())
    u, v = rng.random(n), rng.random(n)
    flip = u + v > 1  # fold the square onto the triangle: uniform over its area
    u, v = np.where(flip, 1 - u, u), np.where(flip, 1 - v, v)
    p = a[tri] + u[:, None] * (b[tri] - a[tri]) + v[:, None] * (c[tri] - a[tri])
    nrm = cross[tri] / np.maximum(area[tri], 1e-30)[:, None]
    return np.concatenate([p, p]), np.concatenate([nrm, -nrm])


def hit_normals(vertices: np.ndarray, faces: np.ndarray, prim: np.ndarray, dirs: np.ndarray) -> np.ndarray:
    """The unit normal of each hit triangle ``prim`` turned to face the ray that hit it (−dirs side), (N, 3);
    NaN where the ray hit nothing (prim < 0)."""
    V, F = np.asarray(vertices, float), np.asarray(faces)
    t = F[np.maximum(prim, 0)]
    n = np.cross(V[t[:, 1]] - V[t[:, 0]], V[t[:, 2]] - V[t[:, 0]])
    n /= np.maximum(np.linalg.norm(n, axis=-1, keepdims=True), 1e-30)
    n = np.where((np.sum(n * dirs, -1) > 0)[:, None], -n, n)
    return np.where((prim >= 0)[:, None], n, np.nan)


def fill(cache: GridCache, scene, vertices, faces, *, samples: int, spp: int, seed: int) -> GridCache:
    """Fill ``cache`` with the radiance leaving ``samples`` surface points on each side (module docstring)."""
    from study.reference.mitsuba import radiance_along

    p, n = surface_samples(vertices, faces, samples, seed)
    L = radiance_along(scene, p + FILL_OFFSET * n, -n, spp=spp, seed=seed)
    cache.add(p, n, np.asarray(L, float))
    return cache
