"""The hierarchical search (study.impostor.pyramid, study.methods.march) against the texel march it replaces: the
pyramid's bound against its slow twin, the same shown points as the texel march (``hierarchical=False``, the brute
force kept) on a one-texel-wide pillar, on grazing rays along the walls, on random rays in a room with a column and
on Embree-peeled depth layers, with fewer lookups, as many as reported and no more than the bound.

Provenance: box impostors from study.impostor.analytic (exact ray–box distances through texel centres); the column
rooms of tests/methods/test_methods_linear_secant.py and tests/methods/test_methods_layered.py (Embree captures,
128²)."""

import numpy as np
import pytest
from conftest import load_script, small_scene_dict

from study import methods
from study.impostor import analytic, cubemap, layers
from study.impostor.envmap import EnvMap
from study.impostor.pyramid import MinPyramid, bound_ref, min_pyramid
from study.impostor.views import Captured
from study.reference.embree import Tracer
from study.scene import scene_from_dict

LO, HI = [-2.0, -1.5, -2.0], [2.0, 1.5, 2.0]


def _trace(name, B, env, x, d, **kw):
    """(shown (N, 3), valid, lookups per ray, bound) of method ``name`` traced on ``env``."""
    m = methods.make(name, **kw)
    with np.errstate(all="ignore"):
        tr = m.trace(B, env, B.vec(x), B.vec(d))
    res = env.res if isinstance(env, (EnvMap, Captured)) else 0
    return (
        B.to_numpy(tr.shown).astype(float),
        B.numpy(tr.valid).astype(bool),
        B.numpy(tr.lookups).astype(float),
        m.lookups_per_ray(res),
    )


def _same_as_texel_march(name, B, env, x, d, tol=1e-3, **kw):
    """Both searches on the same rays: the same valid rays and shown points within ``tol`` (relative) on all but
    0.5 % of them; each ray's lookups ≤ the bound. Returns (texel march, hierarchical) results."""
    flat = _trace(name, B, env, x, d, hierarchical=False, **kw)
    hier = _trace(name, B, env, x, d, hierarchical=True, **kw)
    np.testing.assert_array_equal(flat[1], hier[1])
    v = flat[1]
    rel = np.linalg.norm(flat[0][v] - hier[0][v], axis=1) / np.linalg.norm(flat[0][v], axis=1)
    assert np.mean(rel > tol) <= 0.005, np.sort(rel)[-5:]
    assert flat[2].max() <= flat[3] and hier[2].max() <= hier[3]
    return flat, hier


# ---------------------------------------------------------------------------------------------- the pyramid
@pytest.mark.parametrize("res", [16, 13])
def test_pyramid_bound_is_a_lower_bound_of_the_lookups_and_not_a_loose_one(res, B):
    """Random segments on random faces of random distances (res 16 and an odd 13): the bound never exceeds the
    smallest texel the bilinear lookups along the segment read (bound_ref), and on short segments (≤ 2 texels)
    it is above the face's minimum on most (it reads a small block, not the whole face)."""
    rng = np.random.default_rng(res)
    dist = rng.uniform(1.0, 5.0, (6, res, res)).astype(np.float32)
    n = 300
    face = rng.integers(0, 6, n)
    uv0 = rng.uniform(0, 1, (n, 2))
    short = np.arange(n) < n // 2
    uv1 = np.where(short[:, None], uv0 + rng.uniform(-2, 2, (n, 2)) / res, rng.uniform(0, 1, (n, 2)))
    uv1 = np.clip(uv1, 0, 1)
    pyr = MinPyramid(dist, B)
    f = B.array(face.astype(np.float32))
    got = B.numpy(
        pyr.bound(f, B.array(uv0[:, 0]), B.array(uv0[:, 1]), f, B.array(uv1[:, 0]), B.array(uv1[:, 1]))
    )
    want = np.array([bound_ref(dist, face[i], uv0[i], uv1[i]) for i in range(n)])
    assert np.all(got <= want)
    assert np.mean(got[short] > dist[face[short]].reshape(-1, res * res).min(1) + 1e-3) > 0.8
    other = B.array(((face + 1) % 6).astype(np.float32))  # two faces: no bound
    no = pyr.bound(f, B.array(uv0[:, 0]), B.array(uv0[:, 1]), other, B.array(uv1[:, 0]), B.array(uv1[:, 1]))
    assert np.all(B.numpy(no) < 0)


