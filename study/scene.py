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

Meshes: ``object.shape = "torus" | "knot" | "blob"`` with ``rotation = [rx, ry, rz]`` (degrees) and ``detail``;
``radius`` is then the bounding-sphere radius, which the placement checks use.

Every error is a :class:`~study.errors.StudyError` whose message names the file, the key and what is allowed.
"""
from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Any, Literal, Union

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator, model_validator

from study.errors import StudyError

Vec3 = tuple[float, float, float]
Vec2 = tuple[float, float]
PosFloat = Annotated[float, Field(gt=0, allow_inf_nan=False)]


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


class Mirror(_Strict):
    type: Literal["mirror"]


class Conductor(_Strict):
    type: Literal["conductor"]
    n: tuple[PosFloat, PosFloat, PosFloat]  # real part of the refraction index per RGB channel
    k: tuple[Annotated[float, Field(ge=0)], ...] = Field(min_length=3, max_length=3)  # extinction coefficient


class Dielectric(_Strict):
    type: Literal["dielectric"]
    ior: Annotated[float, Field(gt=1, le=4, allow_inf_nan=False)] = 1.5   # index of refraction inside (outside: 1)


Material = Annotated[Union[Mirror, Conductor, Dielectric], Field(discriminator="type")]


class Sphere(_Strict):
    """The shaded object. ``shape`` "sphere" is analytic; "torus", "knot" and "blob" are triangle meshes with
    smooth vertex normals (:mod:`study.objects`), scaled so that ``radius`` is their bounding-sphere radius,
    turned by ``rotation`` (Euler angles in degrees about x, then y, then z) and tessellated finer with ``detail``."""
    shape: Literal["sphere", "torus", "knot", "blob"] = "sphere"
    center: Vec3 = (0.5, 1.2, 0.3)
    radius: PosFloat = 0.4                       # sphere radius, or bounding-sphere radius of a mesh
    material: Material = Mirror(type="mirror")
    rotation: Vec3 = (0.0, 0.0, 0.0)             # meshes: Euler angles x, y, z in degrees
    detail: Annotated[int, Field(ge=1, le=6)] = 3  # meshes: tessellation level


Object = Sphere


class Camera(_Strict):
    eye: Vec3 = (0.0, 1.5, -1.9)
    target: Vec3 = (0.6, 1.0, 0.5)
    up: Vec3 = (0.0, 1.0, 0.0)
    fov: Annotated[float, Field(gt=0, lt=180)] = 70.0
    width: Annotated[int, Field(ge=8, le=4096)] = 256
    height: Annotated[int, Field(ge=8, le=4096)] = 256


class Render(_Strict):
    cube_res: Annotated[int, Field(ge=4, le=4096)] = 256
    cube_spp: Annotated[int, Field(ge=1)] = 64
    spp: Annotated[int, Field(ge=1)] = 64
    max_depth: Annotated[int, Field(ge=2, le=64)] = 4
    supersample: Annotated[int, Field(ge=1, le=8)] = 2
    seed: Annotated[int, Field(ge=0)] = 0
    fresnel: Literal["exact", "approx"] = "exact"   # object shading: exact conductor Fresnel or the paper's
    refraction: Literal["single", "double"] = "double"  # dielectric objects: paper's single refraction or in-and-out
    exit: Literal["auto", "exact", "distance_map"] = "auto"  # double refraction: how the far side is found
    internal_bounces: Annotated[int, Field(ge=0, le=16)] = 8   # total internal reflections followed, then dropped
    object_res: Annotated[int, Field(ge=4, le=2048)] = 128     # face resolution of the object's own distance map


class Scene(_Strict):
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
    def _placement(self):
        lo, hi = np.array(self.room.min), np.array(self.room.max)
        c, r = np.array(self.object.center), self.object.radius
        mesh = self.object.shape != "sphere"         # meshes are checked by their bounding sphere
        what = f"{self.object.shape} (bounding radius {r})" if mesh else f"sphere (radius {r})"
        who = f"{self.object.shape} (its bounding sphere)" if mesh else "sphere"
        if np.any(c - r <= lo) or np.any(c + r >= hi):
            raise _KeyedError("object.center", f"the {what} must lie inside the room "
                              f"{list(self.room.min)}..{list(self.room.max)}")
        for i, col in enumerate(self.columns):
            blo, bhi = col.box(self.room)
            if np.any(blo[[0, 2]] < lo[[0, 2]]) or np.any(bhi[[0, 2]] > hi[[0, 2]]) or bhi[1] >= hi[1]:
                raise _KeyedError(f"columns[{i}]", "the column must lie inside the room")
            if _box_sphere_distance(blo, bhi, c) <= r:
                raise _KeyedError("object.center", f"the {who} overlaps columns[{i}]; move it or the column")
        for key, p in (("reference.point", self.reference.point), ("light.position", self.light.position),
                       ("camera.eye", self.camera.eye)):
            p = np.array(p)
            if np.any(p <= lo) or np.any(p >= hi):
                raise _KeyedError(key, "must lie strictly inside the room")
            for i, col in enumerate(self.columns):
                if _box_sphere_distance(*col.box(self.room), p) <= 0:
                    raise _KeyedError(key, f"lies inside columns[{i}]")
        for key, p in (("light.position", self.light.position), ("camera.eye", self.camera.eye),
                       ("reference.point", self.reference.point)):
            if key != "reference.point" and float(np.linalg.norm(np.subtract(p, c))) <= r:
                raise _KeyedError(key, "lies inside the object")
        if np.linalg.norm(np.cross(np.subtract(self.camera.target, self.camera.eye), self.camera.up)) < 1e-9:
            raise _KeyedError("camera.up", "must not be parallel to the viewing direction")
        return self

    # ------------------------------------------------------------------ derived geometry
    def with_updates(self, updates: dict[str, Any], *, source: str = "<override>") -> "Scene":
        """A new scene with dotted-key overrides (``{"object.center": [1, 1, 0]}``), validated again."""
        data = self.model_dump(mode="python")
        for key, value in updates.items():
            node, parts = data, key.split(".")
            for p in parts[:-1]:
                if not isinstance(node, dict) or p not in node:
                    raise StudyError(f"unknown scene key; allowed top-level keys: {sorted(data)}", file=source, key=key)
                node = node[p]
            if not isinstance(node, dict) or (parts[-1] not in node and parts[-1] != "material"):
                raise StudyError("unknown scene key", file=source, key=key)
            node[parts[-1]] = value
        return scene_from_dict(data, source=source)

    def mesh(self) -> "RoomMesh":
        return room_mesh(self)


class _KeyedError(ValueError):
    def __init__(self, key: str, msg: str):
        super().__init__(msg)
        self.key = key


def _box_sphere_distance(lo, hi, p) -> float:
    return float(np.linalg.norm(np.maximum(np.maximum(lo - p, 0), p - hi)))


# ---------------------------------------------------------------------------------------------- loading
def _first_error(err: ValidationError) -> tuple[str, str]:
    e = err.errors()[0]
    loc = ".".join(str(p) for p in e["loc"] if not (isinstance(p, str) and p in ("mirror", "conductor", "dielectric")))
    ctx = e.get("ctx") or {}
    inner = ctx.get("error")
    if isinstance(inner, _KeyedError):
        return inner.key, str(inner)
    msg = e["msg"]
    if e["type"] == "extra_forbidden":
        msg = "unknown key"
    elif e["type"] == "union_tag_invalid" or e["type"] == "literal_error":
        msg = f"{msg}"
    return loc or "(top level)", msg


def _allowed(model: type[BaseModel], loc: str) -> str:
    """The allowed keys at a dotted location, for 'unknown key' messages."""
    node: Any = model
    for part in loc.split(".")[:-1]:
        if part.isdigit():
            continue
        field = node.model_fields.get(part) if isinstance(node, type) and issubclass(node, BaseModel) else None
        if field is None:
            return ""
        ann = field.annotation
        args = getattr(ann, "__args__", ())
        node = next((a for a in (ann, *args) if isinstance(a, type) and issubclass(a, BaseModel)), None)
        if node is None:
            return ""
    if isinstance(node, type) and issubclass(node, BaseModel):
        return f"; allowed: {', '.join(node.model_fields)}"
    return ""


def scene_from_dict(data: dict, *, source: str = "<scene>") -> Scene:
    try:
        return Scene.model_validate(data)
    except ValidationError as err:
        key, msg = _first_error(err)
        if msg == "unknown key":
            msg += _allowed(Scene, key)
        raise StudyError(msg, file=source, key=key) from None


def load_scene(path: str | Path) -> Scene:
    """Read and validate a scene TOML file."""
    path = Path(path)
    try:
        data = tomllib.loads(path.read_text())
    except FileNotFoundError:
        raise StudyError("scene file not found", file=str(path)) from None
    except tomllib.TOMLDecodeError as err:
        raise StudyError(f"not valid TOML ({err})", file=str(path)) from None
    return scene_from_dict(data, source=str(path))


# ---------------------------------------------------------------------------------------------- triangles
@dataclass(frozen=True)
class RoomMesh:
    """The environment as triangles: the very ones Mitsuba renders and Embree intersects.

    Attributes
    ----------
    vertices : (V, 3) float32, world space
    faces : (F, 3) int32
    uv : (V, 2) float32, texture coordinates in [0, 1]^2 of each vertex on its surface
    surface : (F,) int32, index into ``surfaces`` (the texture id of each triangle)
    surfaces : names of the textured surfaces, in texture-id order
    """
    vertices: np.ndarray
    faces: np.ndarray
    uv: np.ndarray
    surface: np.ndarray
    surfaces: tuple[str, ...]

    def part(self, surface_id: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(vertices, faces, uv) of one surface, re-indexed."""
        f = self.faces[self.surface == surface_id]
        used, inv = np.unique(f, return_inverse=True)
        return self.vertices[used], inv.reshape(-1, 3).astype(np.int32), self.uv[used]


