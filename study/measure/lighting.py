"""What a run says about its light and its samples: the file's own lights against study's point light, a picture
that is mostly fireflies, and a truth too noisy to rank the methods by.

* ``own_light_share`` (:func:`light_columns`): :func:`study.scene.lights.own_share` of the environment against
  the point light automatic placement suggests; under :data:`study.scene.lights.WEAK_SHARE` the file's lights are
  weak and study's point light is rendered beside them (unless ``light.enabled`` was given): :func:`notes` says so.
* fireflies: ``firefly_fraction`` (:mod:`study.measure.exposure`) over
  :data:`study.measure.exposure.FIREFLY_LIMIT` labels the picture.
* the truth's noise: ``truth_noise_relmse`` over :data:`REFERENCE_NOISE_SHARE` of the best method's
  ``relmse_truth_exposed`` (the reference's own noise is then a quarter or more of the smallest error it is to
  tell apart) labels the ranking, with the ``render.spp`` that would bring it under (the noise's relMSE falls as
  1/spp).
* a black reference (:func:`black_note`): Mitsuba's render shows no light at all (``firefly_fraction`` is NaN: no
  pixel above 0), or the truth is black on the object (every row's relMSE after exposure and the truth's noise
  0). Every error is then 0 and ranks nothing; the note says why, by the keys that light a scene (``light.enabled``,
  ``light.position``, ``environment.sky``), instead of a noise share of 0/0 (which asked for
  ``render.spp ≥ inf``).
* an exact row that is not the exact image (:mod:`study.measure.exact_rows`): a stand-in beats ``traced`` or
  ``traced_glossy`` on a column that measures the method (a glass object's rays through its distance map, a rough
  object's lobe samples); the line names the row, the columns and the cause.

:func:`notes` returns these as lines: ``study run`` prints them, and the run's page, ``index.json`` and viewer
title carry them (:mod:`study.outputs.run_files`).
"""

from __future__ import annotations

import math

import numpy as np

from study.measure import exact_rows, worth
from study.measure.exposure import FIREFLY_LIMIT, FIREFLY_STEP
from study.measure.truth import NOISE_SHARE
from study.scene import lights
from study.tables import REFERENCE_ROWS

#: The truth's own noise (relMSE after exposure, a squared unit) may be at most this share of the best method's
#: error: σ at most a third of the error (:data:`study.measure.truth.NOISE_SHARE`, Whittle et al. 2017), squared.
REFERENCE_NOISE_SHARE = NOISE_SHARE**2


def light_columns(scene) -> dict[str, float]:
    """``own_light_share`` of the scene's environment (NaN for the box, and where the file has no light)."""
    from study.scene.autoplace import light_intensity
    from study.scene.environment import geometry

    env = geometry(scene)
    if not env.point_light or env.bounds is None:
        return {"own_light_share": math.nan}
    return {"own_light_share": lights.own_share(env, light_intensity(*env.bounds))}


def _first(rows: list[dict], col: str) -> float:
    v = [float(r[col]) for r in rows if isinstance(r.get(col), int | float) and math.isfinite(r[col])]
    return v[0] if v else math.nan


def light_note(rows: list[dict], scene) -> str:
    """The weak-light line ('' where the file's lights are not weak or not judged)."""
    share = _first(rows, "own_light_share")
    if not share < lights.WEAK_SHARE:
        return ""
    head = (
        f"the file's own lights are weak: {share:.2%} of the power of study's point light (under "
        f"{lights.WEAK_SHARE:.0%})"
    )
    if scene.lamp():
        i, p = scene.light.intensity, ", ".join(f"{v:.3g}" for v in scene.light.position)
        return (
            f"{head}; study's point light is added beside them ({max(i):.3g} W/sr at ({p})); light.enabled=false "
            "leaves it out"
        )
    return f"{head}, and study's point light is off (light.enabled = false): expect a dark, noisy render"


def firefly_note(rows: list[dict], spp: int) -> str:
    """The firefly label ('' where the picture passes :data:`~study.measure.exposure.FIREFLY_LIMIT`)."""
    f = _first(rows, "firefly_fraction")
    if not f > FIREFLY_LIMIT:
        return ""
    return (
        f"the picture shows fireflies: {f:.1%} of Mitsuba's pixels differ between its two seeds by more than "
        f"{FIREFLY_STEP:g} of the display range (limit {FIREFLY_LIMIT:.0%})"
        + (f"; raise render.spp (now {spp})" if spp else "")
    )


def noise_note(rows: list[dict], spp: int) -> str:
    """The reference-noise label ('' where the truth's noise is under :data:`REFERENCE_NOISE_SHARE` of the best
    method's relMSE after exposure)."""
    noise = _first(rows, "truth_noise_relmse")
    errs = [r.get("relmse_truth_exposed", math.nan) for r in rows if r.get("label") not in REFERENCE_ROWS]
    errs = np.array([e for e in errs if isinstance(e, int | float)], float)
    if not (np.isfinite(errs).any() and noise == noise):
        return ""
    best = float(np.nanmin(errs))
    if not best > 0:  # a method equal to the truth (a black one, :func:`black_note`): no share to state
        return ""
    share = noise / best
    if not share > REFERENCE_NOISE_SHARE:
        return ""
    need = math.ceil(spp * share / REFERENCE_NOISE_SHARE)
    return (
        f"the truth's own noise is {share:.0%} of the best method's relMSE after exposure (limit "
        f"{REFERENCE_NOISE_SHARE:.0%}): differences under it are the reference's noise"
        + (f"; render.spp ≥ {need} (now {spp}) would bring it under" if spp else "")
    )