def test_pyramid_levels_hold_the_minimum_of_their_texels():
    """Level q, dilated, at texel (i, j) holds the minimum over level-0 texels [i 2^q, (i + 2) 2^q) × [j 2^q, …)
    (brute force on random distances, res 12, padded odd sides included)."""
    rng = np.random.default_rng(1)
    dist = rng.uniform(1.0, 5.0, (6, 12, 12)).astype(np.float32)
    flat, offsets = min_pyramid(dist)
    for q, (o, s) in enumerate(offsets):
        lev = flat[o : o + 6 * s * s].reshape(6, s, s)
        for i in range(s):
            for j in range(s):
                a, b = i * 2**q, j * 2**q
                want = dist[:, a : a + 2 ** (q + 1), b : b + 2 ** (q + 1)].min(axis=(1, 2))
                np.testing.assert_array_equal(lev[:, i, j], want)
    assert offsets[-1][1] == 1


def test_the_bound_reads_the_lowest_level_that_covers_its_box(B):
    """Boxes of every whole width 2..R − 4 texels along one row (R = 256 and an odd 13; the bilinear lookups of a
    segment from column 3.25 to 3.25 + width − 2 touch columns 3 … width + 2, rows 5 and 6): the bound equals the
    dilated level q = the least with width ≤ 2^q + 1 (brute force) at the box's first texel, on a map whose texels
    all differ, so a level one too low or too high, or a wrong texel, shows (Backend.exponent picks q)."""
    for res in (256, 13):
        dist = np.linspace(2.0, 1.0, 6 * res * res, dtype=np.float32).reshape(6, res, res)
        flat, offsets = min_pyramid(dist)
        pyr = MinPyramid(dist, B)
        width = np.arange(2, res - 3)
        u0, u1 = np.full(len(width), 3.75 / res), (3.75 + width - 2) / res  # coordinates c = u R − 0.5
        v = np.full(len(width), 5.75 / res)
        f = B.array(np.full(len(width), 2.0, np.float32))
        got = B.numpy(pyr.bound(f, B.array(u0), B.array(v), f, B.array(u1), B.array(v)))
        for w, g in zip(width, got):
            q = next(q for q in range(len(offsets)) if w <= 2**q + 1)
            o, s = offsets[q]
            want = flat[o : o + 6 * s * s].reshape(6, s, s)[2, 5 >> q, 3 >> q] * (1 - 1e-5)
            assert g == pytest.approx(want, rel=1e-7), (res, w)


def test_levels_made_in_the_march_read_what_the_table_of_levels_gives(B):
    """MinPyramid.bound with each level's side, 2^−q and offset made from q (a power-of-two side, K maps of six
    faces: offset 8K (R² − side²)) gives the bits of the same bound read from the table of levels (MinPyramid.made
    off), on random segments of every width over a stack of 1 and of 3 maps (a wrong K reads another level's
    texels); a side of 12 is read from the table."""
    rng = np.random.default_rng(5)
    for R, maps in ((64, 1), (64, 3), (12, 1)):
        dist = np.linspace(2.0, 1.0, 6 * maps * R * R, dtype=np.float32).reshape(6 * maps, R, R)  # all differ
        pyr = MinPyramid(dist, B)
        assert pyr.made == (R == 64)
        f = B.array(rng.integers(0, 6 * maps, 4000).astype(np.float32))
        a = rng.uniform(-0.05, 1.05, (2, 4000))
        b = a + rng.normal(size=(2, 4000)) * 2.0 ** rng.uniform(-8.0, 0.0, 4000)  # every width
        uv = [B.array(c.astype(np.float32)) for c in (*a, *b)]
        got = B.numpy(pyr.bound(f, uv[0], uv[1], f, uv[2], uv[3]))
        pyr.made = False
        want = B.numpy(pyr.bound(f, uv[0], uv[1], f, uv[2], uv[3]))
        assert got.tobytes() == want.tobytes(), (R, maps)
        assert len(np.unique(want)) > 200