SURFACES = ("floor", "ceiling", "wall_x-", "wall_x+", "wall_z-", "wall_z+", "column")


def _quad(p0, du, dv):
    """Two triangles spanning p0, p0+du, p0+du+dv, p0+dv with uv (0,0)..(1,1)."""
    p0, du, dv = map(np.asarray, (p0, du, dv))
    v = np.array([p0, p0 + du, p0 + du + dv, p0 + dv], dtype=np.float64)
    uv = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], dtype=np.float64)
    return v, np.array([[0, 1, 2], [0, 2, 3]]), uv


def _box_quads(lo, hi, *, inward: bool, skip_bottom: bool = False):
    """The six faces of a box as (name-axis, quad); normals point inward for the room, outward for columns."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    s = hi - lo
    ex, ey, ez = np.diag(s)
    quads = {
        "floor": _quad(lo, ez, ex) if inward else _quad(lo, ex, ez),
        "ceiling": _quad(lo + ey, ex, ez) if inward else _quad(lo + ey, ez, ex),
        "wall_x-": _quad(lo, ey, ez) if inward else _quad(lo, ez, ey),
        "wall_x+": _quad(lo + ex, ez, ey) if inward else _quad(lo + ex, ey, ez),
        "wall_z-": _quad(lo, ex, ey) if inward else _quad(lo, ey, ex),
        "wall_z+": _quad(lo + ez, ey, ex) if inward else _quad(lo + ez, ex, ey),
    }
    if skip_bottom:
        del quads["floor"]
    return quads


def room_mesh(scene: Scene) -> RoomMesh:
    """Triangulate the room (inward-facing) and its columns (outward-facing, no bottom face)."""
    V, F, UV, S = [], [], [], []
    n = 0

    def add(quad, sid):
        nonlocal n
        v, f, uv = quad
        V.append(v); F.append(f + n); UV.append(uv); S.append(np.full(len(f), sid))
        n += len(v)

    for name, quad in _box_quads(scene.room.min, scene.room.max, inward=True).items():
        add(quad, SURFACES.index(name))
    for col in scene.columns:
        for quad in _box_quads(*col.box(scene.room), inward=False, skip_bottom=True).values():
            add(quad, SURFACES.index("column"))
    return RoomMesh(np.concatenate(V).astype(np.float32), np.concatenate(F).astype(np.int32),
                    np.concatenate(UV).astype(np.float32), np.concatenate(S).astype(np.int32), SURFACES)


# ---------------------------------------------------------------------------------------------- textures
def texture(surface: str, size: int = 256) -> np.ndarray:
    """Procedural albedo texture of a surface: (size, size, 3) float32 linear RGB in (0, 0.9].

    Generated in code (nothing downloaded) and high in detail, so that a misplaced reflection shows in the
    image metrics: a two-tone checker on the floor, coloured tiles with grout on the walls, a grid on the
    ceiling and stripes on columns.
    """
    y, x = np.mgrid[0:size, 0:size] / size
    hues = {"floor": ((0.75, 0.72, 0.65), (0.25, 0.22, 0.2)), "ceiling": ((0.8, 0.8, 0.8), (0.55, 0.55, 0.6)),
            "wall_x-": ((0.75, 0.3, 0.25), (0.85, 0.7, 0.5)), "wall_x+": ((0.25, 0.45, 0.75), (0.7, 0.8, 0.85)),
            "wall_z-": ((0.3, 0.65, 0.3), (0.8, 0.85, 0.6)), "wall_z+": ((0.8, 0.65, 0.2), (0.45, 0.3, 0.6)),
            "column": ((0.85, 0.85, 0.8), (0.2, 0.2, 0.35))}
    a, b = (np.array(h, np.float32) for h in hues[surface])
    if surface == "floor":
        m = ((np.floor(x * 8) + np.floor(y * 8)) % 2)[..., None]
    elif surface == "ceiling":
        m = ((np.abs((x * 6) % 1 - 0.5) > 0.45) | (np.abs((y * 6) % 1 - 0.5) > 0.45))[..., None]
    elif surface == "column":
        m = (np.floor(y * 10) % 2)[..., None]
    else:
        tile = ((np.floor(x * 6) + 2 * np.floor(y * 5)) % 3)[..., None] / 2
        grout = ((np.abs((x * 6) % 1 - 0.5) > 0.46) | (np.abs((y * 5) % 1 - 0.5) > 0.46))[..., None]
        return np.where(grout, 0.12, a * (1 - tile) + b * tile).astype(np.float32)
    return (a * (1 - m) + b * m).astype(np.float32)


def look_at_basis(eye, target, up) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(forward, right, up) unit vectors of a camera; right = forward × up, as Mitsuba's look_at."""
    f = np.asarray(target, float) - np.asarray(eye, float)
    f /= np.linalg.norm(f)
    r = np.cross(f, up)
    r /= np.linalg.norm(r)
    return f, r, np.cross(r, f)


def camera_rays(cam: Camera, supersample: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """Primary rays through stratified sub-pixel centres, matching Mitsuba's perspective sensor.

    Returns origins (H, W, s*s, 3) and unit directions (H, W, s*s, 3), float64; fov is horizontal.
    """
    f, r, u = look_at_basis(cam.eye, cam.target, cam.up)
    s, W, H = supersample, cam.width, cam.height
    sub = (np.arange(s) + 0.5) / s
    j = (np.arange(W)[:, None] + sub[None, :]).ravel()          # continuous column coordinates
    i = (np.arange(H)[:, None] + sub[None, :]).ravel()
    tan = math.tan(math.radians(cam.fov) / 2)
    xs = (2 * j / W - 1) * tan
    ys = (1 - 2 * i / H) * tan * H / W
    d = f + xs[None, :, None] * r + ys[:, None, None] * u          # (H*s, W*s, 3)
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    d = d.reshape(H, s, W, s, 3).transpose(0, 2, 1, 3, 4).reshape(H, W, s * s, 3)
    o = np.broadcast_to(np.asarray(cam.eye, float), d.shape)
    return np.ascontiguousarray(o), d
