"""Distance impostors: capture from the reference point, save and load as EXR.

A distance impostor (the paper's term) is a cube map (:mod:`study.impostor.cubemap` convention) holding per texel the
radiance (RGB, linear) of the environment point visible from the reference point and its distance from that point.
Radiance is path traced by Mitsuba (box-filtered texel averages); distance is exact, by ray casting (Embree) through
the texel centres. The reflective object is not in its own map.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from study import progress
from study.errors import StudyError
from study.impostor import cubemap
from study.io import atomic_write, read_exr, write_exr
from study.reference import mitsuba as mitsuba_ref
from study.reference.embree import Tracer
from study.reference.tracer import make_tracer
from study.scene import Scene
from study.scene.environment import env_key


@dataclass
class Impostor:
    reference: np.ndarray  # (3,) reference point o, world space
    radiance: np.ndarray  # (6, R, R, 3) float32, linear RGB
    distance: np.ndarray  # (6, R, R) float32, |visible point − o|

    @property
    def res(self) -> int:
        return self.radiance.shape[1]

    def texels(self) -> np.ndarray:
        """(6, R, R, 4): RGB and distance, the layout backends sample."""
        return np.concatenate([self.radiance, self.distance[..., None]], axis=-1).astype(np.float32)

    # ------------------------------------------------------------------------------------ EXR
    def save(self, path: str | Path) -> None:
        """One RGBA EXR of 6R × R (faces stacked downwards, A = distance); the reference point in a sidecar JSON.
        Written to a temporary file and renamed, so a reader never sees half a file."""
        path = Path(path)
        write_exr(path, self.texels().reshape(6 * self.res, self.res, 4))
        atomic_write(
            path.with_suffix(".json"),
            json.dumps({"reference": self.reference.tolist(), "res": self.res}).encode(),
        )

    @classmethod
    def load(cls, path: str | Path) -> Impostor:
        path = Path(path)
        try:
            meta = json.loads(path.with_suffix(".json").read_text())
            res, ref = int(meta["res"]), np.asarray(meta["reference"], float)
        except (OSError, ValueError, KeyError, TypeError) as err:
            raise StudyError(
                f"impostor metadata unreadable ({err})", file=str(path.with_suffix(".json"))
            ) from None
        a = read_exr(path)
        if a.shape != (6 * res, res, 4):
            raise StudyError(
                f"impostor EXR has shape {a.shape}, expected {(6 * res, res, 4)}", file=str(path)
            )
        a = a.reshape(6, res, res, 4)
        if not np.all(np.isfinite(a)) or np.any(a[..., 3] <= 0):
            raise StudyError("impostor holds non-finite values or non-positive distances", file=str(path))
        return cls(ref, np.ascontiguousarray(a[..., :3]), np.ascontiguousarray(a[..., 3]))


def distances_from(tracer: Tracer, o, res: int, *, key: str = "reference.point") -> np.ndarray:
    """Exact distances from the point ``o`` through every texel centre of a res² cube map, by ``tracer``:
    (6, R, R) float32; :data:`study.impostor.cubemap.FAR` where a texel ray leaves the scene ("no surface": its
    radiance is the sky's, :mod:`study.scene.sky`). Every one of them leaving is a StudyError on ``key``."""
    dirs = cubemap.texel_directions(res).reshape(-1, 3)
    t = tracer.distance(np.broadcast_to(np.asarray(o, float), dirs.shape), dirs)
    open_ = ~np.isfinite(t)
    if open_.all():
        raise StudyError(
            "sees no surface: every texel ray leaves the scene; move it near the geometry", key=key
        )
    return np.where(open_, cubemap.FAR, t).reshape(6, res, res).astype(np.float32)


def capture_distance(scene: Scene, res: int, tracer: Tracer | None = None) -> np.ndarray:
    """Exact distances from the reference point through every texel centre: (6, R, R) float32."""
    return distances_from(tracer or make_tracer(scene.mesh()), scene.reference.point, res)


def capture(
    scene: Scene, *, res: int | None = None, spp: int | None = None, tracer: Tracer | None = None
) -> Impostor:
    """Capture the distance impostor of ``scene`` from its reference point (object excluded)."""
    res = res or scene.render.cube_res
    radiance = render_cube(scene, res, spp or scene.render.cube_spp)
    return Impostor(np.asarray(scene.reference.point, float), radiance, capture_distance(scene, res, tracer))


@progress.rendering  # its time: the case's Mitsuba renders (study.progress)
def render_cube(scene: Scene, res: int, spp: int, loaded: dict | None = None) -> np.ndarray:
    """Radiance of the environment seen from the reference point, without the object: (6, R, R, 3) float32.

    Each face is a Mitsuba perspective render (fov 90) along the face's forward axis with the face's up vector, so
    its pixels are the texels of :mod:`study.impostor.cubemap`; texel radiance is the box-filtered pixel average.
    ``loaded`` (a dict): keeps the Mitsuba scene built here for the next call, which renders in it; for scenes
    that differ in the reference point alone (a probe set's probes), which the Mitsuba scene does not hold.
    """
    mi = mitsuba_ref.mi()
    o = np.asarray(scene.reference.point, float)
    faces = []
    sc = None if loaded is None else loaded.get("scene")
    for f, (fwd, _right, up) in enumerate(cubemap.FACES):
        sensor = mi.load_dict(mitsuba_ref.sensor(o, o + fwd, up, 90.0, res, res, spp, scene.render.seed + f))
        if sc is None:
            sc = mi.load_dict(mitsuba_ref.scene_dict(scene, with_object=False, sensor=sensor))
            if loaded is not None:
                loaded["scene"] = sc
        faces.append(np.array(mi.render(sc, sensor=sensor, seed=scene.render.seed + f), dtype=np.float32))
    return np.stack(faces)


def impostor_key(scene: Scene, res: int | None = None, spp: int | None = None) -> str:
    """Content key of an impostor: everything that affects it, and nothing that does not (the object)."""
    fields = {
        "environment": env_key(scene),
        "light": scene.light.model_dump(),
        "reference": scene.reference.model_dump(),
        "res": res or scene.render.cube_res,
        "spp": spp or scene.render.cube_spp,
        "max_depth": scene.render.max_depth,
        "seed": scene.render.seed,
        "v": 2,
    }
    return hashlib.sha256(json.dumps(fields, sort_keys=True).encode()).hexdigest()[:16]
