"""Automatic placement in an environment nobody placed things in (mesh files, Mitsuba scenes): the keys the user
left out, and only those (:data:`KEYS`), suggested by ray casting with Embree (:mod:`study.scene.placement`).

* ``reference.point``: the free, enclosed point of a 5³ grid inside the bounds farthest from every surface (the
  grid is ranked by the nearest hit of 128 rays from each point, then checked exactly);
* ``object.radius``: a quarter of the reference point's clearance, at most 8 % of the bounds' diagonal;
  ``object.center``: a little below the reference point (on the camera's view axis, before the first surface
  it meets, where the scene has a camera: a Mitsuba sensor or a glTF camera), moved to the nearest free spot
  where the sphere touches nothing;
* the camera: the scene's own where it has one (Mitsuba sensor, glTF camera); else the eye, of 64 directions
  around the object at a distance of 1.75 × the clearance, that sees the object unblocked (every sampled ray
  from the eye to the object's near side arrives), preferring eyes level with the object on the reference point's side;
* the light, where ``[light]`` lights the environment: ``light.enabled`` is off when the file brings light of its
  own (emitters, emissive materials, punctual lights); else a point light at the centre of the bounds (0.6 ×
  the clearance above the reference point when the centre is not free, or is the reference point or the
  object) whose intensity scales with the squared diagonal of the bounds: 6 W/sr × (diag / 6.4 m)². The
  irradiance I / r² at walls a fixed fraction of the diagonal away is then the same as in the default
  4 m × 3 m × 4 m room (diagonal 6.4 m) with its 6 W/sr light.
  Where the file's own lights are weak (:mod:`study.scene.lights`), ``light.enabled`` is on beside them.
"""

from __future__ import annotations

from typing import Any

import numpy as np

import study.scene.lights as lights
import study.scene.placement as placement
from study.errors import StudyError
from study.scene.environment import geometry
from study.validation import KeyedError

KEYS = (
    "reference.point",
    "object.center",
    "object.radius",
    "camera.eye",
    "camera.target",
    "camera.up",
    "camera.fov",
    "light.enabled",
    "light.position",
    "light.intensity",
)
DEFAULT_DIAGONAL = float(np.linalg.norm([4.0, 3.0, 4.0]))  # the default room's
DEFAULT_INTENSITY = 6.0  # W/sr, the default room's light


def light_intensity(lo, hi) -> float:
    """W/sr of the suggested point light: the default room's, times (diagonal / default diagonal)²."""
    return DEFAULT_INTENSITY * (float(np.linalg.norm(np.subtract(hi, lo))) / DEFAULT_DIAGONAL) ** 2


def _reference(env) -> tuple[np.ndarray, float]:
    mesh, (lo, hi) = env.mesh, env.bounds
    g = np.linspace(0.15, 0.85, 5)
    grid = lo + (hi - lo) * np.stack(np.meshgrid(g, g, g, indexing="ij"), -1).reshape(-1, 3)
    d = placement.directions()
    t, _ = placement.cast(mesh, np.repeat(grid, len(d), 0), np.tile(d, (len(grid), 1)))
    rough = t.reshape(len(grid), -1).min(1)
    for i in np.argsort(-rough, kind="stable"):
        try:
            placement.check_free(mesh, grid[i], "reference.point", enclosed=True)
        except KeyedError:
            continue
        return grid[i], placement.clearance(mesh, grid[i])
    raise StudyError(
        "found no free point enclosed by the environment for the reference point; give "
        "reference.point, object.center and camera.eye yourself",
        key="environment",
    )


def _free_centre(mesh, start: np.ndarray, radius: float, around: np.ndarray) -> np.ndarray:
    """``start`` if the sphere fits there, else the first of points between it and ``around`` or around it that
    fits; none fits: a StudyError on ``environment`` naming ``object.center``."""
    cands = [start] + [start + (around - start) * f for f in (0.25, 0.5, 0.75, 1.0)]
    cands += [around + 2 * radius * d for d in placement.directions(32)]
    for c in cands:
        if placement.clearance(mesh, c) > 1.2 * radius:
            try:
                placement.check_free(mesh, c, "object.center")
            except KeyedError:
                continue
            return np.asarray(c, float)
    raise StudyError(
        f"automatic placement found no spot for object.center where a sphere of radius {radius:.3g} touches "
        "nothing; set object.center yourself or make object.radius smaller",
        key="environment",
    )


