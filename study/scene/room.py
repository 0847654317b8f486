"""The environment as triangles — the very ones Mitsuba renders and Embree intersects — and their textures."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from study.scene.schema import Scene


# ---------------------------------------------------------------------------------------------- triangles
@dataclass(frozen=True)
class RoomMesh:
    """The environment as triangles: the very ones Mitsuba renders and Embree intersects.

    Attributes
    ----------
    vertices : (V, 3) float32, world space
    faces : (F, 3) int32
    uv : (V, 2) float32, texture coordinates in [0, 1]^2 of each vertex on its surface
    surface : (F,) int32, index into ``surfaces`` (the texture id of each triangle)
    surfaces : names of the textured surfaces, in texture-id order
    colors : (V, 3) float32 linear RGB per vertex, or None (mesh files with vertex or face colours)
    """

    vertices: np.ndarray
    faces: np.ndarray
    uv: np.ndarray
    surface: np.ndarray
    surfaces: tuple[str, ...]
    colors: np.ndarray | None = None

    def part_colors(self, surface_id: int) -> np.ndarray | None:
        """Vertex colours of one surface, in the vertex order of :meth:`part` (None without colours)."""
        if self.colors is None:
            return None
        return self.colors[np.unique(self.faces[self.surface == surface_id])]

    def part(self, surface_id: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(vertices, faces, uv) of one surface, re-indexed."""
        f = self.faces[self.surface == surface_id]
        used, inv = np.unique(f, return_inverse=True)
        return self.vertices[used], inv.reshape(-1, 3).astype(np.int32), self.uv[used]


SURFACES = ("floor", "ceiling", "wall_x-", "wall_x+", "wall_z-", "wall_z+", "column")


def _quad(p0, du, dv):
    """Two triangles spanning p0, p0+du, p0+du+dv, p0+dv with uv (0,0)..(1,1)."""
    p0, du, dv = map(np.asarray, (p0, du, dv))
    v = np.array([p0, p0 + du, p0 + du + dv, p0 + dv], dtype=np.float64)
    uv = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], dtype=np.float64)
    return v, np.array([[0, 1, 2], [0, 2, 3]]), uv


def _box_quads(lo, hi, *, inward: bool, skip_bottom: bool = False):
    """The six faces of a box as (name-axis, quad); normals point inward for the room, outward for columns."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    s = hi - lo
    ex, ey, ez = np.diag(s)
    quads = {
        "floor": _quad(lo, ez, ex) if inward else _quad(lo, ex, ez),
        "ceiling": _quad(lo + ey, ex, ez) if inward else _quad(lo + ey, ez, ex),
        "wall_x-": _quad(lo, ey, ez) if inward else _quad(lo, ez, ey),
        "wall_x+": _quad(lo + ex, ez, ey) if inward else _quad(lo + ex, ey, ez),
        "wall_z-": _quad(lo, ex, ey) if inward else _quad(lo, ey, ex),
        "wall_z+": _quad(lo + ez, ey, ex) if inward else _quad(lo + ez, ex, ey),
    }
    if skip_bottom:
        del quads["floor"]
    return quads


def room_mesh(scene: Scene) -> RoomMesh:
    """Triangulate the room (inward-facing) and its columns (outward-facing, no bottom face)."""
    V, F, UV, S = [], [], [], []
    n = 0

    def add(quad, sid):
        nonlocal n
        v, f, uv = quad
        V.append(v)
        F.append(f + n)
        UV.append(uv)
        S.append(np.full(len(f), sid))
        n += len(v)

    for name, quad in _box_quads(scene.room.min, scene.room.max, inward=True).items():
        add(quad, SURFACES.index(name))
    for col in scene.columns:
        for quad in _box_quads(*col.box(scene.room), inward=False, skip_bottom=True).values():
            add(quad, SURFACES.index("column"))
    return RoomMesh(
        np.concatenate(V).astype(np.float32),
        np.concatenate(F).astype(np.int32),
        np.concatenate(UV).astype(np.float32),
        np.concatenate(S).astype(np.int32),
        SURFACES,
    )


# ---------------------------------------------------------------------------------------------- textures
def texture(surface: str, size: int = 256) -> np.ndarray:
    """Procedural albedo texture of a surface: (size, size, 3) float32 linear RGB in (0, 0.9].

    Generated in code (nothing downloaded) and high in detail, so that a misplaced reflection shows in the
    image metrics: a two-tone checker on the floor, coloured tiles with grout on the walls, a grid on the
    ceiling and stripes on columns.
    """
    y, x = np.mgrid[0:size, 0:size] / size
    hues = {
        "floor": ((0.75, 0.72, 0.65), (0.25, 0.22, 0.2)),
        "ceiling": ((0.8, 0.8, 0.8), (0.55, 0.55, 0.6)),
        "wall_x-": ((0.75, 0.3, 0.25), (0.85, 0.7, 0.5)),
        "wall_x+": ((0.25, 0.45, 0.75), (0.7, 0.8, 0.85)),
        "wall_z-": ((0.3, 0.65, 0.3), (0.8, 0.85, 0.6)),
        "wall_z+": ((0.8, 0.65, 0.2), (0.45, 0.3, 0.6)),
        "column": ((0.85, 0.85, 0.8), (0.2, 0.2, 0.35)),
    }
    a, b = (np.array(h, np.float32) for h in hues[surface])
    if surface == "floor":
        m = ((np.floor(x * 8) + np.floor(y * 8)) % 2)[..., None]
    elif surface == "ceiling":
        m = ((np.abs((x * 6) % 1 - 0.5) > 0.45) | (np.abs((y * 6) % 1 - 0.5) > 0.45))[..., None]
    elif surface == "column":
        m = (np.floor(y * 10) % 2)[..., None]
    else:
        tile = ((np.floor(x * 6) + 2 * np.floor(y * 5)) % 3)[..., None] / 2
        grout = ((np.abs((x * 6) % 1 - 0.5) > 0.46) | (np.abs((y * 5) % 1 - 0.5) > 0.46))[..., None]
        return np.where(grout, 0.12, a * (1 - tile) + b * tile).astype(np.float32)
    return (a * (1 - m) + b * m).astype(np.float32)
