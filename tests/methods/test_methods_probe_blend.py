"""probe_blend: box-projected probes blended by influence (Lagarde 2012), on the analytic box room (exact probes)
and the small room with a column (Embree probes)."""

import dataclasses

import numpy as np
import pytest
from conftest import BACKENDS, BOX_HI, BOX_LO, small_scene_dict

import study
from study import backend as backends
from study import methods
from study.errors import StudyError
from study.impostor import analytic, probes
from study.impostor.envmap import EnvMap
from study.impostor.views import Captured, ProbeSpec
from study.measure import outcomes
from study.methods import probe_blend as PB
from study.reference.embree import Tracer
from study.scene import scene_from_dict

RES = 64
ROOM = (tuple(BOX_LO), tuple(BOX_HI))  # the analytic room around o = 0
GRID = [np.array([a, b, c]) for a in (-1.0, 1.0) for b in (-0.75, 0.75) for c in (-1.0, 1.0)]  # 2×2×2 centres


def _box_env(B, centres=GRID, radiance=None):
    """Probes at ``centres`` in the analytic box room, each an exact box impostor taken there ("radiance": the
    world point of each texel's surface, so the radiance read tells which point was shown)."""
    rad = radiance or (lambda p: p)
    maps = [analytic.box_impostor(RES, BOX_LO, BOX_HI, rad)] + [
        analytic.box_impostor(RES, BOX_LO - c, BOX_HI - c, lambda p, c=c: rad(p + c)) for c in centres
    ]
    ps = probes.ProbeSet(np.stack(maps), np.stack([np.zeros(3), *centres]), B)
    return Captured(
        impostor=EnvMap(maps[0], B), reference=(0.0, 0.0, 0.0), room=ROOM, probes={ProbeSpec(): ps}
    )


def _trace(m, B, env, x, d):
    with np.errstate(all="ignore"):
        tr = m.trace(B, env, B.vec(x), B.vec(d))
    return (
        B.to_numpy(tr.shown).astype(float),
        B.to_numpy(tr.radiance).astype(float),
        B.numpy(tr.valid).astype(bool),
        B.numpy(tr.lookups).astype(float),
        B.numpy((tr.flags or {PB.GHOST: ~tr.valid & tr.valid})[PB.GHOST]).astype(bool),
    )


@pytest.mark.parametrize("name", BACKENDS)
def test_weights_follow_lagarde_s_loop(name):
    """The vectorized weights equal the one-point loop of blend_weights_ref (random NDFs of 4 probes, some outside
    their influence), sum to 1, and a probe at its outer boundary (NDF = 1) weighs 0."""
    B = backends.get(name)
    rng = np.random.default_rng(0)
    nd = rng.uniform(0, 1.4, (500, 4))
    nd[:50] = np.minimum(nd[:50], 0.0)  # inside several inner volumes: equal weights
    nd[50:60] = 1.2  # no probe: the global one
    w, w0 = PB.blend_weights(B, [B.array(nd[:, k]) for k in range(4)])
    got = np.stack([B.numpy(a) for a in w] + [B.numpy(w0)], 1)
    ref = np.array([PB.blend_weights_ref(list(r)) for r in nd])
    np.testing.assert_allclose(got, ref, atol=1e-5)
    np.testing.assert_allclose(got.sum(1), 1.0, atol=1e-5)
    assert np.all(got[:, :4][nd >= 1.0] == 0.0)


