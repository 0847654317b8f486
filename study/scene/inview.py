"""Where the object goes in a file camera's view when the camera's axis has no free spot for it (a chase camera
whose vehicle fills the middle of the frame, as VC.glb's first camera): the camera keeps the file's eye, aim, up
and field of view, and the object goes where that camera sees it whole (:mod:`study.scene.autoplace`).

Of the points seen through a :data:`VIEW_GRID`² grid over the central :data:`SPAN` of the frame, at :data:`STEPS`
distances up to the first surface each ray meets (within the bounds grown by a quarter of their diagonal), the
spot of a sphere that lies whole inside the frame (on the inner side of the four planes through the eye and the
frame's edges), in free space (clear of every triangle by :data:`GAP` radii,
:func:`study.scene.placement.check_free`) and unoccluded from the eye (:func:`unblocked`: rays to 1024 points of
its near half), filling the largest share of the frame's half-width (at most :data:`VIEW_FILL`; at least
:data:`MIN_SHARE`), to within 10 %, then the largest (up to the radius asked for: the object at the scene's scale,
not a bead at the eye), then nearest the frame's centre. A sphere sized to its spot is at least :data:`MIN_SIZE`
of the radius asked for.
"""

from __future__ import annotations

import numpy as np

import study.scene.placement as placement
from study.validation import KeyedError

VIEW_GRID = 9  # image-plane points per side
SPAN = 0.8  # share of the frame's half-width and half-height the grid spans
STEPS = 12  # distances along each ray, as fractions of its free length
VIEW_FILL = (
    0.25  # the sphere's radius at most this share of the frame's half-width where it stands (as on the axis)
)
MIN_SHARE = 0.05  # a sphere smaller than this share of the frame's half-width is a dot: not placed
GAP = 1.25  # the sphere's clearance from every triangle, in radii (more than autoplace._free_centre's 1.2)
MIN_SIZE = 0.1  # a sized sphere's radius at least this share of the radius asked for (not a speck at the eye)


def aspect(width, height) -> float:
    """height / width of the frame; 1 where either is not a positive number (their own validation says so)."""
    try:
        a = float(height) / float(width)
    except (TypeError, ValueError, ZeroDivisionError):
        return 1.0
    return a if np.isfinite(a) and a > 0 else 1.0


def frame_size(sensor: dict | None, given: dict, default: tuple[int, int]) -> dict[str, int]:
    """``camera.width`` or ``camera.height``, where the user left one or both out, at the file camera's aspect (its
    ``fov`` is horizontal: the vertical one is then the file's too): the width given (else ``default``'s) and the
    height at that ratio, or the width at the ratio of the height given; nothing where both are given or the file
    has no frame size (or no camera: None), or the size left out is the default anyway. Sizes that are not
    numbers are left to their own validation."""
    W, H = (sensor.get("width"), sensor.get("height")) if sensor else (None, None)
    if not W or not H or ("camera.width" in given and "camera.height" in given):
        return {}
    ratio = float(sensor.get("aspect") or W / H)  # width / height: a glTF camera's aspectRatio, exact
    try:
        if "camera.height" in given:
            k, v = "camera.width", float(given["camera.height"]) * ratio
        else:
            k, v = "camera.height", float(given.get("camera.width", default[0])) / ratio
        v = int(min(max(round(v), 8), 4096))
    except (TypeError, ValueError, OverflowError):
        return {}
    return {} if v == default[k == "camera.height"] else {k: v}  # as it would be anyway: nothing


def basis(sensor: dict) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(eye, forward, right, up) of a file camera: right = forward × up, as Mitsuba's look_at."""
    eye = np.asarray(sensor["eye"], float)
    f = np.asarray(sensor["target"], float) - eye
    f /= np.linalg.norm(f)
    r = np.cross(f, np.asarray(sensor["up"], float))
    r /= np.linalg.norm(r)
    return eye, f, r, np.cross(r, f)


