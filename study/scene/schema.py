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
    alpha = 0.0                          # GGX roughness α in [0, 1]: 0 a mirror, > 0 glossy (roughconductor)

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
    # probe_spp = 16                     # samples per texel of multi_probe's probes (default: cube_spp)
    flip_against = ["oracle", "truth"]   # the references FLIP is measured against (the others: NaN); "mitsuba"
                                         # adds FLIP against Mitsuba's camera render

The environment is the box ``[room]`` with its ``[[columns]]`` unless ``[environment]`` names another source
(:mod:`study.scene.sources`): ``type = "mesh"`` with ``file = "rooms/l_room.ply"`` (any format trimesh reads; its
colours and textures are used) or ``type = "mitsuba"`` with ``file = "scene.xml"`` or ``builtin = "cornell_box"``
(its own shapes, BSDFs and emitters; ``[light]`` lights it only where it has no emitter). Any environment takes
``sky = "#rrggbb" | [r, g, b] | "sky.exr"``: what rays that leave the scene see (:mod:`study.scene.sky`; left out:
the file's own, else black). There, the placement
keys a scene leaves out are suggested (:mod:`study.scene.autoplace`) and every placement is checked by ray casting
(:mod:`study.scene.placement`); ``light.enabled = false`` leaves the point light out;
``reference.box = [[x0, y0, z0], [x1, y1, z1]]`` gives the proxy methods a box
other than the environment's bounds.

Meshes: ``object.shape = "torus" | "knot" | "blob"`` with ``rotation = [rx, ry, rz]`` (degrees) and ``detail``;
``radius`` is then the bounding-sphere radius, which the placement checks use.

Every error is a :class:`~study.errors.StudyError` whose message names the file, the key and what is allowed.
Numbers are strict: a boolean or a string is not a number (``radius = true`` is an error, not 1.0).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from pydantic import (
    BaseModel,
    ConfigDict,
    PrivateAttr,
    ValidationError,
    ValidationInfo,
    field_validator,
    model_validator,
)

from study import progress
from study.errors import StudyError
from study.io import read_toml
from study.scene.models import (  # noqa: F401  (re-exported: the scene's types live there)
    MAX_SAMPLES,
    MAX_SEED,
    MESH_SUFFIXES,
    Camera,
    Column,
    Conductor,
    Dielectric,
    Float,
    Int,
    Light,
    Material,
    Mirror,
    Object,
    PosFloat,
    Reference,
    Render,
    Room,
    Sphere,
    Vec2,
    Vec3,
    _not_a_set,
    _number,
    _Strict,
)
from study.scene.paths import scene_file_names
from study.scene.room import RoomMesh
from study.scene.sources import SOURCES, BoxEnv, Environment
from study.validation import KeyedError, first_error

#: Keys whose update places anew every key automatic placement chose (the rest of the placement follows from them:
#: the object's spot and the camera's depend on the reference point and the object's size), as loading a mesh file
#: with them given would.
REPLACING = ("reference.point", "object.radius")


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
    _suggested: frozenset = PrivateAttr(default=frozenset())  # placement keys chosen by automatic placement
    _chosen: str = PrivateAttr(default="")  # automatic placement's choice in one line (autoplace.Suggestion)
    _units: str = PrivateAttr(
        default=""
    )  # how the environment was moved into its measuring frame (scene.frame)
    _measure: tuple = PrivateAttr(default=(1.0, (0.0, 0.0, 0.0)))  # that frame's (s, c): x → s·(x − c)

    @field_validator("columns", mode="before")
    @classmethod
    def _list(cls, v):
        return tuple(v) if isinstance(v, list) else v

    @model_validator(mode="before")
    @classmethod
    def _fill_placement(cls, data, info: ValidationInfo):
        """Environments whose source is placed (:attr:`study.scene.sources.Source.placed`: mesh files, Mitsuba
        scenes, not the box): the placement keys the user left out, suggested
        (:func:`study.scene.autoplace.suggest`); the keys suggested are remembered, so that a check that fails on
        one of them blames the automatic placement, not a key the user never set."""
        ctx = info.context if isinstance(info.context, dict) else None
        env = data.get("environment") if isinstance(data, dict) else None
        kind = env.get("type") if isinstance(env, dict) else getattr(env, "type", "box")
        if kind not in SOURCES or not SOURCES[kind].placed:
            return data
        from study.scene.autoplace import KEYS

        data = cls._measuring_frame(data, env, kind, ctx)
        env = data.get("environment")
        given = {}
        for k in (*KEYS, "camera.width", "camera.height"):  # the frame's size: where the object is seen whole
            table, key = k.split(".")
            node = data.get(table)
            node = node.model_dump() if isinstance(node, BaseModel) else node
            if isinstance(node, dict) and key in node:
                given[k] = node[key]
        missing = [k for k in KEYS if k not in given]
        if not missing:
            return data
        from pydantic import TypeAdapter

        from study.scene.autoplace import suggest_placement as suggest

        try:
            model = TypeAdapter(Environment).validate_python(env, context=ctx)
        except ValidationError:
            return data  # the field's own validation says what is wrong
        out = {k: (dict(v.model_dump()) if isinstance(v, BaseModel) else v) for k, v in data.items()}
        with progress.stage("placement"):
            suggested = suggest(model, given)
        for k, v in suggested.items():
            table, key = k.split(".")
            out[table] = {**(out.get(table) or {}), key: v}
        line = getattr(suggested, "line", "")
        if getattr(suggested, "outside", False) and model.sky is None and not _own_sky(model):
            from study.scene.sky import STUDIO

            out["environment"] = {**model.model_dump(), "sky": STUDIO}  # something for a mirror to show
            line += (
                f'; sky "{STUDIO}" (an object seen from outside: a studio gradient it can reflect, unlike the '
                "background behind it; environment.sky sets another)"
            )
        if ctx is not None:
            ctx["suggested"] = set(ctx.get("suggested") or ()) | set(suggested)
            ctx["placement"] = line
        return out

    @staticmethod
    def _measuring_frame(data: dict, env, kind: str, ctx: dict | None) -> dict:
        """A mesh environment far from the origin or far from metres, moved into its measuring frame with the
        points, lengths and intensities the user gave (:mod:`study.scene.frame`); a Mitsuba scene there refused
        in one line. ``data`` unchanged where nothing moves."""
        from pydantic import TypeAdapter

        import study.scene.frame as frame
        from study.scene.environment import geometry

        try:
            model = TypeAdapter(Environment).validate_python(env, context=ctx)
        except ValidationError:
            return data  # the field's own validation says what is wrong
        bounds = geometry(model).bounds
        if kind == "mitsuba":
            why = frame.refusal(*bounds)
            if why:
                raise StudyError(why, key="environment")
            return data
        if kind != "mesh":
            return data
        s, c = frame.choose(*bounds)
        if frame.identity(s, c):
            return data
        out = {k: (dict(v.model_dump()) if isinstance(v, BaseModel) else v) for k, v in data.items()}
        out["environment"] = frame.mesh_keys(model.model_dump(), s, c)
        for k in (*frame.POINTS, *frame.LENGTHS, *frame.INTENSITIES, "reference.box"):
            table, key = k.split(".")
            node = out.get(table)
            if isinstance(node, dict) and key in node:
                try:
                    out[table] = {**node, key: frame.apply(k, node[key], s, c)}
                except (TypeError, ValueError):
                    pass  # not a number: the key's own validation says so
        if ctx is not None:
            ctx["frame"] = frame.units_note(*bounds, s, c)
            ctx["measure"] = (float(s), tuple(float(x) for x in c))
        return out

    @model_validator(mode="after")
    def _frame(self):  # camera.frame_object: target and fov from the object (Camera.framed)
        cam = self.camera.framed(self.object.center, self.object.radius)
        if cam is not self.camera:
            object.__setattr__(self, "camera", cam)
        return self

    @model_validator(mode="after")
    def _placement(self, info: ValidationInfo):
        if isinstance(info.context, dict) and info.context.get("suggested"):
            self._suggested = frozenset(info.context["suggested"])
            self._chosen = info.context.get("placement") or ""
        if isinstance(info.context, dict) and info.context.get("frame"):
            self._units = info.context["frame"]
        if isinstance(info.context, dict) and info.context.get("measure"):
            self._measure = tuple(info.context["measure"])
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

        try:
            check_scene(self)
        except KeyedError as err:
            if err.key in self.suggested_keys():
                raise KeyedError(
                    "environment",
                    f"automatic placement failed: the suggested {err.key} {err}; set {err.key} yourself",
                ) from None
            raise
        return self

    def suggested_keys(self) -> frozenset[str]:
        """The placement keys automatic placement chose (the user left them out)."""
        return self._suggested

    def units_line(self) -> str:
        """How the environment was recentred or rescaled to be measured (:mod:`study.scene.frame`); empty where
        it was measured as it is."""
        return self._units

    def placement_line(self) -> str:
        """Automatic placement's choice in one line, its score terms named; empty where it chose nothing."""
        return self._chosen

    # ------------------------------------------------------------------ derived geometry
    def with_updates(
        self, updates: dict[str, Any], *, source: str = "<override>", frame: str = "file"
    ) -> Scene:
        """A new scene with dotted-key overrides (``{"object.center": [1, 1, 0]}``), validated again.

        ``frame="file"`` (users' ``--set``, ``[overrides]``, sweep axes, API keywords): points, lengths and
        intensities are in the environment file's own units and coordinates, moved into the scene's measuring
        frame as loading the file with them would (:mod:`study.scene.frame`); ``frame="measured"``: values
        already in that frame (what the scene's own keys and bounds hold, e.g. probe points), taken as they are.
        The two agree for every scene measured where it lies (the box room, files in metres near the origin)."""
        assert frame in ("file", "measured"), frame
        data = self.model_dump(mode="python")
        if frame == "file":
            from study.scene.frame import user_updates

            updates = user_updates(updates, *self._measure)
        for key, value in updates.items():
            node, parts = data, key.split(".")
            for i, p in enumerate(parts):
                last = i == len(parts) - 1
                if not isinstance(node, dict) or (p not in node and not (last and p == "material")):
                    where = ".".join(parts[:i]) or "the scene"  # the table the key is missing from
                    valid = (
                        ", ".join(sorted(node)) if isinstance(node, dict) else f"none ({where} is a value)"
                    )
                    raise StudyError(f"unknown scene key; allowed: {valid}", file=source, key=key)
                if not last:
                    node = node[p]
            node[parts[-1]] = value
        keep = frozenset(k for k in self._suggested if k not in updates)
        if keep and any(k in updates for k in REPLACING):  # placed anew around what the user gave
            for k in keep:
                table, key = k.split(".")
                data[table].pop(key, None)
            keep = frozenset()
        line = self._chosen if keep == self._suggested else ""
        return scene_from_dict(
            data, source=source, suggested=keep, placement=line, units=self._units, measure=self._measure
        )

    def mesh(self) -> RoomMesh:
        """The environment as triangles (:func:`study.scene.environment.geometry`): the box room and its columns,
        a mesh file's or a Mitsuba scene's triangles."""
        from study.scene.environment import geometry

        return geometry(self).mesh

    def lamp(self) -> bool:
        """Whether the point light ``[light]`` is rendered: the environment takes it (the box, mesh files,
        Mitsuba scenes without an emitter) and ``light.enabled``."""
        from study.scene.environment import geometry

        return bool(geometry(self).point_light and self.light.enabled)

    def load_summary(self) -> str:
        """One line: what the environment's file held (triangles, materials, textures, lights) and what was
        ignored or dropped, with a count per kind; empty for the box room."""
        from study.scene.environment import geometry

        return geometry(self).summary

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """(min, max) of the environment: the room box, or the bounding box of the environment's triangles."""
        from study.scene.environment import geometry

        return geometry(self).bounds


def _own_sky(env) -> bool:
    """Whether the environment's file brings its own sky (a Mitsuba ``envmap`` or ``constant`` emitter)."""
    from study.scene.environment import geometry

    names = (str(e).lower() for e in geometry(env).emitters)
    return any("environment" in n or "constant" in n or "envmap" in n for n in names)


def _box_sphere_distance(lo, hi, p) -> float:
    return float(np.linalg.norm(np.maximum(np.maximum(lo - p, 0), p - hi)))


# ---------------------------------------------------------------------------------------------- loading
def scene_from_dict(
    data: dict,
    *,
    source: str = "<scene>",
    base: str | Path | None = None,
    suggested=frozenset(),
    placement="",
    units="",
    measure=None,
) -> Scene:
    """Validate a scene dict; the first problem is one StudyError naming ``source`` and the dotted key. Relative
    ``file`` paths resolve against ``base`` (the scene file's directory; the working directory by default).
    In mesh and Mitsuba environments the placement keys ``data`` leaves out are suggested (automatic placement,
    :mod:`study.scene.autoplace`); ``suggested``: keys of ``data`` that automatic placement chose earlier."""
    try:
        ctx = {
            "base": str(base) if base is not None else None,
            "suggested": set(suggested),
            "placement": placement,
            "frame": units,
            "measure": measure,
        }
        return Scene.model_validate(data, context=ctx)
    except ValidationError as err:
        key, msg = first_error(err, Scene, skip=("mirror", "conductor", "dielectric"))
        raise StudyError(msg, file=source, key=key or "(top level)") from None
    except StudyError as err:  # an environment that cannot be loaded (study.scene.environment)
        if err.file:
            raise
        raise StudyError(err.detail, file=source, key=err.key) from None


def load_scene_file(path: str | Path) -> Scene:
    """Read and validate a scene TOML file; every file it names must lie in or below its folder
    (:func:`study.scene.paths.scene_file_names`)."""
    data = read_toml(path, what="scene file")
    scene_file_names(data, Path(path))
    return scene_from_dict(data, source=str(path), base=Path(path).parent)
