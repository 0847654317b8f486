"""The scene's tables as pydantic models — room, columns, light, reference point, materials, object, camera,
render settings — and the strict number types they share; :mod:`study.scene.schema` assembles them into the
:class:`~study.scene.schema.Scene` (its docstring documents every key)."""

from __future__ import annotations

import math
from typing import Annotated, Literal

import numpy as np
from pydantic import (
    BaseModel,
    BeforeValidator,
    ConfigDict,
    Field,
    StrictBool,
    field_validator,
    model_validator,
)
from pydantic_core import PydanticCustomError

from study.scene.paths import resolve
from study.validation import KeyedError


def _number(kind: str):
    """A before-validator: booleans and strings are not numbers (pydantic would read true as 1, "2" as 2)."""

    def check(v):
        if isinstance(v, (bool, np.bool_, str, bytes)):
            what = "a boolean" if isinstance(v, (bool, np.bool_)) else "a string"
            raise PydanticCustomError(f"{kind}_type", f"Input should be a valid {kind}, not {what}")
        return v

    return BeforeValidator(check)


Float = Annotated[float, _number("number")]
Int = Annotated[int, _number("integer")]


def _not_a_set(v):
    if isinstance(v, set | frozenset):
        raise ValueError("a point is a list [x, y, z]; a set has no order")
    return v


Vec3 = Annotated[tuple[Float, Float, Float], BeforeValidator(_not_a_set)]
Vec2 = tuple[Float, Float]
PosFloat = Annotated[Float, Field(gt=0, allow_inf_nan=False)]
MAX_SEED = 2**31 - 1  # Mitsuba's seeds are 32-bit; study adds offsets (second seeds, ray chunks)
MAX_SAMPLES = 2**31 - 1  # per pixel or texel (Mitsuba's sample counts are 32-bit)


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)


class Room(_Strict):
    min: Vec3 = (-2.0, 0.0, -2.0)
    max: Vec3 = (2.0, 3.0, 2.0)

    @model_validator(mode="after")
    def _ordered(self):
        if any(a >= b for a, b in zip(self.min, self.max)):
            raise ValueError("room.max must exceed room.min on every axis")
        return self


class Column(_Strict):
    center: Vec2
    footprint: tuple[PosFloat, PosFloat]
    height: PosFloat

    def box(self, room: Room) -> tuple[np.ndarray, np.ndarray]:
        """The column as an axis-aligned box (lo, hi) standing on the room's floor."""
        (cx, cz), (sx, sz) = self.center, self.footprint
        lo = np.array([cx - sx / 2, room.min[1], cz - sz / 2])
        hi = np.array([cx + sx / 2, room.min[1] + self.height, cz + sz / 2])
        return lo, hi


class Light(_Strict):
    position: Vec3 = (0.0, 2.6, 0.0)
    intensity: tuple[PosFloat, PosFloat, PosFloat] = (6.0, 6.0, 6.0)
    enabled: bool = (
        True  # the point light is rendered (automatic placement turns it off where the file has light)
    )


class Reference(_Strict):
    point: Vec3 = (0.0, 1.5, 0.0)
    box: tuple[Vec3, Vec3] | None = None  # the proxy box of proxy methods (min, max); default: the bounds

    @model_validator(mode="after")
    def _box(self):
        if self.box is not None and any(a >= b for a, b in zip(*self.box)):
            raise ValueError("reference.box: the second corner must exceed the first on every axis")
        return self


class Mirror(_Strict):
    type: Literal["mirror"]


class Conductor(_Strict):
    type: Literal["conductor"]
    n: tuple[PosFloat, PosFloat, PosFloat]  # real part of the refraction index per RGB channel
    k: tuple[Annotated[Float, Field(ge=0)], ...] = Field(min_length=3, max_length=3)  # extinction coefficient


class Dielectric(_Strict):
    type: Literal["dielectric"]
    ior: Annotated[Float, Field(gt=1, le=4, allow_inf_nan=False)] = (
        1.5  # index of refraction inside (outside: 1)
    )


Material = Annotated[Mirror | Conductor | Dielectric, Field(discriminator="type")]


#: mesh file formats an object may be read from (through trimesh)
MESH_SUFFIXES = (".obj", ".ply", ".glb", ".gltf", ".stl", ".off")


