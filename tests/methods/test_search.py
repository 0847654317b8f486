"""The search core (study.methods.search) against its slow per-ray twins on random cubics, the texel march
(samples in equal angles along the arc, the first entry into nested layers), and the object's distance map searched
with it: the same exits on numpy and Dr.Jit, and as many lookups as it reports."""

import numpy as np
import pytest

from study.backend import V3
from study.methods.search import (
    Bracket,
    arc_samples,
    first_crossing,
    first_entry,
    refine,
    secant_point,
    sign_changes,
)
from study.methods.search_ref import first_crossing_ref, first_entry_ref, refine_ref, sign_changes_ref
from study.optics.distance_map import DistanceMap
from study.scene import objects
from tests.conftest import BACKENDS
from tests.methods.test_refraction import glass_scene, snell_by_angles

N, STEPS = 400, 30


def cubics(n, seed):
    """Per ray a cubic c (t − r1)(t − r2)(t − r3): roots in [−0.3, 1.3], |c| in [0.5, 2], either sign."""
    rng = np.random.default_rng(seed)
    roots = rng.uniform(-0.3, 1.3, (n, 3)).astype(np.float32)
    scale = (rng.choice([-1.0, 1.0], n) * rng.uniform(0.5, 2.0, n)).astype(np.float32)
    return roots, scale


def g_core(B, roots, scale):
    r = [B.array(roots[:, i]) for i in range(3)]
    c = B.array(scale)
    return lambda t: c * (t - r[0]) * (t - r[1]) * (t - r[2])


def g_ref(roots, scale, i):
    r0, r1, r2 = (float(v) for v in roots[i])
    c = float(scale[i])
    return lambda t: c * (t - r0) * (t - r1) * (t - r2)


def samples(B, seed=11):
    """Per-ray start t0 in [0, 0.2) and step dt in [0.02, 0.06): 30 steps overrun t_max = 1 on most rays."""
    rng = np.random.default_rng(seed)
    t0 = rng.uniform(0.0, 0.2, N).astype(np.float32)
    dt = rng.uniform(0.02, 0.06, N).astype(np.float32)
    return t0, dt, B.array(t0), B.array(dt)


def ray(b: Bracket, B, i) -> Bracket:
    """Ray i of a core bracket, as plain floats."""
    return Bracket(*(float(B.numpy(v)[i]) for v in b[:4]), bool(B.numpy(b.found)[i]))


def assert_same(B, got: Bracket, want: list[Bracket]):
    np.testing.assert_array_equal(B.numpy(got.found).astype(bool), [w.found for w in want])
    for k in range(4):
        np.testing.assert_allclose(B.numpy(got[k]), [w[k] for w in want], rtol=1e-5, atol=1e-6)


@pytest.mark.parametrize("default", [None, "given"])
def test_first_crossing_matches_its_twin(B, default):
    roots, scale = cubics(N, 1)
    t0, dt, t0b, dtb = samples(B)
    g = g_core(B, roots, scale)
    dflt = (t0b, t0b - 1.0, t0b + 2.0, t0b + 3.0) if default else None
    got = first_crossing(B, g, t0b, g(t0b), dtb, STEPS, t_max=1.0, default=dflt)
    want = []
    for i in range(N):
        gi = g_ref(roots, scale, i)
        d = (float(t0[i]), float(t0[i]) - 1.0, float(t0[i]) + 2.0, float(t0[i]) + 3.0) if default else None
        want.append(
            first_crossing_ref(gi, float(t0[i]), gi(float(t0[i])), float(dt[i]), STEPS, t_max=1.0, default=d)
        )
    assert 0.2 < np.mean([w.found for w in want]) < 0.8  # both outcomes are exercised
    assert_same(B, got, want)


