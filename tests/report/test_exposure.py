"""Figures pick their exposure from the image and state it (study.outputs.figures.figure_exposure): the 99th
percentile of the object's luminance in Mitsuba's render is shown at 0.8. Checked against the rule computed by
hand on a flat image, and by invariance: a scene 100× brighter gets log2(100) = 6.64 EV less and the same PNG
(pixel values within one step of rounding)."""

import io
from types import SimpleNamespace

import numpy as np
import pytest
from PIL import Image

from study.outputs import figures

H = W = 32
LABELS = ["classical", "localized"]


def fake_case(seed: int, scale: float = 1.0):
    """A case's images (seeded noise, linear radiance up to 0.3) on a 32² frame with the object in the middle."""
    rng = np.random.default_rng(seed)
    mask = np.zeros((H, W), bool)
    mask[8:24, 8:24] = True
    img = lambda: (rng.random((H, W, 3)) * 0.3 * scale).astype(np.float32)  # noqa: E731
    return SimpleNamespace(
        scene=SimpleNamespace(object=SimpleNamespace(center=(0.0, 1.0, 0.0), alpha=0.0)),
        images={lab: img() for lab in LABELS},
        mitsuba=img(),
        angle_maps={lab: np.where(mask, rng.random((H, W)) * 10, np.nan) for lab in LABELS},
        outcome_maps={},
        occluded=None,
        mask=mask,
    )


def test_exposure_maps_the_objects_99th_percentile_to_0_8():
    case = fake_case(0)
    case.mitsuba[:] = 0.05  # a grey object (luminance 0.05) in a frame 10× brighter around it
    case.mitsuba[~case.mask] = 0.5
    assert figures.figure_exposure([case]) == pytest.approx(np.log2(0.8 / 0.05))  # +4 EV
    case.mitsuba[:] = 0.0
    assert figures.figure_exposure([case]) == 0.0  # no light on the object: as rendered


def test_a_scene_100x_brighter_gets_6_6_ev_less_and_the_same_png():
    cases = [fake_case(1), fake_case(2)]
    bright = [fake_case(1, scale=100.0), fake_case(2, scale=100.0)]
    ev, ev_bright = figures.figure_exposure(cases), figures.figure_exposure(bright)
    assert ev_bright - ev == pytest.approx(-np.log2(100.0), abs=1e-6)
    assert round(ev_bright - ev, 1) == -6.6
    png = [
        np.asarray(
            Image.open(io.BytesIO(figures.image_grid(c, LABELS, None, title="t", exposure=e))).convert("RGB"),
            np.int16,
        )
        for c, e in ((cases, ev), (bright, ev_bright))
    ]
    assert png[0].shape == png[1].shape
    assert np.abs(png[0] - png[1]).max() <= 1
    unexposed = np.asarray(
        Image.open(io.BytesIO(figures.image_grid(bright, LABELS, None, title="t"))).convert("RGB"), np.int16
    )
    assert np.abs(unexposed - png[1]).max() > 100  # without the exposure it would be white: the test can fail


def test_the_grid_title_states_the_exposure(monkeypatch):
    said = []
    monkeypatch.setattr(figures, "image_grid", lambda cases, labels, path, **kw: said.append(kw) or b"")
    cases = [fake_case(3)]
    figures.image_grids("f", cases, LABELS, title="f: room")
    ev = figures.figure_exposure(cases)
    assert said[0]["exposure"] == ev
    assert said[0]["title"] == f"f: room, exposure {ev:+.2f} EV (object's p99 → 0.8)"


def test_a_long_title_wraps_inside_a_narrow_figure(tmp_path):
    """The exposure statement lengthens every title: on a figure narrower than its title the title wraps, so no
    text touches the image's left or right edge (it was cut there on fig5's image grid)."""
    title = (
        "fig5: (-2, 0, -2)..(2, 3, 2) room, 1 column(s), reference point [0.0, 1.5, 0.0], cube 256², backend "
    )
    figures.image_grid(
        [fake_case(1)], LABELS, tmp_path / "g.png", part="images", title=title + "numpy, exposure −2.78 EV"
    )
    top = np.asarray(Image.open(tmp_path / "g.png").convert("L"), float)[:60]
    assert top[:, :4].min() > 200 and top[:, -4:].min() > 200  # white margins: nothing cut
    assert top.min() < 100  # … and a title is there