def margin(sensor: dict, centre, aspect: float) -> float:
    """How far inside the frame's four edge planes ``centre`` lies (a sphere of a smaller radius is seen whole by
    the camera, ``aspect`` = height / width; the file's ``fov`` is horizontal); negative outside the frame."""
    eye, f, r, u = basis(sensor)
    tx = np.tan(np.radians(float(sensor["fov"])) / 2)
    ty = tx * aspect
    c = np.asarray(centre, float) - eye
    x, y, z = c @ r, c @ u, c @ f
    return float(min((z * tx - abs(x)) / np.hypot(1, tx), (z * ty - abs(y)) / np.hypot(1, ty)))


def _exit(eye, d: np.ndarray, lo, hi) -> np.ndarray:
    """Distance along each ray (eye, d) to where it leaves the box lo..hi (eye inside or not: 0 where it never
    enters)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        a, b = (lo - eye) / d, (hi - eye) / d
    near, far = np.nanmax(np.minimum(a, b), axis=1), np.nanmin(np.maximum(a, b), axis=1)
    return np.where(near <= far, np.maximum(far, 0.0), 0.0)


def unblocked(mesh, eye, centre, radius: float, n: int = 1024) -> bool:
    """Whether the rays from ``eye`` to ``n`` points spread over the sphere's half that faces it all reach the
    sphere before any triangle: seen whole, no pole or wire in front (denser than :func:`placement.sees`)."""
    eye, centre = np.asarray(eye, float), np.asarray(centre, float)
    pts = centre + radius * placement.directions(n)
    pts = pts[(pts - centre) @ (eye - centre) > 0]
    d = pts - eye
    dist = np.linalg.norm(d, axis=1)
    t, _ = placement.cast(mesh, np.broadcast_to(eye, d.shape), d / dist[:, None])
    return bool(np.all(t >= dist * (1 - 1e-6)))


def spot(env, sensor: dict, radius: float, sized: bool, aspect: float) -> tuple[np.ndarray, float] | None:
    """(centre, radius) of the object in the file camera's view (module docstring); ``sized``: the radius the spot
    takes (at least :data:`MIN_SIZE` of ``radius``; else ``radius`` must fit there). None where no spot qualifies."""
    mesh, (lo, hi) = env.mesh, env.bounds
    grow = 0.25 * float(np.linalg.norm(hi - lo))
    eye, f, r, u = basis(sensor)
    tx = np.tan(np.radians(float(sensor["fov"])) / 2)
    g = np.linspace(-SPAN, SPAN, VIEW_GRID)
    X, Y = (v.ravel() for v in np.meshgrid(g * tx, g * tx * aspect))
    d = f + X[:, None] * r + Y[:, None] * u
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    t_hit, _ = placement.cast(mesh, np.broadcast_to(eye, d.shape), d)
    free = np.minimum(t_hit, _exit(eye, d, lo - grow, hi + grow))
    cands = []
    for i in range(len(d)):
        if not np.isfinite(free[i]) or free[i] <= 0:
            continue
        for k in np.geomspace(0.02, 0.9, STEPS):
            t = k * free[i]
            c = eye + t * d[i]
            bound = min(VIEW_FILL * t * tx, margin(sensor, c, aspect), (t_hit[i] - t) / GAP, t / 3)
            if bound < (MIN_SIZE * radius if sized else radius):
                continue
            size = bound if sized else radius
            if size / (t * tx) >= MIN_SHARE:
                cands.append((size / (t * tx), float(np.hypot(X[i] / tx, Y[i] / tx)), t, c, size))
    cands.sort(key=lambda c: -c[0])
    found: list[tuple[float, float, float, np.ndarray, float]] = []
    for share, off, t, c, size in cands:
        if found and share < 0.9 * max(x[0] for x in found):
            break  # no spot left can reach the top's 90 %
        gap = placement.clearance(mesh, c)
        if sized:
            size = min(size, gap / GAP)
        elif gap <= GAP * size:
            continue
        if size / (t * tx) < MIN_SHARE or size < MIN_SIZE * radius:
            continue
        try:
            placement.check_free(mesh, c, "object.center")
        except KeyedError:
            continue
        if not unblocked(mesh, eye, c, size):
            continue
        found.append((size / (t * tx), off, t, c, size))
    if not found:
        return None
    top = max(x[0] for x in found)
    best = min((x for x in found if x[0] >= 0.9 * top), key=lambda x: (-min(x[4], radius), x[1]))
    return best[3], best[4]