def test_sign_changes_of_several_functions_match_their_twin(B):
    """Two functions on the same samples (as layered's layers), the first three sign changes of each."""
    t0, dt, t0b, dtb = samples(B, seed=12)
    funcs = [cubics(N, 2), cubics(N, 3)]
    gs = [g_core(B, *f) for f in funcs]
    got = sign_changes(
        B, lambda t: [g(t) for g in gs], t0b, [g(t0b) for g in gs], dtb, STEPS, count=3, t_max=1.0
    )
    for f, per_fn in zip(funcs, got):
        want = []
        for i in range(N):
            gi = g_ref(*f, i)
            want.append(
                sign_changes_ref(gi, float(t0[i]), gi(float(t0[i])), float(dt[i]), STEPS, count=3, t_max=1.0)
            )
        counts = np.sum([[w.found for w in ws] for ws in want], axis=1)
        assert set(counts) == {0, 1, 2, 3}
        for j in range(3):
            assert_same(B, per_fn[j], [ws[j] for ws in want])


@pytest.mark.parametrize("illinois", [True, False])
@pytest.mark.parametrize("rising", [True, False])
def test_refine_matches_its_twin_and_finds_the_root(B, illinois, rising):
    """From the core's own brackets: the secant point after 0–12 steps agrees with the twin's (float32 against
    float64) wherever a crossing was found; with the Illinois rule, 12 steps put it on a root of the cubic."""
    roots, scale = cubics(N, 4)
    _, _, t0b, dtb = samples(B, seed=13)
    g = g_core(B, roots, scale)
    if rising:
        br = first_crossing(B, g, t0b, g(t0b), dtb, STEPS, t_max=1.0)
    else:
        br = sign_changes(B, g, t0b, g(t0b), dtb, STEPS, count=2, t_max=1.0)[1]  # the second change
    found = B.numpy(br.found).astype(bool)
    assert found.mean() > 0.1
    for steps in (0, 1, 3, 12):
        t = B.numpy(secant_point(refine(B, g, br, steps, illinois=illinois, rising=rising)))
        want = [
            secant_point(
                refine_ref(g_ref(roots, scale, i), ray(br, B, i), steps, illinois=illinois, rising=rising)
            )
            for i in np.nonzero(found)[0]
        ]
        np.testing.assert_allclose(t[found], want, atol=1e-6)
    if illinois:
        nearest = np.abs(t[:, None] - roots).min(axis=1)
        assert np.all(nearest[found] < 1e-4)


# ---------------------------------------------------------------------------------------------- distance map
def _exit_rays(g, n, seed=3):
    """Rays refracted in (n = 1.5) at random points of the surface, hit from outside: entry points and directions."""
    rng = np.random.default_rng(seed)
    o = g.center + rng.normal(size=(n, 3)) * 2 * g.radius
    tgt = g.center + rng.uniform(-0.5, 0.5, (n, 3)) * g.radius
    d = tgt - o
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    t, nrm = g.intersect(o, d)
    hit = np.isfinite(t)
    x, nrm, d = (o + t[:, None] * d)[hit], nrm[hit], d[hit]
    return x, snell_by_angles(d, nrm, 1 / 1.5)


@pytest.mark.skipif("llvm" not in BACKENDS, reason="needs Dr.Jit's LLVM backend")
@pytest.mark.parametrize("shape", ["sphere", "torus"])
def test_distance_map_exit_is_the_same_on_numpy_and_llvm(shape):
    """The same exits from both backends (texture filtering differs only in float32 round-off): on a sphere
    within 1e-6 m everywhere, on a torus (whose map has edges: its hole) on 99 % of the rays, the same ok flags."""
    g = objects.object_geometry(glass_scene(shape=shape))
    x, d = _exit_rays(g, 600)
    e_np, n_np, ok_np = DistanceMap(g, 64).exit(x, d)
    e_ll, n_ll, ok_ll = DistanceMap(g, 64, backend="llvm").exit(x, d)
    assert e_np.dtype == np.float64 and e_np.shape == x.shape and ok_np.dtype == bool
    np.testing.assert_array_equal(ok_np, ok_ll)
    assert ok_np.mean() > 0.99
    de = np.linalg.norm(e_np - e_ll, axis=1)[ok_np]
    dn = np.linalg.norm(n_np - n_ll, axis=1)[ok_np]
    if shape == "sphere":
        assert de.max() < 1e-6 and dn.max() < 1e-4
    else:
        assert np.mean(de < 1e-6) > 0.99 and np.mean(dn < 1e-4) > 0.99


