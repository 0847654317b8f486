"""Automatic placement in an environment nobody placed things in (mesh files, Mitsuba scenes): the keys the user
left out, and only those (:data:`KEYS`), suggested by ray casting with Embree (:mod:`study.scene.placement`).

* ``reference.point``: of a 5³ grid inside the bounds, the free point (seeing some surface, at least half of its
  128 rays hitting one, clearance ≥ :data:`MIN_CLEARANCE` of the diagonal) of the highest rough clearance (the
  nearest hit of its rays) × enclosure² (the share of them that hit): in a closed room the point farthest from
  every surface, as ever; in a room with an open side (the Cornell box's front, a missing ceiling) a point away
  from the opening. No grid point qualifies (a single object seen from outside, :func:`_beside`): a point beside
  the bounds, level with their middle, half their largest extent away, on the side that sees most of them;
  where the object placed then hides from it behind a shape (:func:`_seeing`), a point around the object that
  sees it whole;
* ``object.radius``: a quarter of the reference point's clearance, at most 8 % of the bounds' diagonal;
  ``object.center``: a little below the reference point (on the camera's view axis, before the first surface
  it meets, where the scene has a camera: a Mitsuba sensor or a glTF camera), moved to the nearest free spot
  where the sphere touches nothing;
* the camera: the scene's own where it has one (Mitsuba sensor, glTF camera), with its eye, aim, up and field of
  view (the object on its axis, sized by :func:`_on_axis` to fill some of the frame; where the axis has no free spot,
  where that camera sees it whole, :mod:`study.scene.inview`; re-aimed at the object only where neither has one,
  said in the line); else, of the free eyes around the
  object (64 directions × distances of 3, 4 and 5.5 object radii and 1.75 × the clearance) that see it unblocked,
  aimed at the object (and, for an object seen from outside, also halfway to the bounds' middle), the one of the
  highest :func:`score` (:data:`WEIGHTS`): the object's share of the frame (counted up to :data:`FILL`; below
  :data:`MIN_OBJECT` ranks last), minus the void (pixels whose ray leaves the scene: the sky), the void the
  object mirrors, the tilt from level, plus a little for the reference point's side (:mod:`study.scene.framing`);
  the choice is one line (:attr:`Suggestion.line`, printed by ``study run``) naming the terms;
* the light, where ``[light]`` lights the environment: ``light.enabled`` is off when the file brings light of its
  own (emitters, emissive materials, punctual lights); else a point light at the centre of the bounds (0.6 ×
  the clearance above the reference point when the centre is not free, or is the reference point or the
  object) whose intensity scales with the squared diagonal of the bounds: 6 W/sr × (diag / 6.4 m)². The
  irradiance I / r² at walls a fixed fraction of the diagonal away is then the same as in the default
  4 m × 3 m × 4 m room (diagonal 6.4 m) with its 6 W/sr light. A flat scene (bounds thinner than :data:`FLAT`
  of their diagonal) has its light off its plane, half the diagonal away on the reference point's side.
  Where the file's own lights are weak (:mod:`study.scene.lights`), ``light.enabled`` is on beside them.
* :attr:`Suggestion.outside`: the object is seen from outside, placed by study; where the file and the user give
  no sky, :mod:`study.scene.schema` gives it the ``"studio"`` sky (:mod:`study.scene.sky`) to reflect.
"""

from __future__ import annotations

from typing import Any

import numpy as np

import study.scene.framing as framing
import study.scene.inview as inview
import study.scene.lights as lights
import study.scene.placement as placement
from study.errors import StudyError
from study.scene.environment import geometry
from study.scene.frame import DEFAULT_DIAGONAL
from study.scene.models import Camera
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
MIN_CLEARANCE = (
    0.05  # a reference point nearer than this share of the bounds' diagonal to a surface is no room's
)
DEFAULT_INTENSITY = 6.0  # W/sr, the default room's light


def light_intensity(lo, hi) -> float:
    """W/sr of the suggested point light: the default room's, times (diagonal / default diagonal)²."""
    return DEFAULT_INTENSITY * (float(np.linalg.norm(np.subtract(hi, lo))) / DEFAULT_DIAGONAL) ** 2