class Sphere(_Strict):
    """The shaded object. ``shape`` "sphere" is analytic; "torus", "knot" and "blob" are triangle meshes with
    smooth vertex normals (:mod:`study.scene.objects`), scaled so that ``radius`` is their bounding-sphere radius,
    turned by ``rotation`` (Euler angles in degrees about x, then y, then z) and tessellated finer with ``detail``.
    ``shape = "mesh"`` reads the triangles from ``file`` (OBJ, PLY, GLB/glTF, STL, OFF through trimesh; relative to
    the scene file; ``shape`` may be left out when ``file`` is given), centred on its bounding box and scaled
    in the same way; ``detail`` does not apply to it. Cache keys hash the file's bytes, not its path. ``alpha``
    (0 ≤ α ≤ 1) is the GGX roughness of its surface: 0 is today's smooth material, α > 0 makes Mitsuba render
    ``roughconductor`` (``roughdielectric`` for glass) with that α and ``distribution = "ggx"``, and the glossy
    methods (:mod:`study.methods.glossy`) integrate the lobe."""

    shape: Literal["mesh", "sphere", "torus", "knot", "blob"] = "sphere"
    center: Vec3 = (0.5, 1.2, 0.3)
    radius: PosFloat = 0.4  # sphere radius, or bounding-sphere radius of a mesh
    material: Material = Mirror(type="mirror")
    alpha: Annotated[Float, Field(ge=0, le=1)] = 0.0  # GGX roughness α (isotropic); 0 = a perfect mirror
    rotation: Vec3 = (0.0, 0.0, 0.0)  # meshes: Euler angles x, y, z in degrees
    detail: Annotated[Int, Field(ge=1, le=6)] = 3  # meshes: tessellation level
    file: str | None = None  # shape "mesh": the mesh file (stored as an absolute path)

    @model_validator(mode="before")
    @classmethod
    def _mesh_by_file(cls, data):  # a file alone means shape "mesh"
        implied = isinstance(data, dict) and data.get("file") and "shape" not in data
        return {**data, "shape": "mesh"} if implied else data

    @field_validator("file", mode="before")
    @classmethod
    def _file(cls, v, info):
        return resolve(v, info)

    @model_validator(mode="after")
    def _file_for_mesh(self):
        known = (self.file or ".obj").lower().endswith(MESH_SUFFIXES)
        if (self.shape == "mesh") != (self.file is not None) or not known:
            raise KeyedError(
                "object.file",
                f'a mesh file ({", ".join(MESH_SUFFIXES)}) for shape "mesh", and only '
                f"for it (shape {self.shape!r}, file {self.file!r})",
            )
        return self


Object = Sphere


class Camera(_Strict):
    """A pinhole camera. ``frame_object = true`` frames the object from where the camera stands: ``target``
    becomes the object's centre and ``fov`` the angle at which the object's bounding sphere spans ``frame_fill``
    of the frame's smaller side (both set on validation, so they follow the object when a sweep moves it; what
    the config gives for them is replaced). The eye stays, so the rays the object sends out are the same rays,
    sampled densely: the object's pixels grow as (frame_fill · side)² · π/4 whatever its distance."""

    eye: Vec3 = (0.0, 1.5, -1.9)
    target: Vec3 = (0.6, 1.0, 0.5)
    up: Vec3 = (0.0, 1.0, 0.0)
    fov: Annotated[Float, Field(gt=0, lt=180)] = 70.0
    width: Annotated[Int, Field(ge=8, le=4096)] = 256
    height: Annotated[Int, Field(ge=8, le=4096)] = 256
    frame_object: StrictBool = False  # aim at the object and zoom until it spans frame_fill of the frame
    frame_fill: Annotated[Float, Field(gt=0, le=1)] = 0.8  # share of the frame's smaller side, frame_object

    def framed(self, center, radius: float) -> Camera:
        """This camera aimed at a bounding sphere (``center``, ``radius``) with the field of view at which the
        sphere's image (a disc of radius tan α, sin α = radius / distance, on the unit image plane) spans
        ``frame_fill`` of the frame's smaller side; itself without ``frame_object``."""
        if not self.frame_object:
            return self
        d = float(np.linalg.norm(np.subtract(center, self.eye)))
        if d <= radius:
            raise KeyedError(
                "camera.eye", "lies inside the object's bounding sphere: frame_object cannot frame it"
            )
        tan_half = radius / math.sqrt(d * d - radius * radius)
        tan_x = tan_half / (self.frame_fill * min(1.0, self.height / self.width))
        fov = math.degrees(2 * math.atan(tan_x))
        if fov >= 180:
            raise KeyedError("camera.frame_fill", f"the object is too close to frame (fov {fov:.0f}°)")
        return self.model_copy(update={"target": tuple(float(v) for v in center), "fov": fov})


class Render(_Strict):
    cube_res: Annotated[Int, Field(ge=4, le=4096)] = 256
    cube_spp: Annotated[Int, Field(ge=1, le=MAX_SAMPLES)] = 64
    spp: Annotated[Int, Field(ge=1, le=MAX_SAMPLES)] = 64
    max_depth: Annotated[Int, Field(ge=2, le=64)] = 4
    supersample: Annotated[Int, Field(ge=1, le=8)] = 2
    seed: Annotated[Int, Field(ge=0, le=MAX_SEED)] = 0
    fresnel: Literal["exact", "approx"] = "exact"  # object shading: exact conductor Fresnel or the paper's
    refraction: Literal["single", "double"] = (
        "double"  # dielectric objects: paper's single refraction or in-and-out
    )
    exit: Literal["auto", "exact", "distance_map"] = "auto"  # double refraction: how the far side is found
    internal_bounces: Annotated[Int, Field(ge=0, le=16)] = (
        8  # total internal reflections followed, then dropped
    )
    object_res: Annotated[Int, Field(ge=4, le=2048)] = 128  # face resolution of the object's own distance map
    probe_spp: Annotated[Int, Field(ge=1, le=MAX_SAMPLES)] | None = (
        None  # probes' samples per texel (cube_spp)
    )
    flip_against: tuple[Literal["oracle", "truth", "mitsuba"], ...] = (
        "oracle",
        "truth",
    )  # FLIP refs (add "mitsuba" for FLIP against Mitsuba's camera render)
