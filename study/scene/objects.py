"""The shaded object as geometry: an analytic sphere or a triangle mesh with smooth (interpolated vertex) normals.

Contract
--------
:func:`object_geometry` turns ``scene.object`` into an :class:`ObjectGeometry` with

* ``intersect(o, d)`` → ``(t, normal)``: nearest hit t > 0 of rays (o, unit d), shape (N,), inf on a miss, and the
  unit outward shading normal (N, 3) there (NaN on a miss). Meshes interpolate vertex normals with the hit's
  barycentric coordinates; Embree (embreex, a scene holding only the object) finds the hits.
* ``exit(p, d)`` → ``(e, normal, ok)``: where rays starting on or inside the object leave it (the far side),
  exactly (sphere: closed form; mesh: Embree), for double refraction. (The approximate far side, through the
  object's own distance map, is :class:`study.optics.distance_map.DistanceMap`.)

Meshes (made with trimesh, unit size, then scaled by ``radius`` = bounding-sphere radius, turned by ``rotation``,
moved to ``center``):

* ``torus``: major radius 0.7, minor 0.3 (bounding radius 1), axis along y before rotation;
* ``knot``: a trefoil knot tube (radius 0.12 of the bounding radius), swept along the curve;
* ``blob``: an icosphere subdivided ``detail + 1`` times and displaced radially by a smooth sum of sines;
* ``mesh``: the triangles of ``object.file`` (OBJ and glTF/GLB by study's readers,
  :func:`study.scene.meshfile.triangles`; PLY/STL/OFF by ``trimesh.load(path, force="mesh")``; a file of several
  parts is joined into one), welded (vertices that share a position become one, whatever their texture
  coordinates or normals in the file, so that the normals are smooth across seams), degenerate faces dropped, wound
  consistently, centred on its bounding box like the built-in shapes. The file's own normals are not used: every
  mesh gets trimesh's area-weighted vertex normals. A file that trimesh cannot read, or that holds no faces, is a
  :class:`~study.errors.StudyError` naming the file and ``object.file``.
"""

from __future__ import annotations

import functools
import os
from dataclasses import dataclass

import numpy as np

from study.errors import StudyError
from study.scene.schema import Scene, Sphere

EPS = 1e-4  # ray-origin offset (m) when leaving a surface


# ---------------------------------------------------------------------------------------------- meshes
@dataclass(frozen=True)
class ObjectMesh:
    vertices: np.ndarray  # (V, 3) float64, world space
    faces: np.ndarray  # (F, 3) int32, counter-clockwise seen from outside
    normals: np.ndarray  # (V, 3) float64, unit outward vertex normals (smooth)


def _knot(detail: int):
    import trimesh

    n_t, n_c, r_tube = 96 * detail, 12 * detail, 0.12
    t = np.linspace(0, 2 * np.pi, n_t, endpoint=False)

    def curve(t):
        return np.stack([np.sin(t) + 2 * np.sin(2 * t), np.cos(t) - 2 * np.cos(2 * t), -np.sin(3 * t)], -1)

    c = curve(t)
    T = curve(t + 1e-4) - curve(t - 1e-4)
    T /= np.linalg.norm(T, axis=1, keepdims=True)
    # ----- rotation-minimising frames by parallel transport, closed by twisting the residual angle out
    U = np.zeros_like(T)
    u = np.cross(T[0], [0.0, 0.0, 1.0])
    u /= np.linalg.norm(u)
    for i in range(n_t):
        u = u - np.dot(u, T[i]) * T[i]
        u /= np.linalg.norm(u)
        U[i] = u
    W0 = np.cross(T[0], U[0])
    u_end = U[-1] - np.dot(U[-1], T[0]) * T[0]
    twist = np.arctan2(np.dot(u_end, W0), np.dot(u_end, U[0]))
    ang = -twist * np.arange(n_t) / n_t
    W = np.cross(T, U)
    U, W = (
        U * np.cos(ang)[:, None] + W * np.sin(ang)[:, None],
        W * np.cos(ang)[:, None] - U * np.sin(ang)[:, None],
    )
    phi = np.linspace(0, 2 * np.pi, n_c, endpoint=False)
    scale = 1 / 3.0  # the trefoil reaches about 3 from its centre
    ring = np.cos(phi)[None, :, None] * U[:, None] + np.sin(phi)[None, :, None] * W[:, None]
    V = (c[:, None] + r_tube * 3 * ring) * scale  # tube radius r_tube in unit-bounding units
    i, j = np.meshgrid(np.arange(n_t), np.arange(n_c), indexing="ij")
    a, b = i * n_c + j, ((i + 1) % n_t) * n_c + j
    c2, d2 = ((i + 1) % n_t) * n_c + (j + 1) % n_c, i * n_c + (j + 1) % n_c
    F = np.concatenate([np.stack([a, b, c2], -1).reshape(-1, 3), np.stack([a, c2, d2], -1).reshape(-1, 3)])
    return trimesh.Trimesh(V.reshape(-1, 3), F, process=True)