def _reference(env) -> tuple[np.ndarray, float, float]:
    """(point, clearance, enclosure) of the reference point: the free grid point scoring highest by its rough
    clearance × enclosure² (a closed room: the farthest from every surface, as ever; an open side: away from it);
    no grid point free (a single object seen from outside): a point beside it (:func:`_beside`)."""
    mesh, (lo, hi) = env.mesh, env.bounds
    g = np.linspace(0.15, 0.85, 5)
    grid = lo + (hi - lo) * np.stack(np.meshgrid(g, g, g, indexing="ij"), -1).reshape(-1, 3)
    d = placement.directions()
    t, _ = placement.cast(mesh, np.repeat(grid, len(d), 0), np.tile(d, (len(grid), 1)))
    t = t.reshape(len(grid), -1)
    hit = np.isfinite(t).mean(1)
    score = np.where(hit > 0, t.min(1), 0.0) * hit**2
    for i in np.argsort(-score, kind="stable"):
        if hit[i] < placement.ENCLOSED:
            continue  # open all round: in no room
        try:
            placement.check_reference(mesh, grid[i])
        except KeyedError:
            continue
        gap = placement.clearance(mesh, grid[i])
        if gap < MIN_CLEARANCE * float(np.linalg.norm(hi - lo)):
            continue  # a crevice of a model, not a room
        return grid[i], gap, float(hit[i])
    return _beside(env)


def _beside(env) -> tuple[np.ndarray, float, float]:
    """A single object (or a room open all round): the reference point beside it, level with its middle, half
    its largest extent away from its bounds, on the side that sees most of it (nearest the bounds' middle first)."""
    mesh, (lo, hi) = env.mesh, env.bounds
    mid, size = (lo + hi) / 2, float(np.max(hi - lo))
    up = np.asarray(env.sensor["up"] if env.sensor else (0.0, 1.0, 0.0), float)
    sides = [d for d in placement.directions(32) if abs(float(d @ up)) < 0.5] or list(
        placement.directions(32)
    )
    best = None
    for d in sides:
        reach = float(np.sum(np.abs(d) * (hi - lo) / 2))  # how far the bounds reach along d (their support)
        p = mid + d * (reach + 0.5 * size)
        try:
            placement.check_reference(mesh, p)
        except KeyedError:
            continue
        seen = placement.enclosure(mesh, p)
        if best is None or seen > best[2] + 1e-9:
            best = (p, placement.clearance(mesh, p), seen)
    if best is None:
        raise StudyError(
            "found no free point that sees the environment for the reference point; give "
            "reference.point, object.center and camera.eye yourself",
            key="environment",
        )
    return best


FLAT = (
    0.02  # bounds thinner than this share of their diagonal along one axis: a flat scene (its light off it)
)


def _on_axis(env, sensor, radius: float, diag: float, sized: bool) -> tuple[np.ndarray, float] | None:
    """(start, radius) of the object on the file camera's view axis: before the first surface the axis meets,
    nearest the bounds' middle (the bounds grown by a quarter of their diagonal: a flat scene has no inside);
    ``sized``: the radius the spot takes, grown to a quarter of the frame's half-width there (the object seen,
    not a dot), at most two thirds of the clearance, the spot the one where the object fills most of the frame.
    No free spot on the axis: None."""
    mesh, (lo, hi) = env.mesh, env.bounds
    eye, target = np.array(sensor["eye"], float), np.array(sensor["target"], float)
    axis = (target - eye) / np.linalg.norm(target - eye)
    t_hit = placement.cast(mesh, eye[None], axis[None])[0][0]  # the camera sees up to there
    far = min(2 * diag + np.linalg.norm(eye - (lo + hi) / 2), t_hit - 1.5 * radius)
    pts = eye + np.linspace(0, max(far, 0.0), 200)[1:, None] * axis
    grow = 0.25 * diag
    inside = [p for p in pts if np.all(p > lo - grow) and np.all(p < hi + grow)] or list(pts)
    gaps = {i: placement.clearance(mesh, p) for i, p in enumerate(inside)}
    ok = [i for i in gaps if gaps[i] > (0.0 if sized else 1.5 * radius)]
    if not ok:
        return None
    tan = np.tan(np.radians(float(sensor.get("fov", 45.0))) / 2)

    def fits(i):  # the radius that fits there (a quarter of the frame's half-width, or more), and its share
        t = max(float(np.linalg.norm(inside[i] - eye)), 1e-12)
        r = min(max(radius, 0.25 * t * tan), gaps[i] / 1.5, t / 3)
        return r, min(r / (t * tan), 0.25)

    mid = (lo + hi) / 2
    if sized:  # the largest share of the frame (to within 10 %), then nearest the middle
        ok = [i for i in ok if fits(i)[0] >= 0.1 * radius]  # not a dot at the eye itself
        if not ok:
            return None
        top = max(fits(i)[1] for i in ok)
        ok = [i for i in ok if fits(i)[1] >= 0.9 * top]
    i = min(ok, key=lambda i: np.linalg.norm(inside[i] - mid))
    return inside[i], (fits(i)[0] if sized else radius)


