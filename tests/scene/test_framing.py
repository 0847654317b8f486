"""Enough data to decide (issue 24): the camera can frame the object (camera.frame_object), every shipped figure
and sweep config gives each case ≥ 10⁴ object rays (fig5's cases ≥ 200 hidden ones), and scripts/reproduce.sh
stays within its 35-minute budget by the cost model of study.harness.budget."""

import json
import math
import re
from pathlib import Path

import numpy as np
import pytest

from study.errors import StudyError
from study.harness import budget
from study.harness.config import load_figure_config
from study.harness.sweep import load_sweep
from study.impostor.cubemap import FAR
from study.optics import shading
from study.reference.tracer import make_tracer
from study.scene import load_scene_file
from study.scene.sources import key_fields

MIN_RAYS = 10_000
MIN_HIDDEN = 200
#: The figure and sweep configs scripts/reproduce.sh runs (checked against the script below). Not held to
#: MIN_RAYS: check_sweep.toml (`study check` against the committed reports/baseline), sweep_tiny.toml (tests),
#: sweep_large.toml (throughput of many small cases), motion.toml (the animation's frames; in the budget below).
FIGURES = [
    "fig4",
    "fig5",
    "fig6",
    "fig_probes",
    "fig_cornell",
    "fig_lroom",
    "fig_atrium",
    "fig_attic",
    "fig_glossy",
    "fig_hitcache",
]
SWEEPS = ["sweep", "sweep_cornell", "sweep_lroom", "sweep_atrium", "sweep_glossy"]


def figure_cases(name, root=Path(".")):
    path = root / "configs" / f"{name}.toml"
    cfg, scene, methods = load_figure_config(path)
    return [(f"{name}-{s}", scene.with_updates(o, source=str(path))) for s, _, o in cfg.case_list()], methods


def sweep_cases(name, root=Path(".")):
    sw = load_sweep(root / "configs" / f"{name}.toml")
    return [(c.id, c.scene) for c in sw.cases], sw.methods


def _object_rays(scene) -> tuple[int, int]:
    """(object rays, rays whose exact hit is hidden from the reference point), as run_case counts them."""
    tracer = make_tracer(scene.mesh())
    rays = shading.object_rays(scene, occluder=tracer.distance)
    o = np.asarray(scene.reference.point, float)
    ex_o, ex_d = rays.exact_rays()
    hit = tracer.intersect(ex_o, ex_d)["point"]
    escapes = ~np.all(np.isfinite(hit), axis=-1)  # open environments: "no surface", at infinity
    hit[escapes] = ex_o[escapes] + ex_d[escapes] * FAR
    hit = hit - o
    dist = np.linalg.norm(hit, axis=-1)
    seen = tracer.distance(np.broadcast_to(o, hit.shape), hit / dist[:, None])
    return len(rays.x), int((seen < dist * (1 - 1e-4) - 1e-5).sum())


# ---------------------------------------------------------------------------------------------- the mechanism
def test_frame_object_aims_and_zooms_from_the_same_eye():
    """target = the object's centre; the bounding sphere's image spans frame_fill of the frame's smaller side, so
    its pixels are π (fill · side / 2)² wherever it stands; moving the object (as a sweep does) reframes it."""
    base = load_scene_file("scenes/room.toml").with_updates({"camera.width": 200, "camera.height": 100})
    s = base.with_updates({"camera.frame_object": True, "camera.frame_fill": 0.5})
    assert s.camera.eye == base.camera.eye and s.camera.target == s.object.center
    assert math.isclose(budget.object_pixels(s), math.pi * (0.5 * 100 / 2) ** 2, rel_tol=1e-9)
    moved = s.with_updates({"object.center": [1.4, 0.7, 1.0]})
    assert moved.camera.target == (1.4, 0.7, 1.0) and moved.camera.fov < s.camera.fov  # farther: narrower
    assert math.isclose(budget.object_pixels(moved), budget.object_pixels(s), rel_tol=1e-9)
    n, _ = _object_rays(s.with_updates({"render.supersample": 1}))
    assert abs(n - math.pi * 25**2) < 0.03 * math.pi * 25**2  # pixel centres inside the disc


def test_framing_keys_leave_content_keys_alone():
    """A framed camera and the same camera written out by hand have one content key (cached results shared), and
    scenes without framing keep the keys they had."""
    s = load_scene_file("scenes/room.toml").with_updates({"camera.frame_object": True})
    by_hand = load_scene_file("scenes/room.toml").with_updates(
        {"camera.target": list(s.camera.target), "camera.fov": s.camera.fov}
    )
    assert key_fields(s) == key_fields(by_hand)
    assert "frame_object" not in json.dumps(key_fields(by_hand))


@pytest.mark.parametrize(
    "over, key",
    [
        ({"camera.eye": [0.6, 1.2, 0.5]}, "camera.eye"),  # inside the object
        ({"camera.frame_fill": 0}, "camera.frame_fill"),
        ({"camera.frame_fill": 1.5}, "camera.frame_fill"),
        ({"camera.frame_object": "yes"}, "camera.frame_object"),
    ],
)
def test_frame_object_refusals_name_the_key(over, key):
    with pytest.raises(StudyError) as e:
        load_scene_file("scenes/room.toml").with_updates({"camera.frame_object": True, **over})
    assert e.value.key == key


# ---------------------------------------------------------------------------------------------- shipped configs
def test_reproduce_runs_these_configs():
    script = Path("scripts/reproduce.sh").read_text()
    figures = set(re.findall(r'"figure (fig\w*)"', script))
    sweeps = set(re.findall(r'"sweep configs/(sweep\w*)\.toml', script))
    assert figures == set(FIGURES)
    assert sweeps == set(SWEEPS)


def test_every_case_has_enough_object_rays_and_fig5_enough_hidden_ones():
    """Counted exactly (the camera's sub-pixel rays that hit the object and the rays they send out, as run_case
    counts them; cube resolution and samples do not change them, so each geometry is counted once)."""
    counted, short = {}, []
    for name in FIGURES + SWEEPS:
        cases, _ = figure_cases(name) if name in FIGURES else sweep_cases(name)
        for cid, sc in cases:
            k = key_fields(sc)
            k["render"] = {
                a: b for a, b in k["render"].items() if a not in ("cube_res", "cube_spp", "spp", "seed")
            }
            k = json.dumps(k, sort_keys=True)
            if k not in counted:
                counted[k] = _object_rays(sc)
            n, hidden = counted[k]
            if n < MIN_RAYS or (name == "fig5" and hidden < MIN_HIDDEN):
                short.append(f"{cid}: {n} rays, {hidden} hidden")
    assert not short, short
