"""What a mesh file holds once read (:mod:`study.scene.obj`, :mod:`study.scene.gltf`, trimesh for the rest): its
parts with their linear colours, textures and emission, its punctual lights, and what the loader counted, dropped
and ignored; checked (:func:`clean`) and told in one line (:func:`load_summary_line`).

Lights are plain dicts in world space, radiometric, as Mitsuba takes them (:mod:`study.reference.mitsuba` builds
the emitters): ``{"type": "point", "position", "intensity"}`` (W/sr per RGB channel), ``{"type": "spot",
"position", "direction", "intensity", "cutoff_angle", "beam_width"}`` (degrees) and ``{"type": "directional",
"direction", "irradiance"}`` (W/m²).
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from study.errors import StudyError


@dataclass(frozen=True)
class Part:
    """One surface of the environment (triangles ``mesh.surface == index``) and what it is made of."""

    name: str
    albedo: np.ndarray | None = None  # (H, W, 3) linear RGB texture over the part's uv, or None
    color: tuple | None = None  # constant linear RGB albedo, or None
    vertex_colors: bool = False  # albedo from the mesh's vertex colours (``mesh.part_colors(index)``)
    native: Any = None  # a loaded Mitsuba shape (mitsuba environments): rendered as it is
    emission: tuple | None = None  # linear RGB radiance it emits (an area light), or None


@dataclass
class Piece:
    """One part as a file holds it: triangles (V, F) in the file's space and what they are made of."""

    name: str
    V: np.ndarray  # (n, 3) float64
    F: np.ndarray  # (m, 3) int64 into V
    uv: np.ndarray | None = None  # (n, 2), Mitsuba's convention (v runs down the image)
    colors: np.ndarray | None = None  # (n, 3) linear RGB vertex colours
    color: tuple | None = None  # linear RGB albedo
    albedo: np.ndarray | None = None  # (H, W, 3) linear RGB texture
    emission: tuple | None = None  # linear RGB radiance


@dataclass
class Loaded:
    pieces: list[Piece]
    lights: list[dict] = field(default_factory=list)
    materials: int = 0
    textures: int = 0
    ignored: Counter = field(default_factory=Counter)  # what the file says that is not rendered, per kind
    dropped: Counter = field(default_factory=Counter)  # triangles and parts left out, per reason
    sensor: dict | None = None  # the file's camera: eye, target, up, fov (horizontal degrees), width, height


def srgb_to_linear(c) -> np.ndarray:
    """The sRGB transfer function undone (IEC 61966-2-1), for 8-bit colour textures and colours."""
    c = np.asarray(c, float)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def image_linear(img) -> np.ndarray:
    """A PIL image (an sRGB colour texture) as (H, W, 3) float32 linear RGB."""
    return srgb_to_linear(np.asarray(img.convert("RGB"), float) / 255).astype(np.float32)


def read_image(source, *, what: str, src: str) -> np.ndarray:
    """An sRGB colour texture (a path or the file's bytes) as (H, W, 3) float32 linear RGB.

    An image larger than Pillow's decompression-bomb limit (``PIL.Image.MAX_IMAGE_PIXELS``, 89 M pixels) is refused
    from its header, before it is decoded; one that cannot be decoded is refused too: a StudyError naming ``what``.
    """
    import io
    import warnings

    from PIL import Image

    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error", Image.DecompressionBombWarning)
            img = Image.open(io.BytesIO(source) if isinstance(source, bytes | bytearray) else source)
            return image_linear(img)
    except (Image.DecompressionBombError, Image.DecompressionBombWarning):
        raise StudyError(
            f"{what}: the image is larger than {Image.MAX_IMAGE_PIXELS:,} pixels (Pillow's decompression-bomb "
            "limit); study refuses it",
            key=src,
        ) from None
    except (OSError, SyntaxError, ValueError) as err:
        raise StudyError(
            f"{what}: the image cannot be read ({' '.join(str(err).split())[:120]})", key=src
        ) from None


