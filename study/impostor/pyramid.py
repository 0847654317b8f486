"""Min mip pyramids over a cube map's distances: what lets a search skip texel ranges that hold no crossing.

Level 0 is the distance channel itself, (6, R, R); level q halves the resolution of level q − 1 (a texel is the
minimum of its 2×2 children; a side of odd length is padded with its last texel), up to one texel per face. A
query reads the level *dilated* forward: texel (i, j) of level q holds the minimum over the 2×2 level-q texels
(i..i+1, j..j+1), so one read covers any texel range that is no wider than a level-q texel (2^q texels of level 0)
along each axis, wherever it starts.

:meth:`MinPyramid.bound` answers one question per ray: a lower bound of the bilinear distance lookups (the cube-map
convention of :mod:`study.impostor.cubemap`: the four nearest texel centres of one face, coordinates clamped to the
face's outermost texel centres) anywhere on the straight segment between two points (u₀, v₀) and (u₁, v₁) of one
face. On a face, the gnomonic projection sends great circles to straight lines, so the samples of a search along a
great-circle arc between the two directions lie on that segment; bilinear weights are ≥ 0, so every lookup there is
at least the minimum over the texels the segment's box touches. One read of the dilated level that covers the box:
one lookup, four floats read, like a bilinear lookup. Where the two points are on different faces it gives −1
(no bound: below every distance).

Built once per impostor in numpy (:func:`min_pyramid`, a few milliseconds at R = 256; the :class:`EnvMap` that
holds the capture keeps it) and stored flat, levels one after the other, as one array of the backend. The slow,
obvious twin is :func:`bound_ref` (one segment, the minimum over the texels of a dense sampling of the segment).
"""

from __future__ import annotations

import numpy as np

from study.backend import Backend
from study.impostor import cubemap

#: Relative margin of the bound against float32 rounding of the lookups it stands for.
MARGIN = 1e-5


def _levels(dist: np.ndarray) -> list[np.ndarray]:
    """The plain min pyramid of (6, R, R) distances: levels 0 (the distances) to one texel per face."""
    out = [np.asarray(dist, np.float32)]
    while out[-1].shape[1] > 1:
        a = out[-1]
        if a.shape[1] % 2:
            a = np.concatenate([a, a[:, -1:]], axis=1)
            a = np.concatenate([a, a[:, :, -1:]], axis=2)
        out.append(
            np.minimum.reduce([a[:, 0::2, 0::2], a[:, 1::2, 0::2], a[:, 0::2, 1::2], a[:, 1::2, 1::2]])
        )
    return out


def _dilate(a: np.ndarray) -> np.ndarray:
    """min over (i..i+1, j..j+1), clamped at the last row and column."""
    b = np.minimum(a, np.concatenate([a[:, 1:], a[:, -1:]], axis=1))
    return np.minimum(b, np.concatenate([b[:, :, 1:], b[:, :, -1:]], axis=2))


def min_pyramid(dist: np.ndarray) -> tuple[np.ndarray, list[tuple[int, int]]]:
    """(flat array of every dilated level, [(offset, side) per level]) for (6, R, R) distances."""
    levels = [_dilate(a) for a in _levels(dist)]
    offsets, o = [], 0
    for a in levels:
        offsets.append((o, a.shape[1]))
        o += a.size
    return np.concatenate([a.ravel() for a in levels]).astype(np.float32), offsets


