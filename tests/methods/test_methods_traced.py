"""``traced``, the exact query as a method: on analytic rooms (a box, a box with a column o cannot see over, a box
open at the top) its shown points are the analytic hits (outcome class CORRECT on every ray) where the paper's
search on the same impostor is not; its radiance is what exact shading gives along the ray; without the exact
tracer's hits it is one line naming them; on a bare impostor it traces the room box."""

import numpy as np
import pytest

from study import backend as backends
from study import methods
from study.errors import StudyError
from study.impostor import analytic
from study.impostor.cubemap import FAR
from study.impostor.envmap import EnvMap
from study.impostor.views import Captured
from study.measure import outcomes
from study.reference.embree import Tracer

LO, HI = np.array([-2.0, -1.5, -2.0]), np.array([2.0, 1.5, 2.0])
COL_LO, COL_HI = np.array([-1.2, -1.5, -1.2]), np.array([-0.6, 1.2, -0.6])  # a column; its top hidden from o


def _box_triangles(lo, hi, *, top: bool = True):
    """The 12 triangles of the box [lo, hi] (10 without its top face)."""
    c = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    if not top:
        quads.remove((2, 3, 7, 6))  # y = hi
    return c, np.array([t for a, b, q, d in quads for t in ((a, b, q), (a, q, d))])


def _scene(*parts, shift=(0.0, 0.0, 0.0)):
    """A tracer of the parts' triangles, moved by ``shift`` (the reference point o: rays are relative to it)."""
    V, F, n = [], [], 0
    for v, f in parts:
        V.append(v + np.asarray(shift))
        F.append(f + n)
        n += len(v)
    return Tracer.from_triangles(np.concatenate(V), np.concatenate(F))


def _column_hit(x, d):
    """The analytic first hit: the room's wall, or the column's surface where the ray meets it first."""
    t_room = analytic.box_hit_t(x, d, LO, HI)
    with np.errstate(divide="ignore", invalid="ignore"):
        t1, t2 = (COL_LO - x) / d, (COL_HI - x) / d
    t_in = np.nanmax(np.minimum(t1, t2), axis=1)
    t_out = np.nanmin(np.maximum(t1, t2), axis=1)
    col = (t_in <= t_out) & (t_in > 0)
    t = np.where(col & (t_in < t_room), t_in, t_room)
    return x + d * t[:, None]


def _captured(B, tracer, *, res=32, shade=None, o=(0.0, 0.0, 0.0)):
    tex = analytic.box_impostor(res, LO, HI)  # the room as o sees it: no column (a stand-in that misses it)

    def hits(org, dirs):
        return tracer.intersect(org, dirs)["point"]

    def points(org, dirs):  # "radiance" = the point the tracer hits along the ray (checkable exactly)
        return np.nan_to_num(tracer.intersect(org, dirs)["point"], nan=-7.0) - np.asarray(o)

    return Captured(impostor=EnvMap(tex, B), hits=hits, shade=shade or points, reference=tuple(o))


def _trace(m, B, env, x, d):
    with np.errstate(all="ignore"):
        tr = m.trace(B, env, B.vec(x), B.vec(d))
    return (B.to_numpy(tr.shown).astype(float), B.to_numpy(tr.radiance).astype(float),
            B.numpy(tr.valid).astype(bool), B.numpy(tr.lookups))  # fmt: skip


def _rays(n, seed):
    rng = np.random.default_rng(seed)
    x = rng.uniform(LO * 0.9, HI * 0.9, (n, 3))
    x = x[~np.all((x > COL_LO - 0.05) & (x < COL_HI + 0.05), axis=1)]  # not inside the column
    d = rng.normal(size=(len(x), 3))
    return x, d / np.linalg.norm(d, axis=1, keepdims=True)


