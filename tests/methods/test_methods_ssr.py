"""ssr: screen-space ray tracing through the camera's depth buffer (Embree) of the small room, against Embree."""

import dataclasses

import numpy as np
import pytest
from conftest import small_scene_dict

from study import backend as backends
from study import methods
from study.impostor import analytic
from study.impostor.envmap import EnvMap
from study.impostor.screen import ScreenView, depth_buffer
from study.impostor.views import Captured
from study.measure import outcomes
from study.reference.embree import Tracer
from study.scene import scene_from_dict
from study.scene.camera import camera_rays

W = 48


@pytest.fixture(scope="module")
def room():
    """The small room (no columns: the box proxy is exact), a 48² camera; the colour buffer holds each pixel's
    surface point (world), so the radiance a method reads tells which pixel it took."""
    s = scene_from_dict(small_scene_dict(camera={**small_scene_dict()["camera"], "width": W, "height": W}))
    tracer = Tracer(s.mesh())
    o = np.asarray(s.reference.point)
    eo, ed = (a.reshape(-1, 3) for a in camera_rays(s.camera, 1))
    colour = (eo + ed * tracer.distance(eo, ed)[:, None]).reshape(W, W, 3).astype(np.float32)
    return s, tracer, o, colour


def _rays(s, tracer, o, n=3000, seed=3):
    """Origins on camera rays (so on screen), random directions; exact hits (Embree), relative to o."""
    rng = np.random.default_rng(seed)
    eo, ed = (a.reshape(-1, 3) for a in camera_rays(s.camera, 1))
    pick = rng.integers(0, len(ed), n)
    x = eo[pick] + ed[pick] * (tracer.distance(eo[pick], ed[pick]) * rng.uniform(0.3, 0.8, n))[:, None]
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    return x - o, d, tracer.intersect(x, d)["point"] - o


def _env(B, s, tracer, o, colour):
    lo, hi = np.asarray(s.room.min) - o, np.asarray(s.room.max) - o
    return Captured(
        impostor=EnvMap(analytic.box_impostor(32, lo, hi), B),
        reference=o,
        room=(s.room.min, s.room.max),
        screen=ScreenView.of_scene(s, colour, tracer, B),
    )


def _trace(B, env, x, d, **kw):
    m = methods.make("ssr", **kw)
    with np.errstate(all="ignore"):
        tr = m.trace(B, env, B.vec(x), B.vec(d))
    return (
        float(np.mean(B.numpy(tr.lookups))),  # lookups the rays spent, on average
        B.to_numpy(tr.shown).astype(float),
        B.to_numpy(tr.radiance).astype(float),
        B.numpy(tr.valid).astype(bool),
    )


def test_depth_buffer_is_the_embree_z_depth(room):
    """The buffer is z = t (d·f) of the pixel-centre rays; the room's far wall straight ahead reads its plane."""
    s, tracer, o, _ = room
    z = depth_buffer(s, tracer)
    assert z.shape == (W, W) and np.isfinite(z).all() and (z > 0).all()
    eo, ed = (a.reshape(-1, 3) for a in camera_rays(s.camera, 1))
    f = np.subtract(s.camera.target, s.camera.eye)
    f /= np.linalg.norm(f)
    np.testing.assert_allclose(z.ravel(), tracer.distance(eo, ed) * (ed @ f), rtol=1e-5)


def test_ssr_finds_the_exact_hit_on_screen_and_says_no_hit_off_screen(room, B):
    """Rays whose exact hit is on screen (the room has nothing that hides a surface from the camera): ≥ 96 % shown
    within 1.5 pixel footprints of the exact hit (the buffer holds one depth per pixel; the rest are rays that cross
    a surface seen obliquely between pixel centres by more than the thickness, 0.25 m), and the colour read is that
    of a pixel within 2 footprints of the hit. Rays whose exact hit is off screen: no hit (≤ 0.5 % just beyond the
    screen's edge are found within the thickness at the last pixel, within one footprint of the exact hit). The hybrid
    with the box proxy (exact in this room) is within 1.5 footprints or 3 mm on ≥ 97 % of all rays."""
    s, tracer, o, colour = room
    x, d, exact = _rays(s, tracer, o)
    env = _env(B, s, tracer, o, colour)
    off = outcomes.off_screen(s.camera, exact + o)
    assert 0.3 < off.mean() < 0.8  # both kinds are well represented
    spent, shown, rad, valid = _trace(B, env, x, d, fallback="none")  # screen-space alone
    z = (exact + o - np.asarray(s.camera.eye)) @ env.screen.forward
    foot = z * 2 * np.tan(np.radians(s.camera.fov) / 2) / W  # one pixel at the hit's depth
    err = np.linalg.norm(shown - exact, axis=1)
    assert np.mean(err[~off] <= 1.5 * foot[~off]) >= 0.96
    assert np.mean(np.linalg.norm(rad - (exact + o), axis=1)[~off] <= 2 * foot[~off]) >= 0.97
    assert (
        np.isnan(shown[off & ~valid]).all() and valid[off].mean() <= 0.005
    )  # no hit, except at the very edge:
    assert np.all(err[off & valid] <= foot[off & valid])  # there within a pixel of the hit
    assert 1 < spent < 2 * W < methods.make("ssr").lookups_per_ray()  # steps actually taken, not the budget
    _, shown_fb, _, valid_fb = _trace(B, env, x, d)  # the default: proxy_box fallback
    err = np.linalg.norm(shown_fb - exact, axis=1)
    assert valid_fb.all() and np.mean((err <= 1.5 * np.abs(foot)) | (err < 3e-3)) >= 0.97  # float32: mm