# ---------------------------------------------------------------------------------------------- thin crossings
def _pillar(res=64, near=0.5):
    """A box impostor with a pillar one texel wide: on face +x, texel column j0 holds ``near`` of the wall's
    distance on every row. Returns (texels, pillar directions (res, 3), their distances)."""
    tex = analytic.box_impostor(res, LO, HI)
    j0 = res // 2 + 3
    tex[0, :, j0, -1] *= near
    dirs = cubemap.texel_directions(res)[0, :, j0]
    return tex, dirs, tex[0, :, j0, -1]


def test_a_one_texel_pillar_is_found_by_the_hierarchical_search_as_by_the_texel_march(B):
    """Rays from random points behind o aimed at points 0.4 m behind the pillar's texel centres (rows 8..56): each
    crosses the pillar's bilinear tent, one texel of arc to either side of its centre, in front of the wall. The
    texel march shows a point within 1.5 texels of the pillar's direction and ≥ 0.3 m nearer than the wall on
    ≥ 90 % of them; the hierarchical search shows the same points, from at least 4× fewer lookups on average."""
    res = 64
    tex, dirs, dist = _pillar(res)
    rng = np.random.default_rng(3)
    n = 400
    rows = rng.integers(8, 56, n)
    tgt = dirs[rows] * (dist[rows, None] + 0.4)
    x = rng.uniform(-0.6, 0.6, (n, 3))
    x[:, 0] = rng.uniform(-1.5, -0.5, n)
    d = (tgt - x) / np.linalg.norm(tgt - x, axis=1, keepdims=True)
    env = EnvMap(tex, B)
    flat, hier = _same_as_texel_march("linear_secant", B, env, x, d)
    shown = flat[0] / np.linalg.norm(flat[0], axis=1, keepdims=True)
    off = np.arccos(np.clip((shown * dirs[rows]).sum(1), -1, 1))  # from the pillar's direction
    near = np.linalg.norm(flat[0], axis=1) < dist[rows] / 0.5 - 0.3  # the wall is at dist / 0.5
    assert np.mean((off < 1.5 * 2 / res) & near) >= 0.9
    assert hier[2].mean() * 4 <= flat[2].mean()


def test_grazing_rays_along_the_walls_give_the_texel_march_s_hits(B):
    """Rays 2–8 cm from a wall of the box room, at 0.5–3° to it: the ray point stays within a few texels of
    the wall's surface for metres (the pyramid proves little there) and the hit is on the far wall; the
    hierarchical search shows the texel march's points, within 1 cm of the exact box hit (median) and 6 cm on
    ≥ 99 % (bilinear interpolation of a 64² map at grazing angles)."""
    rng = np.random.default_rng(5)
    n = 400
    tex = analytic.box_impostor(64, LO, HI)
    axis = rng.integers(0, 3, n)
    sign = rng.choice([-1, 1], n)
    x = rng.uniform(-1.0, 1.0, (n, 3))
    lo, hi = np.array(LO), np.array(HI)
    gap = rng.uniform(0.02, 0.08, n)
    x[np.arange(n), axis] = np.where(sign > 0, hi[axis] - gap, lo[axis] + gap)
    along = rng.normal(size=(n, 3))
    along[np.arange(n), axis] = 0
    along /= np.linalg.norm(along, axis=1, keepdims=True)
    ang = np.radians(rng.uniform(0.5, 3.0, n))
    d = along * np.cos(ang)[:, None]
    d[np.arange(n), axis] = sign * np.sin(ang)
    env = EnvMap(tex, B)
    flat, hier = _same_as_texel_march("linear_secant", B, env, x, d)
    exact = analytic.box_hit(x, d, LO, HI)
    err = np.linalg.norm(hier[0] - exact, axis=1)
    assert np.median(err) < 0.01 and np.mean(err < 0.06) >= 0.99  # 64² bilinear: cm at grazing angles


# ---------------------------------------------------------------------------------------------- captured rooms
@pytest.fixture(scope="module")
def column_room():
    """The small room with one column taller than o; three Embree-peeled layers (128²); layer 0 is the impostor."""
    s = scene_from_dict(
        small_scene_dict(columns=[{"center": [-0.8, 0.3], "footprint": [0.5, 0.5], "height": 2.0}])
    )
    o = np.asarray(s.reference.point)
    tracer = Tracer(s.mesh())
    res = 128
    dist, point, _, _ = layers.peel(tracer, o, cubemap.texel_directions(res).reshape(-1, 3), 3)
    d = dist.reshape(3, 6, res, res)
    tex = np.concatenate(
        [point.reshape(3, 6, res, res, 3), layers.depth_jump(d)[..., None], d[..., None]], -1
    )
    return o, tracer, tex.astype(np.float32)


