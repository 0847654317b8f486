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

A map is checked before Mitsuba reads it (:func:`map_problem`), as every other input is: its header first, read
here byte by byte (an OpenEXR header's ``dataWindow`` and ``displayWindow``, or a Radiance ``.hdr``'s resolution
line), so that a file claiming 60000 × 30000 texels is refused without allocating them (at most
:data:`MAX_TEXELS`); then its texels, through Mitsuba's ``Bitmap`` as its ``envmap`` reads them, which must be
finite radiances ≥ 0. A damaged file, a symlink to something that is not an image, a NaN or a negative texel is one
line naming the file (and the key ``environment.sky``), exit 2.
"""

from __future__ import annotations

import functools
import os
import re
import struct
from pathlib import Path
from typing import Any

import numpy as np
from pydantic import ValidationInfo
from pydantic_core import PydanticCustomError

from study.scene.parts import srgb_to_linear
from study.scene.paths import resolve

MAP_SUFFIXES = (".exr", ".hdr")
#: The largest sky map read, in texels (8192 × 4096, an "8k" equirectangular map: 0.4 GB as float32 RGB; Mitsuba's
#: envmap holds it again with its sampling tables). A map's header claiming more is refused before any texel is read.
MAX_TEXELS = 8192 * 4096
#: How much of a file its header may take (bytes read to find the size).
HEADER_BYTES = 1 << 16
EXR_MAGIC = b"\x76\x2f\x31\x01"
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
    path = resolve(s, info)
    st = os.stat(path)
    problem = map_problem(path, st.st_size, st.st_mtime_ns)
    if problem:
        raise PydanticCustomError(
            "sky", "{path}: {problem}", {"path": _shown(s, path, info), "problem": problem}
        )
    return path


def _shown(given: str, path: str, info: ValidationInfo) -> str:
    """The map as the message names it: its path, and where a symlink leads."""
    p = Path(given).expanduser()
    if not p.is_absolute():
        p = Path((info.context or {}).get("base") or ".") / p
    return f"{p} (a symlink to {path})" if p.is_symlink() else path


# ---------------------------------------------------------------------------------------------- map checks
def _exr_size(head: bytes) -> tuple[int, int] | str:
    """(width, height) from an OpenEXR header (the larger of its data and display windows), or what is wrong."""
    if len(head) < 8:
        return "a damaged OpenEXR file (it ends inside its header)"
    flags = struct.unpack_from("<I", head, 4)[0]
    if flags & (1 << 11 | 1 << 12):  # deep data, several parts
        return "a deep or multi-part OpenEXR file; a sky is one single-part RGB image"
    pos, sizes = 8, []
    while True:
        end = head.find(b"\0", pos)
        if end < 0:
            return "a damaged OpenEXR header (an attribute without an end)"
        name = head[pos:end]
        if not name:
            break
        tend = head.find(b"\0", end + 1)
        if tend < 0 or tend + 5 > len(head):
            return "a damaged OpenEXR header (an attribute without an end)"
        kind, size = head[end + 1 : tend], struct.unpack_from("<i", head, tend + 1)[0]
        pos = tend + 5
        if size < 0 or pos + size > len(head):
            return f"a damaged OpenEXR header (attribute {name.decode('latin-1')!r} of {size} bytes)"
        if name in (b"dataWindow", b"displayWindow") and kind == b"box2i" and size == 16:
            x0, y0, x1, y1 = struct.unpack_from("<4i", head, pos)
            sizes.append((x1 - x0 + 1, y1 - y0 + 1))
        pos += size
    if not sizes:
        return "a damaged OpenEXR header (no dataWindow)"
    return max(w for w, _ in sizes), max(h for _, h in sizes)


_HDR_RES = re.compile(rb"([-+])([XY]) +(\d{1,12}) +([-+])([XY]) +(\d{1,12})")


def _hdr_size(head: bytes) -> tuple[int, int] | str:
    """(width, height) from a Radiance RGBE header (``#?RADIANCE``, then lines, a blank one, the resolution
    line ``-Y H +X W``), or what is wrong."""
    blank = head.find(b"\n\n")
    if blank < 0:
        return "a damaged Radiance .hdr header (no blank line before the resolution)"
    line = head[blank + 2 :].split(b"\n", 1)[0].strip()
    m = _HDR_RES.fullmatch(line)
    if not m or m[2] == m[5]:
        return (
            f"a damaged Radiance .hdr header (resolution line {line[:40]!r}; expected like '-Y 512 +X 1024')"
        )
    first, second = int(m[3]), int(m[6])
    return (second, first) if m[2] == b"Y" else (first, second)


@functools.lru_cache(maxsize=64)
def map_problem(path: str, size: int = 0, mtime_ns: int = 0) -> str | None:
    """What is wrong with the sky map at ``path`` (None: nothing): its header (kind, size ≤ :data:`MAX_TEXELS`),
    then its texels as Mitsuba reads them (finite, ≥ 0). ``size`` and ``mtime_ns`` (the file's) key the memo, so a
    changed file is checked again.

    Parameters
    ----------
    path : the map (absolute, resolved)
    size, mtime_ns : the file's size and modification time (memo key only)

    Returns
    -------
    str or None
        one clause for the message (the caller adds the file and key), or None for a good map.
    """
    try:
        with open(path, "rb") as f:
            head = f.read(HEADER_BYTES)
    except OSError as err:
        return f"cannot be read ({err.strerror})"
    if head[:4] == EXR_MAGIC:  # by content, as Mitsuba reads it (a symlink's target may have any name)
        got = _exr_size(head)
    elif head.startswith(b"#?"):
        got = _hdr_size(head)
    else:
        got = f"neither an OpenEXR nor a Radiance .hdr image (it starts with {head[:8]!r})"
    if isinstance(got, str):
        return got
    w, h = got
    if w < 1 or h < 1:
        return f"a damaged header (it says {w} × {h} texels)"
    if w * h > MAX_TEXELS:
        return (f"its header says {w} × {h} texels; a sky map has at most {MAX_TEXELS:,} (8192 × 4096): "
                "downscale it")  # fmt: skip
    from study import runtime

    mi = runtime.mitsuba()
    try:
        bmp = mi.Bitmap(path).convert(mi.Bitmap.PixelFormat.RGB, mi.Struct.Type.Float32, srgb_gamma=False)
        a = np.array(bmp, dtype=np.float32).reshape(bmp.height(), bmp.width(), 3)
    except Exception as err:  # Mitsuba's readers raise RuntimeError on a damaged file
        return f"a damaged image ({(str(err).strip().splitlines() or [''])[0][-120:]})"
    for bad, what in ((~np.isfinite(a), "not finite (NaN or inf)"), (a < 0, "negative")):
        if bad.any():
            r, c, k = (int(i[0]) for i in np.nonzero(bad))
            n, of = int(bad.any(axis=-1).sum()), a.shape[0] * a.shape[1]
            return (f"{n} of {of} texels are {what} (the first at row {r}, column {c}: {'RGB'[k]} = "
                    f"{a[r, c, k]:g}); a sky holds radiances ≥ 0")  # fmt: skip
    return None


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
