"""Whether a file's own lights are weak: their power against the point light study would add.

A mesh file's light (emissive materials, glTF punctual lights) has the file's radiometric scale, which need not be
the one it is meant to be seen at: a glTF lamp shade of ``emissiveFactor`` 1 glows in a room a viewer lights with
its own environment. :func:`own_power` is the luminous-weighted power the file's lights emit (Rec. 709 luminance of
each RGB quantity, W): an emissive part π·L·A (a one-sided Lambertian emitter of radiance L over its area A), a
point light 4π·I, a spot 2π(1 − cos θ)·I (θ its cutoff angle), a directional light E·π r² over the bounds' sphere.
:func:`own_share` divides it by the power 4π·I of study's suggested point light (:mod:`study.scene.autoplace`:
the default room's 6 W/sr scaled by the bounds' squared diagonal). Under :data:`WEAK_SHARE` (5 %, 4.3 EV darker
than the room study would light) the file's lights are **weak**: automatic placement then renders study's point
light beside them (``light.enabled`` unless given) and the run says so in one line, in its table's
``own_light_share`` and in ``index.json`` (:mod:`study.measure.lighting`). Mitsuba scenes' emitters are not
judged (NaN): study's light does not go into a Mitsuba scene that has its own.
"""

from __future__ import annotations

import math

import numpy as np

#: Under this share of study's point light's power a file's own lights are weak (module docstring).
WEAK_SHARE = 0.05
_LUMINANCE = (0.2126, 0.7152, 0.0722)  # Rec. 709 weights of an RGB radiometric quantity


def _lum(rgb) -> float:
    return float(np.asarray(rgb, float).reshape(-1, 3).mean(0) @ np.asarray(_LUMINANCE))


def _part_areas(mesh) -> np.ndarray:
    """Area per surface id of a :class:`~study.scene.room.RoomMesh` (m²)."""
    v = np.asarray(mesh.vertices, float)[np.asarray(mesh.faces)]
    area = 0.5 * np.linalg.norm(np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0]), axis=-1)
    return np.bincount(
        np.asarray(mesh.surface), weights=area, minlength=int(np.max(mesh.surface, initial=-1)) + 1
    )


def own_power(env) -> float:
    """The luminance-weighted power (W) of the lights an environment (:class:`~.sources.base.EnvGeometry`) brings:
    emissive parts and punctual lights (module docstring); NaN where it has Mitsuba emitters (not judged)."""
    if env.emitters:
        return math.nan
    areas = _part_areas(env.mesh) if any(p.emission is not None for p in env.parts) else ()
    total = sum(
        math.pi * _lum(p.emission) * areas[i] for i, p in enumerate(env.parts) if p.emission is not None
    )
    lo, hi = env.bounds
    radius = 0.5 * float(np.linalg.norm(np.subtract(hi, lo)))
    for light in env.lights:
        kind = light.get("type")
        if kind == "point":
            total += 4 * math.pi * _lum(light["intensity"])
        elif kind == "spot":
            cutoff = math.radians(float(light.get("cutoff_angle", 90.0)))
            total += 2 * math.pi * (1 - math.cos(cutoff)) * _lum(light["intensity"])
        elif kind == "directional":
            total += _lum(light["irradiance"]) * math.pi * radius**2
    return float(total)


def own_share(env, intensity) -> float:
    """:func:`own_power` over the power 4π·I of a point light of ``intensity`` (W/sr, RGB or one value); NaN where
    the environment has no light of its own or is not judged."""
    if not env.lit:
        return math.nan
    study = 4 * math.pi * _lum(np.broadcast_to(np.asarray(intensity, float), (3,)))
    return own_power(env) / study if study > 0 else math.nan


def weak(env, intensity) -> bool:
    """Whether the environment's own lights are weak: :func:`own_share` under :data:`WEAK_SHARE`."""
    return bool(own_share(env, intensity) < WEAK_SHARE)