def test_random_rays_in_a_room_with_a_column_linear_secant_and_layered(column_room, B):
    """2000 random rays from within 0.5 m of o: linear_secant on the impostor and layered on the three layers
    show the texel march's points with the hierarchical search (≥ 99.5 % within 0.1 %), from ≥ 4× fewer lookups
    on average."""
    o, tracer, tex = column_room
    x, d = analytic.random_rays(2000, extent=0.5, seed=4)
    imp = tex[0][..., [0, 1, 2, 4]]  # RGB, distance
    env = Captured(impostor=EnvMap(imp, B), reference=o, layers=tuple(EnvMap(t, B) for t in tex))
    for name in ("linear_secant", "layered"):
        flat, hier = _same_as_texel_march(name, B, env, x, d)
        assert hier[2].mean() * 4 <= flat[2].mean(), name


def test_every_sample_a_block_jump_skips_is_in_front_of_the_surface(column_room, B):
    """The skipper's reach against brute force: 3000 random rays from within 0.6 m of o in the column room, each
    with a random block (k, k_b]: every sample of k + 1 … reach that the march would skip has g < 0 (the ray
    point nearer than the bilinear lookup there: linear_secant's g at t = Samples.direct), so a skip never steps
    over a crossing. The reach is not vacuous: it clears whole blocks on some rays and jumps part of the way on
    others (the bound holds the ray off the surface up to a point inside the block)."""
    from study.methods import linear_secant
    from study.methods.search import arc_samples

    o, _, tex = column_room
    env = EnvMap(tex[0][..., [0, 1, 2, 4]], B)
    n = linear_secant.march_steps(env.res, linear_secant.TexelMarchParams())
    rng = np.random.default_rng(5)
    m = 3000
    xn, dn = analytic.random_rays(m, extent=0.6, seed=6)
    x, R = B.vec(xn), B.vec(dn)
    a = B.maximum(B.length(x), 1e-6)
    skip = linear_secant.skipper(B, env.pyramid, x, R, a, n)
    smp = arc_samples(B, x.dot(R) / a, n)
    k = rng.integers(0, n - 1, m).astype(np.float32)
    kb = np.minimum(k + 2.0 ** rng.integers(1, 9, m), n).astype(np.float32)
    kb = np.minimum(kb, B.numpy(skip.edge(B.array(k))))
    t_at = lambda kk: B.minimum(smp.direct(B.array(kk)), 1.0)  # noqa: E731
    reach = B.numpy(skip.reach(B.array(k), B.array(kb), t_at(k + 1.0), t_at(kb)))
    assert np.all((reach >= k) & (reach <= kb))
    for j in range(1, int((reach - k).max()) + 1):  # every skipped sample, the j-th after k
        on = k + j <= reach
        t = t_at(np.where(on, k + j, k + 1.0).astype(np.float32))
        p = x * (1.0 - t) + R * (a * t)
        g = B.numpy(B.length(p) - (1.0 - t) * env.distance(p))
        assert np.all(g[on] < 0.0), j
    whole, part = reach == kb, (reach > k) & (reach < kb)
    assert whole.mean() > 0.05 and part.mean() > 0.05, (whole.mean(), part.mean())


