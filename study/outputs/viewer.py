"""A figure's images for people: per case EXR files named for what they hold, and the HTML viewer's images.

For every case of a figure (:class:`~study.measure.case.CaseOutput`) the figure command writes, in its output set:

* ``exr/<case>.exr``: one multi-layer EXR (full frame, float32, :func:`study.io.layers_exr_bytes`) whose layers
  are named for what they hold (channels ``<layer>.R/.G/.B`` or ``<layer>.Y``): ``truth_at_hit``,
  ``oracle_map``, ``mitsuba`` and one per method (linear RGB radiance; method labels as file names,
  :func:`study.io.file_stem`: ``localized-iterations-10``); ``angle-<method>`` (degrees), ``outcome-<method>``
  (codes 0 correct, 1 wrong depth, 2 wrong surface, 3 no hit; NaN off the object), ``flip-<method>`` /
  ``error-<method>`` where the case has them, ``hidden`` (fraction of each pixel's rays whose exact hit the
  reference point cannot see), ``mask`` (1 on the object's pixels) and ``held`` (1 on the object's pixels whose
  every hit the reference point's views hold: where oracle_map has a value and the ``*_oracle`` columns are
  measured; the others are magenta in ``oracle_map``). Openable in tev (one layer per entry) or
  with :func:`study.io.read_exr_layers`. They are large, so not committed (``.gitignore``);
  ``bash scripts/reproduce.sh`` makes them.
* ``viewer/<case>.js``: the same images cropped to the object (:func:`crop_box`) as RGBE-coded PNGs
  (:func:`rgbe_png`: mantissas on the left half, the shared exponent on the right, no alpha, so the browser hands
  the bytes over unchanged) embedded as data URLs in a script, which the report's viewer loads on demand (a script
  and data URLs are what a page opened as ``file://`` may read pixels from);
* ``viewer/index.json``: what each case holds (sources, layers, how each is displayed, its EXR), which the
  report embeds (:mod:`study.outputs.html`).
"""

from __future__ import annotations

import base64
import io
import json
import os
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

from study.io import file_stems, json_text, layers_exr_bytes, read_json
from study.measure.exposure import FRAME_RULE, auto_exposure  # noqa: F401  (re-exported: the viewer's rule)
from study.measure.outcomes import NAMES as OUTCOME_NAMES

#: Colours of the outcome classes (study.measure.outcomes codes 0..3): correct, wrong depth, wrong surface, no hit.
OUTCOME_COLORS = ("#9fd39a", "#f28e2b", "#d62728", "#3b3b3b")
#: How each layer is shown: radiance with an exposure; maps through a colour map over a fixed range.
DISPLAY = {
    "image": {"type": "hdr"},
    "angle": {
        "type": "log",
        "lo": 0.01,
        "hi": 30.0,
        "cmap": "magma",
        "unit": "deg",
        "title": "angular error at the shading point",
    },
    "outcome": {
        "type": "classes",
        "colors": list(OUTCOME_COLORS),
        "names": list(OUTCOME_NAMES),
        "title": "outcome: most frequent class of the pixel's rays",
    },
    "flip": {
        "type": "linear",
        "lo": 0.0,
        "hi": 1.0,
        "cmap": "magma",
        "unit": "",
        "title": "LDR-FLIP against truth_at_hit",
    },
    "error": {"type": "linear", "lo": 0.0, "hi": None, "cmap": "magma", "unit": "", "title": "error map"},
    "hidden": {
        "type": "linear",
        "lo": 0.0,
        "hi": 1.0,
        "cmap": "viridis",
        "unit": "",
        "title": "fraction of the pixel's rays whose exact hit is hidden from the reference point",
    },
}
MANIFEST = "viewer/index.json"
#: A hidden map of one ray per pixel is yes or no: shown as two classes, not a colour bar.
HIDDEN_COLORS = ("#d9e8f5", "#8a2be2")
HIDDEN_NAMES = ("visible from the reference point", "hidden from the reference point")


