"""The environment as one thing behind one interface, whatever its source (:mod:`study.scene.sources`):
triangles with surface ids (the very ones Embree intersects and Mitsuba renders), each surface's material, the
emitters, and the bounds.

:func:`geometry` turns a scene into an :class:`EnvGeometry`; the result is memoized by content (files by their
bytes), so every caller of one case shares one load of a mesh file or a Mitsuba scene.
"""

from __future__ import annotations

import json
from collections import OrderedDict
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from study.errors import StudyError
from study.scene.room import SURFACES, RoomMesh, room_mesh, texture
from study.scene.sources import key_fields

if TYPE_CHECKING:
    from study.scene.schema import Scene


@dataclass(frozen=True)
class Part:
    """One surface of the environment (triangles ``mesh.surface == index``) and what it is made of."""

    name: str
    albedo: np.ndarray | None = None  # (H, W, 3) linear RGB texture over the part's uv, or None
    color: tuple | None = None  # constant linear RGB albedo, or None
    vertex_colors: bool = False  # albedo from the mesh's vertex colours (``mesh.part_colors(index)``)
    native: Any = None  # a loaded Mitsuba shape (mitsuba environments): rendered as it is


@dataclass(frozen=True)
class EnvGeometry:
    """The environment of a scene (all coordinates world space, metres).

    mesh : RoomMesh            triangles, uv, surface id per triangle (index into ``parts``)
    parts : tuple[Part, ...]   materials, one per surface id
    emitters : tuple           Mitsuba emitters that are not area lights (mitsuba environments; else empty)
    point_light : bool         whether the scene's ``[light]`` lights it (box and mesh environments)
    sensor : dict | None       the Mitsuba scene's own camera: eye, target, up, fov (horizontal, degrees), width, height
    """

    mesh: RoomMesh
    parts: tuple[Part, ...]
    emitters: tuple = ()
    point_light: bool = True
    sensor: dict | None = None
    kind: str = "box"
    bounds: tuple[np.ndarray, np.ndarray] = field(default=None)  # (min, max) of the triangles

    def __post_init__(self):
        if self.bounds is None:
            v = self.mesh.vertices.astype(float)
            object.__setattr__(self, "bounds", (v.min(0), v.max(0)))


# ---------------------------------------------------------------------------------------------- sources
def _box(scene: Scene) -> EnvGeometry:
    return EnvGeometry(
        room_mesh(scene),
        tuple(Part(n, albedo=texture(n)) for n in SURFACES),
        bounds=(np.array(scene.room.min, float), np.array(scene.room.max, float)),
    )


def _srgb_to_linear(c: np.ndarray) -> np.ndarray:
    c = np.asarray(c, float)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def _mesh_file(env) -> EnvGeometry:
    import trimesh
    from trimesh.transformations import euler_matrix

    src = f"environment.file ({env.file})"
    try:
        sc = trimesh.load(env.file, force="scene")
        meshes = [g for g in sc.dump(concatenate=False) if isinstance(g, trimesh.Trimesh)]
    except Exception as err:  # noqa: BLE001 - any reader failure is bad input
        raise StudyError(f"cannot read the mesh file ({type(err).__name__}: {err})", key=src) from None
    meshes = [g for g in meshes if len(g.faces)]
    if not meshes:
        raise StudyError("the mesh file holds no triangles (no faces)", key=src)
    M = euler_matrix(*np.radians(env.rotation), "sxyz")[:3, :3] * env.scale
    V, F, UV, S, C, parts = [], [], [], [], [], []
    n = 0
    for i, g in enumerate(meshes):
        vis, uv, part = g.visual, None, None
        kind = getattr(vis, "kind", None)
        verts, faces = np.asarray(g.vertices, float), np.asarray(g.faces)
        if kind == "texture":
            mat = vis.material
            img = getattr(mat, "image", None) or getattr(mat, "baseColorTexture", None)
            if img is not None and vis.uv is not None and len(vis.uv) == len(verts):
                tex = _srgb_to_linear(np.asarray(img.convert("RGB"), float) / 255)
                uv = np.c_[vis.uv[:, 0], 1 - vis.uv[:, 1]]  # OBJ's v runs up, Mitsuba's down
                part = Part(f"part{i}", albedo=tex.astype(np.float32))
            else:
                c = getattr(mat, "main_color", None)
                part = Part(
                    f"part{i}",
                    color=tuple(_srgb_to_linear(np.asarray(c[:3]) / 255))
                    if c is not None
                    else tuple(env.color),
                )
        elif kind == "face":  # one colour per face: unshare the vertices
            verts, faces = verts[faces].reshape(-1, 3), np.arange(3 * len(faces)).reshape(-1, 3)
            col = _srgb_to_linear(np.repeat(np.asarray(vis.face_colors)[:, :3], 3, axis=0) / 255)
            part = Part(f"part{i}", vertex_colors=True)
        elif kind == "vertex":
            col = _srgb_to_linear(np.asarray(vis.vertex_colors)[:, :3] / 255)
            part = Part(f"part{i}", vertex_colors=True)
        else:
            part = Part(f"part{i}", color=tuple(env.color))
        if not part.vertex_colors:
            col = np.broadcast_to(np.asarray(part.color if part.color else env.color, float), (len(verts), 3))
        C.append(col)
        V.append(verts @ M.T + np.asarray(env.translate))
        F.append(faces + n)
        UV.append(uv if uv is not None else np.zeros((len(verts), 2)))
        S.append(np.full(len(faces), i))
        parts.append(part)
        n += len(verts)
    mesh = RoomMesh(
        np.concatenate(V).astype(np.float32),
        np.concatenate(F).astype(np.int32),
        np.concatenate(UV).astype(np.float32),
        np.concatenate(S).astype(np.int32),
        tuple(p.name for p in parts),
        np.concatenate(C).astype(np.float32),
    )
    return EnvGeometry(mesh, tuple(parts), kind="mesh")