# ---------------------------------------------------------------------------------------------- face edges
def test_exit_angle_is_where_a_dense_walk_along_the_circle_changes_face():
    """cubemap.exit_angle against its slow twin: 300 random great circles and start angles, walked in steps of
    π/20000 from the start; the first step on another face (cubemap.face_uv) lies within a step of the computed
    angle (float32 trigonometry: 2e-4 rad), never before it."""
    from study import backend

    nb = backend.get("numpy")
    rng = np.random.default_rng(11)
    e1 = rng.normal(size=(300, 3))
    e1 /= np.linalg.norm(e1, axis=1, keepdims=True)
    e2 = rng.normal(size=(300, 3))
    e2 -= e1 * (e1 * e2).sum(1, keepdims=True)
    e2 /= np.linalg.norm(e2, axis=1, keepdims=True)
    phi = rng.uniform(0, np.pi, 300)
    got = cubemap.exit_angle(nb, nb.vec(e1), nb.vec(e2), phi.astype(np.float32)).astype(float)
    walk = phi[:, None] + np.linspace(0, np.pi, 20001)[None, :]  # (300, 20001)
    d = np.cos(walk)[..., None] * e1[:, None] + np.sin(walk)[..., None] * e2[:, None]
    face = cubemap.face_uv(nb, d[..., 0], d[..., 1], d[..., 2])[0]
    first = np.argmax(face != face[:, :1], axis=1)  # every half turn changes face at least once
    assert (first > 0).all()
    true = walk[np.arange(300), first]
    assert np.all(got <= true + 2e-4), np.max(got - true)
    assert np.all(got >= walk[np.arange(300), first - 1] - 2e-4), np.min(got - true)


def test_blocks_cut_at_face_edges_give_the_same_points_from_fewer_lookups(column_room, B, monkeypatch):
    """The march with blocks cut at the cube's face edges (Skip.edge) against the same march without the cut (the
    pyramid never clears a block across an edge; it halves the block instead): the same shown points on the random
    rays of the column room, and fewer lookups on average for linear_secant and layered (measured: 35 against 46
    on fig4's close-up batch)."""
    from study.methods import layered, linear_secant

    o, tracer, tex = column_room
    x, d = analytic.random_rays(2000, extent=0.5, seed=4)
    imp = tex[0][..., [0, 1, 2, 4]]
    env = Captured(impostor=EnvMap(imp, B), reference=o, layers=tuple(EnvMap(t, B) for t in tex))
    cut = {n: _trace(n, B, env, x, d, hierarchical=True) for n in ("linear_secant", "layered")}
    plain = linear_secant.skipper

    def uncut(*a):
        s = plain(*a)
        s.edge = None
        return s

    monkeypatch.setattr(linear_secant, "skipper", uncut)
    monkeypatch.setattr(layered, "skipper", uncut)
    for name, (shown, valid, lookups, bound) in cut.items():
        u_shown, u_valid, u_lookups, _ = _trace(name, B, env, x, d, hierarchical=True)
        np.testing.assert_array_equal(valid, u_valid)
        np.testing.assert_allclose(shown[valid], u_shown[valid], rtol=1e-5, atol=1e-6)
        assert lookups.max() <= bound
        assert lookups.mean() < 0.95 * u_lookups.mean(), (name, lookups.mean(), u_lookups.mean())


# ---------------------------------------------------------------------------------------------- fewer instructions
def test_tabulated_arc_samples_are_bit_identical_to_the_per_ray_sine_and_cosine(B):
    """Samples.direct after tabulate() (Dr.Jit: cos φ_k and sin φ_k read from two tables, one gather each, in
    place of a sine and a cosine per ray and step) gives the same bits as computing them per ray, for every k of
    0 … steps + 2 (past the arc's end too) on 500 random arcs (20 with cos θ rounded below −1), n = 805 (cube 256²)
    and an odd 37; on Dr.Jit the tables are made (the march reads them), on numpy not."""
    from study.methods.search import arc_samples

    rng = np.random.default_rng(8)
    for n in (805, 37):
        c = rng.uniform(-1.0, 1.0, 500).astype(np.float32)
        c[:20] = np.nextafter(np.float32(-1.0), np.float32(-2.0))  # x̂·R below −1 (the table's end: −2)
        c = B.array(c)
        k = rng.integers(0, n + 3, 500).astype(np.float32)
        plain = arc_samples(B, c, n)
        want = B.numpy(plain.direct(B.array(k)))
        tab = arc_samples(B, c, n)
        tab.tabulate()
        assert (tab.table is None) == (B.name == "numpy")
        got = B.numpy(tab.direct(B.array(k)))
        assert got.tobytes() == want.tobytes()
        assert np.all((want >= 0.0) & (want <= 1.0)) and np.any(want == 1.0) and np.any(want < 0.5)


