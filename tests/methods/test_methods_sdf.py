"""sdf: sphere tracing through a signed distance grid of the environment's triangles (study.impostor.sdf).

References, all independent of the grid's code: trimesh's exact closest points (the grid's values), the analytic
box (an empty room's hits), Embree's exact hits (fig5's column top), Mitsuba's ``sdfgrid`` shape (exact ray /
trilinear-cell intersection on the very same grid: the tracing error alone)."""

import numpy as np
import pytest
from conftest import small_scene_dict

from study import backend as backends
from study import methods
from study.cache import Cache
from study.cache import flush as cache_flush
from study.errors import StudyError
from study.harness.config import load_figure_config
from study.impostor import probes
from study.impostor.envmap import EnvMap
from study.impostor.sdf import SdfGrid, build_grid, grid_frame, sdf_grid
from study.impostor.views import Captured, SdfSpec
from study.measure import outcomes
from study.reference.embree import Tracer
from study.scene import scene_from_dict

RES = 64  # cube maps of the tests


@pytest.fixture(scope="module")
def fig5():
    """fig5's room (4 × 3 × 4 m, o at 1.5 m) with its column 1.7 m tall; grids at 64³ and 128³; an impostor
    whose "radiance" is the world position of each texel's surface point (what a method reads tells which point
    it shows)."""
    _, s, _ = load_figure_config("configs/fig5.toml")
    mesh = s.mesh()
    o = np.asarray(s.reference.point, float)
    tracer = Tracer(mesh)
    grids = {res: build_grid(mesh.vertices, mesh.faces, s.bounds(), SdfSpec(res=res)) for res in (64, 128)}
    imp = probes.probe_texels(tracer, o, RES, lambda pts: pts)
    return s, o, tracer, grids, imp


def _env(B, o, imp, grids, res, **extra):
    spec = SdfSpec(res=res)
    return Captured(
        impostor=EnvMap(imp, B), reference=tuple(o), sdfs={spec: SdfGrid(*grids[res], o, B)}, **extra
    )


def _trace(m, B, env, x, d):
    with np.errstate(all="ignore"):
        tr = m.trace(B, env, B.vec(x), B.vec(d))
    return (
        B.to_numpy(tr.shown).astype(float),
        B.to_numpy(tr.radiance).astype(float),
        B.numpy(tr.valid).astype(bool),
        B.numpy(tr.lookups).astype(float),
    )