def _mitsuba(env) -> EnvGeometry:
    from study import runtime

    m = runtime.mitsuba()
    try:
        if env.file is not None:
            sc = m.load_file(env.file)
        else:
            sc = m.load_dict(m.cornell_box() if env.builtin == "cornell_box" else dict(env.scene))
    except Exception as err:  # noqa: BLE001 - Mitsuba's parser errors
        raise StudyError(
            f"Mitsuba cannot load the scene ({' '.join(str(err).split())[:300]})", key="environment"
        ) from None
    V, F, S, parts = [], [], [], []
    n = 0
    for i, s in enumerate(sc.shapes()):
        name = s.id() or f"shape{i}"
        if not s.is_mesh():
            kind = str(s).split("[")[0].strip()
            raise StudyError(
                f"shape {name!r} is an analytic {kind}, not a triangle mesh: Embree needs the same "
                "triangles Mitsuba renders; replace it by a mesh (obj, ply or a Mitsuba cube/rectangle)",
                key="environment",
            )
        v = np.array(s.vertex_positions_buffer(), np.float64).reshape(-1, 3)
        f = np.array(s.faces_buffer(), np.int64).reshape(-1, 3)
        if s.has_flipped_normals():  # flip_normals: the free side is the other one
            f = f[:, ::-1]
        V.append(v)
        F.append(f + n)
        S.append(np.full(len(f), i))
        n += len(v)
        parts.append(Part(name, native=s))
    if not V or not sum(len(f) for f in F):
        raise StudyError("the Mitsuba scene holds no triangles", key="environment")
    emitters = tuple(e for e in sc.emitters() if not m.has_flag(e.flags(), m.EmitterFlags.Surface))
    mesh = RoomMesh(
        np.concatenate(V).astype(np.float32),
        np.concatenate(F).astype(np.int32),
        np.zeros((n, 2), np.float32),
        np.concatenate(S).astype(np.int32),
        tuple(p.name for p in parts),
    )
    return EnvGeometry(
        mesh, tuple(parts), emitters=emitters, point_light=False, sensor=_sensor(m, sc), kind="mitsuba"
    )


def _sensor(m, sc) -> dict | None:
    """The scene's first camera as eye/target/up/fov (horizontal degrees)/size, or None."""
    if not sc.sensors():
        return None
    s = sc.sensors()[0]
    T = (
        np.array(m.traverse(s)["to_world"].matrix, float).reshape(4, 4)
        if "to_world" in m.traverse(s)
        else None
    )
    if T is None:
        T = np.array(s.world_transform().matrix, float).reshape(4, 4)
    eye, fwd, up = T[:3, 3], T[:3, 2], T[:3, 1]
    W, H = (int(x) for x in s.film().size())
    x_fov = float(np.ravel(m.traverse(s)["x_fov"])[0]) if "x_fov" in m.traverse(s) else 45.0
    return {
        "eye": eye.tolist(),
        "target": (eye + fwd).tolist(),
        "up": (up / np.linalg.norm(up)).tolist(),
        "fov": x_fov,
        "width": W,
        "height": H,
    }


# ---------------------------------------------------------------------------------------------- one per content
_MEMO: OrderedDict[str, EnvGeometry] = OrderedDict()


def env_key(scene: Scene) -> str:
    """Content key of what :func:`geometry` returns: the environment source (files by their bytes), and for the
    box the room and columns."""
    from study import runtime

    env = scene.environment
    parts: dict = {"environment": key_fields(env)}
    if env.type == "box":
        parts["room"], parts["columns"] = scene.room.model_dump(), [c.model_dump() for c in scene.columns]
    if env.type == "mitsuba":
        parts["variant"] = runtime.current_variant() if hasattr(runtime, "current_variant") else "llvm_ad_rgb"
    return json.dumps(parts, sort_keys=True)


