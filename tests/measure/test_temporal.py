"""The torch-free temporal error (study.measure.temporal): the exact flow against frames whose colour is painted
on the surfaces (so the truth of the warp is known), zero motion reads every pixel back (E_warp 0), a planted
flicker is caught, disoccluded pixels are masked, the projection inverts the camera's rays, and frames that differ
in more than the motion are refused in one line."""

import numpy as np
import pytest

from study.errors import StudyError
from study.measure import temporal
from study.reference.tracer import make_tracer
from study.scene import camera_rays, scene_from_dict
from tests.conftest import small_scene_dict

CENTERS = [[0.6, 1.2, 0.3], [0.66, 1.17, 0.33], [0.72, 1.14, 0.36], [0.78, 1.11, 0.39]]


@pytest.fixture(scope="module")
def frames():
    """Four frames of the sphere stepping 7 cm at a time (64², one ray per pixel), and the environment's tracer."""
    d = small_scene_dict()
    d["camera"].update(width=64, height=64)
    first = scene_from_dict(d, source="test")
    scenes = [first.with_updates({"object.center": c}) for c in CENTERS]
    return scenes, make_tracer(first.mesh())


def painted(scene, tracer):
    """A frame (H, W, 3) whose colour is painted on the surfaces: a function of the point in the object's own
    frame on the object, of the world point elsewhere — what a perfectly stable renderer would show."""
    o, d = camera_rays(scene.camera, 1)
    H, W = d.shape[:2]
    o, d = o.reshape(-1, 3), d.reshape(-1, 3)
    t_env, t_obj = temporal._first_hits(scene, tracer, o, d)
    on = t_obj < t_env
    x = o + d * np.minimum(t_env, t_obj)[:, None]
    local = x - np.asarray(scene.object.center)
    img = np.where(on[:, None], 0.5 + 0.4 * np.sin(7 * local + [0, 1, 2]), 0.2 + 0.1 * np.cos(3 * x))
    return img.reshape(H, W, 3)


def test_projection_inverts_the_camera_rays(frames):
    scenes, _ = frames
    cam = scenes[0].camera
    o, d = camera_rays(cam, 1)
    pts = (o + 2.5 * d).reshape(-1, 3)
    rc = temporal.project(cam, pts)
    rows, cols = np.meshgrid(np.arange(cam.height), np.arange(cam.width), indexing="ij")
    np.testing.assert_allclose(rc, np.stack([rows.ravel(), cols.ravel()], -1), atol=1e-9)
    dirs = temporal.project(cam, d.reshape(-1, 3), at_infinity=np.ones(len(pts), bool))
    np.testing.assert_allclose(dirs, rc, atol=1e-9)


def test_zero_motion_gives_zero_ewarp(frames):
    """A frame warped onto itself with no motion: the flow is the pixel grid, every pixel of one surface is
    valid, and E_warp is exactly 0."""
    scenes, tracer = frames
    flow = temporal.exact_flow(scenes[0], scenes[0], tracer)
    rows, cols = np.meshgrid(np.arange(64), np.arange(64), indexing="ij")
    np.testing.assert_allclose(flow.coords, np.stack([rows, cols], -1), atol=1e-9)
    assert flow.valid[flow.surface != temporal.MIXED].all()
    img = painted(scenes[0], tracer)
    e = temporal.ewarp(img, img, flow)
    assert (
        e["ewarp_l2"] == 0 and e["ewarp_flip"] == 0 and e["ewarp_pixels"] == (flow.surface == 1).sum() > 100
    )


def test_exact_flow_follows_the_painted_surfaces(frames):
    """The previous frame brought along the exact flow matches the next frame up to bilinear interpolation: its
    E_warp is a small fraction of what the same frames give with no motion assumed."""
    scenes, tracer = frames
    a, b = scenes[0], scenes[1]
    flow = temporal.exact_flow(a, b, tracer)
    ia, ib = painted(a, tracer), painted(b, tracer)
    on = flow.valid & (flow.surface == temporal.OBJECT)
    still = temporal.Flow(temporal.exact_flow(a, a, tracer).coords, flow.valid, flow.surface)
    moved, naive = temporal.ewarp(ia, ib, flow), temporal.ewarp(ia, ib, still, region=on)
    assert moved["ewarp_pixels"] == naive["ewarp_pixels"] > 80
    assert moved["ewarp_l2"] < naive["ewarp_l2"] / 30 and moved["ewarp_flip"] < naive["ewarp_flip"] / 3


def test_a_planted_flicker_is_caught(frames):
    """Painted frames along the path, then the same with every other frame's object 15 % brighter: the stable
    sequence's E_warp is small, the flickering one's many times larger, at every step."""
    scenes, tracer = frames
    flows = temporal.sequence_flows(scenes, tracer)
    clean = [painted(s, tracer) for s in scenes]
    flicker = [
        np.where((f.surface == temporal.OBJECT)[..., None] & (k % 2 == 1), img * 1.15, img)
        for k, (img, f) in enumerate(zip(clean, [flows[0], *flows]))
    ]
    stable, steps = temporal.sequence_ewarp(clean, flows)
    flick, fsteps = temporal.sequence_ewarp(flicker, flows)
    assert len(steps) == len(scenes) - 1
    assert flick["ewarp_l2"] > 10 * stable["ewarp_l2"] and flick["ewarp_flip"] > 2 * stable["ewarp_flip"]
    assert all(f["ewarp_l2"] > 5 * s["ewarp_l2"] for f, s in zip(fsteps, steps))


def test_occlusion_mask_excludes_disoccluded_pixels(frames):
    """Background the sphere covered a frame earlier is not compared (it was not seen); background it covers in
    neither frame is, and so is the sphere's surface seen in both. A step across the frame uncovers more."""
    scenes, tracer = frames
    a, b = scenes[0], scenes[3]  # a step of 21 cm
    flow = temporal.exact_flow(a, b, tracer)
    sa, sb = temporal.surfaces(a, tracer), temporal.surfaces(b, tracer)
    uncovered = (sa != temporal.ENV_SURFACE) & (sb == temporal.ENV_SURFACE)
    assert uncovered.sum() > 20 and not flow.valid[uncovered].any()
    never = (sa == temporal.ENV_SURFACE) & (sb == temporal.ENV_SURFACE)
    inner = never.copy()  # away from the sphere by a pixel: the bilinear lookup reads background only
    for ax in (0, 1):
        for s in (1, -1):
            inner &= np.roll(never, s, axis=ax)
    assert flow.valid[inner].all()
    assert flow.valid[(sa == temporal.OBJECT) & (sb == temporal.OBJECT)].mean() > 0.6
    assert not flow.valid[sb == temporal.MIXED].any()
    # the sphere's far side coming into view: a point of b's sphere whose spot on a's sphere faced away
    moved_back = temporal.exact_flow(b, a, tracer)  # the other way round: uncovered pixels of a
    assert not moved_back.valid[(sb != temporal.ENV_SURFACE) & (sa == temporal.ENV_SURFACE)].any()


def test_frames_that_differ_in_more_than_the_motion_are_refused(frames):
    scenes, tracer = frames
    other = scenes[1].with_updates({"object.radius": 0.3})
    with pytest.raises(StudyError) as err:
        temporal.exact_flow(scenes[0], other, tracer)
    text = str(err.value)
    assert "differ only in object.center and the camera; these differ in object" in text and "\n" not in text