def _blob(detail: int):
    import trimesh

    m = trimesh.creation.icosphere(subdivisions=detail + 1)
    v = m.vertices
    r = (
        1
        + 0.18 * np.sin(3 * v[:, 0] + 0.5) * np.sin(2 * v[:, 1] + 1.0)
        + 0.12 * np.sin(4 * v[:, 2] + 2 * v[:, 0])
    )
    return trimesh.Trimesh(v * r[:, None], m.faces, process=True)


def read_mesh_file(path: str):
    """The triangles of a mesh file as a welded trimesh.Trimesh (not yet centred or scaled): see the module
    docstring. Read once per file version (path, modification time, size)."""
    try:
        st = os.stat(path)
    except OSError as err:
        raise StudyError(
            f"cannot read the mesh file ({os.strerror(err.errno)})", file=path, key="object.file"
        ) from None
    return _read_mesh(str(path), st.st_mtime_ns, st.st_size).copy()


@functools.lru_cache(maxsize=8)
def _read_mesh(path: str, mtime_ns: int, size: int):
    import trimesh

    if path.lower().endswith((".obj", ".gltf", ".glb")):  # study's readers: negative OBJ indices, refusals
        from study.scene.meshfile import triangles

        V, F = triangles(path, "object.file")
        m = trimesh.Trimesh(V, F, process=False)
    else:
        m = None
    try:
        m = m if m is not None else trimesh.load(path, force="mesh")
    except Exception as err:  # trimesh raises many kinds on a damaged file
        first = (str(err).strip().splitlines() or [type(err).__name__])[0][:160]
        raise StudyError(f"unreadable mesh file ({first})", file=path, key="object.file") from None
    faces = np.asarray(getattr(m, "faces", np.zeros((0, 3))))
    if not isinstance(m, trimesh.Trimesh) or faces.ndim != 2 or len(faces) == 0:
        raise StudyError(
            "the mesh file holds no faces (triangles or polygons); a point cloud or an empty file "
            "cannot be shaded",
            file=path,
            key="object.file",
        )
    m = trimesh.Trimesh(np.asarray(m.vertices, float), faces, process=True)  # welded by position only
    m.update_faces(m.nondegenerate_faces())
    m.remove_unreferenced_vertices()
    if len(m.faces) == 0 or not np.isfinite(m.vertices).all() or np.ptp(m.vertices, axis=0).max() <= 0:
        raise StudyError("the mesh file holds no faces of non-zero area", file=path, key="object.file")
    return m