def _file_view(
    env, radius: float, diag: float, sized: bool, aspect: float
) -> tuple[np.ndarray, float] | None:
    """(start, radius) of the object in the file camera's view: on its axis (:func:`_on_axis`), else where that
    camera sees it whole (:func:`study.scene.inview.spot`); None where neither has a free spot."""
    got = _on_axis(env, env.sensor, radius, diag, sized)
    return got if got is not None else inview.spot(env, env.sensor, radius, sized, aspect)


def _seeing(env, centre, radius: float, best, gap: float, enclosed: float) -> tuple[np.ndarray, float, float]:
    """A reference point that sees the object whole, where the chosen one (``best``) does not: of free points
    around the object (32 directions × 3, 5 and 8 radii, and the chosen point's distance), the one of the highest
    clearance × enclosure² among those that see it unblocked; none: ``best`` as it was."""
    mesh = env.mesh
    dist = float(np.linalg.norm(np.asarray(best) - centre))
    found = None
    for d in placement.directions(32):
        for k in sorted({3.0 * radius, 5.0 * radius, 8.0 * radius, dist}):
            p = centre + d * k
            try:
                placement.check_reference(mesh, p)
            except KeyedError:
                continue
            if placement.sees(mesh, p, centre, radius) < 1.0:
                continue
            g, e = placement.clearance(mesh, p), placement.enclosure(mesh, p)
            if found is None or g * e * e > found[0]:
                found = (g * e * e, p, g, e)
    return (best, gap, enclosed) if found is None else found[1:]


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


#: Weights of the camera's score terms (:func:`_eye`): the object's share of the frame (up to :data:`FILL`), the
#: share of the frame that is void (primary rays that leave the scene), the share of the object's mirror image that
#: is void, the view's tilt from level, and the eye on the reference point's side.
WEIGHTS = {"object": 1.0, "void": 3.0, "mirrored_void": 0.5, "tilt": 0.25, "side": 0.1}
MIN_OBJECT = (
    0.05  # a camera that shows the object smaller than this share of the frame ranks below every other
)
FILL = 0.12  # the object's share of the frame beyond which a larger object scores no higher
DISTANCES = (
    3.0,
    4.0,
    5.5,
)  # eye distances tried, in object radii (and 1.75 × the reference point's clearance)


def _terms(env, eye, target, d, centre, radius, toward, up, fov) -> dict[str, float]:
    f = framing.numbers(env.mesh, eye, target, up, fov, 1, 1, centre, radius, n=24)
    return {
        "object": min(f["object"], FILL) / FILL,
        "void": f["void"],
        "mirrored_void": f["mirrored_void"],
        "tilt": abs(float(d @ up)),
        "side": float(d @ toward),
    }


def score(terms: dict[str, float]) -> float:
    """A candidate camera's score: the object's term and the side's count for it, the others against it."""
    sign = {"object": 1.0, "side": 1.0}
    return sum(sign.get(k, -1.0) * WEIGHTS[k] * v for k, v in terms.items())


