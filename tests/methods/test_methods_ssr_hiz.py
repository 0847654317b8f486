"""ssr_hiz: the Hi-Z march over the camera's depth buffer (Embree) of the small room, against Embree, its slow twin
and the DDA of ``ssr``."""

import dataclasses

import numpy as np
import pytest
from conftest import BACKENDS, load_script, small_scene_dict

from study import backend as backends
from study import methods
from study.impostor import analytic
from study.impostor.envmap import EnvMap
from study.impostor.screen import ScreenView, depth_buffer, normal_buffer
from study.impostor.views import Captured
from study.measure import outcomes
from study.methods import ssr_hiz as H
from study.reference.embree import Tracer
from study.scene import scene_from_dict
from study.scene.camera import camera_rays

W = 48
COLUMN = {"center": [-0.8, 0.3], "footprint": [0.5, 0.5], "height": 2.0}


@pytest.fixture(scope="module")
def room():
    """The small room with a column, a 48² camera; the colour buffer holds each pixel's surface point (world)."""
    d = small_scene_dict(camera={**small_scene_dict()["camera"], "width": W, "height": W}, columns=[COLUMN])
    s = scene_from_dict(d)
    tracer = Tracer(s.mesh())
    o = np.asarray(s.reference.point)
    eo, ed = (a.reshape(-1, 3) for a in camera_rays(s.camera, 1))
    colour = (eo + ed * tracer.distance(eo, ed)[:, None]).reshape(W, W, 3).astype(np.float32)
    return s, tracer, o, colour


def _rays(s, tracer, o, n=3000, seed=3):
    """Origins on camera rays (on screen), random directions; exact hits, which of them the camera sees, and one
    pixel's footprint at each hit."""
    rng = np.random.default_rng(seed)
    eo, ed = (a.reshape(-1, 3) for a in camera_rays(s.camera, 1))
    pick = rng.integers(0, len(ed), n)
    x = eo[pick] + ed[pick] * (tracer.distance(eo[pick], ed[pick]) * rng.uniform(0.3, 0.8, n))[:, None]
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    exact = tracer.intersect(x, d)["point"]
    eye = np.asarray(s.camera.eye)
    to = exact - eye
    dist = np.linalg.norm(to, axis=1)
    seen = ~outcomes.off_screen(s.camera, exact) & (
        tracer.distance(np.tile(eye, (n, 1)), to / dist[:, None]) > dist - 1e-3
    )
    f = np.subtract(s.camera.target, s.camera.eye)
    foot = (to @ (f / np.linalg.norm(f))) * 2 * np.tan(np.radians(s.camera.fov) / 2) / W
    return x - o, d, exact - o, seen, foot


def _env(B, s, tracer, o, colour, depth=None, normals=True):
    """The views of a case (the G-buffer's normals with ``normals``, else the depths stand in for them)."""
    lo, hi = np.asarray(s.room.min) - o, np.asarray(s.room.max) - o
    z = depth_buffer(s, tracer) if depth is None else depth
    n = normal_buffer(s, tracer) if normals else None
    return Captured(
        impostor=EnvMap(analytic.box_impostor(32, lo, hi), B),
        reference=o,
        room=(s.room.min, s.room.max),
        screen=ScreenView(z, colour, s.camera, o, B, normals=n),
    )


def _trace(B, env, x, d, name="ssr_hiz", **kw):
    m = methods.make(name, **kw)
    with np.errstate(all="ignore"):
        tr = m.trace(B, env, B.vec(x), B.vec(d))
    spent = B.numpy(tr.lookups).astype(float)
    assert spent.max() <= m.lookups_per_ray()
    return spent.mean(), B.to_numpy(tr.shown).astype(float), B.numpy(tr.valid).astype(bool)


