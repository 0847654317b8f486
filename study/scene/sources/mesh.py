"""A mesh file as the environment (``type = "mesh"``): the triangles of ``file`` (OBJ and glTF/GLB by study's own
readers, :mod:`study.scene.obj`, :mod:`study.scene.gltf`; PLY, STL, OFF through trimesh), moved by ``scale``,
``rotation`` (degrees about x, y, z) and ``translate``.

Each part keeps its texture, material colour or vertex colours where the file has them, else ``color``; emissive
materials are area lights and glTF punctual lights are lights; lit by ``[light]`` where the file has no light (or
the scene gives ``[light]``); one summary line tells what was read and ignored (:mod:`study.scene.meshfile`).
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any, Literal

from pydantic import Field, ValidationInfo, field_validator

from study.scene.sources.base import EnvGeometry, Source, register_source
from study.scene.sources.keys import resolve

Vec3 = tuple[float, float, float]


@register_source
class MeshEnv(Source):
    type: Literal["mesh"]
    file: str  # OBJ / glTF / GLB by study's readers; PLY / STL / OFF by trimesh
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

    def build(self, scene: Any) -> EnvGeometry:
        import study.scene.meshfile as meshfile

        mesh, parts, lights, line, sensor = meshfile.load(self)
        return EnvGeometry(mesh, parts, kind="mesh", lights=tuple(lights), summary=line, sensor=sensor)

    def describe(self, scene: Any) -> str:
        return f"mesh {Path(self.file).name}"
