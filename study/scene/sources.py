"""Where the environment comes from: the built-in box room, a mesh file, or a Mitsuba scene (the ``[environment]``
table of a scene).

=================  ============================================================================================
``type``           the environment is …
=================  ============================================================================================
``"box"``          the axis-aligned ``[room]`` with its ``[[columns]]``, procedurally textured, lit by ``[light]``
                   (the default: the paper's scenes)
``"mesh"``         the triangles of ``file`` (OBJ and glTF/GLB by study's own readers, :mod:`study.scene.obj`,
                   :mod:`study.scene.gltf`; PLY, STL, OFF through trimesh), moved by ``scale``, ``rotation``
                   (degrees about x, y, z) and ``translate``; each part keeps its texture, material colour or
                   vertex colours where the file has them, else ``color``; emissive materials are area lights
                   and glTF punctual lights are lights; lit by ``[light]`` where the file has no light (or
                   the scene gives ``[light]``); one summary line tells what was read and ignored
``"mitsuba"``      a Mitsuba 3 scene: ``file`` (XML), ``builtin = "cornell_box"`` (Mitsuba's own
                   ``mitsuba.cornell_box()``) or, from Python, ``scene`` (a scene dict); its meshes, BSDFs and
                   emitters (area lights included) are used as they are, ``[light]`` is ignored; shapes that are
                   not triangle meshes (an analytic ``sphere``, ``disk``, …) are refused, naming the shape
=================  ============================================================================================

A relative ``file`` is resolved against the directory of the scene file that names it (the validation context's
``"base"``; the working directory otherwise) and stored absolute. Cache keys hash the file's bytes, not its path,
and the bytes of every file it references (:func:`key_fields`, :mod:`study.scene.references`).
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path
from typing import Annotated, Any, Literal

from pydantic import (
    AliasChoices,
    BaseModel,
    ConfigDict,
    Field,
    ValidationInfo,
    field_validator,
    model_validator,
)
from pydantic_core import PydanticCustomError

Vec3 = tuple[float, float, float]


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)


def resolve(v: Any, info: ValidationInfo) -> Any:
    """A ``file`` field: absolute, resolved against the scene file's directory; it must exist."""
    if v is None or not isinstance(v, (str, Path)):
        return v
    p = Path(v).expanduser()
    if not p.is_absolute():
        base = (info.context or {}).get("base") if info.context else None
        p = Path(base or ".") / p
    p = p.resolve()
    if not p.is_file():
        raise PydanticCustomError("file", "no such file: {path}", {"path": str(p)})
    return str(p)


class BoxEnv(_Strict):
    type: Literal["box"] = "box"


class MeshEnv(_Strict):
    type: Literal["mesh"]
    file: str  # OBJ / PLY / GLB / STL / OFF, read by trimesh
    scale: Annotated[float, Field(gt=0)] = 1.0  # applied first
    rotation: Vec3 = (0.0, 0.0, 0.0)  # then Euler angles x, y, z in degrees
    translate: Vec3 = (0.0, 0.0, 0.0)  # then moved
    color: tuple[Annotated[float, Field(ge=0, le=1)], ...] = Field(
        (0.6, 0.6, 0.6), min_length=3, max_length=3
    )
    #   linear RGB albedo of parts without a texture or colour of their own

    @field_validator("file", mode="before")
    @classmethod
    def _file(cls, v, info: ValidationInfo):
        return resolve(v, info)


class MitsubaEnv(_Strict):
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


Environment = Annotated[BoxEnv | MeshEnv | MitsubaEnv, Field(discriminator="type")]


# ---------------------------------------------------------------------------------------------- content keys
def file_digest(path: str) -> str:
    """sha256 of a file's bytes and of every file it references (:func:`study.scene.references.referenced`: an
    OBJ's materials and textures, a glTF's buffers and images, a Mitsuba XML's includes, meshes, textures and
    envmaps): a change to any of them changes the key. A referenced file that is missing counts by its name."""
    from study.scene.references import referenced

    p = Path(path)
    h = hashlib.sha256(p.read_bytes())
    for ref in referenced(p):
        h.update(b"\0" + str(ref.name).encode() + b"\0")
        h.update(ref.read_bytes() if ref.is_file() else b"<missing>")
    return "sha256:" + h.hexdigest()


def _canon(v: Any) -> Any:
    """A JSON-able stand-in for any value of a scene: files by content, Mitsuba objects by their repr."""
    if isinstance(v, dict):
        return {str(k): _canon(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [_canon(x) for x in v]
    if isinstance(v, (str, int, float, bool)) or v is None:
        return v
    return repr(v)


#: Camera keys that only set others (``target``, ``fov``) on validation: content keys leave them out, so a framed
#: camera and the same camera given by hand share their results, and older keys stay valid.
FRAMING_KEYS = ("frame_object", "frame_fill")
#: Object keys added later, left out of content keys at their default (the object's GGX ``alpha`` = 0: a mirror),
#: so that every result made before they existed keeps its key.
LATER_DEFAULTS = {"alpha": 0.0}


def key_fields(model: BaseModel | dict) -> dict:
    """``model_dump`` of a scene (or part of one) for content keys: every field called ``file`` (or ``filename``,
    in a Mitsuba scene dict) replaced by the digest of the file's bytes (and of the files it references), Python
    objects (Mitsuba transforms in a scene dict) by their repr; the framing keys (:data:`FRAMING_KEYS`) left
    out, and the object's later keys at their defaults (:data:`LATER_DEFAULTS`)."""
    data = model.model_dump(mode="python") if isinstance(model, BaseModel) else model

    def walk(v):
        if isinstance(v, dict):
            return {
                k: (
                    file_digest(x)
                    if k in ("file", "filename") and isinstance(x, str) and Path(x).is_file()
                    else walk(x)
                )
                for k, x in v.items()
                if k not in FRAMING_KEYS and not ("material" in v and LATER_DEFAULTS.get(k, ()) == x)
            }
        if isinstance(v, (list, tuple)):
            return [walk(x) for x in v]
        return v

    return json.loads(json.dumps(_canon(walk(data)), sort_keys=True))