def _eye(env, centre, radius, best, gap, up, fov, targets) -> tuple[np.ndarray, np.ndarray, str]:
    """The camera's eye and target: of the free spots around the object (64 directions × :data:`DISTANCES`) that
    see it unblocked, each aimed at each of ``targets``, the one of the highest :func:`score`; none sees it whole:
    the one that sees most of it, aimed at the object. Also the line that says why (the terms, named)."""
    mesh = env.mesh
    toward = best - centre
    toward = toward / (np.linalg.norm(toward) or 1)
    dists = sorted({max(1.75 * gap, 3.0 * radius)} | {k * radius for k in DISTANCES})
    chosen, fallback, n = None, None, 0
    for d, dist in ((d, dist) for d in placement.directions(64) for dist in dists):
        for target in targets:
            eye = centre + d * dist
            try:
                placement.check_free(mesh, eye, "camera.eye")
            except KeyedError:
                continue
            if placement.clearance(mesh, eye) < 0.05 * dist:
                continue
            seen = placement.sees(mesh, eye, centre, radius)
            if seen < 1.0:
                if fallback is None or seen > fallback[0]:
                    fallback = (seen, eye)
                continue
            if np.linalg.norm(np.cross(target - eye, up)) < 1e-9 * dist:
                continue  # looking straight up or down: no up vector
            terms = _terms(env, eye, target, d, centre, radius, toward, up, fov)
            n += 1
            rank = (terms["object"] * FILL >= MIN_OBJECT, score(terms))  # the object framed first
            if chosen is None or rank > chosen[0]:
                chosen = (rank, eye, target, terms)
    if chosen is not None:
        (_, sc), eye, target, terms = chosen
        named = " ".join(f"{k} {v:.2f}×{WEIGHTS[k]:g}" for k, v in terms.items())
        return (
            eye,
            target,
            f"camera scored {sc:.2f} ({named}; best of {n} candidates seeing the object whole)",
        )
    if fallback is None:
        raise StudyError(
            "found no free spot for the camera around the object; give camera.eye yourself", key="environment"
        )
    return fallback[1], centre, f"camera sees {100 * fallback[0]:.0f} % of the object (no spot sees it whole)"


def _want(given: dict, k: str) -> bool:
    return k not in given


def _light(env, given: dict, centre, radius: float, best, gap: float, up) -> dict[str, Any]:
    """The point light's keys the user left out, where ``[light]`` lights the environment."""
    mesh, (lo, hi) = env.mesh, env.bounds
    out: dict[str, Any] = {}
    if not env.point_light:
        return out
    if _want(given, "light.enabled"):
        weak = env.lit and lights.weak(env, light_intensity(lo, hi))
        out["light.enabled"] = not env.lit or weak or any(k.startswith("light.") for k in given)
    if _want(given, "light.position"):
        c = (lo + hi) / 2
        try:
            placement.check_free(mesh, c, "light.position")
            if np.linalg.norm(c - centre) <= 1.5 * radius or np.linalg.norm(c - best) < 0.3 * gap:
                raise KeyedError("light.position", "in the object or at the reference point")
        except KeyedError:
            c = best + up / np.linalg.norm(up) * 0.6 * gap
        ext = hi - lo
        diag = float(np.linalg.norm(ext))
        flat = int(np.argmin(ext))
        if ext[flat] <= FLAT * diag:  # a flat scene: off its plane, on the reference point's side
            side = np.sign(best[flat] - (lo[flat] + hi[flat]) / 2) or 1.0
            c = np.array((lo + hi) / 2, float)
            c[flat] += side * 0.5 * diag
            c += (
                0.25 * diag * up / np.linalg.norm(up) * (abs(up[flat]) < 0.9)
            )  # and above it, lighting at a slant
        out["light.position"] = np.asarray(c, float).tolist()
    if _want(given, "light.intensity"):
        out["light.intensity"] = [light_intensity(lo, hi)] * 3
    return out


class Suggestion(dict):
    """Dotted scene keys → suggested values, and :attr:`line`: the choice in one line, its score terms named."""

    line: str = ""
    outside: bool = False  # the reference point stands outside the geometry: an object seen from outside


