"""layered: depth layers (study.impostor.layers) marched together texel by texel; a column top hidden from o."""

import numpy as np
import pytest
from conftest import small_scene_dict

from study import backend as backends
from study import methods
from study.impostor import cubemap, layers
from study.impostor.envmap import EnvMap
from study.impostor.views import Captured
from study.methods.linear_secant import march_steps
from study.reference.embree import Tracer
from study.scene import scene_from_dict

RES = 128
COLUMN = {"center": [-0.8, 0.3], "footprint": [0.5, 0.5], "height": 2.0}  # top 0.5 m above o (1.5 m)


@pytest.fixture(scope="module")
def column_layers():
    """Three Embree-peeled layers (128²) of the small room with one column taller than o; "radiance" = the
    world position of each texel's surface point, so what a method reads tells which point it shows."""
    s = scene_from_dict(small_scene_dict(columns=[COLUMN]))
    o = np.asarray(s.reference.point)
    tracer = Tracer(s.mesh())
    dist, point, normal, new = layers.peel(tracer, o, cubemap.texel_directions(RES).reshape(-1, 3), 3)
    d = dist.reshape(3, 6, RES, RES)
    tex = np.concatenate(
        [point.reshape(3, 6, RES, RES, 3), layers.depth_jump(d)[..., None], d[..., None]], -1
    )
    return s, o, tracer, tex.astype(np.float32), (dist, new)


def test_peeled_layers_are_ordered_and_complete(column_layers):
    """Layer k+1 never lies nearer than layer k; layer 0 is the first hit (Embree from o); a texel whose ray
    crosses the column has a real second surface (and mostly a third) and the wall texels repeat the first."""
    s, o, tracer, tex, (dist, new) = column_layers
    assert np.all(np.diff(dist, axis=0) >= 0)
    dirs = cubemap.texel_directions(RES).reshape(-1, 3)
    np.testing.assert_allclose(dist[0], tracer.distance(np.broadcast_to(o, dirs.shape), dirs), rtol=1e-5)
    assert new[0].all() and 0.01 < new[1].mean() < 0.2
    assert not np.any(new[2] & ~new[1])  # a third surface only after a second
    assert new[2].sum() > 0.5 * new[1].sum()  # enter, leave, wall (or the floor inside)
    np.testing.assert_array_equal(dist[1][~new[1]], dist[0][~new[1]])


def _top_rays(tracer, o, n=400, seed=7):
    """Rays from 0.6 m above the column coming down onto its top (y = 2.0 m), relative to o, with exact hits."""
    rng = np.random.default_rng(seed)
    x = np.c_[rng.uniform(-1.0, -0.6, n), np.full(n, 2.6), rng.uniform(0.1, 0.5, n)] - o
    d = np.c_[rng.normal(0, 0.15, n), -np.ones(n), rng.normal(0, 0.15, n)]
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    h = tracer.intersect(x + o, d)
    top = np.abs(h["point"][:, 1] - 2.0) < 1e-4
    assert top.mean() > 0.5  # most rays do land on the top
    return x[top], d[top], h["point"][top] - o


def test_layered_recovers_a_column_top_hidden_from_the_reference_point(column_layers, B):
    """The column top faces up and no ray from o (1.5 m) sees it from above. localized (10 iterations, first
    layer) misses it by > 10 cm on ≥ 90 % of the rays (it stops on the silhouette's skin or the wall), and so does
    layered with one layer; layered with 2 layers shows a point within 2 cm of the exact hit on ≥ 90 %, and
    the radiance it reads (here: the surface point's position) belongs to that point."""
    s, o, tracer, tex, _ = column_layers
    x, d, exact = _top_rays(tracer, o)
    loc = methods.make("localized", iterations=10).trace(
        B, EnvMap(tex[0][..., [0, 1, 2, 4]], B), B.vec(x), B.vec(d)
    )
    assert np.mean(np.linalg.norm(B.to_numpy(loc.shown) - exact, axis=1) > 0.1) >= 0.9
    env = Captured(impostor=EnvMap(tex[0], B), reference=o, layers=tuple(EnvMap(t, B) for t in tex))
    for n_layers in (1, 2):
        lay = methods.make("layered", layers=n_layers, iterations=10).trace(B, env, B.vec(x), B.vec(d))
        err = np.linalg.norm(B.to_numpy(lay.shown) - exact, axis=1)
        if n_layers == 1:
            assert np.mean(err < 0.02) < 0.1
            continue
        assert np.mean(err < 0.02) >= 0.9
        rad_err = np.linalg.norm(B.to_numpy(lay.radiance) - (exact + o), axis=1)
        assert np.mean(rad_err < 0.02) >= 0.9