def black_note(rows: list[dict], scene) -> str:
    """The black-reference line ('' where Mitsuba's render shows light on the object): a render with no pixel
    above 0 (``firefly_fraction`` NaN in every row that has it), or a truth black on the object (every row's
    ``relmse_truth_exposed`` and ``truth_noise_relmse`` 0), with the reason the scene's keys give."""
    ff = [r["firefly_fraction"] for r in rows if isinstance(r.get("firefly_fraction"), int | float)]
    frame = bool(ff) and all(math.isnan(v) for v in ff)
    errs = [r.get("relmse_truth_exposed") for r in rows] + [r.get("truth_noise_relmse") for r in rows]
    nums = [e for e in errs if isinstance(e, int | float) and not math.isnan(e)]
    on_object = bool(nums) and all(e == 0 for e in nums)
    if not (frame or on_object):
        return ""
    what = (
        "Mitsuba's reference is black: no pixel of its render shows light"
        if frame
        else "the truth is black on the object: nothing the object shows is lit"
    )
    return f"{what}, so every error is 0 and ranks nothing; {_why_dark(scene, frame)}"


def _why_dark(scene, frame: bool) -> str:
    """Which key leaves the scene dark."""
    from study.scene.environment import geometry

    env = geometry(scene)
    sky = getattr(scene.environment, "sky", None)
    light = scene.light
    if not scene.lamp() and not env.lit and sky is None:
        why = "light.enabled = false" if not light.enabled else "the environment's file takes no point light"
        return f"nothing emits light ({why}, and the environment has no emitter of its own): set light.enabled = true"
    if not frame:
        return "what the object reflects is unlit (a black sky, environment.sky, or walls the light misses)"
    p = ", ".join(f"{v:.3g}" for v in light.position)
    return f"the light reaches nothing the camera sees: check light.position ({p}) and camera.target"


def picture_label(rows: list[dict]) -> str:
    """A few words for a picture's title where it is mostly fireflies ('' where it passes)."""
    f = _first(rows, "firefly_fraction")
    return (
        f"FIREFLIES: {f:.1%} of pixels differ between seeds (limit {FIREFLY_LIMIT:.0%})"
        if f > FIREFLY_LIMIT
        else ""
    )


#: The truth's own distance from Mitsuba's render (rmse_mitsuba_debiased of truth_at_hit) over this share of the
#: smallest method's rmse_mitsuba: that column measures light no method models more than it measures the methods.
UNMODELLED_SHARE = 0.5
OWN_SHADOW = 0.05  # share of the object's rays in its own shadow over which the line names it as the cause


def unmodelled_note(rows: list[dict]) -> str:
    """The line saying that RMSE against Mitsuba's render is not a measure of the methods here ('' where the truth
    is close to that render: under :data:`UNMODELLED_SHARE` of the smallest method's rmse_mitsuba)."""
    truth = [r for r in rows if r.get("label") == "truth_at_hit"]
    own = float(truth[0].get("rmse_mitsuba_debiased", math.nan)) if truth else math.nan
    errs = [r.get("rmse_mitsuba", math.nan) for r in rows if r.get("label") not in REFERENCE_ROWS]
    errs = np.array([e for e in errs if isinstance(e, int | float)], float)
    if not (own > 0 and np.isfinite(errs).any()):
        return ""
    best = float(np.nanmin(errs))
    if not own > UNMODELLED_SHARE * best:
        return ""
    shade = float(rows[0].get("own_shadow", math.nan))
    why = (
        f"mostly the object's own shadow: {shade:.0%} of its rays see surfaces it shades from the point light, "
        "lit in the truth (taken without the object)"
        if shade > OWN_SHADOW
        else "the point light's highlight, the object's shadow and own reflections"
    )
    return (
        f"RMSE against Mitsuba's render is not a measure of the methods here: the exact truth_at_hit is itself "
        f"{own:.3g} from it beyond its noise ({own / best:.0%} of the best method's {best:.3g}): light no method "
        f"models ({why}); rank on rmse_truth or relMSE after exposure"
    )


def notes(rows: list[dict], scene) -> list[str]:
    """The run's lines about its light and samples (module docstring), in that order; empty where all is well."""
    spp = getattr(getattr(scene, "render", None), "spp", 0)  # 0: not known (a figure's case without a scene)
    units = scene.units_line() if hasattr(scene, "units_line") else ""  # moved to be measured (scene.frame)
    black = black_note(
        rows, scene
    )  # a black reference says why in its own line (the worth line says no more)
    worth_line = worth.verdict(rows[0]) if rows and not black else ""  # what a reader would complain about
    said = (units, worth_line, black, light_note(rows, scene), firefly_note(rows, spp),
            noise_note(rows, spp), unmodelled_note(rows), *exact_rows.exact_notes(rows))  # fmt: skip
    return [s for s in said if s]
