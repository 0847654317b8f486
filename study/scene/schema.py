"""The one scene description that feeds Mitsuba, Embree and the methods.

A scene is a TOML file (or dict) validated on load; y is up, units are metres. Example::

    [room]
    min = [-2.0, 0.0, -2.0]              # box room, inner faces textured and diffuse
    max = [2.0, 3.0, 2.0]

    [[columns]]                          # optional boxes standing on the floor
    center = [1.0, -1.0]                 # (x, z) of the footprint centre
    footprint = [0.4, 0.4]               # extent along x and z
    height = 1.2

    [light]                              # point light, radiant intensity per RGB channel (W/sr)
    position = [0.0, 2.6, 0.0]
    intensity = [6.0, 6.0, 6.0]

    [reference]
    point = [0.0, 1.5, 0.0]              # where the distance impostor is taken

    [object]
    shape = "sphere"
    center = [0.5, 1.2, 0.3]
    radius = 0.4
    material = { type = "conductor", n = [0.155, 0.117, 0.138], k = [4.83, 3.12, 2.15] }

    [camera]
    eye = [0.0, 1.5, -1.9]
    target = [0.6, 1.0, 0.5]
    up = [0.0, 1.0, 0.0]
    fov = 70.0                           # horizontal, degrees
    width = 256
    height = 256
    frame_object = false                 # true: target = the object's centre, fov such that its bounding
    frame_fill = 0.8                     # sphere spans this share of the frame (follows the object; eye kept)

    [render]
    cube_res = 256                       # impostor face resolution
    cube_spp = 64                        # Mitsuba samples per texel for the impostor radiance
    spp = 64                             # Mitsuba samples per pixel for the ground truth
    max_depth = 4                        # path length of Mitsuba's path tracer
    supersample = 2                      # method rays per pixel side
    seed = 0
    fresnel = "exact"                    # "exact" conductor Fresnel (as Mitsuba) or the paper's "approx"
    refraction = "double"                # dielectric objects: "single" (paper) or "double" (in and out)
    exit = "auto"                        # far side: "exact" (analytic sphere / Embree), "distance_map" (the
                                         # object's own map); "auto" = exact for a sphere, distance map for meshes
    internal_bounces = 8                 # total internal reflections followed before a ray is dropped (counted)
    object_res = 128                     # face resolution of the object's own distance map

The environment is the box ``[room]`` with its ``[[columns]]`` unless ``[environment]`` names another source
(:mod:`study.scene.sources`): ``type = "mesh"`` with ``file = "rooms/l_room.ply"`` (any format trimesh reads; its
colours and textures are used) or ``type = "mitsuba"`` with ``file = "scene.xml"`` or ``builtin = "cornell_box"``
(its own shapes, BSDFs and emitters; ``[light]`` is then ignored). Placement in those is checked by ray casting
(:mod:`study.scene.placement`); ``reference.box = [[x0, y0, z0], [x1, y1, z1]]`` gives the proxy methods a box
other than the environment's bounds.

Meshes: ``object.shape = "torus" | "knot" | "blob"`` with ``rotation = [rx, ry, rz]`` (degrees) and ``detail``;
``radius`` is then the bounding-sphere radius, which the placement checks use.

Every error is a :class:`~study.errors.StudyError` whose message names the file, the key and what is allowed.
Numbers are strict: a boolean or a string is not a number (``radius = true`` is an error, not 1.0).
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Annotated, Any, Literal

import numpy as np
from pydantic import (
    BaseModel,
    BeforeValidator,
    ConfigDict,
    Field,
    StrictBool,
    ValidationError,
    field_validator,
    model_validator,
)
from pydantic_core import PydanticCustomError

from study.errors import StudyError
from study.io import read_toml
from study.scene.room import RoomMesh
from study.scene.sources import BoxEnv, Environment, resolve
from study.validation import KeyedError, first_error


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
    in the same way; ``detail`` does not apply to it. Cache keys hash the file's bytes, not its path."""

    shape: Literal["mesh", "sphere", "torus", "knot", "blob"] = "sphere"
    center: Vec3 = (0.5, 1.2, 0.3)
    radius: PosFloat = 0.4  # sphere radius, or bounding-sphere radius of a mesh
    material: Material = Mirror(type="mirror")
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
        tan_alpha = radius / math.sqrt(d * d - radius * radius)
        tan_x = tan_alpha / (self.frame_fill * min(1.0, self.height / self.width))
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