def test_layered_finds_top_hits_near_the_edge_that_uniform_steps_step_over(column_layers, B):
    """Rays descending at 20–40° onto the column top 2–5 cm inside its edge nearest to o: on the layer that holds
    the top (seen from below) the ray is behind it only from the top's silhouette to the hit, a few texels of arc,
    and then in front of it again. The texel march (a sample at least every texel) shows a point within 2 cm of
    the exact hit on every ray; a uniform 30-step search in t did on 21 %."""
    s, o, tracer, tex, _ = column_layers
    rng = np.random.default_rng(3)
    n = 300
    tgt = np.c_[-0.55 - rng.uniform(0.02, 0.05, n), np.full(n, 2.0), rng.uniform(0.15, 0.45, n)]
    elev = np.radians(rng.uniform(20, 40, n))
    d = np.c_[-np.cos(elev), -np.sin(elev), rng.normal(0, 0.1, n)]
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    org = tgt - d * rng.uniform(0.3, 0.6, n)[:, None]
    h = tracer.intersect(org, d)
    assert np.all(np.linalg.norm(h["point"] - tgt, axis=1) < 1e-3)  # the first hit is the target on the top
    env = Captured(impostor=EnvMap(tex[0], B), reference=o, layers=tuple(EnvMap(t, B) for t in tex))
    lay = methods.make("layered").trace(B, env, B.vec(org - o), B.vec(d))
    err = np.linalg.norm(B.to_numpy(lay.shown) + o - tgt, axis=1)
    assert np.all(err < 0.02)


def test_false_position_on_the_top_layer_stops_on_the_skin(column_layers):
    """Why layered does not run the paper's false position on each layer: on the second layer (which holds the
    top, seen from below) it ends > 10 cm from the top on ≥ 90 % of these rays, mostly (≥ 90 %) converged
    (|q − 1| < 0.01), at least half of them on points whose depth jump marks the silhouette's skin (> 0.1)."""
    s, o, tracer, tex, _ = column_layers
    B = backends.get("numpy")
    x, d, exact = _top_rays(tracer, o)
    env1 = EnvMap(tex[1], B)
    l = methods.make("localized", iterations=10).localize(B, env1, B.vec(x), B.vec(d)).l
    ch = env1.lookup(l)
    q = B.numpy(B.length(l)) / ch[-1]
    ln = B.to_numpy(l)
    miss = np.linalg.norm(ln - exact, axis=1) > 0.1
    assert miss.mean() >= 0.9 and np.mean(np.abs(q - 1) < 0.01) >= 0.9
    assert np.mean(miss & (ch[3] > 0.1)) >= 0.5


def test_deeper_layers_are_shaded_from_their_free_side():
    """The column top is lit by the light 0.6 m above it: Mitsuba's radiance from its free side (above) is
    bright (> 0.1), from inside the column (what a ray through o would see) black (< 0.01)."""
    s = scene_from_dict(small_scene_dict(columns=[COLUMN]))
    cx, cz = COLUMN["center"]
    p = np.c_[np.linspace(cx - 0.2, cx + 0.2, 50), np.full(50, 2.0), np.full(50, cz)]
    up = np.tile([0.0, 1.0, 0.0], (50, 1))
    lit = layers.surface_radiance(s, p, up, 8)
    inside = layers.surface_radiance(s, p, -up, 8)
    assert lit.mean() > 0.1 and inside.mean() < 0.01