def test_distance_map_spends_the_lookups_it_reports(B):
    """Every lookup of the exit search goes through the map's EnvMap: as many calls as lookups_per_ray() (on
    Dr.Jit with its loops unrolled: a symbolic loop traces its body once)."""
    g = objects.object_geometry(glass_scene())
    x, d = _exit_rays(g, 50)
    dm = DistanceMap(g, 16, steps=7, iterations=5, backend=B.name)
    calls = []
    env = dm.env
    dm.env = type(
        "Counting",
        (),
        {
            "distance": lambda self, v: calls.append("distance") or env.distance(v),
            "lookup": lambda self, v: calls.append("lookup") or env.lookup(v),
        },
    )()
    symbolic = getattr(dm.B, "symbolic_loops", None)
    try:
        if symbolic is not None:
            dm.B.symbolic_loops = False
        dm.exit(x, d)
    finally:
        if symbolic is not None:
            dm.B.symbolic_loops = symbolic
    assert len(calls) == dm.lookups_per_ray() == 2 + 7 + 5


# ---------------------------------------------------------------------------------------------- texel march
def nested(B, n, seed, K=3):
    """Per ray K = 3 nested functions g_0 ≥ g_1 ≥ g_2 (as a layered map's layers, nearest first): a cubic minus
    0, minus |a cubic|, minus that plus |another| — many sign changes, in both directions, of each; K = 2: the
    first two, the second equal to the first on every other ray (a layer that repeats the one before)."""
    (r0, c0), (r1, c1), (r2, c2) = cubics(n, seed), cubics(n, seed + 1), cubics(n, seed + 2)
    if K == 2:
        c1 = c1 * (np.arange(n) % 2)
    h, d1, d2 = g_core(B, r0, c0), g_core(B, r1, c1 * 0.3), g_core(B, r2, c2 * 0.3)
    core = lambda t: [h(t), h(t) - B.abs(d1(t)), h(t) - B.abs(d1(t)) - B.abs(d2(t))][:K]

    def ref(i):
        a, b, c = g_ref(r0, c0, i), g_ref(r1, c1 * 0.3, i), g_ref(r2, c2 * 0.3, i)
        return lambda t: [a(t), a(t) - abs(b(t)), a(t) - abs(b(t)) - abs(c(t))][:K]

    return core, ref


@pytest.mark.parametrize("K", [2, 3])
@pytest.mark.parametrize("hold", [0, 2, 4])
def test_first_entry_matches_its_twin(B, hold, K):
    """The first kept entry into the inside of nested functions (entries kept, dropped as skin, clips; with two,
    behind both counts as inside only where they are equal) on the same samples as its per-ray twin: the same
    found flags, brackets and entry functions."""
    t0, dt, t0b, dtb = samples(B, seed=14)
    core, ref = nested(B, N, 5, K)
    dflt = (t0b, t0b - 1.0, t0b + 1.0, t0b + 1.0)
    got, e = first_entry(B, core, t0b, core(t0b), dtb, STEPS, hold=hold, t_max=1.0, default=dflt)
    want, want_e = [], []
    for i in range(N):
        gi = ref(i)
        w, we = first_entry_ref(
            gi,
            float(t0[i]),
            gi(float(t0[i])),
            float(dt[i]),
            STEPS,
            hold=hold,
            t_max=1.0,
            default=(float(t0[i]), float(t0[i]) - 1.0, float(t0[i]) + 1.0, float(t0[i]) + 1.0),
        )
        want.append(w)
        want_e.append(we)
    found = np.array([w.found for w in want])
    assert 0.2 < found.mean() < 1.0
    assert set(np.array(want_e)[found]) == set(range(K))
    assert_same(B, got, want)
    np.testing.assert_array_equal(B.numpy(e), want_e)


