"""A Mitsuba 3 scene as the environment (``type = "mitsuba"``): ``file`` (XML), ``builtin = "cornell_box"``
(Mitsuba's own ``mitsuba.cornell_box()``) or, from Python, ``scene`` (a scene dict).

Its meshes, BSDFs and emitters (area lights included) are used as they are, ``[light]`` lights it only where it
has no emitter; shapes that are not triangle meshes (an analytic ``sphere``, ``disk``, …) are refused, naming the
shape. Its first sensor is the scene's own camera.
"""

from __future__ import annotations

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
            f"loaded {env.label()}: {sum(len(f) for f in F):,} triangles, {len(parts)} shapes, "
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
