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
from study.scene.parts import Part
from study.scene.room import SURFACES, RoomMesh, room_mesh, texture
from study.scene.sources import key_fields

if TYPE_CHECKING:
    from study.scene.schema import Scene


@dataclass(frozen=True)
class EnvGeometry:
    """The environment of a scene (all coordinates world space, metres).

    mesh : RoomMesh            triangles, uv, surface id per triangle (index into ``parts``)
    parts : tuple[Part, ...]   materials, one per surface id
    emitters : tuple           Mitsuba emitters that are not area lights (mitsuba environments; else empty)
    point_light : bool         whether the scene's ``[light]`` may light it (box and mesh environments, Mitsuba
                               scenes without an emitter); off where the file brings light and ``light.enabled``
                               says so (:mod:`study.reference.mitsuba`)
    sensor : dict | None       the file's own camera (Mitsuba sensor, glTF camera): eye, target, up, fov
                               (horizontal, degrees), width, height
    """

    mesh: RoomMesh
    parts: tuple[Part, ...]
    emitters: tuple = ()
    point_light: bool = True
    sensor: dict | None = None
    kind: str = "box"
    bounds: tuple[np.ndarray, np.ndarray] = field(default=None)  # (min, max) of the triangles
    lights: tuple[
        dict, ...
    ] = ()  # a mesh file's punctual lights (study.scene.parts: world space, radiometric)
    summary: str = ""  # one line: what was loaded, ignored and dropped (mesh files and Mitsuba scenes)

    @property
    def lit(self) -> bool:
        """Whether the environment brings light of its own (emitters, emissive parts, punctual lights)."""
        return bool(self.emitters or self.lights or any(p.emission is not None for p in self.parts))

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


def _mesh_file(env) -> EnvGeometry:
    from study.scene import meshfile

    mesh, parts, lights, line, sensor = meshfile.load(env)
    return EnvGeometry(mesh, parts, kind="mesh", lights=tuple(lights), summary=line, sensor=sensor)


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
    n_area = len(sc.emitters()) - len(emitters)
    line = (
        f"loaded {describe_source(env)}: {sum(len(f) for f in F):,} triangles, {len(parts)} shapes, "
        f"{n_area} area light(s), {len(emitters)} other emitter(s)"
        + ("" if sc.emitters() else "; no emitter: the point light [light] lights it")
    )
    mesh = RoomMesh(
        np.concatenate(V).astype(np.float32),
        np.concatenate(F).astype(np.int32),
        np.zeros((n, 2), np.float32),
        np.concatenate(S).astype(np.int32),
        tuple(p.name for p in parts),
    )
    return EnvGeometry(
        mesh,
        tuple(parts),
        emitters=emitters,
        point_light=not sc.emitters(),
        sensor=_sensor(m, sc),
        kind="mitsuba",
        summary=line,
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
def suggest_placement(scene: Scene | Any, given: dict[str, Any] | None = None) -> dict[str, Any]:
    """Where to put things in an environment nobody placed them in (:func:`study.scene.autoplace.suggest`): dotted
    overrides for the placement keys missing from ``given`` (the user's dotted keys → values). ``scene`` is a
    scene or an environment alone (a mesh or Mitsuba source, as :func:`geometry` takes)."""
    from study.scene import autoplace

    return autoplace.suggest(geometry(scene), given)


def describe_source(env) -> str:
    """The source of a mesh or Mitsuba environment in a few words (its file name, builtin or "scene dict")."""
    from pathlib import Path

    if env.type == "mesh" or env.file:
        return Path(env.file).name
    return env.builtin or "scene dict"


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
