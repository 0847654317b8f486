"""The box room (``type = "box"``, the default and the paper's scenes): the axis-aligned ``[room]`` with its
``[[columns]]``, procedurally textured, lit by ``[light]``."""

from __future__ import annotations

from typing import Any, ClassVar, Literal

import numpy as np

from study.scene.parts import Part
from study.scene.room import SURFACES, room_mesh, texture
from study.scene.sources.base import EnvGeometry, Source, register_source


@register_source
class BoxEnv(Source):
    type: Literal["box"] = "box"
    placed: ClassVar[bool] = False  # the scene's defaults are the paper's placement

    def build(self, scene: Any) -> EnvGeometry:
        return EnvGeometry(
            room_mesh(scene),
            tuple(Part(n, albedo=texture(n)) for n in SURFACES),
            bounds=(np.array(scene.room.min, float), np.array(scene.room.max, float)),
        )

    def key_extra(self, scene: Any) -> dict:
        return {"room": scene.room.model_dump(), "columns": [c.model_dump() for c in scene.columns]}

    def label(self) -> str:
        return "box room"

    def describe(self, scene: Any) -> str:
        fmt = lambda v: "(" + ", ".join(f"{x:g}" for x in v) + ")"  # noqa: E731
        return f"{fmt(scene.room.min)}..{fmt(scene.room.max)} room" + (
            f", {len(scene.columns)} column(s)" if scene.columns else ""
        )
