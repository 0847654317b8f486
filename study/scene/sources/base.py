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
"""

from __future__ import annotations

import typing
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
from pydantic import BaseModel, ConfigDict, ValidationInfo
from pydantic_core import PydanticCustomError

from study.errors import StudyError
from study.scene.parts import Part
from study.scene.room import RoomMesh
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
        if self.bounds is None:
            v = self.mesh.vertices.astype(float)
            object.__setattr__(self, "bounds", (v.min(0), v.max(0)))


class Source(BaseModel):
    """One ``[environment]`` table: the base of every environment source (the contract: module docstring)."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)
    type: str
    placed: ClassVar[bool] = True  # automatic placement fills the placement keys a scene leaves out

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