@pytest.mark.parametrize("name", ["layered", "linear_secant"])
@pytest.mark.parametrize("hierarchical", [False, True])
def test_the_march_spends_the_lookups_it_reports(name, hierarchical, monkeypatch):
    """Every distance fetched from a texture (the final lookup's colour comes with its distance) and every read of
    the min pyramid's texels is counted in Trace.lookups (rays traced one at a time: numpy then runs only the side
    of each branch the ray takes). The texel march (hierarchical=False) spends the bound lookups_per_ray(16) on
    every ray: g(0) and the n = ⌈π 16⌉ = 51 steps of the march on every ray (for layered on each of its 3 layers),
    the secant steps, the final lookup (layered: on the kept layer alone). The hierarchical march spends fewer on
    average, never more than its bound."""
    from study.impostor import analytic

    B = backends.get("numpy")
    tex = analytic.box_impostor(16, [-2, -1.5, -2], [2, 1.5, 2])
    env = Captured(impostor=EnvMap(tex, B), layers=tuple(EnvMap(tex, B) for _ in range(3)))
    fetched = []
    sample, gather_at = type(B).sample, type(B).gather_at
    monkeypatch.setattr(
        type(B), "sample", lambda self, t, *a: fetched.append(t.shape[-1]) or sample(self, t, *a)
    )
    texels = EnvMap(tex, B).pyramid.levels_at  # the pyramid's texels; its per-level table after them

    def read(
        self, data, base, index
    ):  # a read of the pyramid's texels (not of its table of levels) is a lookup
        fetched.append("pyramid" if np.all(np.asarray(base) + np.asarray(index) < texels) else "table")
        return gather_at(self, data, base, index)

    monkeypatch.setattr(type(B), "gather_at", read)
    x, d = analytic.random_rays(30, extent=0.8, seed=0)
    m = methods.make(name, hierarchical=hierarchical)
    n = march_steps(16, m.params)
    texel = 1 + n + 4 + 1 if name == "linear_secant" else 3 * (1 + n) + 10 + 1
    counted = []
    for i in range(len(x)):
        fetched.clear()
        tr = m.trace(B, env, B.vec(x[i : i + 1]), B.vec(d[i : i + 1]), check_origin=False)
        assert fetched.count(1) + fetched.count("pyramid") == B.numpy(tr.lookups)[0] <= m.lookups_per_ray(16)
        counted.append(B.numpy(tr.lookups)[0])
    if hierarchical:
        assert np.mean(counted) < texel
    else:
        assert m.lookups_per_ray(16) == texel and np.all(np.array(counted) == texel)


def test_layer_cache_key_includes_the_layer_count():
    s = scene_from_dict(small_scene_dict())
    assert layers.layers_key(s, 2) != layers.layers_key(s, 3)
    assert layers.layers_key(s, 2) == layers.layers_key(s.with_updates({"object.radius": 0.3}), 2)
    assert layers.layers_key(s, 2) != layers.layers_key(s.with_updates({"render.cube_res": 16}), 2)


def test_case_gives_layered_its_layers(tmp_path):
    """run_case with layered(layers=2) captures two layers through the cache (nothing recomputed on a second
    run) and reports a row for it with every ray valid."""
    from study.cache import Cache
    from study.measure.case import run_case

    s = scene_from_dict(small_scene_dict(columns=[COLUMN]))
    cache = Cache(tmp_path)
    ms = [methods.make("localized"), methods.make("layered", layers=2)]
    out = run_case(s, ms, cache=cache, keep_images=False)
    row = next(r for r in out.rows if r["method"] == "layered")
    n = march_steps(s.render.cube_res, ms[1].params)  # ⌈π 32⌉ = 101 steps for a half turn
    # the hierarchical march: fewer than the texel march's 2 (1 + n) + 10 + 1 = 215, more than the fixed 2 + 11
    assert row["valid_fraction"] == 1.0 and 2 + 11 < row["lookups_per_ray"] < 2 * (1 + n) + 10 + 1 == 215
    assert cache.misses > 0
    cache2 = Cache(tmp_path)
    run_case(s, ms, cache=cache2, keep_images=False)
    assert cache2.misses == 0
