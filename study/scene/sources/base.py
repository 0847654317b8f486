"""The contract every environment source fulfils, the registry of sources by name, and :class:`EnvGeometry`,
what a source builds: triangles with surface ids, each surface's material, the emitters, and the bounds.

A source is a pydantic model (one ``[environment]`` table of a scene) deriving from :class:`Source`, with a field
``type: Literal["<name>"]`` and its own keys, decorated with :func:`register_source`. It answers four questions:

=========================  ===================================================================================
``build(scene)``           the environment as an :class:`EnvGeometry` (``scene``: the whole scene, for sources
                           that read other tables — the box reads ``[room]`` and ``[[columns]]``)
``key_extra(scene)``       what else :meth:`build` depends on beyond the source's own keys (content keys; files
                           called ``file`` are hashed by their bytes already, :func:`.keys.key_fields`)
``label()``                the source in a few words (its file name, builtin, …) for log lines
``describe(scene)``        a short name for figure titles
=========================  ===================================================================================

and one class attribute, :attr:`Source.placed`: whether automatic placement (:mod:`study.scene.autoplace`) fills
in the placement keys a scene leaves out (true for any environment nobody placed things in; false for the box,
whose defaults are the paper's placement).

Every source is built through :func:`checked_build`, which holds what ``build`` returns to the contract (an
:class:`EnvGeometry` of finite vertices, at least one triangle, vertex indices and surface ids in range) and turns
a plug-in's failures (an exception, ``sys.exit``) into one StudyError line naming it, as
:meth:`study.methods.Method._guarded` does for methods; a plug-in's code is part of its content keys
(:func:`.keys.key_fields`).
"""

from __future__ import annotations

import typing
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
from pydantic import BaseModel, ConfigDict, ValidationInfo, field_validator
from pydantic_core import PydanticCustomError

from study.errors import StudyError, plugin_guard
from study.scene.parts import Part
from study.scene.room import RoomMesh
from study.scene.sky import validate_sky
from study.validation import KeyedError


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
        if self.bounds is None:  # left None where there are no vertices: :func:`checked_build` says so
            v = np.asarray(getattr(self.mesh, "vertices", ()), float)
            if v.ndim == 2 and len(v):
                object.__setattr__(self, "bounds", (v.min(0), v.max(0)))


class Source(BaseModel):
    """One ``[environment]`` table: the base of every environment source (the contract: module docstring)."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)
    type: str
    placed: ClassVar[bool] = True  # automatic placement fills the placement keys a scene leaves out
    sky: str | tuple[float, float, float] | None = None  # what escaping rays see (study.scene.sky)

    @field_validator("sky", mode="before")
    @classmethod
    def _sky(cls, v, info: ValidationInfo):
        return validate_sky(v, info)

    def build(self, scene: Any) -> EnvGeometry:
        raise NotImplementedError

    def key_extra(self, scene: Any) -> dict:
        return {}

    def label(self) -> str:
        file = getattr(self, "file", None)
        return Path(file).name if file else self.type

    def describe(self, scene: Any) -> str:
        return f"{self.type} {self.label()}"


#: Source name (its ``type``) → its model class, filled by :func:`register_source`.
SOURCES: dict[str, type[Source]] = {}


def register_source(cls: type[Source]) -> type[Source]:
    """Class decorator: add an environment source under the name its ``type: Literal["name"]`` field gives."""
    args = typing.get_args(cls.model_fields["type"].annotation) if "type" in cls.model_fields else ()
    if not (isinstance(cls, type) and issubclass(cls, Source)) or len(args) != 1:
        raise StudyError(
            f"{getattr(cls, '__name__', cls)!r} is not an environment source: derive from "
            'study.scene.sources.Source with one field type: Literal["name"]',
            key="environment.type",
        )
    name = args[0]
    if name in SOURCES and SOURCES[name] is not cls:
        raise StudyError(f"environment type {name!r} is taken (by {SOURCES[name].__module__})", key=name)
    SOURCES[name] = cls
    return cls


def _keys(cls: type[Source]) -> list[str]:
    """The keys a source's table may hold: its fields and their alternative names."""
    out = []
    for name, f in cls.model_fields.items():
        out.append(name)
        out += [a for a in getattr(f.validation_alias, "choices", ()) if isinstance(a, str) and a != name]
    return out


def validate_source(v: Any, info: ValidationInfo) -> Source:
    """An ``[environment]`` table → the model of the source its ``type`` names (a registered one); unknown types
    and keys are errors naming the allowed values."""
    if isinstance(v, Source):
        return v
    if not isinstance(v, dict):
        raise PydanticCustomError("source", "expected a table with a type ({allowed})", {"allowed": _names()})
    kind = v.get("type")
    if kind not in SOURCES:
        raise KeyedError(
            "environment.type",
            ("missing" if kind is None else f"unknown environment type {kind!r}") + f"; allowed: {_names()}",
        )
    cls = SOURCES[kind]
    extra = [k for k in v if k not in _keys(cls)]
    if extra:
        raise KeyedError(f"environment.{extra[0]}", f"unknown key; allowed: {', '.join(_keys(cls))}")
    return cls.model_validate(v, context=info.context)


def _names() -> str:
    return ", ".join(sorted(SOURCES))


# ---------------------------------------------------------------------------------------------- plug-ins
def is_source_plugin(cls: type) -> bool:
    """Whether a source class comes from outside study's own package (a plug-in)."""
    return not cls.__module__.startswith("study.scene.sources.")