def clean(loaded: Loaded, src: str) -> Loaded:
    """Refuse indices out of range and non-finite vertices that faces use (one StudyError on ``src``); drop
    degenerate triangles (a repeated index or zero area) and empty parts, counted in ``loaded.dropped``."""
    keep = []
    for p in loaded.pieces:
        F = np.asarray(p.F, np.int64).reshape(-1, 3)
        if len(F) and (F.min() < 0 or F.max() >= len(p.V)):
            raise StudyError(
                f"part {p.name!r}: a face index is out of range (0..{len(p.V) - 1}, got {F.min()}..{F.max()})",
                key=src,
            )
        bad = ~np.isfinite(p.V).all(1)
        if len(F) and bad[F].any():
            i = int(np.flatnonzero(bad[F].any(1))[0])
            v = int(F[i][bad[F[i]]][0])
            raise StudyError(
                f"part {p.name!r}: vertex {v} is not finite ({p.V[v].tolist()}), used by "
                f"{int(bad[F].any(1).sum())} triangle(s); fix the file (dropping them would leave a hole)",
                key=src,
            )
        rep = (F[:, 0] == F[:, 1]) | (F[:, 1] == F[:, 2]) | (F[:, 0] == F[:, 2])
        V = p.V
        area = np.linalg.norm(np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]]), axis=1)
        degen = rep | (area <= 0)
        if degen.any():
            loaded.dropped["degenerate triangle"] += int(degen.sum())
            F = F[~degen]
        if not len(F):
            loaded.dropped["empty part"] += 1
            continue
        p.F = F
        keep.append(p)
    if not keep:
        n = loaded.dropped["degenerate triangle"]
        raise StudyError(
            f"the mesh file holds no faces of non-zero area ({n} degenerate)"
            if n
            else "the mesh file holds no faces",
            key=src,
        )
    loaded.pieces = keep
    return loaded


def _n(count: int, what: str) -> str:
    plural = what if count == 1 else (what[:-1] + "ies" if what.endswith("y") else what + "s")
    return f"{count:,} {plural}"


def load_summary_line(name: str, loaded: Loaded) -> str:
    """``loaded rooms/x.glb: 1,234 triangles, 5 materials, 2 textures, 1 emissive material, 1 punctual light;
    ignored: 1 transmission, 2 alpha; dropped: 3 degenerate triangles``."""
    tris = sum(len(p.F) for p in loaded.pieces)
    emissive = sum(p.emission is not None for p in loaded.pieces)
    out = f"loaded {name}: {_n(tris, 'triangle')}, {_n(loaded.materials, 'material')}, "
    out += f"{_n(loaded.textures, 'texture')}, {_n(emissive, 'emissive material')}, "
    out += _n(len(loaded.lights), "punctual light")
    if loaded.ignored:
        out += "; ignored: " + ", ".join(f"{n} {k}" for k, n in sorted(loaded.ignored.items()))
    if loaded.dropped:
        out += "; dropped: " + ", ".join(_n(n, k) for k, n in sorted(loaded.dropped.items()))
    return out


def transform_sensor(sensor: dict | None, M: np.ndarray, t: np.ndarray) -> dict | None:
    """A camera moved by x → M x + t (eye and target; up turned by M)."""
    if sensor is None:
        return None
    up = M @ np.asarray(sensor["up"], float)
    return {
        **sensor,
        "eye": (M @ np.asarray(sensor["eye"], float) + t).tolist(),
        "target": (M @ np.asarray(sensor["target"], float) + t).tolist(),
        "up": (up / np.linalg.norm(up)).tolist(),
    }


def transform_lights(lights: list[dict], M: np.ndarray, t: np.ndarray) -> list[dict]:
    """Lights moved by x → M x + t (positions) and M d (directions, normalised); a point or spot light's
    intensity (W/sr) scaled by the square of M's scale, so that the irradiance it gives the scaled scene's walls
    is the same (:mod:`study.scene.frame`)."""
    out = []
    k2 = abs(float(np.linalg.det(M))) ** (2 / 3)  # (linear scale)²
    for li in lights:
        li = dict(li)
        if "intensity" in li and li.get("type") in ("point", "spot") and k2 != 1.0:
            li["intensity"] = (np.asarray(li["intensity"], float) * k2).tolist()
        if "position" in li:
            li["position"] = (M @ np.asarray(li["position"], float) + t).tolist()
        if "direction" in li:
            d = M @ np.asarray(li["direction"], float)
            li["direction"] = (d / np.linalg.norm(d)).tolist()
        out.append(li)
    return out
