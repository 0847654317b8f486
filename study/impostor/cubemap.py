"""The one cube-map convention of study, stated once here.

A cube map of resolution ``R`` is an array ``(6, R, R, C)``: face, row, column, channel.

Faces, in this order, each with the camera that captures it (``forward``, ``right``, ``up``; right = forward × up,
which is Mitsuba's ``look_at`` convention, so a face is rendered by a perspective sensor looking along ``forward``
with ``up`` and ``fov = 90``)::

    face  forward  right  up
    0     +x       +z     +y
    1     -x       -z     +y
    2     +y       +x     +z
    3     -y       +x     -z
    4     +z       -x     +y
    5     -z       +x     +y

Texel (row i, column j) of a face looks along ``forward + s·right + t·up`` with
``s = 2(j + ½)/R − 1`` and ``t = 1 − 2(i + ½)/R``; rows go downwards in the image, columns to the right.
A direction is sent to the face of its largest component (ties to x, then y), and to face coordinates
``u = (s + 1)/2`` (along columns) and ``v = (1 − t)/2`` (along rows), both in [0, 1].

Lookups are bilinear between the four nearest texel centres of the same face; coordinates are clamped to the
face's outermost texel centres, so a lookup never bleeds into a neighbouring face (the half-texel band along each
edge is constant rather than blended across the edge).

**No surface.** Where a texel's ray leaves the scene (an open environment such as the Cornell box's front), the
map stores the radiance arriving from there (the background) and the distance :data:`FAR`: a finite stand-in for
infinity, so that every method's arithmetic stays finite (|r| = ∞ in the paper's eq. 2 would give ∞·0 = NaN) and
a point x + R·FAR looked up from the reference point lies, to float32 precision, in direction R. A distance
≥ :data:`FAR_MIN` means "no surface": the shown point is at infinity in that direction.

These functions are backend-generic: ``xp`` is a :class:`study.backend.Backend`, vectors are 1-D arrays.
"""

from __future__ import annotations

import functools
import math

import numpy as np

#: The distance stored where a texel sees no surface (its square, 1e12, is far inside float32's range).
FAR = 1.0e6
#: Distances at or beyond this are "no surface" (bilinear lookups between a surface and FAR give values in between).
FAR_MIN = 0.5 * FAR

#: (forward, right, up) per face, in face order.
FACES = np.array(
    [
        [[1, 0, 0], [0, 0, 1], [0, 1, 0]],
        [[-1, 0, 0], [0, 0, -1], [0, 1, 0]],
        [[0, 1, 0], [1, 0, 0], [0, 0, 1]],
        [[0, -1, 0], [1, 0, 0], [0, 0, -1]],
        [[0, 0, 1], [-1, 0, 0], [0, 1, 0]],
        [[0, 0, -1], [1, 0, 0], [0, 1, 0]],
    ],
    dtype=np.float64,
)


@functools.lru_cache(maxsize=8)
def texel_directions(res: int) -> np.ndarray:
    """Unit directions through every texel centre: (6, R, R, 3) float64, read-only (one array per resolution,
    shared by every caller)."""
    c = (np.arange(res) + 0.5) / res * 2 - 1
    s = c[None, :]  # along columns
    t = -c[:, None]  # along rows, downwards
    fwd, right, up = FACES[:, 0], FACES[:, 1], FACES[:, 2]
    d = (
        fwd[:, None, None, :]
        + s[None, ..., None] * right[:, None, None, :]
        + t[None, ..., None] * up[:, None, None, :]
    )
    d = d / np.linalg.norm(d, axis=-1, keepdims=True)
    d.flags.writeable = False
    return d


def face_uv(xp, dx, dy, dz, *, rough: bool = False):
    """Direction (need not be unit) → (face, u, v): face as a float array 0..5, u, v in [0, 1]. ``rough``: u and
    v from the major coordinate's approximate reciprocal (:meth:`study.backend.Backend.rcp`), within about 3e-7 of
    the exact ones (the face the same): for the pyramid's boxes, which a texel margin of 1e-3 covers, never for a
    lookup."""
    ax, ay, az = xp.abs(dx), xp.abs(dy), xp.abs(dz)
    is_x = (ax >= ay) & (ax >= az)
    is_y = ~is_x & (ay >= az)
    # per face: major coordinate ma, s = dot(d, right)/ma, t = dot(d, up)/ma (table FACES above)
    face = xp.select(
        is_x,
        xp.select(dx >= 0, 0.0, 1.0),
        xp.select(is_y, xp.select(dy >= 0, 2.0, 3.0), xp.select(dz >= 0, 4.0, 5.0)),
    )
    ma = xp.select(is_x, ax, xp.select(is_y, ay, az))
    sc = xp.select(is_x, xp.select(dx >= 0, dz, -dz), xp.select(is_y, dx, xp.select(dz >= 0, -dx, dx)))
    tc = xp.select(is_x, dy, xp.select(is_y, xp.select(dy >= 0, dz, -dz), dy))
    ma = xp.maximum(ma, 1e-30)
    if rough:
        r = xp.rcp(ma)
        return face, 0.5 * (sc * r + 1.0), 0.5 * (1.0 - tc * r)
    u = 0.5 * (sc / ma + 1.0)
    v = 0.5 * (1.0 - tc / ma)
    return face, u, v


