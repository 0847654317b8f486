"""The frame a scene is measured in: a mesh file in millimetres, kilometres or 10⁵ units from the origin measures
what the same file measures in metres at the origin.

Everything the float32 methods and renderers see (Embree, Mitsuba, the cube maps, the 1 cm floor of the wrong-hit
tolerance, :data:`study.measure.outcomes.EPS_FIXED`) assumes a room of metres near the origin: far from it, float32
positions lose the room's detail (at 10⁵ units one float32 step is 8 mm); a room of 4 mm sits inside the 1 cm
tolerance; a room of 10⁵ m lies beyond Mitsuba's far clip. So an environment whose bounds' diagonal ``D`` lies
outside [:data:`SMALL`, :data:`LARGE`] is **rescaled** by the power of ten that brings it nearest the default
room's 6.4 m (``s = 10^round(log10(6.4 / D))``: a file in millimetres is read in metres, one in kilometres too),
and one whose bounds' centre lies more than :data:`FAR_DIAGONALS` diagonals from the origin is **recentred** by
that centre rounded to the power of ten above the diagonal (a room 10⁵ m away comes back to where it was drawn). A point
``x`` of the file is then measured at ``s·(x − c)`` (:func:`apply`); every length scales by ``s``, a point light's
intensity (W/sr) by ``s²`` (so that irradiance I/r² at the walls, and the picture, stay the same).

Mesh environments are moved by their own ``scale`` and ``translate`` (:func:`mesh_keys`), so the triangles are
computed in float64 and only then stored as float32. Mitsuba scenes are not moved (their emitters and sensors are
Mitsuba's): one out of range is refused in one line naming float precision (:func:`refusal`).
"""

from __future__ import annotations

import math

import numpy as np

SMALL, LARGE = 1.0, 100.0  # diagonals (scene units) measured as they are; outside: rescaled by a power of ten
FAR_DIAGONALS = 10.0  # a centre more than this many diagonals from the origin is recentred
DEFAULT_DIAGONAL = float(np.linalg.norm([4.0, 3.0, 4.0]))  # the default room's, m (automatic placement's too)

#: Scene keys that are points (moved and scaled), lengths (scaled) and radiant intensities (scaled by s²).
POINTS = ("reference.point", "object.center", "camera.eye", "camera.target", "light.position")
LENGTHS = ("object.radius",)
INTENSITIES = ("light.intensity",)


def choose(lo, hi) -> tuple[float, np.ndarray]:
    """(s, c) of the measuring frame of bounds (``lo``, ``hi``): s = 1 and c = 0 for a room of metres near the
    origin (module docstring)."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    diag = float(np.linalg.norm(hi - lo))
    if not (np.isfinite(diag) and diag > 0):
        return 1.0, np.zeros(3)
    s = 1.0
    if not SMALL <= diag <= LARGE:
        s = 10.0 ** round(math.log10(DEFAULT_DIAGONAL / diag))
    mid = (lo + hi) / 2
    c = np.zeros(3)
    if float(np.linalg.norm(mid)) > FAR_DIAGONALS * diag:
        q = 10.0 ** math.ceil(math.log10(diag))
        c = np.round(mid / q) * q
    return float(s), c


def identity(s: float, c) -> bool:
    return s == 1.0 and not np.any(np.asarray(c, float))


def apply(key: str, value, s: float, c):
    """``value`` of the dotted scene ``key`` in the measuring frame (s, c); other keys unchanged."""
    if key in POINTS:
        return (s * (np.asarray(value, float) - c)).tolist()
    if key in LENGTHS:
        return s * float(value)
    if key in INTENSITIES:
        return (s * s * np.asarray(value, float)).tolist()
    if key == "reference.box" and value is not None:
        return [(s * (np.asarray(p, float) - c)).tolist() for p in value]
    return value


def user_updates(updates: dict, s: float, c) -> dict:
    """A user's dotted-key ``updates`` of a loaded scene (file units and coordinates: ``--set``, ``[overrides]``,
    sweep axes, API keywords) in its measuring frame (s, c), as loading the file with them would measure them;
    unchanged where the frame is the file's, where the environment itself is updated, or for a value that is not
    a number (the key's own validation says so)."""
    if identity(s, c) or any(k.startswith("environment") for k in updates):
        return updates
    out = {}
    for k, v in updates.items():
        try:
            out[k] = apply(k, v, s, np.asarray(c, float))
        except (TypeError, ValueError):
            out[k] = v
    return out


def mesh_keys(env: dict, s: float, c) -> dict:
    """A mesh environment's table moved into the measuring frame: x' = s·(M x + t − c), so its ``scale`` is
    multiplied by s and its ``translate`` becomes s·(t − c)."""
    t = np.asarray(env.get("translate", (0.0, 0.0, 0.0)), float)
    return {**env, "scale": float(env.get("scale", 1.0)) * s, "translate": (s * (t - c)).tolist()}


def units_note(lo, hi, s: float, c) -> str:
    """The run's note: how the environment was moved ('' where it was not)."""
    if identity(s, c):
        return ""
    fmt = lambda v: "(" + ", ".join(f"{x:.6g}" for x in v) + ")"  # noqa: E731
    diag = float(np.linalg.norm(np.subtract(hi, lo)))
    moved = []
    if np.any(c):
        moved.append(f"recentred by {fmt(c)}")
    if s != 1.0:
        moved.append(f"rescaled by {s:g}")
    return (
        f"units: the environment spans {fmt(lo)}..{fmt(hi)} (diagonal {diag:.3g}); it is measured "
        f"{' and '.join(moved)} (x → {s:g}·(x − c)) so that float32 positions, Mitsuba's clip planes and the "
        "1 cm tolerance hold; positions and lengths in the table and keys are in that frame"
    )


#: A Mitsuba scene (not moved) is measured where its diagonal lies in this range and its centre within
#: :data:`MITSUBA_FAR` diagonals of the origin; else refused (:func:`refusal`).
MITSUBA_RANGE, MITSUBA_FAR = (0.1, 10000.0), 100.0


def refusal(lo, hi) -> str:
    """Why a Mitsuba scene (not moved by study) cannot be measured where it lies ('' where it can)."""
    diag = float(np.linalg.norm(np.subtract(hi, lo)))
    mid = (np.asarray(lo, float) + np.asarray(hi, float)) / 2
    (a, b), far = MITSUBA_RANGE, MITSUBA_FAR
    if a <= diag <= b and float(np.linalg.norm(mid)) <= far * diag:
        return ""
    return (
        f"the scene's bounds (diagonal {diag:.3g}, centre {float(np.linalg.norm(mid)):.3g} from the origin) lie "
        f"outside what float32 renderers measure faithfully (a diagonal in [{a:g}, {b:g}] units within "
        f"{far:g} diagonals of the origin; study does not move Mitsuba scenes): scale or move the XML's shapes, or "
        "export the geometry as a mesh file (moved for you)"
    )
