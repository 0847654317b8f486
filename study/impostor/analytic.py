"""Analytic scenes with exact answers, independent of Mitsuba and Embree: the box room seen from inside.

Used by the tests (and by anyone who wants to check a method without rendering): exact ray–box hits and a
distance impostor whose distances are exact along texel-centre directions and whose "radiance" is any function of
the hit point.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from study.impostor import cubemap


def box_hit_t(o: np.ndarray, d: np.ndarray, lo, hi) -> np.ndarray:
    """Ray parameter t > 0 where rays o + t d (inside the box [lo, hi]) leave it: (N,) float64.

    Parameters
    ----------
    o, d : (N, 3) origins (inside the box) and directions (need not be unit)
    lo, hi : (3,) box corners
    """
    o, d = np.asarray(o, float), np.asarray(d, float)
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where(d > 0, (hi - o) / d, (lo - o) / d)
    t = np.where(np.isfinite(t) & (t > 0), t, np.inf)
    return t.min(axis=-1)


def box_hit(o: np.ndarray, d: np.ndarray, lo, hi) -> np.ndarray:
    """Exact exit points of rays o + t d from the box: (N, 3)."""
    return np.asarray(o, float) + np.asarray(d, float) * box_hit_t(o, d, lo, hi)[:, None]


def box_impostor(res: int, lo, hi, radiance: Callable[[np.ndarray], np.ndarray] | None = None) -> np.ndarray:
    """Cube-map texels (6, R, R, 4) of the box [lo, hi] seen from the origin (lo < 0 < hi).

    Channels: RGB = ``radiance(points)`` of the exact texel-centre hit (default: |direction|, a smooth
    direction-dependent colour), and the exact distance.
    """
    dirs = cubemap.texel_directions(res).reshape(-1, 3)
    t = box_hit_t(np.zeros_like(dirs), dirs, lo, hi)
    pts = dirs * t[:, None]
    rgb = np.abs(dirs) if radiance is None else radiance(pts)
    return np.concatenate([rgb, t[:, None]], -1).reshape(6, res, res, 4).astype(np.float32)


def random_rays(n: int, *, extent: float, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """``n`` rays with origins uniform in [−extent, extent]³ and uniform unit directions (fixed seed)."""
    rng = np.random.default_rng(seed)
    x = rng.uniform(-extent, extent, (n, 3))
    d = rng.normal(size=(n, 3))
    return x, d / np.linalg.norm(d, axis=1, keepdims=True)


def angle_deg(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Angle between row vectors a and b in degrees (atan2 form, accurate for tiny angles)."""
    c = np.linalg.norm(np.cross(a, b), axis=-1)
    return np.degrees(np.arctan2(c, (a * b).sum(-1)))


class AnalyticBox:
    """An exact environment on a backend: the box [lo, hi] (around the reference point at the origin) with
    ``distance(v)`` computed in closed form instead of read from texels. Same interface as
    :class:`study.impostor.envmap.EnvMap`; RGB is |v̂| (a smooth direction-dependent colour)."""

    def __init__(self, lo, hi, B):
        self.B, self.lo, self.hi = B, [float(a) for a in lo], [float(a) for a in hi]
        self.res, self.channels = 0, 4

    def distance(self, v):
        B = self.B
        n = B.length(v)
        t = None
        for c, lo, hi in zip((v.x, v.y, v.z), self.lo, self.hi):
            dc = c / n
            tc = B.select(
                dc > 0, hi / B.maximum(dc, 1e-30), B.select(dc < 0, lo / B.minimum(dc, -1e-30), 1e30)
            )
            t = tc if t is None else B.minimum(t, tc)
        return t

    def lookup(self, v):
        n = self.B.length(v)
        return [self.B.abs(v.x / n), self.B.abs(v.y / n), self.B.abs(v.z / n), self.distance(v)]
