"""A Mitsuba 3 scene as the environment (``type = "mitsuba"``): ``file`` (XML), ``builtin = "cornell_box"``
(Mitsuba's own ``mitsuba.cornell_box()``) or, from Python, ``scene`` (a scene dict).

Its meshes, BSDFs and emitters (area lights included) are used as they are, ``[light]`` lights it only where it
has no emitter. The analytic ``sphere``, ``cylinder`` and ``disk`` are tessellated (:data:`TESSELLATION`: a
sphere of 32 × 64 quads, a cylinder's side of 64, a disk of 64 sectors, in the shape's own frame, then its
``to_world``) and the *same* triangles, with the shape's BSDF and area light, replace the shape in Mitsuba's
render, Embree's queries and the methods' captures; the summary line says how many. Other shapes that are not
triangle meshes (curves, SDF grids, instances) are refused, naming the shape by its ``id`` or its place in the
file. Every file the XML (or an XML it includes) names must lie in the scene file's folder
(:func:`study.scene.references.xml_outside`), checked before Mitsuba reads anything. Its first sensor is the
scene's own camera.
"""

from __future__ import annotations

import re
from collections import Counter
from pathlib import Path
from typing import Any, Literal

import numpy as np
from pydantic import AliasChoices, ConfigDict, Field, ValidationInfo, field_validator, model_validator
from pydantic_core import PydanticCustomError

from study.errors import StudyError
from study.scene.parts import Part
from study.scene.room import RoomMesh
from study.scene.sources.base import EnvGeometry, Source, register_source
from study.scene.sources.keys import resolve


@register_source
class MitsubaEnv(Source):
    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False, arbitrary_types_allowed=True)
    type: Literal["mitsuba"]
    file: str | None = None  # a Mitsuba XML scene
    builtin: Literal["cornell_box"] | None = None  # Mitsuba's own test scenes
    scene: dict[str, Any] | None = Field(None, validation_alias=AliasChoices("scene", "dict"))
    #   a scene dict (Python API; also accepted as ``dict``)

    @field_validator("file", mode="before")
    @classmethod
    def _file(cls, v, info: ValidationInfo):
        return resolve(v, info)

    @model_validator(mode="after")
    def _one_source(self):
        given = [k for k in ("file", "builtin", "scene") if getattr(self, k) is not None]
        if len(given) != 1:
            raise PydanticCustomError(
                "source",
                'give exactly one of environment.file (XML), environment.builtin ("cornell_box") '
                "or environment.scene (a dict; got {given})",
                {"given": ", ".join(given) or "none"},
            )
        return self

    def key_extra(self, scene: Any) -> dict:
        from study import runtime

        return {"variant": runtime.current_variant()}

    def label(self) -> str:
        return Path(self.file).name if self.file else self.builtin or "scene dict"

    def describe(self, scene: Any) -> str:
        return f"Mitsuba {self.label()}"

    def build(self, scene: Any) -> EnvGeometry:
        from study import runtime

        m = runtime.mitsuba()
        env = self
        if env.file is not None:
            from study.scene.references import xml_outside

            outside = xml_outside(env.file)
            if outside:
                raise StudyError(outside, key="environment.file")
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
        tessellated: Counter = Counter()
        for i, s in enumerate(sc.shapes()):
            kind = str(s).split("[")[0].strip()
            named = bool(s.id()) and not _AUTO_ID.fullmatch(s.id())
            name = s.id() if named else f"{kind.lower()}{i}"
            if not s.is_mesh():
                if kind.lower() not in TESSELLATION:
                    where = f"shape {s.id()!r}" if named else _position(env.file, kind.lower())
                    raise StudyError(
                        f"{where} ({kind}) is not a triangle mesh and study tessellates only "
                        f"{', '.join(TESSELLATION)}: Embree needs the same triangles Mitsuba renders; replace it by "
                        "a mesh (obj, ply or a Mitsuba cube/rectangle)",
                        key="environment",
                    )
                s = _tessellated(m, s, kind.lower(), name)
                tessellated[kind.lower()] += 1
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
            f"loaded {env.label()}: {sum(len(f) for f in F):,} triangles, {len(parts)} shapes, "
            f"{n_area} area light(s), {len(emitters)} other emitter(s)"
            + ("" if sc.emitters() else "; no emitter: the point light [light] lights it")
            + (
                "; tessellated: "
                + ", ".join(
                    f"{k} {TESSELLATION[k][0]}" + (f" ×{c}" if c > 1 else "")
                    for k, c in sorted(tessellated.items())
                )  # fmt: skip
                if tessellated
                else ""
            )
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


#: analytic shapes → (how they are told, their triangles in the shape's own frame): Mitsuba's sphere is the unit
#: sphere, its cylinder the unit-radius side along z ∈ [0, 1] (open ends), its disk the unit disk in z = 0 facing
#: +z; each shape's ``to_world`` (centre, radius, p0/p1 folded in) places them.
TESSELLATION = {
    "sphere": ("32 × 64 quads", lambda: _sphere(32, 64)),
    "cylinder": ("64 sides", lambda: _cylinder(64)),
    "disk": ("64 sectors", lambda: _disk(64)),
}
_AUTO_ID = re.compile(r"_?unnamed_\d+|shape_?\d+|")