def _eye(env, centre, radius, best, gap, up) -> np.ndarray:
    mesh = env.mesh
    dist = max(1.75 * gap, 3.0 * radius)
    toward = best - centre
    toward = toward / (np.linalg.norm(toward) or 1)
    scored = []
    for d in placement.directions(64):
        eye = centre + d * dist
        score = -abs(float(d @ up)) + 0.5 * float(d @ toward)  # level with the object, the reference side
        scored.append((score, eye))
    scored.sort(key=lambda s: -s[0])
    fallback = None
    for _, eye in scored:
        try:
            placement.check_free(mesh, eye, "camera.eye")
        except KeyedError:
            continue
        if placement.clearance(mesh, eye) < 0.05 * dist:
            continue
        seen = placement.sees(mesh, eye, centre, radius)
        if seen == 1.0:
            return eye
        if fallback is None or seen > fallback[0]:
            fallback = (seen, eye)
    if fallback is None:
        raise StudyError(
            "found no free spot for the camera around the object; give camera.eye yourself", key="environment"
        )
    return fallback[1]


def suggest(env, given: dict[str, Any] | None = None) -> dict[str, Any]:
    """Dotted scene keys → values for the placement keys (:data:`KEYS`) missing from ``given`` (the user's),
    in the environment ``env`` (:class:`~study.scene.environment.EnvGeometry`)."""
    given = dict(given or {})
    mesh, (lo, hi) = env.mesh, env.bounds
    diag = float(np.linalg.norm(hi - lo))
    out: dict[str, Any] = {}

    def want(k: str) -> bool:
        return k not in given

    if want("reference.point"):
        best, gap = _reference(env)
        out["reference.point"] = best.tolist()
    else:
        best = np.asarray(given["reference.point"], float)
        placement.check_free(mesh, best, "reference.point", enclosed=True)  # the user's: checked first
        gap = placement.clearance(mesh, best)
    radius = float(given.get("object.radius", min(0.25 * gap, 0.08 * diag)))
    if want("object.radius"):
        out["object.radius"] = radius
    up = np.asarray(given.get("camera.up", env.sensor["up"] if env.sensor else (0.0, 1.0, 0.0)), float)
    if want("object.center"):
        start = best - up / np.linalg.norm(up) * 0.45 * gap
        s = env.sensor
        if s is not None and want("camera.eye"):  # onto the Mitsuba camera's view axis
            eye, target = np.array(s["eye"]), np.array(s["target"])
            axis = (target - eye) / np.linalg.norm(target - eye)
            t_hit = placement.cast(mesh, eye[None], axis[None])[0][0]  # the camera sees up to there
            far = min(2 * diag + np.linalg.norm(eye - (lo + hi) / 2), t_hit - 1.5 * radius)
            pts = eye + np.linspace(0, max(far, 0.0), 200)[:, None] * axis
            inside = [p for p in pts if np.all(p > lo) and np.all(p < hi)]
            ok = [p for p in inside if placement.clearance(mesh, p) > 1.5 * radius]
            if ok:
                start = min(ok, key=lambda p: np.linalg.norm(p - (lo + hi) / 2))
        centre = _free_centre(mesh, start, radius, best)
        out["object.center"] = centre.tolist()
    else:
        centre = np.asarray(given["object.center"], float)
        placement.check_object(mesh, centre, radius, f"object (bounding radius {radius:g})")
    if want("camera.up"):
        out["camera.up"] = up.tolist()
    if want("camera.eye"):
        if env.sensor is not None:
            out["camera.eye"] = list(env.sensor["eye"])
        else:
            out["camera.eye"] = _eye(env, centre, radius, best, gap, up / np.linalg.norm(up)).tolist()
    if want("camera.target"):
        out["camera.target"] = centre.tolist()
    if want("camera.fov") and env.sensor is not None and want("camera.eye"):  # the file's view, whole
        out["camera.fov"] = env.sensor["fov"]
    if env.point_light:
        if want("light.enabled"):
            weak = env.lit and lights.weak(env, light_intensity(lo, hi))
            out["light.enabled"] = not env.lit or weak or any(k.startswith("light.") for k in given)
        if want("light.position"):
            c = (lo + hi) / 2
            try:
                placement.check_free(mesh, c, "light.position")
                if np.linalg.norm(c - centre) <= 1.5 * radius or np.linalg.norm(c - best) < 0.3 * gap:
                    raise KeyedError("light.position", "in the object or at the reference point")
            except KeyedError:
                c = best + up / np.linalg.norm(up) * 0.6 * gap
            out["light.position"] = np.asarray(c, float).tolist()
        if want("light.intensity"):
            out["light.intensity"] = [light_intensity(lo, hi)] * 3
    return out


def suggest_placement(scene: Any, given: dict[str, Any] | None = None) -> dict[str, Any]:
    """Where to put things in an environment nobody placed them in (:func:`suggest`): dotted overrides for the
    placement keys missing from ``given`` (the user's dotted keys → values). ``scene`` is a scene or an environment
    alone (a mesh or Mitsuba source, as :func:`study.scene.environment.geometry` takes)."""
    return suggest(geometry(scene), given)