def suggest(env, given: dict[str, Any] | None = None) -> Suggestion:
    """Dotted scene keys → values for the placement keys (:data:`KEYS`) missing from ``given`` (the user's),
    in the environment ``env`` (:class:`~study.scene.environment.EnvGeometry`)."""
    given = dict(given or {})
    mesh, (lo, hi) = env.mesh, env.bounds
    diag = float(np.linalg.norm(hi - lo))
    out = Suggestion()
    why, target = "", None

    def want(k: str) -> bool:
        return k not in given

    if want("reference.point"):
        best, gap, enclosed = _reference(env)
        out["reference.point"] = best.tolist()
    else:
        best = np.asarray(given["reference.point"], float)
        placement.check_reference(mesh, best)  # the user's: checked first
        gap, enclosed = placement.clearance(mesh, best), placement.enclosure(mesh, best)
    radius = float(given.get("object.radius", min(0.25 * gap, 0.08 * diag)))
    if want("object.radius"):
        out["object.radius"] = radius
    up = np.asarray(given.get("camera.up", env.sensor["up"] if env.sensor else (0.0, 1.0, 0.0)), float)
    size = {f"camera.{k}": Camera.model_fields[k].default for k in ("width", "height")}
    out.update(inview.frame_size(env.sensor if want("camera.eye") else None, given, tuple(size.values())))
    aspect = inview.aspect(*({**size, **given, **out}[k] for k in size))
    if want("object.center"):
        start = best - up / np.linalg.norm(up) * 0.45 * gap
        if env.sensor is not None and want(
            "camera.eye"
        ):  # onto the file camera's view axis, else into its view
            start, radius = _file_view(env, radius, diag, want("object.radius"), aspect) or (start, radius)
            if want("object.radius"):
                out["object.radius"] = radius
        centre = _free_centre(mesh, start, radius, best)
        out["object.center"] = centre.tolist()
        if want("reference.point") and placement.sees(mesh, best, centre, radius) < 1.0:
            best, gap, enclosed = _seeing(env, centre, radius, best, gap, enclosed)
            out["reference.point"] = best.tolist()
    else:
        centre = np.asarray(given["object.center"], float)
        placement.check_object(mesh, centre, radius, f"object (bounding radius {radius:g})")
    if want("camera.up"):
        out["camera.up"] = up.tolist()
    if want("camera.eye"):
        if env.sensor is not None:
            out["camera.eye"] = list(env.sensor["eye"])
        else:
            fov = float(given.get("camera.fov", Camera.model_fields["fov"].default))
            targets = [centre]
            if want("camera.target") and enclosed < placement.ENCLOSED:  # an object seen from outside: both
                targets.append(centre + 0.5 * ((lo + hi) / 2 - centre))
            eye, target, why = _eye(env, centre, radius, best, gap, up / np.linalg.norm(up), fov, targets)
            out["camera.eye"] = eye.tolist()
    if want("camera.target"):  # the file's camera aims where the file says (at the object outside its view)
        aim = env.sensor["target"] if env.sensor is not None and want("camera.eye") else None
        if aim is not None and want("object.center") and inview.margin(env.sensor, centre, aspect) < radius:
            aim = None  # no free spot in the file camera's view: aimed at the object
            why = "the file's camera re-aimed at the object (no free spot in its view)"
        out["camera.target"] = (
            list(aim) if aim is not None else (target if target is not None else centre).tolist()
        )
    if want("camera.fov") and env.sensor is not None and want("camera.eye"):  # the file's view, whole
        out["camera.fov"] = env.sensor["fov"]
    out.update(_light(env, given, centre, radius, best, gap, up))
    # a single object seen from outside, placed by study (a sky it can reflect): not where the user placed things
    out.outside = enclosed < placement.ENCLOSED and want("reference.point") and want("object.center")
    fmt = lambda v: "(" + ", ".join(f"{x:.3g}" for x in v) + ")"  # noqa: E731
    out.line = (
        f"placement: reference point {fmt(best)} (enclosure {enclosed:.2f}, clearance {gap:.3g}), object "
        f"{fmt(centre)} radius {radius:.3g}, camera eye {fmt(out.get('camera.eye', given.get('camera.eye', ())))}"
        + (
            f"; {why}"
            if why
            else "; the file's camera" + (" (its frame's aspect)" if {*size} & {*out} else "")
            if env.sensor is not None and want("camera.eye")
            else ""
        )
    )
    return out


def suggest_placement(scene: Any, given: dict[str, Any] | None = None) -> Suggestion:
    """Where to put things in an environment nobody placed them in (:func:`suggest`): dotted overrides for the
    placement keys missing from ``given`` (the user's dotted keys → values). ``scene`` is a scene or an environment
    alone (a mesh or Mitsuba source, as :func:`study.scene.environment.geometry` takes)."""
    return suggest(geometry(scene), given)