def _who(source: Source) -> str:
    cls = type(source)
    return f"environment {source.type!r} (" + (
        f"plug-in {cls.__module__})" if is_source_plugin(cls) else f"{source.label()})"
    )


def source_call(source: Source, what: str, call):
    """``call()`` (the source's ``what``, e.g. ``"build()"``), with a plug-in's failures and any ``sys.exit`` turned
    into one StudyError line naming the source (bad input, exit 2); a failure of study's own sources stays what it
    is (a bug, exit 4)."""
    who = _who(source)
    return plugin_guard(
        call,
        plugin=is_source_plugin(type(source)),
        exited=lambda code: f"{who}: {what} called sys.exit({code!r})",
        failed=f"{who}: {what} failed",
    )


def checked_build(source: Source, scene: Any) -> EnvGeometry:
    """``source.build(scene)`` (:func:`source_call`), and what it built held to the contract (:func:`geometry_problem`):
    anything else is one StudyError line naming the source and the first wrong element (exit 2)."""
    geo = source_call(source, "build()", lambda: source.build(scene))
    problem = geometry_problem(geo)
    if problem:
        raise StudyError(f"{_who(source)}: {problem}")
    return geo


def geometry_problem(geo: Any) -> str | None:
    """What is wrong with a source's :class:`EnvGeometry` (the first thing found), or None: the arrays of its mesh
    and their shapes, finite vertices and uv, at least one triangle, every vertex index and surface id in range,
    every part a :class:`~study.scene.parts.Part`, finite colours (vertices', parts', textures'), emissions and
    bounds. The message names the element: a vertex, a triangle, a part."""
    if not isinstance(geo, EnvGeometry):
        return f"build() returned {_what(geo)}, not an EnvGeometry"
    m = geo.mesh
    if not isinstance(m, RoomMesh):
        return f"built mesh = {_what(m)}, not a study.scene.room.RoomMesh"
    for name, a, kind, cols in (
        ("vertices", m.vertices, "f", 3),
        ("faces", m.faces, "i", 3),
        ("uv", m.uv, "f", 2),
        ("surface ids", m.surface, "i", None),
    ):
        if not isinstance(a, np.ndarray):
            return f"{name} are {_what(a)}, not a numpy array"
        want = "(V, 3)" if name == "vertices" else "(F, 3)" if name == "faces" else "(V, 2)"
        if cols is not None and (a.ndim != 2 or a.shape[1] != cols):
            return f"{name} have shape {a.shape}, not {want}"
        if kind == "i" and a.dtype.kind not in "iu" or kind == "f" and a.dtype.kind not in "fiu":
            return f"{name} are {a.dtype}, not {'integers' if kind == 'i' else 'numbers'}"
    V, F, S = m.vertices, m.faces, m.surface
    if len(F) == 0 or len(V) == 0:
        return "built no triangles"
    if S.shape != (len(F),):
        return f"surface ids for {S.size} triangles; the mesh has {len(F)}"
    if len(m.uv) != len(V):
        return f"uv for {len(m.uv)} vertices; the mesh has {len(V)}"
    for name, a in (("vertex", V), ("uv", m.uv)):
        bad = np.flatnonzero(~np.isfinite(a).all(axis=1))
        if bad.size:
            return f"{name} {bad[0]} is not finite ({', '.join(f'{x:g}' for x in a[bad[0]])})"
    bad = np.flatnonzero(((F < 0) | (F >= len(V))).any(axis=1))
    if bad.size:
        i = bad[0]
        v = next(int(x) for x in F[i] if not 0 <= x < len(V))
        return f"triangle {i} has vertex index {v}; the mesh has {len(V)} vertices"
    bad = np.flatnonzero((S < 0) | (S >= len(geo.parts)))
    if bad.size:
        return f"triangle {bad[0]} has surface id {S[bad[0]]}; there are {len(geo.parts)} parts"
    wrong = next((i for i, p in enumerate(geo.parts) if not isinstance(p, Part)), None)
    if wrong is not None:
        return f"part {wrong} is {_what(geo.parts[wrong])}, not a study.scene.parts.Part"
    if m.colors is not None:
        if not isinstance(m.colors, np.ndarray) or m.colors.shape != V.shape:
            return (
                f"vertex colours are {_what(m.colors)} of shape {np.shape(m.colors)}, not one RGB per vertex"
            )
        bad = np.flatnonzero(~np.isfinite(m.colors).all(axis=1))
        if bad.size:
            v = int(bad[0])
            used = np.flatnonzero((F == v).any(axis=1))
            part = f" (part {geo.parts[S[used[0]]].name!r})" if used.size else ""
            return f"the colour of vertex {v}{part} is not finite ({_rgb(m.colors[v])})"
    for i, p in enumerate(geo.parts):
        for what, value in (("colour", p.color), ("emission", p.emission)):
            if value is not None and not np.isfinite(np.asarray(value, float)).all():
                return f"part {i} ({p.name!r}): its {what} is not finite ({_rgb(value)})"
        if p.albedo is not None and not np.isfinite(np.asarray(p.albedo, float)).all():
            r, c = np.argwhere(~np.isfinite(np.asarray(p.albedo, float)).all(axis=-1))[0][:2]
            return f"part {i} ({p.name!r}): its texture is not finite (first at row {r}, column {c})"
    if geo.bounds is None or not all(np.isfinite(np.asarray(b, float)).all() for b in geo.bounds):
        return f"bounds {geo.bounds} are not finite"
    return None


def _rgb(v: Any) -> str:
    return ", ".join(f"{float(x):g}" for x in np.ravel(v))


def _what(v: Any) -> str:
    return "None" if v is None else f"a {type(v).__name__}"
