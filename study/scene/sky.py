"""The sky: what a ray that leaves the scene sees (``environment.sky``), one emitter at infinity that Mitsuba's
references, the impostor's captures and every method's escaping rays read alike.

=====================  ==========================================================================================
``sky`` value           meaning
=====================  ==========================================================================================
left out               the file's own sky (a Mitsuba scene's ``envmap`` or ``constant`` emitter), else none: a
                       ray that leaves the scene sees black, as every scene did before skies existed
``"#rrggbb"``          a constant sky of that colour (sRGB, as a colour picker gives it; decoded to linear radiance)
``[r, g, b]``          a constant sky of that linear radiance (W/(m² sr), may exceed 1)
``"studio"``           a studio gradient (:func:`studio`): bright above, dark below, brighter on one side; what
                       automatic placement gives a single object seen from outside, so that a mirror shows it
``"sky.exr"``          an HDR environment map (``.exr`` or ``.hdr``, equirectangular, +y up: Mitsuba's
                       ``envmap``), relative to the scene file; hashed by its bytes in content keys
=====================  ==========================================================================================

A sky the user gives replaces the file's own (Mitsuba renders one environment emitter per scene).
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import numpy as np
from pydantic import ValidationInfo
from pydantic_core import PydanticCustomError

from study.scene.parts import srgb_to_linear
from study.scene.paths import resolve

MAP_SUFFIXES = (".exr", ".hdr")
ALLOWED = '"#rrggbb" (sRGB), [r, g, b] (linear radiance, ≥ 0), "studio" or an equirectangular .exr/.hdr map'
STUDIO = "studio"


def hex_linear(hex_colour: str) -> tuple[float, float, float]:
    """``"#rrggbb"`` → linear RGB (:func:`study.scene.parts.srgb_to_linear`)."""
    c = np.array([int(hex_colour[i : i + 2], 16) for i in (1, 3, 5)], float) / 255.0
    return tuple(float(x) for x in srgb_to_linear(c))


def _bad(got: Any) -> PydanticCustomError:
    return PydanticCustomError("sky", "{got}; allowed: {allowed}", {"got": got, "allowed": ALLOWED})


def validate_sky(v: Any, info: ValidationInfo) -> Any:
    """An ``environment.sky`` value, checked and stored as: None, a lower-case ``"#rrggbb"``, a tuple of three
    floats, or the map's absolute path."""
    if v is None:
        return None
    if isinstance(v, (list, tuple)):
        ok = len(v) == 3 and all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in v)
        if not ok or not all(np.isfinite(x) and x >= 0 for x in v):
            raise _bad(f"{list(v)!r} is not three finite radiances ≥ 0")
        return tuple(float(x) for x in v)
    if not isinstance(v, (str, Path)):
        raise _bad(f"a {type(v).__name__}")
    s = str(v)
    if s == STUDIO:
        return s
    if s.startswith("#"):
        if not re.fullmatch(r"#[0-9a-fA-F]{6}", s):
            raise _bad(f"{s!r} is not a colour #rrggbb")
        return s.lower()
    if not s.lower().endswith(MAP_SUFFIXES):
        raise _bad(f"{s!r} is neither a colour nor an .exr/.hdr file")
    return resolve(s, info)


def sky_radiance(sky: Any) -> tuple[float, float, float] | None:
    """The constant radiance of a constant sky (linear RGB), None for a map or no sky."""
    if isinstance(sky, str) and sky.startswith("#"):
        return hex_linear(sky)
    if isinstance(sky, tuple):
        return sky
    return None


def emitter(sky: Any) -> dict | None:
    """The Mitsuba emitter dict of a sky the user gave (None for none, or for a black constant one: nothing to
    add)."""
    if sky is None:
        return None
    if sky == STUDIO:
        from study import runtime

        return {"type": "envmap", "bitmap": runtime.mitsuba().Bitmap(studio())}
    rgb = sky_radiance(sky)
    if rgb is None:
        return {"type": "envmap", "filename": str(sky)}
    if not any(rgb):
        return None
    return {"type": "constant", "radiance": {"type": "rgb", "value": list(rgb)}}


def studio(height: int = 64) -> np.ndarray:
    """The ``"studio"`` sky: an equirectangular (height, 2·height, 3) float32 map (+y up, as Mitsuba's ``envmap``)
    of linear radiance 1.0 overhead falling to 0.35 at the horizon and 0.04 underfoot, warm above and cool below,
    brighter by half on one side (cos of the azimuth): a mirror shows its gradient and its bright side."""
    v = (np.arange(height) + 0.5) / height
    u = (np.arange(2 * height) + 0.5) / (2 * height)
    elev = (0.5 - v)[:, None] * np.pi  # +π/2 overhead
    level = np.where(elev > 0, 0.35 + 0.65 * np.sin(elev), 0.35 * (1 + np.sin(elev)) + 0.04)
    side = 0.75 + 0.25 * np.cos(2 * np.pi * u)[None, :]
    tint = np.where(elev[..., None] > 0, [1.0, 0.97, 0.9], [0.8, 0.85, 1.0])
    return (level * side)[..., None].astype(np.float32) * tint.astype(np.float32)