def geometry(scene: Scene | Any) -> EnvGeometry:
    """The environment of ``scene`` (memoized: the last few loaded environments are kept). ``scene`` may also be
    a mesh or Mitsuba environment on its own (a :mod:`study.scene.sources` model or its dict)."""
    if not hasattr(scene, "environment"):  # an environment alone (not the box: that needs its room)
        from pydantic import TypeAdapter

        from study.scene.sources import Environment

        env = scene if hasattr(scene, "type") else TypeAdapter(Environment).validate_python(scene)
        scene = type("_EnvOnly", (), {"environment": env, "room": None, "columns": ()})()
    key = env_key(scene)
    if key not in _MEMO:
        env = scene.environment
        _MEMO[key] = (
            _box(scene) if env.type == "box" else _mesh_file(env) if env.type == "mesh" else _mitsuba(env)
        )
        while len(_MEMO) > 8:
            _MEMO.popitem(last=False)
    _MEMO.move_to_end(key)
    return _MEMO[key]


# ---------------------------------------------------------------------------------------------- placement
# for new scenes
def suggest(scene: Scene | Any) -> dict[str, Any]:
    """Where to put things in an environment nobody placed them in: dotted overrides for ``reference.point``,
    ``object.center``, ``object.radius``, ``light.position`` (mesh environments) and the camera.

    The reference point is the free, enclosed point of a 5³ grid inside the bounds that lies farthest from every
    surface; the object (radius a quarter of that clearance, at most 8 % of the bounds' diagonal) a little below
    it; the camera is the Mitsuba scene's own (its sensor) when it has one — the object then moves onto its view
    axis, at the free point nearest the bounds' centre — else it stands back from the object towards the reference
    point's far side and looks at it. Every suggestion passes the placement checks (:mod:`study.scene.placement`).
    ``scene`` is a scene or an environment alone (a mesh or Mitsuba source, as :func:`geometry` takes).
    """
    from study.scene import placement
    from study.validation import KeyedError

    env = geometry(scene)
    mesh, (lo, hi) = env.mesh, env.bounds
    diag = float(np.linalg.norm(hi - lo))
    g = np.linspace(0.15, 0.85, 5)
    grid = lo + (hi - lo) * np.stack(np.meshgrid(g, g, g, indexing="ij"), -1).reshape(-1, 3)
    best, gap = None, 0.0
    for p in sorted(grid, key=lambda p: -placement.clearance(mesh, p)):
        try:
            placement.check_free(mesh, p, "reference.point", enclosed=True)
        except KeyedError:
            continue
        best, gap = p, placement.clearance(mesh, p)
        break
    if best is None:
        raise StudyError(
            "found no free point enclosed by the environment for the reference point; give "
            "reference.point, object.center and camera.eye yourself",
            key="environment",
        )
    radius = min(0.25 * gap, 0.08 * diag)
    out: dict[str, Any] = {"reference.point": best.tolist(), "object.radius": float(radius)}
    centre = best - np.array([0.0, 0.45 * gap, 0.0])
    if env.sensor is not None:
        s = env.sensor
        eye, target = np.array(s["eye"]), np.array(s["target"])
        axis = (target - eye) / np.linalg.norm(target - eye)
        ts = np.linspace(0, 2 * diag + np.linalg.norm(eye - (lo + hi) / 2), 200)
        pts = eye + ts[:, None] * axis
        free = [
            p
            for p in pts
            if np.all(p > lo) and np.all(p < hi) and placement.clearance(mesh, p) > 1.5 * radius
        ]
        if free:
            centre = min(free, key=lambda p: np.linalg.norm(p - (lo + hi) / 2))
        out.update(
            {
                "camera.eye": s["eye"],
                "camera.target": centre.tolist(),
                "camera.up": s["up"],
                "camera.fov": s["fov"],
            }
        )
    else:
        view = (
            np.array([1.0, 0.0, 0.0]) if abs((hi - lo)[0]) >= abs((hi - lo)[2]) else np.array([0.0, 0.0, 1.0])
        )
        eye = best + view * 0.7 * gap + np.array([0.0, 0.1 * gap, 0.0])
        out.update(
            {"camera.eye": eye.tolist(), "camera.target": centre.tolist(), "camera.up": [0.0, 1.0, 0.0]}
        )
    out["object.center"] = np.asarray(centre, float).tolist()
    if env.point_light:
        out["light.position"] = (best + np.array([0.0, 0.6 * gap, 0.0])).tolist()
    return out


def describe(scene: Scene) -> str:
    """A short name of the environment for titles: "(-2, 0, -2)..(2, 3, 2) room", "mesh l_room.ply", "Mitsuba
    cornell_box"."""
    env = scene.environment
    if env.type == "box":
        fmt = lambda v: "(" + ", ".join(f"{x:g}" for x in v) + ")"  # noqa: E731
        return f"{fmt(scene.room.min)}..{fmt(scene.room.max)} room" + (
            f", {len(scene.columns)} column(s)" if scene.columns else ""
        )
    if env.type == "mesh":
        from pathlib import Path

        return f"mesh {Path(env.file).name}"
    from pathlib import Path

    return f"Mitsuba {env.builtin or (Path(env.file).name if env.file else 'scene dict')}"