class MinPyramid:
    """The dilated min pyramid of one cube map's distances on a backend (``data``: one flat array; a frozen
    function must get it through its arguments, as it gets the textures)."""

    def __init__(self, dist: np.ndarray, B: Backend):
        flat, self.offsets = min_pyramid(dist)
        # after the levels, per level q: (offset, side, 2^−q), read by level where not made (one array: one frozen
        # argument)
        levels = np.array([(o, s, 2.0**-q) for q, (o, s) in enumerate(self.offsets)], np.float32)
        self.B, self.res, self.levels_at = B, dist.shape[1], int(flat.size)
        # a power-of-two side R and six faces per map (K maps): level q's side R 2^−q, its offset
        # 6K Σ_{p<q} side_p² = 8K (R² − side²), made in the march where float32 holds them exactly, not read
        R, K = self.res, dist.shape[0] / 6.0
        made = [np.float32(8.0 * K) * np.float32(R * R - (R >> q) ** 2) for q in range(len(self.offsets))]
        self.made = R & (R - 1) == 0 and K.is_integer() and made == [o for o, _ in self.offsets]
        self.maps = K
        self.data = B.array(np.concatenate([flat, levels.ravel()]))

    def bound(self, face0, u0, v0, face1, u1, v1):
        """A lower bound of the bilinear lookups on the segment (u₀, v₀)–(u₁, v₁) of face ``face0`` (−∞ where
        ``face1`` differs: −1, below any distance): one read of the pyramid."""
        B, R = self.B, self.res
        hi_c = float(max(R - 2, 0))

        def texels(a, b):  # the texels lo … hi + 1 the bilinear lookups between coordinates a and b touch
            # (the lookups clamp c to 0 … R − 1; lo and hi are clamped to 0 … R − 2 after the min and max)
            ca, cb = a * R - 0.5, b * R - 0.5
            lo = B.minimum(B.floor(B.maximum(B.minimum(ca, cb) - 1e-3, 0.0)), hi_c)
            return lo, B.minimum(B.floor(B.maximum(B.maximum(ca, cb), 0.0) + 1e-3), hi_c)

        j0, j1 = texels(u0, u1)  # columns
        i0, i1 = texels(v0, v1)  # rows
        # the lowest level q whose dilated texel at the box's start covers the box, of width w = d + 2 texels
        # along its wider axis: w ≤ 2^q + 1, q = ⌈log₂(w − 1)⌉ = ⌊log₂(2 w − 3)⌋ = ⌊log₂(2 d + 1)⌋ (0 at d = 0)
        d = B.maximum(j1 - j0, i1 - i0)
        q = B.minimum(B.exponent(d * 2.0 + 1.0), len(self.offsets) - 1.0)
        if self.made:  # no table read: see __init__
            scale = B.pow2(0.0 - q)
            side = scale * float(R)
            off = (float(R * R) - side * side) * (8.0 * self.maps)
        else:
            off, side, scale = (B.gather_at(self.data, self.levels_at, q * 3.0 + c) for c in (0.0, 1.0, 2.0))
        i, j = B.floor(i0 * scale), B.floor(j0 * scale)
        value = B.gather_at(self.data, off, (face0 * side + i) * side + j)  # integers: past 2²⁴ texels
        same = face0 == face1
        return B.select(same, value * (1.0 - MARGIN), value * 0.0 - 1.0)

    def bound_along(self, pa, pb, base=None):
        """A lower bound of every bilinear lookup along the arc between directions p̂_a and p̂_b (V3s, any length;
        −1 where they are on different faces): :meth:`bound` on their face coordinates. ``base`` (per ray, or
        None: 0): the first face of the cube map read, for maps stacked six faces each (probe k of a
        :class:`study.impostor.probes.ProbeSet`: 6k)."""
        fa, ua, va = cubemap.face_uv(self.B, pa.x, pa.y, pa.z)
        fb, ub, vb = cubemap.face_uv(self.B, pb.x, pb.y, pb.z)
        if base is not None:
            fa, fb = fa + base, fb + base
        return self.bound(fa, ua, va, fb, ub, vb)


def bound_ref(dist: np.ndarray, face: int, uv0, uv1, samples: int = 2000) -> float:
    """Slow twin of :meth:`MinPyramid.bound` on one segment of one face: the smallest texel that a bilinear lookup
    at any of ``samples`` points along the segment reads (the exact minimum it bounds from below)."""
    R = dist.shape[1]
    m = np.inf
    for s in np.linspace(0.0, 1.0, samples):
        u = uv0[0] + s * (uv1[0] - uv0[0])
        v = uv0[1] + s * (uv1[1] - uv0[1])
        cj, ci = min(max(u * R - 0.5, 0), R - 1), min(max(v * R - 0.5, 0), R - 1)
        j, i = min(int(cj), max(R - 2, 0)), min(int(ci), max(R - 2, 0))
        m = min(m, dist[face, i : i + 2, j : j + 2].min())
    return float(m)