def _ordinal(k: int) -> str:
    return f"{k}{'th' if 10 <= k % 100 <= 20 else {1: 'st', 2: 'nd', 3: 'rd'}.get(k % 10, 'th')}"


def _position(file: str | None, kind: str) -> str:
    """Where an unnamed shape of ``kind`` stands in the scene file ("the 3rd <shape> of s.xml"): Mitsuba lists its
    shapes in an order of its own, so the file is read for it."""
    import xml.etree.ElementTree as ET

    if file is None:
        return f"an unnamed {kind} shape"
    try:
        shapes = list(ET.parse(file).getroot().iter("shape"))
    except (ET.ParseError, OSError):
        return f"an unnamed {kind} shape"
    at = [k for k, el in enumerate(shapes, 1) if el.get("type") == kind and not el.get("id")]
    return (
        f"the {_ordinal(at[0])} <shape> of {Path(file).name}"
        if at
        else f"an unnamed {kind} shape (in an include)"
    )


def _sphere(n_theta: int, n_phi: int) -> tuple[np.ndarray, np.ndarray]:
    """A UV sphere of radius 1 (poles on ±z), faces wound counter-clockwise seen from outside."""
    th = np.linspace(0, np.pi, n_theta + 1)
    ph = np.linspace(0, 2 * np.pi, n_phi + 1)[:-1]
    T, P = np.meshgrid(th, ph, indexing="ij")
    V = np.stack([np.sin(T) * np.cos(P), np.sin(T) * np.sin(P), np.cos(T)], -1).reshape(-1, 3)
    i, j = np.meshgrid(np.arange(n_theta), np.arange(n_phi), indexing="ij")
    a, b = i * n_phi + j, i * n_phi + (j + 1) % n_phi
    c, d = a + n_phi, b + n_phi
    F = np.concatenate([np.stack([a, c, b], -1).reshape(-1, 3), np.stack([b, c, d], -1).reshape(-1, 3)])
    return V, F


def _cylinder(n: int) -> tuple[np.ndarray, np.ndarray]:
    """The side of a cylinder of radius 1 along z ∈ [0, 1], open ends, facing outward (as Mitsuba's)."""
    ph = np.linspace(0, 2 * np.pi, n + 1)[:-1]
    ring = np.stack([np.cos(ph), np.sin(ph)], -1)
    V = np.concatenate([np.c_[ring, np.zeros(n)], np.c_[ring, np.ones(n)]])
    j = np.arange(n)
    k = (j + 1) % n
    F = np.concatenate([np.stack([j, k, k + n], -1), np.stack([j, k + n, j + n], -1)])
    return V, F


def _disk(n: int) -> tuple[np.ndarray, np.ndarray]:
    """The unit disk in z = 0 facing +z, as a fan of ``n`` sectors around its centre."""
    ph = np.linspace(0, 2 * np.pi, n + 1)[:-1]
    V = np.concatenate([[[0.0, 0.0, 0.0]], np.stack([np.cos(ph), np.sin(ph), np.zeros(n)], -1)])
    j = np.arange(n)
    F = np.stack([np.zeros(n, int), 1 + j, 1 + (j + 1) % n], -1)
    return V, F


def _tessellated(m, shape, kind: str, name: str):
    """A Mitsuba mesh of ``shape``'s tessellation, with its BSDF and (a copy of) its area light."""
    V, F = TESSELLATION[kind][1]()
    T = np.array(m.traverse(shape)["to_world"].matrix, float).reshape(4, 4)
    Vw = V @ T[:3, :3].T + T[:3, 3]
    props = m.Properties()
    props["bsdf"] = shape.bsdf()
    if shape.emitter() is not None:
        p = m.traverse(shape.emitter())
        if "radiance.value" not in p:
            raise StudyError(f"{name} ({kind}) emits a textured radiance, which study does not carry over to its "
                             "tessellation; give it a constant radiance", key="environment")  # fmt: skip
        val = np.ravel(np.array(p["radiance.value"], float))
        rad = (
            {"type": "rgb", "value": val.tolist()}
            if len(val) == 3
            else {"type": "uniform", "value": float(val[0])}
        )
        props["emitter"] = m.load_dict({"type": "area", "radiance": rad})
    if shape.has_flipped_normals():
        props["flip_normals"] = True
    mesh = m.Mesh(f"{name} (tessellated {kind})", len(Vw), len(F), props=props)
    params = m.traverse(mesh)
    params["vertex_positions"] = m.Float(Vw.astype(np.float32).ravel())
    params["faces"] = m.UInt32(F.astype(np.uint32).ravel())
    params.update()
    return mesh