def test_a_counted_while_loop_gives_the_iterations_each_lane_ran(B):
    """Backend.while_loop(counted=True) (the march's lookups where each iteration is one): x ← x/2 while x ≥ 1, at
    most 6 times; the first output per lane is how many times it halved (counted one lane at a time in Python),
    the state is as without counting."""
    x0 = np.array([0.5, 1.0, 3.0, 8.0, 40.0, 1000.0, 0.0], np.float32)
    want = []
    for v in x0:
        c = 0
        while v >= 1.0 and c < 6:
            v, c = v / 2.0, c + 1
        want.append(c)
    kw = dict(cond=lambda x: x >= 1.0, body=lambda x: (x * 0.5,), limit=6)
    count, x = B.while_loop((B.array(x0),), counted=True, **kw)
    (plain,) = B.while_loop((B.array(x0),), **kw)
    np.testing.assert_array_equal(B.numpy(count), np.array(want, np.float32))
    assert B.numpy(x).tobytes() == B.numpy(plain).tobytes()


def _march_ir():
    return load_script("march_ir")


def _llvm_or_skip():
    from conftest import BACKENDS

    if "llvm" not in BACKENDS:
        pytest.skip("needs Dr.Jit's LLVM backend")


def test_the_instruction_count_sees_each_side_of_a_branch_in_a_loop():
    """scripts/march_ir.py's count on a loop it can be checked by hand: y = x/2 before a branch, 2y + 1 on one
    side (2 instructions), y − 1 on the other (1); literal broadcasts (hex floats included) and phis not counted;
    the loop's own work (the test on i, the masked updates, the branch's two mask reductions) in cond/common."""
    _llvm_or_skip()
    import drjit as dr
    from drjit.llvm import Float, UInt32

    count = _march_ir().count

    def body(i, x):
        y = x * 0.5
        x = dr.if_stmt((y,), y > 3.0, lambda y: (y * 2.0 + 1.0,), lambda y: (y - 1.0,))[0]
        return i + 1, x

    flag = dr.flag(dr.JitFlag.KernelHistory)
    dr.set_flag(dr.JitFlag.KernelHistory, True)
    try:
        dr.kernel_history()
        i, x = dr.while_loop((UInt32(0), dr.arange(Float, 64)), lambda i, x: i < 5, body)
        dr.eval(x)
        (k,) = [k for k in dr.kernel_history() if k.get("type") == dr.KernelType.JIT]
    finally:
        dr.set_flag(dr.JitFlag.KernelHistory, flag)
    (c,) = count(k["ir"].getvalue())
    assert (c["true"], c["false"], c["state"]) == (2, 1, 2), c
    assert c["ops"] == c["cond"] + c["common"] + c["true"] + c["false"]


def test_the_march_makes_sample_k_plus_1_once_per_step_and_no_sine():
    """linear_secant's hierarchical march loop, counted in Dr.Jit's LLVM IR (scripts/march_ir.py, close-up rays):
    sample k + 1 (its t from the tabulated arc, the ray point, |p|, its face coordinates) made once before the
    branch, read by both sides, no sine or cosine per step, and no arc point made for a jump (the bracket's start
    kept as a sample index; t_prev no longer a loop variable). At 2b63288: 708 instructions (sample read 200,
    pyramid read 465, outside the branch 28), 11 loop variables; at 91494d0: 407 (78, 218, 96), 10 and 12 gathers;
    measured now (the pyramid's levels made, not read; no test of the arc's end; no clamp of t ≤ 1 to 1 nor of k ≤ n
    to n; 1 − t made once, in the Look; the lookups from the loop's own count): 371 (76, 190, 90), 9 and 9 gathers.
    Bounds with a small margin for Dr.Jit's code generation."""
    _llvm_or_skip()
    loops = _march_ir().method_loops("linear_secant", {})
    march = max(loops, key=lambda r: r["ops"])
    assert march["ops"] <= 385 and march["true"] <= 90 and march["false"] <= 200, march
    assert march["gathers"] <= 9, march  # no table of levels read (3 gathers at 91494d0)
    assert march["common"] >= 80 and march["state"] <= 9, march  # the shared sample, outside the branch