@pytest.mark.parametrize("name", BACKENDS)
def test_exact_in_the_box_room_and_blending_costs_lookups(name):
    """The box room: every probe box-projected onto the room shows the exact hit, so the blend does too (≥ 99.5 %
    within ε, its radiance too) and nothing ghosts (≤ 0.5 %: texels interpolated across a
    corner). A point deep inside a cell reads its probe alone (1 lookup); the room's centre, where all 8 cells meet,
    reads all 8; without a blend region every point reads 1. Sphere projection is wrong in a box (< 60 % correct)."""
    B = backends.get(name)
    env = _box_env(B)
    x, d = analytic.random_rays(4000, extent=1.3, seed=1)
    exact = analytic.box_hit(x, d, BOX_LO, BOX_HI)
    eps = outcomes.tolerance(np.zeros(3), exact, RES)
    m = methods.make("probe_blend")
    shown, rad, valid, spent, ghost = _trace(m, B, env, x, d)
    assert valid.all() and np.mean(np.linalg.norm(shown - exact, axis=1) <= eps) >= 0.995
    assert np.mean(np.linalg.norm(rad - exact, axis=1) <= eps) >= 0.995
    assert ghost.mean() <= 0.005 and spent.max() <= m.lookups_per_ray() and 1.0 < spent.mean() < 4.0
    if name != "numpy":
        return  # the rest on numpy alone (each parameter set is a kernel of its own to compile)
    pts = np.array([[-1.0, -0.75, -1.0], [0.0, 0.0, 0.0]])
    dirs = np.tile([0.0, 1.0, 0.0], (2, 1))
    assert list(_trace(m, B, env, pts, dirs)[3]) == [1.0, 8.0]
    assert np.all(_trace(methods.make("probe_blend", blend=0.0), B, env, x, d)[3] == 1.0)
    shown_s = _trace(methods.make("probe_blend", projection="sphere"), B, env, x, d)[0]
    assert np.mean(np.linalg.norm(shown_s - exact, axis=1) <= eps) < 0.6


@pytest.mark.parametrize("name", BACKENDS)
def test_probes_of_weight_zero_are_not_read(name):
    """The masked read (issue 56): a probe k ≥ 1 of weight 0 is looked up only on the lanes that weigh it (a
    branch; numpy runs a mixed branch's sides on every lane, so its lanes that do not weigh it are looked up in the
    fixed direction (1, 1, 1)); a probe of weight > 0, and the global probe 0, in their own directions. A point
    deep inside cell 1 (probe 1 alone: 1 lookup) and the room's centre (all 8 probes); the shown points, radiance
    and lookups are those of every probe read on every lane."""
    B = backends.get(name)
    env = _box_env(B)
    P = next(iter(env.probes.values()))
    seen = []
    plain = P.lookup
    P.lookup = lambda k, v: (seen.append((int(B.numpy(k)[0]), B.to_numpy(v))), plain(k, v))[1]
    pts = np.array([[-1.0, -0.75, -1.0], [0.0, 0.0, 0.0]])
    dirs = np.tile([0.0, 1.0, 0.0], (2, 1))
    masked = _trace(methods.make("probe_blend"), B, env, pts, dirs)
    assert list(masked[3]) == [1.0, 8.0]
    looked = {k: v for k, v in seen}
    assert sorted(looked) == list(range(9))
    if name == "numpy":  # both sides on every lane of a mixed branch
        fixed = {k: np.all(v == 1.0, axis=1) for k, v in looked.items()}
        assert list(fixed[1]) == [False, False]  # probe 1 (centre GRID[0]) weighs > 0 at both points
        assert all(list(fixed[k]) == [True, False] for k in range(2, 9))  # weight 0 at the first point alone
    # the branch's condition per probe: the lanes that weigh it (probe 0: where it is usable)
    conds, orig = [], B.branch
    B.branch = lambda cond, state, t, f: (conds.append(B.numpy(cond).astype(bool)), orig(cond, state, t, f))[
        1
    ]
    try:
        _trace(methods.make("probe_blend"), B, env, pts, dirs)
    finally:
        B.branch = orig
    assert len(conds) == 9 and list(conds[0]) == list(conds[1]) == [True, True]
    assert all(list(c) == [False, True] for c in conds[2:])
    # every probe read on every lane (no branch): the same shown points, radiance and lookups
    B.branch = lambda cond, state, t, f: tuple(t(*state))
    try:
        full = _trace(methods.make("probe_blend"), B, env, pts, dirs)
    finally:
        B.branch = orig
    for a, b in zip(masked[:4], full[:4]):
        np.testing.assert_array_equal(a, b)


COLUMN = {"center": [-0.8, 0.3], "footprint": [0.5, 0.5], "height": 2.0}