@pytest.mark.parametrize("backend", ["numpy", "llvm"])
def test_exact_on_a_room_with_a_column_where_the_search_is_not(backend):
    """Random rays in a box room with a column (its top, 1.2 m, hidden from o at 0 only in part: rays from above
    it see what o does not): traced shows the analytic hit on every ray (CORRECT with ε = 1 mm), its radiance is
    exact shading's, one lookup per ray; localized(10) on the same impostor misses the column on some rays. The
    world is moved by o (the reference point): rays and shown points are relative to it, the tracer's are not."""
    B = backends.get(backend)
    o = (0.3, 0.2, -0.1)
    tracer = _scene(_box_triangles(LO, HI), _box_triangles(COL_LO, COL_HI), shift=o)
    x, d = _rays(3000, 1)
    exact = _column_hit(x, d)
    env = _captured(B, tracer, o=o)
    shown, rad, valid, spent = _trace(methods.make("traced"), B, env, x, d)
    assert valid.all()
    np.testing.assert_allclose(shown, exact, atol=2e-5)
    np.testing.assert_allclose(rad, exact, atol=2e-5)  # the shading of its own rays, not the impostor's
    cls = outcomes.classify(x, d, shown, exact, eps=1e-3).cls
    assert (cls == outcomes.CORRECT).all()
    assert (spent == 1).all() and methods.make("traced").lookups_per_ray() == 1
    loc, _, _, _ = _trace(methods.make("localized", iterations=10), B, env, x, d)
    wrong = outcomes.classify(x, d, loc, exact, eps=1e-3).cls != outcomes.CORRECT
    assert wrong.mean() > 0.05  # the impostor holds no column: the search cannot find it


def test_open_room_rays_escape_to_infinity_along_their_own_direction():
    """A box without its top: rays leaving through the opening are shown at FAR along their own direction (the
    case's exact hit for an escaping ray), CORRECT by direction; the others hit the walls exactly."""
    B = backends.get("numpy")
    tracer = _scene(_box_triangles(LO, HI, top=False))
    x, d = analytic.random_rays(2000, extent=1.0, seed=3)
    t = tracer.intersect(x, d)
    esc = ~np.isfinite(t["t"])
    assert 0.05 < esc.mean() < 0.5
    exact = np.where(esc[:, None], x + d * FAR, t["point"])
    shown, _, valid, _ = _trace(methods.make("traced"), B, _captured(B, tracer), x, d)
    assert valid.all()
    np.testing.assert_allclose(shown[~esc], exact[~esc], atol=2e-5)
    cls = outcomes.classify(x, d, shown, exact, eps=outcomes.tolerance(np.zeros(3), exact, 64)).cls
    assert (cls == outcomes.CORRECT).all()


def test_origins_the_reference_point_cannot_see_are_traced_too():
    """Origins behind the column from o (the stand-ins drop or misjudge them): traced traces them exactly."""
    B = backends.get("numpy")
    tracer = _scene(_box_triangles(LO, HI), _box_triangles(COL_LO, COL_HI))
    rng = np.random.default_rng(5)
    x = np.c_[rng.uniform(-1.9, -1.5, 200), rng.uniform(-1.0, 0.5, 200), rng.uniform(-1.9, -1.5, 200)]
    hidden = tracer.distance(np.zeros_like(x), x / np.linalg.norm(x, axis=1, keepdims=True))
    assert (hidden < np.linalg.norm(x, axis=1)).mean() > 0.5  # most of them behind the column seen from o
    d = rng.normal(size=(200, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    shown, _, valid, _ = _trace(methods.make("traced"), B, _captured(B, tracer), x, d)
    assert valid.all()
    np.testing.assert_allclose(shown, _column_hit(x, d), atol=2e-5)


def test_missing_hits_are_one_line_and_a_bare_impostor_traces_the_room_box():
    B = backends.get("numpy")
    tex = analytic.box_impostor(16, LO, HI)
    env = Captured(impostor=EnvMap(tex, B), shade=lambda o, d: o)  # a case's Captured without the tracer
    x, d = analytic.random_rays(50, extent=1.0, seed=0)
    with pytest.raises(StudyError, match="the exact tracer's hits") as err:
        methods.make("traced").trace(B, env, B.vec(x), B.vec(d))
    assert "traced" in str(err.value) and "\n" not in str(err.value)
    shown, _, valid, spent = _trace(methods.make("traced"), B, EnvMap(tex, B), x, d)
    assert valid.all() and (spent == 1).all()
    np.testing.assert_allclose(shown, analytic.box_hit(x, d, LO, HI), atol=1e-5)


def test_traced_is_a_mirror_method_in_all_and_asks_for_the_tracer():
    m = methods.make("traced")
    assert "traced" in {x.name for x in methods.all_methods()} and m.knob is None
    v = m.views_needed()
    assert v.hits and v.shade and v.layers == 1 and not v.screen