def test_the_widest_first_block_and_a_second_read_at_a_surface_give_the_same_points_from_fewer_lookups(
    column_room, B, monkeypatch
):
    """The march's first block the widest (march.FIRST None: the rest of the face in one pyramid read) and one
    more sample read alone where a block of 2 was not cleared (march.AT_SURFACE) against the rules before (a first
    block of 64 samples, a block of 2 tried after every read): the same shown points on the random rays of the
    column room, from fewer lookups on average for linear_secant and layered, every ray within the bound
    (measured here: linear_secant 16.75 → 16.07, layered 41.17 → 40.21; on fig4's close-up at 512² rays 14.59 →
    13.29 and 36.59 → 35.29)."""
    from study.methods import march

    o, tracer, tex = column_room
    x, d = analytic.random_rays(2000, extent=0.5, seed=4)
    imp = tex[0][..., [0, 1, 2, 4]]
    env = Captured(impostor=EnvMap(imp, B), reference=o, layers=tuple(EnvMap(t, B) for t in tex))
    now = {n: _trace(n, B, env, x, d, hierarchical=True) for n in ("linear_secant", "layered")}
    below = {"linear_secant": 0.97, "layered": 0.985}
    monkeypatch.setattr(march, "FIRST", 64)
    monkeypatch.setattr(march, "AT_SURFACE", False)
    for name, (shown, valid, lookups, bound) in now.items():
        o_shown, o_valid, o_lookups, _ = _trace(name, B, env, x, d, hierarchical=True)
        np.testing.assert_array_equal(valid, o_valid)
        np.testing.assert_array_equal(shown[valid], o_shown[valid])  # the same bracket, the same bits
        assert lookups.max() <= bound
        assert lookups.mean() < below[name] * o_lookups.mean(), (name, lookups.mean(), o_lookups.mean())


def test_rough_reciprocals_in_the_pyramid_read_keep_every_bracket(column_room, B, monkeypatch):
    """The pyramid read's divisions as approximate reciprocals (linear_secant.ROUGH: the block end's face
    coordinates, the partial jump's h/b) against exact divisions: the same shown points and valid rays bit for
    bit on the random rays of the column room, for linear_secant and layered, within the bound; the face
    coordinates within 1e-6 of the exact ones on the same face. Planted: reciprocals 2 % off (far outside the
    boxes' 1e-3-texel dilation) step over surfaces, and the shown points change."""
    from study.methods import linear_secant

    dirs = analytic.random_rays(5000, extent=1.0, seed=9)[1] * np.float32(3.0)
    v = B.vec(dirs)
    exact, rough = cubemap.face_uv(B, v.x, v.y, v.z), cubemap.face_uv(B, v.x, v.y, v.z, rough=True)
    np.testing.assert_array_equal(B.numpy(exact[0]), B.numpy(rough[0]))
    for e, r in zip(exact[1:], rough[1:]):
        assert np.abs(B.numpy(e) - B.numpy(r)).max() < 1e-6

    o, tracer, tex = column_room
    x, d = analytic.random_rays(2000, extent=0.5, seed=4)
    imp = tex[0][..., [0, 1, 2, 4]]
    env = Captured(impostor=EnvMap(imp, B), reference=o, layers=tuple(EnvMap(t, B) for t in tex))
    now = {n: _trace(n, B, env, x, d, hierarchical=True) for n in ("linear_secant", "layered")}
    monkeypatch.setattr(linear_secant, "ROUGH", False)
    for name, (shown, valid, lookups, bound) in now.items():
        e_shown, e_valid, e_lookups, _ = _trace(name, B, env, x, d, hierarchical=True)
        np.testing.assert_array_equal(valid, e_valid)
        np.testing.assert_array_equal(shown[valid], e_shown[valid])
        assert lookups.max() <= bound and abs(lookups.mean() - e_lookups.mean()) < 0.01 * e_lookups.mean()
    monkeypatch.setattr(linear_secant, "ROUGH", True)
    exact_rcp = B.rcp
    monkeypatch.setattr(B, "rcp", lambda a: exact_rcp(a) * 1.02)
    p_shown, p_valid, _, _ = _trace("linear_secant", B, env, x, d, hierarchical=True)
    shown, valid = now["linear_secant"][:2]
    assert not (np.array_equal(valid, p_valid) and np.array_equal(shown[valid], p_shown[valid]))