class Scene(_Strict):
    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False, arbitrary_types_allowed=True)
    environment: Environment = (
        BoxEnv()
    )  # box room (default), mesh file or Mitsuba scene (study.scene.sources)
    room: Room = Room()
    columns: tuple[Column, ...] = ()
    light: Light = Light()
    reference: Reference = Reference()
    object: Sphere = Sphere()
    camera: Camera = Camera()
    render: Render = Render()

    @field_validator("columns", mode="before")
    @classmethod
    def _list(cls, v):
        return tuple(v) if isinstance(v, list) else v

    @model_validator(mode="after")
    def _frame(self):  # camera.frame_object: target and fov from the object (Camera.framed)
        cam = self.camera.framed(self.object.center, self.object.radius)
        if cam is not self.camera:
            object.__setattr__(self, "camera", cam)
        return self

    @model_validator(mode="after")
    def _placement(self):
        if self.environment.type != "box":
            return self._placement_any()
        lo, hi = np.array(self.room.min), np.array(self.room.max)
        c, r = np.array(self.object.center), self.object.radius
        mesh = self.object.shape != "sphere"  # meshes are checked by their bounding sphere
        what = f"{self.object.shape} (bounding radius {r})" if mesh else f"sphere (radius {r})"
        who = f"{self.object.shape} (its bounding sphere)" if mesh else "sphere"
        if np.any(c - r <= lo) or np.any(c + r >= hi):
            raise KeyedError(
                "object.center",
                f"the {what} must lie inside the room {list(self.room.min)}..{list(self.room.max)}",
            )
        for i, col in enumerate(self.columns):
            blo, bhi = col.box(self.room)
            if np.any(blo[[0, 2]] < lo[[0, 2]]) or np.any(bhi[[0, 2]] > hi[[0, 2]]) or bhi[1] >= hi[1]:
                raise KeyedError(f"columns[{i}]", "the column must lie inside the room")
            if _box_sphere_distance(blo, bhi, c) <= r:
                raise KeyedError("object.center", f"the {who} overlaps columns[{i}]; move it or the column")
        for key, p in (
            ("reference.point", self.reference.point),
            ("light.position", self.light.position),
            ("camera.eye", self.camera.eye),
        ):
            p = np.array(p)
            if np.any(p <= lo) or np.any(p >= hi):
                raise KeyedError(key, "must lie strictly inside the room")
            for i, col in enumerate(self.columns):
                if _box_sphere_distance(*col.box(self.room), p) <= 0:
                    raise KeyedError(key, f"lies inside columns[{i}]")
        for key, p in (
            ("light.position", self.light.position),
            ("camera.eye", self.camera.eye),
            ("reference.point", self.reference.point),
        ):
            if key != "reference.point" and float(np.linalg.norm(np.subtract(p, c))) <= r:
                raise KeyedError(key, "lies inside the object")
        if np.linalg.norm(np.cross(np.subtract(self.camera.target, self.camera.eye), self.camera.up)) < 1e-9:
            raise KeyedError("camera.up", "must not be parallel to the viewing direction")
        return self

    def _placement_any(self):
        from study.scene.placement import check_scene

        check_scene(self)
        return self

    # ------------------------------------------------------------------ derived geometry
    def with_updates(self, updates: dict[str, Any], *, source: str = "<override>") -> Scene:
        """A new scene with dotted-key overrides (``{"object.center": [1, 1, 0]}``), validated again."""
        data = self.model_dump(mode="python")
        for key, value in updates.items():
            node, parts = data, key.split(".")
            for p in parts[:-1]:
                if not isinstance(node, dict) or p not in node:
                    raise StudyError(
                        f"unknown scene key; allowed top-level keys: {sorted(data)}", file=source, key=key
                    )
                node = node[p]
            if not isinstance(node, dict) or (parts[-1] not in node and parts[-1] != "material"):
                raise StudyError("unknown scene key", file=source, key=key)
            node[parts[-1]] = value
        return scene_from_dict(data, source=source)

    def mesh(self) -> RoomMesh:
        """The environment as triangles (:func:`study.scene.environment.geometry`): the box room and its columns,
        a mesh file's or a Mitsuba scene's triangles."""
        from study.scene.environment import geometry

        return geometry(self).mesh

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """(min, max) of the environment: the room box, or the bounding box of the environment's triangles."""
        from study.scene.environment import geometry

        return geometry(self).bounds


def _box_sphere_distance(lo, hi, p) -> float:
    return float(np.linalg.norm(np.maximum(np.maximum(lo - p, 0), p - hi)))


# ---------------------------------------------------------------------------------------------- loading
def scene_from_dict(data: dict, *, source: str = "<scene>", base: str | Path | None = None) -> Scene:
    """Validate a scene dict; the first problem is one StudyError naming ``source`` and the dotted key. Relative
    ``file`` paths resolve against ``base`` (the scene file's directory; the working directory by default)."""
    try:
        return Scene.model_validate(data, context={"base": str(base) if base is not None else None})
    except ValidationError as err:
        key, msg = first_error(
            err, Scene, skip=("mirror", "conductor", "dielectric", "box", "mesh", "mitsuba")
        )
        raise StudyError(msg, file=source, key=key or "(top level)") from None
    except StudyError as err:  # an environment that cannot be loaded (study.scene.environment)
        if err.file:
            raise
        raise StudyError(err.detail, file=source, key=err.key) from None


def load_scene(path: str | Path) -> Scene:
    """Read and validate a scene TOML file."""
    return scene_from_dict(read_toml(path, what="scene file"), source=str(path), base=Path(path).parent)