def unit_shape(shape: str, detail: int = 3, file: str | None = None):
    """The shape as a trimesh.Trimesh centred at the origin with bounding radius 1 and outward winding
    (``file``: the mesh file of shape "mesh")."""
    import trimesh

    if shape == "mesh":
        if file is None:
            raise StudyError('shape "mesh" needs a mesh file', key="object.file")
        m = read_mesh_file(file)
    elif shape == "torus":
        m = trimesh.creation.torus(0.7, 0.3, major_sections=16 * detail, minor_sections=8 * detail)
        m.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, [1, 0, 0]))  # axis z → y
    elif shape == "knot":
        m = _knot(detail)
    elif shape == "blob":
        m = _blob(detail)
    else:
        raise ValueError(f"not a mesh shape: {shape!r}")
    m.fix_normals()  # consistent, outward winding
    m.apply_translation(-m.bounding_box.centroid)
    m.apply_scale(1 / np.linalg.norm(m.vertices, axis=1).max())
    return m


def rotation_matrix(degrees) -> np.ndarray:
    """Euler rotation: about x, then y, then z (degrees), as a (3, 3) matrix acting on column vectors."""
    ax, ay, az = np.radians(degrees)
    Rx = np.array([[1, 0, 0], [0, np.cos(ax), -np.sin(ax)], [0, np.sin(ax), np.cos(ax)]])
    Ry = np.array([[np.cos(ay), 0, np.sin(ay)], [0, 1, 0], [-np.sin(ay), 0, np.cos(ay)]])
    Rz = np.array([[np.cos(az), -np.sin(az), 0], [np.sin(az), np.cos(az), 0], [0, 0, 1]])
    return Rz @ Ry @ Rx


def object_mesh(obj: Sphere) -> ObjectMesh:
    """The object's triangles in world space with smooth outward vertex normals (trimesh's area-weighted
    average of the face normals around each vertex)."""
    m = unit_shape(obj.shape, obj.detail, obj.file)
    Rm = rotation_matrix(obj.rotation)
    V = (m.vertices @ Rm.T) * obj.radius + np.asarray(obj.center, float)
    N = np.asarray(m.vertex_normals) @ Rm.T
    N /= np.linalg.norm(N, axis=1, keepdims=True)
    return ObjectMesh(V, np.asarray(m.faces, np.int32), N)


# ---------------------------------------------------------------------------------------------- geometry
class ObjectGeometry:
    center: np.ndarray
    radius: float

    def intersect(self, o, d) -> tuple[np.ndarray, np.ndarray]: ...
    def exit(self, p, d) -> tuple[np.ndarray, np.ndarray, np.ndarray]: ...


def intersect_sphere(o, d, center, radius) -> np.ndarray:
    """Nearest positive ray parameter of rays (o, unit d) with a sphere, inf on a miss: (N,)."""
    L = o - np.asarray(center, float)
    b = np.sum(L * d, axis=-1)
    c = np.sum(L * L, axis=-1) - radius * radius
    disc = b * b - c
    s = np.sqrt(np.maximum(disc, 0))
    t0, t1 = -b - s, -b + s
    t = np.where(t0 > 1e-9, t0, np.where(t1 > 1e-9, t1, np.inf))
    return np.where(disc >= 0, t, np.inf)


def sphere_exit(x: np.ndarray, d: np.ndarray, center, radius) -> np.ndarray:
    """Far intersection of rays starting inside (or on) a sphere: points (N, 3)."""
    L = x - np.asarray(center, float)
    b = np.sum(L * d, axis=-1)
    c = np.sum(L * L, axis=-1) - radius * radius
    t = -b + np.sqrt(np.maximum(b * b - c, 0))
    return x + t[:, None] * d


class SphereGeometry(ObjectGeometry):
    def __init__(self, center, radius):
        self.center, self.radius = np.asarray(center, float), float(radius)

    def intersect(self, o, d):
        t = intersect_sphere(o, d, self.center, self.radius)
        with np.errstate(invalid="ignore"):
            n = (o + d * t[:, None] - self.center) / self.radius
            n = n / np.linalg.norm(n, axis=-1, keepdims=True)
        return t, n

    def exit(self, p, d):
        e = sphere_exit(p, d, self.center, self.radius)
        return e, (e - self.center) / self.radius, np.ones(len(p), bool)