def test_pyramid_levels_are_the_minima_of_their_pixels():
    """Level m of the pyramid holds the minimum of d = −1/z over its 2^m × 2^m pixels (numpy block minima), the
    padding and pixels that see no surface at d = 0; HiZ.cell (by 1/2^m) returns those cells on every backend, every
    cell of every level (the rows of S cells, level m from row 2S − 2S/2^m), and HiZ.read clamps cells off the
    level into it."""
    rng = np.random.default_rng(0)
    z = rng.uniform(0.5, 9.0, (20, 27)).astype(np.float32)
    z[3, 4] = 3e38  # sees no surface
    levels = H.hiz_levels(z)
    assert [a.shape[0] for a in levels] == [32, 16, 8, 4, 2, 1]
    d = np.zeros((32, 32))
    d[:20, :27] = np.where(z < 1e30, -1.0 / z, 0.0)
    for m, a in enumerate(levels):
        k = 2**m
        np.testing.assert_allclose(a, d.reshape(32 // k, k, 32 // k, k).min(axis=(1, 3)), rtol=1e-6)
    for name in BACKENDS:
        B = backends.get(name)
        hz = H.HiZ(z, B)
        for m, a in enumerate(levels):
            cy, cx = (g.ravel().astype(np.float32) for g in np.indices(a.shape))
            inv = B.array(np.full(cx.size, 2.0**-m, np.float32))
            got = B.numpy(hz.cell(inv, B.array(cx), B.array(cy)))
            assert got.tobytes() == a.ravel().tobytes(), m
        cx, cy = np.array([-3.0, 5, 40, np.inf]), np.array([0.0, -1, 7, 2])
        inv = B.array(np.full(4, 0.25, np.float32))
        got = B.numpy(hz.read(inv, B.array(cx), B.array(cy)))
        assert got.tobytes() == levels[2][[0, 0, 7, 2], [0, 5, 7, 0]].tobytes()


@pytest.mark.parametrize("name", BACKENDS)
def test_march_follows_its_slow_twin(room, name):
    """The vectorized march and the one-ray loop of hiz_march_ref (cell minima from level 0) end at the same
    place after the same reads on ≥ 98 % of the rays (the rest: float32 against float64 at a plane)."""
    s, tracer, o, colour = room
    x, d, _, _, _ = _rays(s, tracer, o, n=300)
    B = backends.get(name)
    env = _env(B, s, tracer, o, colour)
    r = H.screen_ray(B, env.screen, B.vec(x), B.vec(d))
    t, _, reads, _ = H.hiz_march(B, env.screen, H.hiz_of(env.screen), r, 64)
    t, reads = B.numpy(t).astype(float), B.numpy(reads)
    start = B.numpy(r.start).astype(bool)
    assert start.mean() > 0.9
    depth = depth_buffer(s, tracer)
    same = []
    for k in np.flatnonzero(start):
        P0 = [float(B.numpy(a)[k]) for a in (r.px0, r.py0, r.d0)]
        D = [float(B.numpy(a)[k]) for a in (r.Dx, r.Dy, r.Dd)]
        t_ref, _, n_ref = H.hiz_march_ref(depth, P0, D, 64)
        same.append(n_ref == reads[k] and abs(t_ref - t[k]) <= 1e-3 * max(1.0, abs(t_ref)))
    assert np.mean(same) >= 0.98, np.mean(same)


@pytest.mark.parametrize("name", BACKENDS)
def test_hiz_against_ssr_false_and_missed_hits(room, name):
    """Screen space alone (fallback none), rays from on screen in the room with a column. A *false hit*: a ray shown
    farther than 1.5 pixel footprints from its exact hit; a *missed hit*: no hit on a ray whose exact hit the
    camera sees. Measured at 48² (3000 rays): ssr 1.05 % false, 3.2 % missed, 17.6 reads; ssr_hiz 0.25 % false,
    21 % missed (its confidence rejects hits whose ray point lies ≳ 9 cm off the pixel's depth, thickness 0.25 m),
    9.5 lookups; at 128²: ssr 1.25 % / 0.42 % / 45 reads, ssr_hiz 0.08 % / 11 % / 12. So Hi-Z: fewer false
    hits and far fewer reads, more missed hits (which its blend sends to the environment). The hybrid (proxy_box
    fallback) answers every ray."""
    s, tracer, o, colour = room
    x, d, exact, seen, foot = _rays(s, tracer, o)
    B = backends.get(name)
    env = _env(B, s, tracer, o, colour)
    out = {}
    for m in ("ssr", "ssr_hiz"):
        spent, shown, valid = _trace(B, env, x, d, m, fallback="none")
        good = valid & (np.linalg.norm(shown - exact, axis=1) <= 1.5 * foot)
        out[m] = (np.mean(valid & ~good), np.mean(~valid[seen]), spent)
    (f0, m0, c0), (f1, m1, c1) = out["ssr"], out["ssr_hiz"]
    assert f1 < 0.006 and f1 < f0 < 0.02
    assert m0 < 0.05 and 0.1 < m1 < 0.3
    assert c1 < 0.8 * c0
    _, shown, valid = _trace(B, env, x, d)
    assert valid.all() and np.isfinite(shown).all()


def test_validation_rejects_what_sssr_rejects(room):
    """A depth buffer 0.5 m too deep: the march finds the wrong surfaces, so few shown points are right (the test
    above can fail). A back face (the ray's direction reversed at the same hit) has
    confidence 0; max_iterations = 2 leaves most hits unfound, spending ≤ 2 + 5 lookups; min_occupancy = 32 stops
    every wave after its first read (a host loop: the budget counts its steps)."""
    s, tracer, o, colour = room
    B = backends.get("numpy")
    x, d, exact, seen, foot = _rays(s, tracer, o, n=1000)
    env = _env(B, s, tracer, o, colour)
    _, shown, valid = _trace(B, env, x, d, fallback="none")
    good = valid & (np.linalg.norm(shown - exact, axis=1) <= 1.5 * foot)
    assert good[seen].mean() > 0.7
    bad = _env(B, s, tracer, o, colour, depth=depth_buffer(s, tracer) + 0.5)
    _, shown, valid = _trace(B, bad, x, d, fallback="none")
    assert (valid & (np.linalg.norm(shown - exact, axis=1) <= 1.5 * foot))[seen].mean() < 0.2
    m = methods.make("ssr_hiz")
    r = H.screen_ray(B, env.screen, B.vec(x), B.vec(d))
    t, _, _, on = H.hiz_march(B, env.screen, H.hiz_of(env.screen), r, 128)
    c, _ = m.confidence(B, env.screen, r, t, on)
    flipped = dataclasses.replace(r, Rc=tuple(-a for a in r.Rc))
    c_back, _ = m.confidence(B, env.screen, flipped, t, on)
    hit = c > 0.5
    assert hit.mean() > 0.2 and np.all(c_back[hit] == 0.0)
    spent, _, valid2 = _trace(B, env, x, d, max_iterations=2, fallback="none")
    assert valid2[seen].mean() < 0.5 and spent <= 7
    r = H.screen_ray(B, env.screen, B.vec(x), B.vec(d))
    _, _, reads, _ = H.hiz_march(B, env.screen, H.hiz_of(env.screen), r, 128, min_occupancy=32)
    assert reads.max() == 1.0
    assert (
        methods.make("ssr_hiz", min_occupancy=4).host_steps() == 128
        and methods.make("ssr_hiz").host_steps() == 0
    )


def test_without_a_screen_every_ray_goes_to_the_fallback(room):
    """A bare impostor (no camera buffer): ssr_hiz is its fallback, ray for ray and lookup for lookup."""
    s, tracer, o, _ = room
    B = backends.get("numpy")
    x, d, _, _, _ = _rays(s, tracer, o, n=500)
    lo, hi = np.asarray(s.room.min) - o, np.asarray(s.room.max) - o
    env = EnvMap(analytic.box_impostor(32, lo, hi), B)
    a = _trace(B, env, x, d, fallback="localized")
    b = _trace(B, env, x, d, "localized")
    assert a[0] == b[0] and np.array_equal(a[2], b[2])
    np.testing.assert_array_equal(a[1][a[2]], b[1][b[2]])


@pytest.mark.skipif("llvm" not in BACKENDS, reason="needs Dr.Jit's LLVM backend")
@pytest.mark.parametrize("name", ["ssr", "ssr_hiz", "probe_blend"])
def test_bench_times_the_screen_march_frozen(room, name):
    """As ``study bench`` runs them: with the camera's buffer (bench_screen, its texture and pyramid arguments of the
    frozen function) the screen methods march on screen (more lookups than their fallback alone), the frozen call,
    replayed, gives the plain call's points, and both match numpy on ≥ 99 % of the rays; probe_blend freezes with
    the impostor as its only probe."""
    from study.bench.timing import bench_screen, camera_depth, method_runner

    s, tracer, o, _ = room
    x, d, _, _, _ = _rays(s, tracer, o, n=1000)
    lo, hi = np.asarray(s.room.min) - o, np.asarray(s.room.max) - o
    tex = analytic.box_impostor(32, lo, hi)
    info = {"reference": tuple(o), "room": (s.room.min, s.room.max)}
    depth = camera_depth(s.camera, tracer)
    m = methods.make(name)
    out = {}
    for nm, frozen in (("llvm", False), ("llvm", True), ("numpy", False)):
        B = backends.get(nm)
        scr = bench_screen(depth, s.camera, o, B)
        call, finish = method_runner(m, B, tex, x, d, frozen=frozen, info=info, screen=scr)
        res = call()
        finish(res)
        res = call()  # frozen: a replay
        finish(res)
        out[(nm, frozen)] = (B.to_numpy(res[0]), float(np.mean(B.numpy(res[4]))))
    np.testing.assert_allclose(out[("llvm", True)][0], out[("llvm", False)][0], rtol=1e-6)
    a, b = out[("numpy", False)][0], out[("llvm", False)][0]
    both = np.isfinite(a).all(1) & np.isfinite(b).all(1)
    assert np.mean(both) > 0.9 and np.mean(np.linalg.norm(a[both] - b[both], axis=1) < 1e-3) >= 0.99
    if name != "probe_blend":
        assert out[("llvm", True)][1] > methods.make("proxy_box").lookups_per_ray() + 5


def test_normals_from_depth_agree_with_the_g_buffer(room):
    """The G-buffer's normals (Embree's triangles, turned towards the camera) are unit and face the camera; the
    normals ssr_hiz reconstructs from the depths alone (a buffer without normals, as the bench's) agree with them
    within 5° on ≥ 90 % of the pixels (the rest: silhouettes, where a neighbour on either side lies on another
    surface)."""
    s, tracer, o, colour = room
    B = backends.get("numpy")
    scr = _env(B, s, tracer, o, colour).screen
    i, j = (a.ravel().astype(np.float32) for a in np.mgrid[0:W, 0:W])
    g = np.stack(scr.fetch_normal(j, i), 1)
    eo, ed = (a.reshape(-1, 3) for a in camera_rays(s.camera, 1))
    assert np.allclose(np.linalg.norm(g, axis=1), 1, atol=1e-5) and np.all(np.sum(g * ed, 1) < 0)
    zs = scr.fetch(j, i)[3]
    n = H.depth_normal(B, scr, j, i, zs)
    rec = np.stack([n.x, n.y, n.z], 1) @ np.stack([scr.right, scr.up, scr.forward])  # camera axes → world
    cos = np.sum(rec * g, 1) / np.linalg.norm(rec, axis=1)
    assert np.mean(cos > np.cos(np.radians(5))) >= 0.9  # measured 93 %


# ---------------------------------------------------------------------------------------------- fewer instructions
def test_the_march_step_reads_one_cell_and_nothing_else(tmp_path):
    """The Hi-Z march's loop, counted in Dr.Jit's LLVM IR (scripts/march_ir.py on the bench's close-up rays, issue
    56): one gather per step (the cell; no table of the level's offset, side and cell size read before it), no
    division and no double. At 91494d0: 103 instructions (test 30, body 73), 4 gathers (3 of them the level's
    table), 2 divisions, 4 loop variables; measured now: 75 (21, 54), 1 gather, no division, 7 variables (the ray's
    pixel position carried, the cell size and its inverse for the level). Bounds with a small margin for Dr.Jit's
    code generation."""
    if "llvm" not in BACKENDS:
        pytest.skip("needs Dr.Jit's LLVM backend")
    (march,) = load_script("march_ir").method_loops("ssr_hiz", {}, tmp_path)
    assert march["gathers"] == 1 and march["f64"] == 0, march
    assert march["ops"] <= 80 and march["cond"] <= 24, march
    ir = (tmp_path / f"ssr_hiz-{march['kernel']}.ll").read_text()
    loop = ir[ir.index(f"l_{march['loop']}_cond:") : ir.index(f"l_{march['loop']}_done:")]
    assert "fdiv" not in loop and "fdiv" in ir  # (the kernel divides, outside the loop)


def test_the_screen_buffers_from_one_cast_are_intersect_s(room):
    """buffers() (one cast of the pixel rays, in chunks at once) gives the depth and normals made from
    Tracer.intersect's t and prim of one whole cast, bit for bit; 64² rays, so that 3 chunks are cast."""
    from study.impostor.screen import buffers

    s, _, _, _ = room
    s = s.model_copy(update={"camera": s.camera.model_copy(update={"width": 64, "height": 64})})
    tracer = Tracer(s.mesh(), threads=3)
    eo, ed = (a.reshape(-1, 3) for a in camera_rays(s.camera, 1))
    hit = tracer.intersect(eo, ed)
    f = np.subtract(s.camera.target, s.camera.eye)
    f = f / np.linalg.norm(f)
    depth = (hit["t"] * (ed @ f)).reshape(64, 64).astype(np.float32)
    prim = hit["prim"]
    tri = tracer.mesh.vertices[tracer.mesh.faces[np.maximum(prim, 0)]].astype(np.float64)
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    n *= np.where(np.sum(n * ed, axis=1) > 0, -1.0, 1.0)[:, None]
    n[prim < 0] = 0.0
    got_depth, got_n = buffers(s, tracer)
    assert np.isinf(depth).any() or (prim >= 0).all()
    np.testing.assert_array_equal(got_depth, depth)
    np.testing.assert_array_equal(got_n, n.reshape(64, 64, 3).astype(np.float32))
    np.testing.assert_array_equal(got_depth, depth_buffer(s, tracer))
    np.testing.assert_array_equal(got_n, normal_buffer(s, tracer))