# ---------------------------------------------------------------------------------------------- exposure
# auto_exposure and FRAME_RULE: study.measure.exposure (the errors after exposure use the same rule)


#: The viewer's exposure slider spans at least this (EV), and this much beyond any image's own exposure.
SLIDER_EV, SLIDER_MARGIN = 8.0, 4.0


def exposure_span(images, start: float = 0.0) -> list[float]:
    """[lo, hi] EV a viewer's slider spans for ``images`` (linear RGB): ±:data:`SLIDER_EV`, ``start`` and every
    image's :func:`auto_exposure`, with :data:`SLIDER_MARGIN` either side."""
    evs = [start, *(e for e in map(auto_exposure, images) if e is not None)]
    lo = min(-SLIDER_EV, np.floor(min(evs) - SLIDER_MARGIN))
    hi = max(SLIDER_EV, np.ceil(max(evs) + SLIDER_MARGIN))
    return [float(lo), float(hi)]


def crop_box(mask: np.ndarray, margin: float = 0.35) -> tuple[slice, slice]:
    """A square around the object's pixels, with a margin, inside the image."""
    ys, xs = np.nonzero(mask)
    H, W = mask.shape
    if ys.size == 0:
        return slice(0, H), slice(0, W)
    cy, cx = (ys.min() + ys.max()) / 2, (xs.min() + xs.max()) / 2
    half = max(ys.max() - ys.min(), xs.max() - xs.min()) / 2 * (1 + margin) + 2
    half = min(half, H / 2, W / 2)
    y0 = int(np.clip(cy - half, 0, H - 2 * half))
    x0 = int(np.clip(cx - half, 0, W - 2 * half))
    return slice(y0, y0 + int(2 * half)), slice(x0, x0 + int(2 * half))


# ---------------------------------------------------------------------------------------------- RGBE in a PNG
def rgbe(a: np.ndarray) -> np.ndarray:
    """(H, W, C) floats, C = 1 or 3 → (H, 2W, C) uint8: per pixel the channels' 8-bit mantissas m (left half) and
    their shared exponent E (right half, E = 0 for zero) with value = m · 2^(E − 136) (Ward's RGBE, rounded).
    Negative values are stored as 0; NaN or ±inf pixels as E = 0, m = 255 (decoded as NaN)."""
    a = np.asarray(a, np.float64)
    bad = ~np.isfinite(a).all(-1)
    v = np.where(np.isfinite(a), np.maximum(a, 0.0), 0.0)
    mx = v.max(-1)
    frac, e = np.frexp(mx)  # mx = frac · 2^e, frac in [0.5, 1)
    ok = mx > 2.0**-120
    scale = np.where(ok, 2.0 ** (8 - e.astype(float)), 0.0)  # m = v · 2^(8 − e)  (≤ 256·frac < 256)
    m = np.clip(np.rint(v * scale[..., None]), 0, 255)
    E = np.where(ok, np.clip(e + 128, 1, 255), 0)
    m[bad], E[bad] = 255, 0
    return np.concatenate([m, np.repeat(E[..., None], a.shape[-1], -1)], axis=1).astype(np.uint8)


def unrgbe(b: np.ndarray) -> np.ndarray:
    """The inverse of :func:`rgbe` (as the viewer's JavaScript decodes it): (H, 2W, C) uint8 → (H, W, C) float."""
    W = b.shape[1] // 2
    m, E = b[:, :W].astype(np.float64), b[:, W:, :1].astype(np.float64)
    v = np.where(E > 0, m * 2.0 ** (E - 136), 0.0)
    v[(E[..., 0] == 0) & (m[..., 0] == 255)] = np.nan
    return v


def png(a: np.ndarray) -> bytes:
    """A uint8 (H, W) or (H, W, 3) array as PNG bytes (Pillow; no gamma or colour-profile chunk). zlib's level 6:
    on a case's RGBE crops 2.1x faster than level 9 for 1.5 % more bytes."""
    from PIL import Image

    buf = io.BytesIO()
    Image.fromarray(a[..., 0] if a.ndim == 3 and a.shape[-1] == 1 else a).save(
        buf, format="PNG", compress_level=6
    )
    return buf.getvalue()