def _arcs(n, seed, top=179):
    """Unit x̂ and R at 20°–``top``° from each other, and θ."""
    rng = np.random.default_rng(seed)
    xh = rng.normal(size=(n, 3))
    xh /= np.linalg.norm(xh, axis=1, keepdims=True)
    perp = np.cross(xh, rng.normal(size=(n, 3)))
    perp /= np.linalg.norm(perp, axis=1, keepdims=True)
    th = rng.uniform(np.radians(20), np.radians(top), n)
    R = xh * np.cos(th)[:, None] + perp * np.sin(th)[:, None]
    return xh, R, th


def test_arc_samples_turn_the_direction_by_at_most_one_step(B):
    """Consecutive samples' directions (1 − t) x̂ + t R are at most π/steps apart (float32 rounding aside), turn
    by exactly that until the arc's end and reach R (t = 1) at the last step."""
    steps = 805  # ⌈π 256⌉: one texel of a 256² cube map per step
    xh, R, th = _arcs(300, 6)
    at = arc_samples(B, B.array((xh * R).sum(1).astype(np.float32)), steps)
    ts = np.stack([np.zeros(len(xh))] + [B.numpy(at(k)).astype(float) for k in range(1, steps + 1)])
    d = (1 - ts)[..., None] * xh + ts[..., None] * R
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    turn = np.arccos(np.clip((d[1:] * d[:-1]).sum(-1), -1, 1))
    assert turn.max() < np.pi / steps * 1.01
    before_end = np.arange(1, steps + 1)[:, None] * np.pi / steps < th - 1e-3
    np.testing.assert_allclose(turn[before_end], np.pi / steps, rtol=0.01)
    assert np.all(ts[-1] == 1.0) and np.all(np.diff(ts, axis=0) >= 0)


def test_a_texel_wide_bump_is_stepped_over_by_uniform_steps_but_not_by_the_texel_march(B):
    """g(t) ≥ 0 only where the lookup direction p̂(t) lies within w/2 of f, a direction on the arc (x̂ and R up to
    170° apart): a bump one texel of a 256² map wide (w = 1/256 rad). linear_secant's old search (n = max(30 (1 −
    x̂·R)/2, 10) uniform steps in t) finds it on < 10 % of the rays; the march of 805 equal angles (one texel each)
    on every ray, with the bump inside its bracket."""
    n = 400
    xh, R, th = _arcs(n, 7, top=170)
    rng = np.random.default_rng(8)
    phi = th * rng.uniform(0.1, 0.9, n)  # the bump's centre along the arc
    f = np.cos(phi)[:, None] * xh + np.sin(phi)[:, None] * np.cross(np.cross(xh, R), xh) / np.sin(th)[:, None]
    w = 1 / 256
    X, RR, F = B.vec(xh), B.vec(R), B.vec(f)
    zero = B.array(np.zeros(n, np.float32))

    def g(t):  # sin(w/2) − |p̂ × f| on f's side: no cancellation
        p = X * (1.0 - t) + RR * t
        cx = V3(p.y * F.z - p.z * F.y, p.z * F.x - p.x * F.z, p.x * F.y - p.y * F.x)
        return B.select(p.dot(F) > 0.0, float(np.sin(w / 2)) - B.length(cx) / B.length(p), zero - 1.0)

    cos = (xh * R).sum(1)
    n_old = np.maximum(30 * (1 - cos) / 2, 10).astype(np.float32)
    old = first_crossing(B, g, zero, g(zero), B.array(1 / n_old), 30, t_max=1.0)
    new = first_crossing(
        B, g, zero, g(zero), arc_samples(B, B.array(cos.astype(np.float32)), 805), 805, t_max=1.0
    )
    assert B.numpy(old.found).mean() < 0.1
    assert B.numpy(new.found).all()
    t_edge = np.sin(phi - w / 2) / (np.sin(phi - w / 2) + np.sin(th - phi + w / 2))  # where g turns ≥ 0
    assert np.all((B.numpy(new.t_lo) <= t_edge + 1e-6) & (t_edge <= B.numpy(new.t_hi) + 1e-6))