def test_ghosting_where_probes_disagree_around_a_column():
    """The small room with a column (probes traced by Embree at the default 2×2×2 grid): the probes see the column
    from different sides, so a blend mixes surfaces: ghosting on 1–20 % of the rays with blend 0.25 (measured 2.4 %),
    none without a blend region (one probe per point), never on a ray without an answer. The blend shows the exact
    hit more often than the one box-projected probe at o (proxy_box)."""
    s = scene_from_dict(small_scene_dict(columns=[COLUMN]))
    o = np.asarray(s.reference.point)
    tracer = Tracer(s.mesh())
    spec = ProbeSpec()
    pts = probes.probe_points(spec, (s.room.min, s.room.max), tracer)
    maps = [probes.probe_texels(tracer, p, 32, lambda q: q) for p in [o, *pts]]
    B = backends.get("numpy")
    ps = probes.ProbeSet.around(np.stack(maps), np.stack([o, *pts]), o, B)
    env = Captured(impostor=EnvMap(maps[0], B), reference=o, room=(s.room.min, s.room.max), probes={spec: ps})
    rng = np.random.default_rng(1)
    x = rng.uniform([-1.8, 0.2, -1.8], [1.8, 2.8, 1.8], (3000, 3))
    d = rng.normal(size=(3000, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    exact = tracer.intersect(x, d)["point"]
    eps = outcomes.tolerance(o, exact, 32)
    shown, _, valid, spent, ghost = _trace(methods.make("probe_blend"), B, env, x - o, d)
    assert 0.01 <= ghost.mean() <= 0.2 and not ghost[~valid].any()
    g0 = _trace(methods.make("probe_blend", blend=0.0), B, env, x - o, d)[4]
    assert not g0.any()
    box = _trace(methods.make("proxy_box"), B, env, x - o, d)[0]  # a single box-projected probe at o
    ok = lambda sh: np.mean(np.linalg.norm(sh + o - exact, axis=1) <= eps)  # noqa: E731
    assert ok(shown) > ok(box)  # probes nearer the rays see more of what o cannot


TINY = {"render.cube_res": 16, "camera.width": 32, "camera.height": 32}


@pytest.fixture(scope="module")
def cache(tmp_path_factory):
    return tmp_path_factory.mktemp("probe-blend-cache")  # the two evaluate tests share renders


def test_rows_carry_the_ghost_column(cache):
    """Through study.evaluate (a tiny case): probe_blend's row has ghost_fraction in [0, 1], other methods' rows
    none; ssr_hiz's row its lookups within its bound."""
    res = study.evaluate(
        small_scene_dict(columns=[COLUMN]),
        [methods.make("probe_blend", grid=(1, 1, 2)), "ssr_hiz", "classical"],
        overrides=TINY,
        cache=cache,
    )
    t = res.table.set_index("method")
    assert 0.0 <= t.loc["probe_blend", PB.GHOST] <= 1.0
    assert np.isnan(t.loc["classical", PB.GHOST])
    assert 0 < t.loc["ssr_hiz", "lookups_per_ray"] <= t.loc["ssr_hiz", "lookups_bound"]


class _Flagged(PB.ProbeBlend):
    """probe_blend with its flags replaced (not registered: a stand-in for a plug-in)."""

    name = "flagged"

    def __init__(self, flags, **kw):
        super().__init__(**kw)
        self.make_flags = flags

    def search(self, B, env, x, R):
        return dataclasses.replace(super().search(B, env, x, R), flags=self.make_flags(x))


def test_flags_must_be_masks_of_declared_columns(cache):
    """A method's flags are boolean masks, one per ray (else one line naming the method), of declared columns (else
    one line naming the column, from the case)."""
    B = backends.get("numpy")
    env = _box_env(B)
    x, d = analytic.random_rays(50, extent=0.5, seed=2)
    with pytest.raises(StudyError, match=r"'flagged' returned flags\['ghost_fraction'\] as float"):
        _Flagged(lambda x: {PB.GHOST: x.x * 0.0}).trace(B, env, B.vec(x), B.vec(d))
    tr = _Flagged(lambda x: {PB.GHOST: x.x > 0.0}).trace(B, env, B.vec(x), B.vec(d))
    assert np.array_equal(B.numpy(tr.flags[PB.GHOST]), (x[:, 0] > 0) & B.numpy(tr.valid))
    with pytest.raises(StudyError, match="flags the column 'no_such_column', which is not declared"):
        study.evaluate(
            small_scene_dict(columns=[COLUMN]),
            [_Flagged(lambda x: {"no_such_column": x.x > 0.0}, grid=(1, 1, 2))],
            overrides=TINY,
            cache=cache,
        )