def rgbe_png(a: np.ndarray) -> bytes:
    """(H, W) or (H, W, C) floats as an RGBE-coded PNG (grey for one channel, RGB for three)."""
    a = np.asarray(a, float)
    return png(rgbe(a[..., None] if a.ndim == 2 else a))


# ---------------------------------------------------------------------------------------------- one case
def case_layers(case, labels: list[str]) -> list[tuple[str, str, np.ndarray]]:
    """(source, layer, full-frame array) of every image of a case: the references first (truth_at_hit, oracle_map,
    mitsuba), then each method's image, then each method's maps (those the case has), then the hidden fraction.
    ``labels``: the methods, in order."""
    out = [
        ("truth_at_hit", "image", case.truth),
        ("oracle_map", "image", case.oracle),
        ("mitsuba", "image", case.mitsuba),
        *[(lab, "image", case.images[lab]) for lab in labels],
    ]
    for layer, maps in (
        ("angle", case.angle_maps),
        ("outcome", case.outcome_maps),
        ("flip", getattr(case, "flip_maps", None) or {}),
        ("error", getattr(case, "error_maps", None) or {}),
    ):
        out += [(lab, layer, maps[lab]) for lab in labels if maps.get(lab) is not None]
    occ = getattr(case, "occluded", None)
    if occ is not None and case.mask is not None:
        out.append(("truth_at_hit", "hidden", np.where(case.mask | (occ > 0), occ, np.nan)))
    return [(s, la, np.asarray(a, np.float32)) for s, la, a in out if a is not None]


def source_stems(labels: list[str]) -> dict[str, str]:
    """Layer names of a case's sources: the references keep theirs, methods get :func:`study.io.file_stem`."""
    return file_stems(["truth_at_hit", "oracle_map", "mitsuba", *labels])


def exr_layer(source: str, layer: str, stems: dict[str, str]) -> str:
    """The layer of a case's EXR that holds ``layer`` of ``source``: ``classical``, ``angle-classical``,
    ``hidden``, ``mask`` (channels ``<layer>.R/.G/.B`` or ``<layer>.Y``)."""
    if layer == "image":
        return stems[source]
    return layer if layer in ("hidden", "mask") else f"{layer}-{stems[source]}"


def _display(layer: str, a: np.ndarray) -> dict:
    d = dict(DISPLAY[layer])
    if layer == "error" and a.ndim == 3 and a.shape[-1] == 3:
        d = {"type": "hdr", "title": "error image"}
    elif layer == "hidden" and np.isin(a[np.isfinite(a)], (0.0, 1.0)).all():  # one ray per pixel: yes or no
        d = {
            "type": "classes",
            "colors": list(HIDDEN_COLORS),
            "names": list(HIDDEN_NAMES),
            "title": d["title"],
        }
    elif d.get("hi", 0) is None:  # a map without a fixed range: its 99th percentile
        fin = a[np.isfinite(a)]
        d["hi"] = float(max(np.percentile(fin, 99), 1e-6)) if fin.size else 1.0
    return d


