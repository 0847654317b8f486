"""``hit_cache``: the exact hit (as ``traced``) shaded from the hit-lighting cache. On a box room whose cache holds a
known field it shows the exact hit on every ray, its radiance is the cache's read at that hit (not the exact
shading's), a ray that leaves the scene takes the exact radiance along it, "all" leaves it out, and a case asks the
inputs for a cache of its resolution."""

import dataclasses

import numpy as np
import pytest

from study import backend as backends
from study import methods
from study.impostor import hitcache
from study.measure import outcomes
from tests.methods.test_methods_traced import HI, LO, _box_triangles, _captured, _rays, _scene, _trace


@pytest.mark.parametrize("backend", ["numpy", "llvm"])
def test_exact_hit_with_the_caches_radiance(backend):
    B = backends.get(backend)
    tracer = _scene(_box_triangles(LO, HI))
    V, F = tracer.mesh.vertices, tracer.mesh.faces
    p, n = hitcache.surface_samples(V, F, 50_000, seed=1)
    field = lambda q: np.repeat(q[:, :1] + 5.0, 3, axis=1)  # noqa: E731  radiance = x + 5 on every wall
    grids = {}
    for res in (4, 16):
        grids[res] = hitcache.GridCache.empty(LO, HI, res)
        grids[res].add(p, n, field(p))

    def cached(res, org, dirs):
        hit = tracer.intersect(org, dirs)
        nrm = hitcache.hit_normals(V, F, hit["prim"], dirs)
        return grids[res].query(hit["point"], nrm)[0]

    env = dataclasses.replace(_captured(B, tracer), cached=cached)
    x, d = _rays(2000, 3)
    exact = tracer.intersect(x, d)["point"]
    errs = {}
    for res in (4, 16):
        shown, rad, valid, spent = _trace(methods.make("hit_cache", res=res), B, env, x, d)
        assert valid.all() and (spent == 1).all()
        np.testing.assert_allclose(shown, exact, atol=2e-5)
        assert (outcomes.classify(x, d, shown, exact, eps=1e-3).cls == outcomes.CORRECT).all()
        errs[res] = np.abs(rad - field(exact)).max()
        assert errs[res] <= 4.0 / res / 2 * 1.3  # half a cell of a unit gradient (+ the cells' sampling)
    assert errs[16] < errs[4] / 2


def test_escaping_rays_read_the_exact_radiance_and_all_leaves_it_out():
    B = backends.get("numpy")
    tracer = _scene(_box_triangles(LO, HI, top=False))
    env = dataclasses.replace(
        _captured(B, tracer, shade=lambda org, dirs: np.full((len(org), 3), 9.0)),
        cached=lambda res, org, dirs: np.full((len(org), 3), 1.0),
    )
    x = np.zeros((2, 3))
    d = np.array([[0.0, 1.0, 0.0], [0.0, -1.0, 0.0]])  # out through the open top; onto the floor
    _, rad, _, _ = _trace(methods.make("hit_cache"), B, env, x, d)
    assert rad[:, 0].tolist() == [9.0, 1.0]
    assert "hit_cache" not in [m.name for m in methods.all_methods()]
    assert methods.make("hit_cache", res=8).views_needed().caches == (8,)


def test_the_fill_is_keyed_on_the_environment_not_the_case(monkeypatch, tmp_path):
    """One fill per environment (study.measure.inputs.fill_key): cases that move the object, the camera, the reference
    point or change the cube resolution read the same cached fill (path traced once); other columns, light,
    samples or seed make another. Planted: a key holding the object (the key before) fills per case."""
    from conftest import small_scene_dict

    from study.api import load_scene
    from study.cache import Cache
    from study.measure import inputs
    from study.reference.tracer import make_tracer

    base = load_scene(small_scene_dict())
    same = [
        base.with_updates({"object.center": [0.3, 1.0, 0.2]}),
        base.with_updates({"render.cube_res": 2 * base.render.cube_res, "camera.width": 40}),
        base.with_updates({"reference.point": [0.1, 1.2, 0.0]}),
    ]
    other = [
        base.with_updates({"render.spp": base.render.spp + 1}),
        base.with_updates({"render.seed": base.render.seed + 1}),
        base.with_updates({"columns": [{"center": [-1.0, -0.9], "footprint": [0.3, 0.3], "height": 2.0}]}),
        base.with_updates({"light.intensity": [14.0, 14.0, 14.0]}),
    ]
    assert all(inputs.fill_key(s) == inputs.fill_key(base) for s in same)
    assert len({inputs.fill_key(s) for s in [base, *other]}) == 1 + len(other)
    calls = []
    monkeypatch.setattr(inputs.hitcache, "FILL_SAMPLES", 64)  # a tiny fill: the count is what is tested
    monkeypatch.setattr(
        inputs, "radiance_along", lambda sc, o, d, **kw: calls.append(1) or np.ones((len(o), 3))
    )
    cache = Cache(tmp_path)
    for s in [base, *same]:
        inputs.hit_caches(s, cache, make_tracer(s.mesh()), (4,))
    assert len(calls) == 1