def test_ssr_misses_what_the_camera_cannot_see_and_a_small_budget_shows(room, B):
    """A depth buffer that is wrong by 0.5 m (the far side of every surface) makes the same rays fail: the test
    above can fail. A step budget of 2 pixels leaves most on-screen hits unfound (no hit), and reports fewer
    lookups than the full budget."""
    s, tracer, o, colour = room
    x, d, exact = _rays(s, tracer, o, n=800)
    off = outcomes.off_screen(s.camera, exact + o)
    env = _env(B, s, tracer, o, colour)
    scr = env.screen
    shifted = ScreenView(depth_buffer(s, tracer) + 0.5, colour, s.camera, o, B)
    bad = dataclasses.replace(
        env, impostor=EnvMap(analytic.box_impostor(8, [-2, -1.5, -2], [2, 1.5, 2]), B), screen=shifted
    )
    _, shown, _, _ = _trace(B, bad, x, d, fallback="none")
    assert np.mean(np.linalg.norm(shown - exact, axis=1)[~off] < 0.1) < 0.5
    spent, shown, _, valid = _trace(B, env, x, d, max_steps=2, fallback="none")
    assert valid[~off].mean() < 0.5 and spent <= 3
    assert scr.width == W


def test_numpy_and_llvm_agree(room):
    if "llvm" not in __import__("conftest").BACKENDS:
        pytest.skip("no LLVM")
    s, tracer, o, colour = room
    x, d, _ = _rays(s, tracer, o, n=1000)
    out = []
    for name in ("numpy", "llvm"):
        B = backends.get(name)
        spent, shown, rad, valid = _trace(B, _env(B, s, tracer, o, colour), x, d, fallback="localized")
        out.append((shown, rad, valid, spent))
    (s0, _, v0, c0), (s1, _, v1, c1) = out
    assert np.mean(v0 == v1) >= 0.998 and abs(c0 - c1) < 0.5
    both = v0 & v1
    assert np.mean(np.linalg.norm(s0[both] - s1[both], axis=1) < 1e-3) >= 0.995


def test_off_screen_and_the_projection_agree_with_the_camera_rays(room):
    """Points along the camera's own pixel-centre rays are on screen and project to those pixels' centres
    (ScreenView.project); points behind the eye, or along rays 1.2× beyond the frame's edges, are off screen."""
    s, tracer, o, colour = room
    B = backends.get("numpy")
    eo, ed = (a.reshape(-1, 3) for a in camera_rays(s.camera, 1))
    pts = eo + ed * 2.5
    assert not outcomes.off_screen(s.camera, pts).any()
    assert outcomes.off_screen(s.camera, eo - ed * 2.5).all()  # behind the camera
    px, py, _ = ScreenView(depth_buffer(s, tracer), colour, s.camera, o, B).project(B.vec(pts - o))
    j, i = np.meshgrid(np.arange(W) + 0.5, np.arange(W) + 0.5)
    np.testing.assert_allclose(px, j.ravel(), atol=1e-3)
    np.testing.assert_allclose(py, i.ravel(), atol=1e-3)
    f = np.subtract(s.camera.target, s.camera.eye)
    f /= np.linalg.norm(f)
    side = ed - f * (ed @ f)[:, None]  # stretch the frame by 1.2
    out = f * (ed @ f)[:, None] + side * 1.2
    edge = (np.abs(j.ravel() - W / 2) > W / 2 - 1) | (np.abs(i.ravel() - W / 2) > W / 2 - 1)
    assert outcomes.off_screen(s.camera, eo + out * 2.5)[edge].all()