def case_files(
    name: str,
    stem: str,
    case,
    labels: list[str],
    *,
    title: str = "",
    case_id: str = "",
    exposure_ev: float = 0.0,
    exr: bool = True,
) -> tuple[dict[str, bytes | str], dict]:
    """One case's files, made in memory (relative path → bytes, for :func:`study.io.write_set`): its multi-layer
    EXR ``exr/<stem>.exr`` and its viewer script ``viewer/<stem>.js``; and its manifest entry. ``stem``: the
    case's file name (distinct among the figure's cases, :func:`study.io.file_stems`). ``exposure_ev``: the
    exposure the viewer starts at (the figure's grid exposure, so the viewer first shows what the PNG shows); its
    slider spans :func:`exposure_span` of the case's images (``exposure_span`` in the entry). ``exr`` False: the
    viewer script alone (the entry still names the EXR, which the viewer then says is not in this copy)."""
    layers = case_layers(case, labels)
    occ = getattr(case, "occluded", None)
    sy, sx = (
        crop_box(case.mask | (occ > 0) if occ is not None else case.mask)
        if case.mask is not None
        else (slice(None), slice(None))
    )
    stems = source_stems(labels)
    exr_file = f"exr/{stem}.exr"
    named = _exr_layers(case, layers, stems)
    entries, urls = [], []
    with ThreadPoolExecutor(min(8, os.cpu_count() or 1)) as pool:  # zlib releases the GIL: PNGs in parallel
        pngs = list(pool.map(lambda la: rgbe_png(la[2][sy, sx]), layers))
    for (source, layer, a), data in zip(layers, pngs):
        crop = a[sy, sx]
        urls.append("data:image/png;base64," + base64.b64encode(data).decode())
        entries.append(
            {
                "source": source,
                "layer": layer,
                "channels": 1 if crop.ndim == 2 else crop.shape[-1],
                "display": _display(layer, a),
                "exr": exr_file,
                "exr_layer": exr_layer(source, layer, stems),
            }
        )
    H, W = layers[0][2].shape[:2]
    y0, x0 = sy.start or 0, sx.start or 0
    script = f"viewer/{stem}.js"
    key = f"{name}/{stem}"
    text = (
        "(window.STUDY_VIEWER_DATA = window.STUDY_VIEWER_DATA || {})["
        + json.dumps(key)
        + "] = "
        + json.dumps(urls)
        + ";\n"
    )
    entry = {
        "id": case_id or stem,
        "key": key,
        "title": title or case_id or stem,
        "size": [H, W],
        "crop": [y0, x0, (sy.stop or H) - y0, (sx.stop or W) - x0],
        "script": script,
        "exr": exr_file,
        "layers": entries,
        "exposure_ev": round(float(exposure_ev), 2),
        "exposure_span": exposure_span(
            [a[sy, sx] for _, la, a in layers if la == "image" and a.ndim == 3], exposure_ev
        ),
    }
    return ({exr_file: layers_exr_bytes(named)} if exr else {}) | {script: text}, entry


def _exr_layers(case, layers, stems) -> dict[str, np.ndarray]:
    """The multi-layer EXR's named arrays of a case (its images, then ``mask`` and ``held``)."""
    named = {exr_layer(s, la, stems): a for s, la, a in layers}
    if case.mask is not None:
        named["mask"] = case.mask.astype(np.float32)
        if getattr(case, "held", None) is not None:  # the pixels the *_oracle columns are measured over
            named["held"] = (case.mask & case.held).astype(np.float32)
    return named


def case_exr(stem: str, case, labels: list[str]) -> dict[str, bytes]:
    """One case's multi-layer EXR alone (``exr/<stem>.exr``, as :func:`case_files` writes it): a figure's cases
    beyond its picture, which the viewer does not show but the glossy split and the user's tools read."""
    return {
        f"exr/{stem}.exr": layers_exr_bytes(
            _exr_layers(case, case_layers(case, labels), source_stems(labels))
        )
    }


def manifest_text(name: str, cases: list[dict]) -> str:
    """``viewer/index.json`` of a figure: its cases as :func:`case_files` returned them."""
    return json_text({"figure": name, "cases": cases}, indent=1)


def read_manifest(fig_dir: Path) -> dict | None:
    """A figure's viewer manifest, or None where the figure has none (or it is unreadable)."""
    try:
        m = read_json(fig_dir / MANIFEST, what="viewer manifest")  # nested 10⁵ deep: one line, exit 2
    except (OSError, ValueError):
        return None
    ok = (
        isinstance(m, dict)
        and isinstance(m.get("cases"), list)
        and all(
            isinstance(c, dict) and isinstance(c.get("layers"), list) and isinstance(c.get("script"), str)
            for c in m["cases"]
        )
    )
    return m if ok else None