def _room_rays(o, n=3000, seed=5):
    """Origins in fig5's free space above the column (y 1.8–2.4 m, around the mirror of fig5's first position)
    and inside the room elsewhere, uniform directions; relative to o."""
    rng = np.random.default_rng(seed)
    x = np.r_[
        rng.uniform(-0.3, 0.3, (n // 2, 3)) + np.array([-0.9, 2.1, -0.9]),
        rng.uniform([-0.3, 0.3, -0.3], [1.7, 2.7, 1.7], (n - n // 2, 3)),
    ]
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    return x - o, d


# ---------------------------------------------------------------------------------------------- the grid
def test_grid_values_are_exact_in_the_band_and_a_lower_bound_outside(fig5):
    """Band nodes: |φ| = the distance to the nearest triangle (trimesh, brute force over all 22 triangles) to
    float32 rounding; sign + in the room's free space, − inside the column or outside the room. Nodes outside
    the band: 0 < |φ| ≤ the true distance (sphere tracing never steps through a surface), same sign rule."""
    from trimesh.triangles import closest_point

    s, o, tracer, grids, _ = fig5
    grid, lo, h = grids[64]
    mesh = s.mesh()
    tri = mesh.vertices[mesh.faces].astype(float)
    rng = np.random.default_rng(0)
    idx = rng.integers(0, 64, (1500, 3))  # (i, j, k) = x, y, z
    p = lo + h * idx
    phi = grid[idx[:, 2], idx[:, 1], idx[:, 0]].astype(float)
    q = np.stack([closest_point(tri, np.broadcast_to(pt, (len(tri), 3))) for pt in p])
    true = np.min(np.linalg.norm(q - p[:, None], axis=-1), axis=1)
    in_room = np.all((p > [-2, 0, -2]) & (p < [2, 3, 2]), axis=1)
    in_col = np.all((p > [-1.2, 0, -1.2]) & (p < [-0.6, 1.7, -0.6]), axis=1)
    free = in_room & ~in_col
    band = np.abs(phi) < 4 * h
    assert band.sum() > 100 and (~band).sum() > 100
    np.testing.assert_allclose(np.abs(phi[band]), true[band], atol=2e-6)
    clear = true > 1e-3
    np.testing.assert_array_equal(phi[clear] > 0, free[clear])
    assert np.all(np.abs(phi[~band]) <= true[~band] + 1e-6) and np.all(np.abs(phi[~band]) >= 4 * h - 1e-6)


def test_grid_is_cached_by_triangles_and_spec(fig5, tmp_path):
    """sdf_grid stores the grid once; the second call reads it back (same values), another spec is another entry."""
    s = fig5[0]
    cache = Cache(tmp_path)
    g1, lo, h = sdf_grid(s, SdfSpec(res=32), cache)
    g2, _, _ = sdf_grid(s, SdfSpec(res=32), cache)
    assert (cache.misses, cache.hits) == (1, 1)
    np.testing.assert_array_equal(g1, g2)
    sdf_grid(s, SdfSpec(res=32, band=2.0), cache)
    assert cache.misses == 2
    assert np.allclose(lo, grid_frame(s.bounds(), SdfSpec(res=32))[0])


# ---------------------------------------------------------------------------------------------- the trace
def test_sphere_trace_hits_within_one_voxel_in_an_analytic_room(B):
    """An empty box room (4 × 3 × 4 m) at 48³: every ray from inside finds the wall the analytic box intersection
    gives, within one voxel (in fact to float32 rounding: trilinear interpolation is exact on planes), and spends
    no more lookups than its bound."""
    s = scene_from_dict(small_scene_dict(columns=[]))
    o = np.asarray(s.reference.point, float)
    mesh = s.mesh()
    spec = SdfSpec(res=48)
    grid, lo, h = build_grid(mesh.vertices, mesh.faces, s.bounds(), spec)
    rng = np.random.default_rng(11)
    n = 2000
    x = rng.uniform([-1.8, 0.2, -1.8], [1.8, 2.8, 1.8], (n, 3))
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    lo_b, hi_b = np.array([-2.0, 0.0, -2.0]), np.array([2.0, 3.0, 2.0])
    t_exit = np.min(np.maximum((lo_b - x) / d, (hi_b - x) / d), axis=1)  # slab exit
    exact = x + d * t_exit[:, None]
    imp = np.ones((6, 8, 8, 4), np.float32) * 3.0
    env = Captured(impostor=EnvMap(imp, B), reference=tuple(o), sdfs={spec: SdfGrid(grid, lo, h, o, B)})
    m = methods.make("sdf", res=48)
    shown, _, valid, spent = _trace(m, B, env, x - o, d)
    assert valid.all()
    err = np.linalg.norm(shown + o - exact, axis=1)
    assert err.max() < h and np.median(err) < 1e-4
    assert spent.max() <= m.lookups_per_ray()


def test_fig5_hidden_column_top_found_by_the_field_shaded_wrong_by_the_impostor(fig5):
    """Rays coming down onto fig5's column top (1.7 m; o at 1.5 m never sees it). At 128³ sdf shows the exact hit
    (outcome class CORRECT, ε of a 128² cube map) on ≥ 90 % of them, where localized (the impostor) does on
    ≤ 10 %. Its radiance error there, reported: the impostor's radiance in the hit's direction is the column's
    side seen from o, > 5 cm from the hit on ≥ 90 % of the rays; shading from a probe above the column
    (shading = "probes") reads the hit's own radiance (< 3 cm) on ≥ 90 %, and exact shading (shading = "exact",
    ``Captured.shade``) within 1 cm; without ``Captured.shade`` the exact variant is a StudyError."""
    s, o, tracer, grids, imp = fig5
    B = backends.get("numpy")
    rng = np.random.default_rng(7)
    n = 400
    tgt = np.c_[rng.uniform(-1.15, -0.65, n), np.full(n, 1.7), rng.uniform(-1.15, -0.65, n)]
    x = np.array([-0.9, 2.1, -0.9]) + rng.uniform(-0.25, 0.25, (n, 3))
    d = tgt - x
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    hit = tracer.intersect(x, d)["point"]
    top = np.abs(hit[:, 1] - 1.7) < 1e-4
    assert top.mean() > 0.9
    x, d, hit = x[top], d[top], hit[top]
    eps = outcomes.tolerance(o, hit, 128)
    env = _env(B, o, imp, grids, 128)
    shown, rad, valid, _ = _trace(methods.make("sdf", res=128), B, env, x - o, d)
    cls = outcomes.classify(x, d, shown + o, hit, eps=eps).cls
    wrong = float(np.mean(cls != outcomes.CORRECT))
    loc, _, _, _ = _trace(methods.make("localized", iterations=10), B, env, x - o, d)
    loc_cls = outcomes.classify(x, d, loc + o, hit, eps=eps).cls
    assert wrong <= 0.10 and np.mean(loc_cls == outcomes.CORRECT) <= 0.10
    rad_err = np.linalg.norm(rad - hit, axis=1)
    print(
        f"fig5 column top, 128³: wrong {wrong:.3f}; impostor radiance > 5 cm off on {np.mean(rad_err > 0.05):.3f}"
    )
    assert np.mean(rad_err > 0.05) >= 0.9
    above = (-0.9, 2.3, -0.9)
    tex = np.stack([imp, probes.probe_texels(tracer, above, RES, lambda pts: pts)])
    m = methods.make("sdf", res=128, shading="probes", grid=(1, 1, 1))
    ps = probes.ProbeSet.around(tex, np.stack([o, above]), o, B)
    env_p = _env(B, o, imp, grids, 128, probes={m.probe_spec(): ps})
    shown_p, rad_p, _, spent = _trace(m, B, env_p, x - o, d)
    np.testing.assert_allclose(shown_p, shown, atol=1e-6)
    assert np.mean(np.linalg.norm(rad_p - hit, axis=1) < 0.03) >= 0.9
    assert spent.max() <= m.lookups_per_ray()
    # exact shading (here: "radiance" = the point Embree hits from 2 voxels before sdf's hit): the hit's own point
    m = methods.make("sdf", res=128, shading="exact")
    env_e = _env(B, o, imp, grids, 128, shade=lambda org, dirs: tracer.intersect(org, dirs)["point"])
    _, rad_e, _, spent = _trace(m, B, env_e, x - o, d)
    assert np.mean(np.linalg.norm(rad_e - hit, axis=1) < 0.01) >= 0.9 and spent.max() <= m.lookups_per_ray()
    with pytest.raises(StudyError, match="exact shading"):
        m.trace(B, _env(B, o, imp, grids, 128), B.vec(x - o), B.vec(d))


def test_numpy_and_llvm_agree(fig5):
    """The same rays on numpy (trilinear by hand) and LLVM (Dr.Jit Texture3f): same valid rays, shown points
    within 1 mm on ≥ 99.5 % (float32 and filter rounding can tip a step on a grazing ray), the radiance read
    there within 1 cm on ≥ 99 %, same lookups mostly."""
    s, o, tracer, grids, imp = fig5
    x, d = _room_rays(o)
    out = {}
    for name in ("numpy", "llvm"):
        B = backends.get(name)
        out[name] = _trace(methods.make("sdf", res=64), B, _env(B, o, imp, grids, 64), x, d)
    (s0, r0, v0, l0), (s1, r1, v1, l1) = out["numpy"], out["llvm"]
    assert np.mean(v0 == v1) >= 0.999 and v0.mean() > 0.95
    both = v0 & v1
    assert np.mean(np.linalg.norm(s0[both] - s1[both], axis=1) < 1e-3) >= 0.995
    assert np.mean(np.linalg.norm(r0[both] - r1[both], axis=1) < 1e-2) >= 0.99  # radiance: surface points
    assert np.mean(l0 == l1) >= 0.98


def test_sphere_trace_agrees_with_mitsubas_exact_trace_of_the_same_grid(fig5):
    """The tracing error alone: Mitsuba's sdfgrid shape (exact intersection of the ray with the trilinear cells)
    on the same 64³ grid and the same rays. sdf's hit lies within 1 mm of Mitsuba's on ≥ 98 % of the rays (the
    rest: grazing rays that cross a rounded edge by less than the smallest step, 1/4 voxel); and the field's
    own error against the triangles (Embree) is larger than the tracing error."""
    from study import runtime

    mi = runtime.mitsuba()
    s, o, tracer, grids, imp = fig5
    grid, lo, h = grids[64]
    side = h * (grid.shape[0] - 1)
    shape = {
        "type": "sdfgrid",
        "grid": mi.TensorXf(np.ascontiguousarray(grid[..., None] / side)),  # values in the unit cube's units
        "to_world": mi.ScalarTransform4f().translate([float(c) for c in lo]).scale(side),
    }
    scene = mi.load_dict({"type": "scene", "field": shape})
    x, d = _room_rays(o)
    B = backends.get("numpy")
    shown, _, valid, _ = _trace(methods.make("sdf", res=64), B, _env(B, o, imp, grids, 64), x, d)
    w = x + o
    ray = mi.Ray3f(mi.Point3f(*(w[:, i] for i in range(3))), mi.Vector3f(*(d[:, i] for i in range(3))))
    si = scene.ray_intersect(ray)
    t = np.asarray(si.t, float)
    ok = np.isfinite(t) & valid
    assert ok.mean() > 0.95
    ref = w + d * t[:, None]
    tracing = np.linalg.norm(shown[ok] + o - ref[ok], axis=1)
    exact = tracer.intersect(w, d)["point"]
    field = np.linalg.norm(ref[ok] - exact[ok], axis=1)
    print(
        f"tracing error median {np.median(tracing):.2e} p99 {np.quantile(tracing, 0.99):.2e}; field error "
        f"median {np.median(field):.2e} p99 {np.quantile(field, 0.99):.2e}"
    )
    assert np.mean(tracing < 1e-3) >= 0.98
    assert np.quantile(field, 0.99) > np.quantile(tracing, 0.99)


def test_ssr_then_sdf_takes_the_screen_where_it_has_the_hit_and_the_field_elsewhere(B):
    """The engine chain ``ssr_sdf`` on the small room (a 48² camera whose colour buffer holds each pixel's surface
    point): rays whose screen trace finds a hit show exactly what ``ssr`` alone shows; every other ray (off
    screen: ≥ 30 % of them) is traced in the default (128³) field and lands within one voxel of the exact hit
    (Embree)."""
    from study.impostor.screen import ScreenView
    from study.scene.camera import camera_rays

    W = 48
    s = scene_from_dict(small_scene_dict(camera={**small_scene_dict()["camera"], "width": W, "height": W}))
    tracer = Tracer(s.mesh())
    o = np.asarray(s.reference.point, float)
    eo, ed = (a.reshape(-1, 3) for a in camera_rays(s.camera, 1))
    colour = (eo + ed * tracer.distance(eo, ed)[:, None]).reshape(W, W, 3).astype(np.float32)
    rng = np.random.default_rng(3)
    n = 1500
    pick = rng.integers(0, len(ed), n)
    x = eo[pick] + ed[pick] * (tracer.distance(eo[pick], ed[pick]) * rng.uniform(0.3, 0.8, n))[:, None]
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    exact = tracer.intersect(x, d)["point"]
    spec = methods.make("sdf").spec()  # the chain's fallback: sdf at its defaults
    grid, lo, h = build_grid(s.mesh().vertices, s.mesh().faces, s.bounds(), spec)
    env = Captured(
        impostor=EnvMap(probes.probe_texels(tracer, o, 32, lambda pts: pts), B),
        reference=tuple(o),
        room=(s.room.min, s.room.max),
        screen=ScreenView.of_scene(s, colour, tracer, B),
        sdfs={spec: SdfGrid(grid, lo, h, o, B)},
    )
    alone, _, on, _ = _trace(methods.make("ssr", fallback="none"), B, env, x - o, d)
    chain = methods.make("ssr_sdf")
    assert chain.params.fallback == "sdf" and spec.res == 128  # the chain's fallback: sdf at its defaults
    shown, _, valid, spent = _trace(chain, B, env, x - o, d)
    assert valid.all() and 0.3 < np.mean(~on) < 0.9
    np.testing.assert_allclose(shown[on], alone[on], atol=1e-6)
    assert np.all(np.linalg.norm(shown[~on] + o - exact[~on], axis=1) < h)
    assert spent.max() <= chain.lookups_per_ray()


def test_case_gives_sdf_its_field_through_the_cache(tmp_path):
    """run_case on the small room with a column taller than o: sdf, its exact-shading variant and ssr_sdf get
    the field (one 128³ grid at the defaults, stored once: a second run recomputes nothing), every ray valid, the
    measured lookups within the bound; the exact variant shows the same points as sdf (same field, same trace)."""
    from study.measure.case import run_case

    s = scene_from_dict(
        small_scene_dict(columns=[{"center": [-0.8, 0.3], "footprint": [0.5, 0.5], "height": 2.0}])
    )
    ms = [methods.make("sdf"), methods.make("sdf", shading="exact"), methods.make("ssr_sdf")]
    cache = Cache(tmp_path)
    rows = {r["label"]: r for r in run_case(s, ms, cache=cache, keep_images=False).rows}
    for m in ms:
        row = rows[m.label]
        assert row["valid_fraction"] == 1.0 and row["lookups_per_ray"] <= m.lookups_per_ray()
    a, b = rows["sdf(res=128)"], rows["sdf(res=128, shading='exact')"]
    assert a["wrong_fraction"] == b["wrong_fraction"] and a["dist_p95"] == b["dist_p95"]
    cache_flush()  # the cache's entries on disk (written off this thread)
    assert len(list((tmp_path / "sdf").glob("*.npy"))) == 1
    cache2 = Cache(tmp_path)
    run_case(s, ms, cache=cache2, keep_images=False)
    assert cache2.misses == 0
