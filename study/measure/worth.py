"""Whether a run's picture is worth looking at: what a reader would complain about, measured, and the one line
that names the cause and the key to change.

=====================  =========================================================================================
``black_share``        share of Mitsuba's picture (with the object) that shows black: luminance under
                       :data:`BLACK` after its exposure (:func:`study.measure.exposure.auto_exposure`, at most
                       :data:`MAX_BOOST` EV brighter: a picture that needs more is unlit, and shows black)
``clipped_share``      share of it above 1 after that exposure (white)
``object_share``       share of the frame fully on the object (the pixels every column is measured on)
``mirrored_void``      share of the object's rays whose exact hit leaves the scene: the object mirrors the void
``reference_seen``     share of the object's bounding sphere the reference point sees unblocked
                       (:func:`study.scene.placement.sees`): the impostor is captured from there
=====================  =========================================================================================

Each has a limit (:data:`WORTH_LIMITS`); :func:`verdict` names the first that fails, with its number, its cause and
the key to change, in one line, and ``study run`` prints it as a note (:func:`study.measure.lighting.notes`).

A case whose every object ray leaves the scene where no sky shows (``mirrored_void`` 1) cannot be measured: there
is no surface to find, every method is trivially right and the object black in every image. :func:`refuse_void`
refuses it before anything is rendered, in one line naming why (a StudyError: exit 2).
"""

from __future__ import annotations

import math

import numpy as np

from study.errors import StudyError
from study.measure.exposure import auto_exposure, luminance

BLACK = 0.002  # linear luminance after exposure under which a pixel shows black (about 12/255 in sRGB)
MAX_BOOST = 8.0  # EV: the most the exposure brightens a picture before it counts as unlit

#: column → (limit, "above"/"below": where it fails, cause, the key to change)
WORTH_LIMITS = {
    "black_share": (
        0.5,
        "above",
        "Mitsuba's picture is {v:.0%} black",
        "light (light.position, light.intensity, light.enabled) or environment.sky",
    ),
    "object_share": (
        0.02,
        "below",
        "the object fills {v:.1%} of the frame",
        "camera.eye, camera.fov or object.radius (or camera.frame_object = true)",
    ),
    "mirrored_void": (
        0.5,
        "above",
        "the object mirrors the void in {v:.0%} of its rays",
        "environment.sky (a sky it can reflect) or object.center",
    ),
    "reference_seen": (
        0.5,
        "below",
        "the reference point sees {v:.0%} of the object",
        "reference.point (a point that sees the object)",
    ),
    "clipped_share": (
        0.1,
        "above",
        "{v:.0%} of Mitsuba's picture is clipped white",
        "light.intensity",
    ),
}


def worth_columns(
    scene, mitsuba: np.ndarray, mask: np.ndarray, escapes: np.ndarray, points: np.ndarray | None = None
) -> dict[str, float]:
    """The numbers of the module docstring for one case: Mitsuba's picture ``mitsuba`` (H, W, 3), the object's
    pixels ``mask`` (H, W), its rays' ``escapes`` (K,) and exact hits ``points`` (K, 3; :func:`own_shadow`)."""
    from study.scene.placement import sees

    lum = luminance(np.nan_to_num(np.asarray(mitsuba, float)))
    ev = auto_exposure(mitsuba)
    shown = lum * 2.0 ** min(ev if ev is not None else 0.0, MAX_BOOST)
    with np.errstate(invalid="ignore", divide="ignore"):  # a reference point at the object's centre: NaN
        seen = sees(scene.mesh(), scene.reference.point, scene.object.center, scene.object.radius)
    esc = np.asarray(escapes, bool) & ~shows_sky(scene)  # under a sky, a ray that leaves the scene shows it
    return {
        "black_share": float(np.mean(shown < BLACK)),
        "clipped_share": float(np.mean(shown > 1.0)),
        "object_share": float(np.mean(np.asarray(mask, bool))),
        "mirrored_void": float(esc.mean()) if esc.size else math.nan,
        "reference_seen": seen,
        "own_shadow": own_shadow(scene, points, escapes) if points is not None else math.nan,
    }


def own_shadow(scene, points: np.ndarray, escapes: np.ndarray) -> float:
    """Share of the object's rays whose exact hit lies in the object's own shadow from the point light (the
    segment from the hit to ``light.position`` crosses the object's bounding sphere): there Mitsuba's render
    with the object is darker than truth_at_hit, which is taken without it (the object's shadow is light no
    method models). NaN where the point light is not rendered or no ray hits."""
    if not scene.lamp():
        return math.nan
    p = np.asarray(points, float)[~np.asarray(escapes, bool)]
    if not len(p):
        return math.nan
    c, r = np.asarray(scene.object.center, float), float(scene.object.radius)
    d = np.asarray(scene.light.position, float) - p  # hit → light
    t = np.clip(np.einsum("ij,ij->i", c - p, d) / np.maximum(np.einsum("ij,ij->i", d, d), 1e-30), 0.0, 1.0)
    return float(np.mean(np.linalg.norm(p + t[:, None] * d - c, axis=1) < r))


def refuse_void(scene, escapes: np.ndarray, case: str = "") -> None:
    """Refuse a case whose every object ray leaves the scene with no sky to show (module docstring)."""
    esc = np.asarray(escapes, bool)
    if esc.size and esc.all() and not shows_sky(scene):
        where = f" (case {case})" if case else ""
        raise StudyError(
            f"every one of the object's {esc.size} rays leaves the scene and no sky shows there{where}: no surface "
            "to find, nothing to measure (every method trivially right, the object black); move object.center "
            "(or the camera) so that the object reflects the environment's surfaces, or give environment.sky",
            key="object.center",
        )


def shows_sky(scene) -> bool:
    """Whether rays that leave the scene see something: a sky given (not black), or the file's own emitter at
    infinity (a Mitsuba ``envmap``, ``constant``)."""
    from study.scene.environment import geometry
    from study.scene.sky import sky_radiance

    given = getattr(scene.environment, "sky", None)
    if given is not None:
        rgb = sky_radiance(given)
        return rgb is None or any(rgb)
    m = [type(e).__name__.lower() + str(e) for e in geometry(scene).emitters]
    return any(("envmap" in t or "constant" in t) for t in (x.lower() for x in m))


def failures(values: dict) -> list[str]:
    """'cause: change key' for each number of ``values`` past its limit, in the order of :data:`WORTH_LIMITS`."""
    out = []
    for k, (limit, side, cause, key) in WORTH_LIMITS.items():
        v = values.get(k, math.nan)
        if isinstance(v, int | float) and math.isfinite(v) and (v > limit if side == "above" else v < limit):
            out.append(
                f"{cause.format(v=v)} ({'over' if side == 'above' else 'under'} {limit:g}): change {key}"
            )
    return out


def verdict(values: dict) -> str:
    """One line saying the picture is not worth looking at, and why (every cause, the first first); '' where it
    is."""
    bad = failures(values)
    return ("the picture is not worth looking at: " + "; ".join(bad)) if bad else ""