class MeshGeometry(ObjectGeometry):
    """A triangle mesh in its own Embree scene; hits carry interpolated vertex normals."""

    def __init__(self, mesh: ObjectMesh, center, radius):
        from embreex import rtcore_scene as rtcs
        from embreex.mesh_construction import TriangleMesh

        self.mesh, self.center, self.radius = mesh, np.asarray(center, float), float(radius)
        self.scene = rtcs.EmbreeScene()
        TriangleMesh(self.scene, mesh.vertices.astype(np.float32), mesh.faces.astype(np.int32))

    def hits(self, o, d) -> dict[str, np.ndarray]:
        """t (N,) (inf on a miss), smooth normal (N, 3) and geometric normal (N, 3) (NaN on a miss)."""
        o32 = np.ascontiguousarray(o, np.float32).reshape(-1, 3)
        d32 = np.ascontiguousarray(d, np.float32).reshape(-1, 3)
        res = self.scene.run(o32, d32, output=1)
        hit = res["geomID"] != -1
        prim = np.where(hit, res["primID"], 0)
        u, v = res["u"].astype(float), res["v"].astype(float)
        f = self.mesh.faces[prim]
        nv = self.mesh.normals
        n = (1 - u - v)[:, None] * nv[f[:, 0]] + u[:, None] * nv[f[:, 1]] + v[:, None] * nv[f[:, 2]]
        n /= np.linalg.norm(n, axis=1, keepdims=True)
        P = self.mesh.vertices[f]
        ng = np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0])
        ng /= np.linalg.norm(ng, axis=1, keepdims=True)
        t = np.where(hit, res["tfar"].astype(float), np.inf)
        nan = np.where(hit, 0.0, np.nan)[:, None]
        return {"t": t, "normal": n + nan, "geometric": ng + nan}

    def intersect(self, o, d):
        h = self.hits(o, d)
        return h["t"], h["normal"]

    def exit(self, p, d):
        """Leave the mesh from inside: the next surface hit along d (origin offset by EPS); ``ok`` False where none
        is found (round-off at grazing entries). The shading normal is replaced by the geometric one where it
        does not face along d (smooth normals can, near silhouettes), so that refraction stays well defined."""
        h = self.hits(p + EPS * d, d)
        e = p + (h["t"] + EPS)[:, None] * d
        n = np.where((np.sum(h["normal"] * d, -1) > 1e-6)[:, None], h["normal"], h["geometric"])
        return e, n, np.isfinite(h["t"]) & (np.sum(n * d, -1) > 0)


def object_geometry(scene: Scene) -> ObjectGeometry:
    obj = scene.object
    if obj.shape == "sphere":
        return SphereGeometry(obj.center, obj.radius)
    return MeshGeometry(object_mesh(obj), obj.center, obj.radius)


def farthest_surface(
    geom: ObjectGeometry, dirs: np.ndarray, max_layers: int = 16
) -> tuple[np.ndarray, np.ndarray]:
    """Distance (N,) and outward normal (N, 3) of the farthest surface along rays from the centre (0 on a miss)."""
    c = np.broadcast_to(geom.center, dirs.shape)
    if isinstance(geom, SphereGeometry):
        return np.full(len(dirs), geom.radius), dirs.copy()
    dist, nrm = np.zeros(len(dirs)), np.zeros_like(dirs)
    s = np.zeros(len(dirs))
    live = np.ones(len(dirs), bool)
    for _ in range(max_layers):
        h = geom.hits(c[live] + (s[live] + EPS)[:, None] * dirs[live], dirs[live])
        hit = np.isfinite(h["t"])
        idx = np.nonzero(live)[0]
        s[idx[hit]] += h["t"][hit] + EPS
        dist[idx[hit]] = s[idx[hit]]
        nrm[idx[hit]] = h["normal"][hit]
        live[idx[~hit]] = False
        if not live.any():
            break
    return dist, nrm