# ---------------------------------------------------------------------------------------------- issue 44 (1)
def _run_case(frame: float = 0.02, highlight: float = 50.0):
    """A run's case: a dim room (luminance ``frame``, a void of zeros on the left) and an object whose reflection
    holds a tiny, very bright highlight (``highlight``) — what made the old rule (object's p99 → 0.8) go dark."""
    case = fake_case(4)
    grey = np.full((H, W, 3), frame, np.float32)
    grey[:, :6] = 0.0  # the void beyond an open front: shows no light, not counted
    grey[10:12, 10:12] = highlight  # the lamp in the mirror sphere
    case.mitsuba = grey
    case.truth = case.oracle = grey.copy()
    case.images = {lab: grey.copy() for lab in LABELS}
    return case


def test_auto_exposure_is_from_the_image_as_a_whole():
    from study.outputs.viewer import auto_exposure

    img = np.full((H, W, 3), 0.05, np.float32)
    assert auto_exposure(img) == pytest.approx(np.log2(0.18 / 0.05))  # median → middle grey
    img[:, :8] = 0.0  # pixels that show no light do not count
    img[0, :4] = 1e4  # fireflies: 4 pixels of 1024 do not move it
    assert auto_exposure(img) == pytest.approx(np.log2(0.18 / 0.05))
    img[:, 8:16] = 10.0  # a third of the visible pixels bright: their p95 goes to 1, not the median to grey
    assert auto_exposure(img) == pytest.approx(np.log2(1 / 10.0))
    assert auto_exposure(np.zeros((4, 4, 3))) is None and auto_exposure(None) is None


def test_a_runs_png_is_exposed_for_the_whole_picture_and_says_so():
    """run.png, index.json and the viewer take the exposure of Mitsuba's image as a whole: +3.17 EV in a dim
    room (median 0.02 → 0.18) whose object reflects a lamp — the object's p99 would have made it −4.6 EV."""
    import json

    from study.outputs import run_files

    case = _run_case()
    want = np.log2(0.18 / 0.02)
    old = figures.figure_exposure([case])
    assert old < -4 and want > 3  # the rule planted back would fail below
    said = []
    real = figures.image_grid
    figures.image_grid = lambda cases, labels, path, **kw: said.append(kw) or b""
    try:
        files, index = run_files.result_files(case, [{"label": "classical"}], LABELS, title="room.obj")
    finally:
        figures.image_grid = real
    assert said[0]["exposure"] == pytest.approx(want)
    assert (
        f"exposure {want:+.2f} EV (Mitsuba image: median of the visible luminance → 0.18" in said[0]["title"]
    )
    assert index["exposure_ev"] == pytest.approx(want, abs=1e-4) and "median" in index["exposure_rule"]
    entry = json.loads(files["viewer/index.json"])["cases"][0]
    assert entry["exposure_ev"] == pytest.approx(want, abs=0.01)  # the viewer starts where the PNG is
    lo, hi = entry["exposure_span"]
    assert lo <= -8 and hi >= want + 4  # the slider reaches past what the page's images need


def test_the_slider_spans_what_a_dark_page_needs():
    """The GLB room of issue 44 needed +9.14 EV: the span goes past it, and every image's own exposure."""
    from study.outputs.viewer import exposure_span

    dark = np.full((8, 8, 3), 0.18 * 2**-9.14, np.float32)
    lo, hi = exposure_span([dark], 9.14)
    assert lo == -8 and hi >= 13.14
    lo, hi = exposure_span([dark * 2**-6], 9.14)  # one image darker still
    assert hi >= 15.14
    assert exposure_span([], 0.0) == [-8.0, 8.0]