def exit_angle(xp, e1, e2, phi):
    """Where the great circle d(φ) = cos φ e₁ + sin φ e₂ (e₁, e₂ orthonormal V3s) leaves the face of d(``phi``):
    the least φ' ≥ ``phi`` with |d_i(φ')| = |d_j(φ')|, i the major axis of d(``phi``) (:func:`face_uv`) and j one
    of the other two (a face changes only there; a tangent touch gives a φ' too early, never too late), at most
    ``phi`` + π. Each of d_i = ±d_j is A cos φ + B sin φ = 0, with roots atan2(−A, B) + mπ."""
    c, s = xp.cos(phi), xp.sin(phi)
    dx, dy, dz = (e1.x * c + e2.x * s), (e1.y * c + e2.y * s), (e1.z * c + e2.z * s)
    ax, ay, az = xp.abs(dx), xp.abs(dy), xp.abs(dz)
    is_x = (ax >= ay) & (ax >= az)
    is_y = ~is_x & (ay >= az)

    def pick(v, a, b, c_):  # the component of v on axis a (is_x), b (is_y) or c_
        return xp.select(is_x, getattr(v, a), xp.select(is_y, getattr(v, b), getattr(v, c_)))

    major = (pick(e1, "x", "y", "z"), pick(e2, "x", "y", "z"))
    others = [
        (pick(e1, "y", "x", "x"), pick(e2, "y", "x", "x")),
        (pick(e1, "z", "z", "y"), pick(e2, "z", "z", "y")),
    ]
    best = phi + math.pi
    for o1, o2 in others:
        for sign in (1.0, -1.0):
            r0 = xp.atan2(sign * o1 - major[0], major[1] - sign * o2)  # a root of d_i − sign·d_j
            off = r0 - phi
            off = off - math.pi * xp.floor(off * (1.0 / math.pi))  # the next root: in [0, π)
            best = xp.minimum(best, phi + off)
    return best


def face_uv_to_direction(face: np.ndarray, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Inverse of :func:`face_uv` (numpy only): unit directions (..., 3)."""
    f = FACES[np.asarray(face, int)]
    d = (
        f[..., 0, :]
        + (2 * np.asarray(u) - 1)[..., None] * f[..., 1, :]
        + (1 - 2 * np.asarray(v))[..., None] * f[..., 2, :]
    )
    return d / np.linalg.norm(d, axis=-1, keepdims=True)


def lookup_ref(texels: np.ndarray, d: np.ndarray) -> np.ndarray:
    """Slow, obvious bilinear lookup, one direction at a time: the ``_ref`` twin of the backends' lookups.

    texels: (6, R, R, C); d: (N, 3). Returns (N, C) float64.
    """

    class _np:
        abs, maximum = staticmethod(np.abs), staticmethod(np.maximum)
        select = staticmethod(np.where)

    R = texels.shape[1]
    out = np.empty((len(d), texels.shape[-1]))
    for n, (x, y, z) in enumerate(np.asarray(d, float)):
        f, u, v = (float(a) for a in face_uv(_np, np.array(x), np.array(y), np.array(z)))
        cj = min(max(u * R - 0.5, 0.0), R - 1.0)
        ci = min(max(v * R - 0.5, 0.0), R - 1.0)
        j0, i0 = min(int(cj), R - 2) if R > 1 else 0, min(int(ci), R - 2) if R > 1 else 0
        fj, fi = cj - j0, ci - i0
        t = texels[int(f)].astype(np.float64)
        j1, i1 = min(j0 + 1, R - 1), min(i0 + 1, R - 1)
        out[n] = (1 - fi) * ((1 - fj) * t[i0, j0] + fj * t[i0, j1]) + fi * (
            (1 - fj) * t[i1, j0] + fj * t[i1, j1]
        )
    return out
