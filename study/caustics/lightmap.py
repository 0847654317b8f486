"""uv map and light maps: where a photon lands in texture space, and the irradiance its splat adds there.

uv map (the paper's ``uvmap``): a cube map in the :mod:`study.impostor.cubemap` layout, taken from the
reference point, that
stores per texel the texture id (surface id of :func:`study.scene.room_mesh`), u and v of the surface point visible
through the texel centre (Embree), plus id² so a lookup can tell a texel block that straddles two surfaces.

Lookup (backend-generic, :meth:`UVMap.lookup`): the texture id is the *nearest* texel's; (u, v) are bilinear between
the four nearest texels when they all lie on one surface (the paper's ``texCUBE(uvmap, l)``), else the nearest
texel's (a bilinear mix of two surfaces' coordinates is meaningless).

Light maps: one (M, M, 3) irradiance texture per surface id (W/m²), texel (row i, column j) ↔ (u, v) =
((j + ½)/M, (i + ½)/M). :func:`splat` adds each photon as a Gaussian of standard deviation ``sigma`` metres on the
surface, truncated to 3σ and to the surface and renormalised, so that Σ E · texel area = photon power exactly.
Caveat: all columns share the texture id "column", so their light maps overlap (the default scenes have none).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from study.backend import V3, Backend
from study.impostor import cubemap
from study.reference.embree import Tracer
from study.reference.tracer import make_tracer
from study.scene import RoomMesh, Scene, texture


def uv_map_texels(scene: Scene, res: int, tracer: Tracer | None = None) -> np.ndarray:
    """(6, R, R, 4) float32: (texture id, u, v, id²) of the point seen from the reference point per texel."""
    tracer = tracer or make_tracer(scene.mesh())
    dirs = cubemap.texel_directions(res).reshape(-1, 3)
    hit = tracer.intersect(np.broadcast_to(np.asarray(scene.reference.point, float), dirs.shape), dirs)
    sid = hit["surface"].astype(np.float64)
    out = np.stack([sid, hit["uv"][:, 0], hit["uv"][:, 1], sid * sid], -1)
    return out.reshape(6, res, res, 4).astype(np.float32)


def _floor(B: Backend, a):
    return np.floor(a) if B.name == "numpy" else B.dr.floor(a)


class UVMap:
    """The uv map bound to a backend."""

    def __init__(self, texels: np.ndarray, B: Backend):
        self.B, self.res = B, texels.shape[1]
        self.tex = B.texture(texels)

    def lookup(self, l: V3):
        """(id, u, v) of the surface point seen from the reference point in direction l (float arrays on B)."""
        B, R = self.B, self.res
        face, u, v = cubemap.face_uv(B, l.x, l.y, l.z)
        un, vn = (_floor(B, u * R) + 0.5) / R, (_floor(B, v * R) + 0.5) / R  # nearest texel centre
        sid, nu, nv, _ = B.sample(self.tex, face, un, vn)
        bid, bu, bv, bid2 = B.sample(self.tex, face, u, v)
        one = B.abs(bid2 - bid * bid) < 1e-3  # all four texels on one surface
        return sid, B.select(one, bu, nu), B.select(one, bv, nv)


# ---------------------------------------------------------------------------------------------- light maps
@dataclass(frozen=True)
class SurfaceFrames:
    """Metres per unit of u and of v for each texture id (from the first triangle of each surface)."""

    size_u: np.ndarray  # (S,)
    size_v: np.ndarray  # (S,)

    @classmethod
    def of(cls, mesh: RoomMesh) -> SurfaceFrames:
        S = len(mesh.surfaces)
        su, sv = np.ones(S), np.ones(S)
        for s in range(S):
            f = np.nonzero(mesh.surface == s)[0]
            if f.size == 0:
                continue
            a, b, c = mesh.faces[f[0]]
            P, T = mesh.vertices[[a, b, c]].astype(float), mesh.uv[[a, b, c]].astype(float)
            # solve [dP/du dP/dv] from two edges
            E, D = P[1:] - P[0], T[1:] - T[0]
            J = np.linalg.solve(D, E)  # rows: dP/du, dP/dv
            su[s], sv[s] = np.linalg.norm(J[0]), np.linalg.norm(J[1])
        return cls(su, sv)


def splat(
    surface: np.ndarray,
    uv: np.ndarray,
    power: np.ndarray,
    frames: SurfaceFrames,
    *,
    res: int = 256,
    sigma: float = 0.02,
) -> np.ndarray:
    """Gaussian splatting of photons into per-surface light maps.

    Parameters
    ----------
    surface : (P,) int texture id of each photon (photons with id < 0 are skipped)
    uv : (P, 2) texture coordinates of the hits
    power : (P, 3) photon power (W per RGB channel)
    frames : metres per unit u, v of each surface
    res : light-map resolution M per surface
    sigma : Gaussian standard deviation on the surface, metres

    Returns
    -------
    (S, M, M, 3) float64 irradiance, W/m².
    """
    S = len(frames.size_u)
    ok = (surface >= 0) & np.all(np.isfinite(uv), -1) & np.all(np.isfinite(power), -1)
    s, uv, power = surface[ok].astype(np.int64), uv[ok], power[ok]
    out = np.zeros((S * res * res, 3))
    if s.size == 0:
        return out.reshape(S, res, res, 3)
    su, sv = frames.size_u[s], frames.size_v[s]
    K = int(np.ceil(3 * sigma / (min(frames.size_u.min(), frames.size_v.min()) / res)))
    off = np.arange(-K, K + 1)
    cj = np.floor(uv[:, 0] * res).astype(np.int64)
    ci = np.floor(uv[:, 1] * res).astype(np.int64)
    j = cj[:, None, None] + off[None, None, :]  # (P, 1, W)
    i = ci[:, None, None] + off[None, :, None]  # (P, W, 1)
    du = ((j + 0.5) / res - uv[:, 0, None, None]) * su[:, None, None]  # metres
    dv = ((i + 0.5) / res - uv[:, 1, None, None]) * sv[:, None, None]
    r2 = du * du + dv * dv
    inside = (j >= 0) & (j < res) & (i >= 0) & (i < res) & (r2 <= 9 * sigma * sigma)
    w = np.where(inside, np.exp(-0.5 * r2 / sigma**2), 0.0)
    w /= np.maximum(w.sum(axis=(1, 2), keepdims=True), 1e-300)  # truncated Gaussian, renormalised
    area = su * sv / res**2  # m² per texel
    w = w / area[:, None, None]
    idx = (s[:, None, None] * res + np.clip(i, 0, res - 1)) * res + np.clip(j, 0, res - 1)
    idx, w = np.broadcast_arrays(idx, w)
    for c in range(3):
        out[:, c] = np.bincount(idx.ravel(), (w * power[:, c, None, None]).ravel(), minlength=out.shape[0])
    return out.reshape(S, res, res, 3)


def sample(maps: np.ndarray, surface: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """Bilinear lookup of per-surface maps (S, M, M, C) at (surface id, uv): (N, C); 0 where surface < 0."""
    M = maps.shape[1]
    ok = surface >= 0
    s = np.where(ok, surface, 0).astype(np.int64)
    u, v = np.nan_to_num(uv[:, 0]), np.nan_to_num(uv[:, 1])
    cj, ci = np.clip(u * M - 0.5, 0, M - 1), np.clip(v * M - 0.5, 0, M - 1)
    j0, i0 = np.minimum(cj.astype(np.int64), max(M - 2, 0)), np.minimum(ci.astype(np.int64), max(M - 2, 0))
    fj, fi = (cj - j0)[:, None], (ci - i0)[:, None]
    j1, i1 = np.minimum(j0 + 1, M - 1), np.minimum(i0 + 1, M - 1)
    out = (1 - fi) * ((1 - fj) * maps[s, i0, j0] + fj * maps[s, i0, j1]) + fi * (
        (1 - fj) * maps[s, i1, j0] + fj * maps[s, i1, j1]
    )
    return np.where(ok[:, None], out, 0.0)


def albedo_maps(mesh: RoomMesh, size: int = 256) -> np.ndarray:
    """(S, size, size, 3) the surfaces' procedural textures, row index along v (as Mitsuba's bitmap)."""
    return np.stack([texture(name, size) for name in mesh.surfaces])
