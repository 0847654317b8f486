"""`study bench` end to end on a tiny batch, its timing harness and exact tracer, and the fast Dr.Jit paths
against the plain one.

Expected outcomes are stated per test; exact values come from study.impostor.analytic (the box room), not from the
code under test.
"""

import math
import time

import numpy as np
import pytest
from conftest import BACKENDS, BOX_HI, BOX_LO, run_cli

from study import backend as backends
from study import methods
from study.bench.batches import distance_texels, room_triangles
from study.bench.output import write_outputs
from study.bench.run import BenchOptions, bench_methods, run_bench
from study.bench.timing import median_time, method_runner
from study.codehash import code_hash
from study.impostor import analytic
from study.impostor.envmap import EnvMap
from study.reference.embree import Tracer
from study.tables import read_csv

needs_llvm = pytest.mark.skipif("llvm" not in BACKENDS, reason="needs Dr.Jit's LLVM backend")

#: the methods benched by default: every mirror method of "all" and then the exact-query ones "all" leaves out
#: (hit_cache); glossy ones are asked for by name
MIRROR = [
    n
    for n in methods.names()
    if not methods.REGISTRY[n].glossy and getattr(methods.REGISTRY[n], "in_all", True)
] + [
    n
    for n in methods.names()
    if not getattr(methods.REGISTRY[n], "in_all", True) and methods.REGISTRY[n].bench_query
]
DEFAULTS = [methods.make(n).label for n in MIRROR]


@pytest.mark.slow
def test_bench_cli_tiny_writes_tables(tmp_path):
    """A tiny bench (--no-ladder) writes bench-cpu.csv and .md: one exact Embree row per batch (3 batches), one
    row per registered method (its defaults) × backend × batch, plus the plain path of localized on Dr.Jit,
    positive times, and speed-ups finite and consistent with the exact rows."""
    names = ",".join(BACKENDS)
    res = run_cli(
        *[
            "bench",
            "--out",
            str(tmp_path),
            "--scene-res",
            "32",
            "--rays",
            "2048",
            "--cube-res",
            "16",
            "--repeats",
            "1",
            "--no-ladder",
            "--no-scaling",
            "--backends",
            names,
            "--tag",
            "cpu",
        ],
    )
    assert res.exit_code == 0, res.output
    rows = read_csv(tmp_path / "bench-cpu.csv")
    md = (tmp_path / "bench-cpu.md").read_text()
    assert "drjit" in md and "| batch | backend |" in md
    made_by = code_hash(run_bench, *{type(m) for m in bench_methods(BenchOptions(ladder=False))})
    assert f"code: {made_by} (" in md  # the numbers name the code that made them (study.codehash)
    batches = {r["batch"] for r in rows}
    assert len(batches) == 4  # fig4, close-up, synthetic, synthetic sorted by direction
    assert sum(r["label"] == "exact: Embree" for r in rows) == 4
    timed = [r for r in rows if not r["label"].startswith("exact")]
    defaults = set(DEFAULTS)
    assert len(defaults) == len(MIRROR)
    focus = methods.make("localized").label
    for b in batches:
        for nm in BACKENDS:
            got = [r["label"] for r in timed if r["batch"] == b and r["backend"] == nm]
            assert sorted(got) == sorted([*defaults] + ([focus] if nm != "numpy" else [])), (b, nm)
            if nm != "numpy":
                assert {
                    r["path"] for r in timed if r["batch"] == b and r["backend"] == nm and r["label"] == focus
                } == {"frozen", "plain"}
    for r in rows:
        assert r["ms_per_call"] > 0 and math.isclose(
            r["ms_per_frame"], r["ms_per_call"] / r["rays"] * 1024**2, rel_tol=1e-6
        )
    for r in timed:  # the device's time in its kernels (Dr.Jit's kernel history): on Dr.Jit only
        if r["backend"] == "numpy":
            assert not math.isfinite(r["kernel_ms_per_frame"])
        else:
            traced = r["label"] == "traced"  # the exact query: no floor (a traversal, not fetches)
            assert 0 < r["kernel_ms_per_frame"] and traced != math.isfinite(r["kernel_x_floor"]), r["label"]
    for r in (r for r in timed if r["label"] == "traced"):  # not timed twice: the exact rows' own numbers

        def ms(label, path, b=r["batch"]):
            return next(e for e in rows if e["batch"] == b and e["label"] == label and e["path"] == path)[
                "ms_per_frame"
            ]

        mi = "exact: Mitsuba llvm_ad_rgb"
        bare, full = (
            (ms("exact: Embree", "embree"),) * 2 if r["backend"] == "numpy" else
            (ms(mi, "ray_intersect_preliminary"), ms(mi, "ray_intersect"))
        )  # fmt: skip
        shading = ms(mi, "shade_material") + ms(mi, "shadow_ray")  # a renderer's shading at the hit (LLVM's)
        assert r["path"] == "shaded" and math.isclose(r["query_ms_per_frame"], bare, rel_tol=1e-6)
        assert math.isclose(r["ms_per_frame"], full + shading, rel_tol=1e-6)
    for r in timed:  # what a ray reads (study.bench.carry): within the method's bound, bytes from lookups
        assert 0 <= r["lookups_mean"] <= r["lookups_bound"] * (1 + 1e-6)
        assert r["bytes_per_ray"] == pytest.approx((r["lookups_mean"] + 1) * 16 + 64 + 53)
    for r in timed:
        emb = next(e for e in rows if e["batch"] == r["batch"] and e["label"] == "exact: Embree")
        assert math.isfinite(r["x_vs_embree"]) and r["x_vs_embree"] > 0
        assert math.isclose(r["x_vs_embree"], emb["ms_per_frame"] / r["ms_per_frame"], rel_tol=1e-6)
        mit = {
            e["path"]: e
            for e in rows
            if e["batch"] == r["batch"] and e["label"] == "exact: Mitsuba llvm_ad_rgb"
        }
        if mit:  # Mitsuba's LLVM variant present: every query, ratios right
            assert set(mit) == {
                "ray_intersect",
                "ray_intersect_preliminary",
                "ray_test",
                "shade_material",
                "shadow_ray",
            }
            for q, col in [
                ("ray_intersect", "x_vs_mitsuba"),
                ("ray_intersect_preliminary", "x_vs_preliminary"),
                ("ray_test", "x_vs_ray_test"),
            ]:
                assert math.isclose(r[col], mit[q]["ms_per_frame"] / r["ms_per_frame"], rel_tol=1e-6)
            pre = mit["ray_intersect_preliminary"]["kernel_ms_per_frame"]  # the device's time alone
            assert pre > 0 and (r["backend"] == "numpy" or r["kernel_x_vs_preliminary"] > 0)
        if (
            r["backend"] == "llvm" and r["label"] != "traced"
        ):  # a measured floor: positive, ratio = time / floor
            assert r["floor_ms_per_frame"] > 0
            assert math.isclose(r["x_floor"], r["ms_per_frame"] / r["floor_ms_per_frame"], rel_tol=1e-6)
    if "llvm" in BACKENDS:
        assert "## Measured floors" in md and (tmp_path / "floors-cpu.csv").exists()
        _the_issue_45_rows(rows)


def _the_issue_45_rows(rows):
    """ssr_hiz, probe_blend and hit_cache on Dr.Jit: lookups and bytes per ray, a measured floor and the ratio to it;
    probe_blend reads more than one probe (the bench places the probe sets as a case does); hit_cache is the exact
    query plus its cache read, at its floor."""
    llvm = [r for r in rows if r["backend"] == "llvm" and not r["label"].startswith("exact")]
    by = {
        lab: [r for r in llvm if r["label"].startswith(lab)]
        for lab in ("ssr_hiz", "probe_blend", "hit_cache")
    }
    for lab, rs in by.items():
        assert rs, lab
        for r in rs:
            assert r["lookups_mean"] > 0 and r["bytes_per_ray"] > 0 and r["floor_ms_per_frame"] > 0, r
            assert r["x_floor"] == pytest.approx(r["ms_per_frame"] / r["floor_ms_per_frame"]), r
    assert max(r["lookups_mean"] for r in by["probe_blend"]) > 1.5
    for r in by["hit_cache"]:
        q = next(e for e in rows if e["batch"] == r["batch"] and e["label"] == "exact: Mitsuba llvm_ad_rgb"
                 and e["path"] == "ray_intersect_preliminary")  # fmt: skip
        assert r["ms_per_frame"] > q["ms_per_frame"] and r["x_floor"] == pytest.approx(1.0)


def test_method_list_is_every_method_at_every_knob_value():
    """The methods timed: every registered method at each value of its declared knob's ladder (none looked up by
    parameter name), the defaults only with ladder=False, just the named ones with ``methods``."""
    got = [m.label for m in bench_methods(BenchOptions())]
    want = []
    for name in MIRROR:
        cls = methods.REGISTRY[name]
        want += (
            [methods.make(name, **{cls.knob.param: v}).label for v in cls.knob.ladder]
            if cls.knob
            else [methods.make(name).label]
        )
    assert got == want and len(got) > len(MIRROR)
    assert [m.label for m in bench_methods(BenchOptions(ladder=False))] == DEFAULTS
    assert [m.label for m in bench_methods(BenchOptions(methods=("localized", "classical")))] == [
        f"localized(iterations={n})" for n in methods.REGISTRY["localized"].knob.ladder
    ] + ["classical"]


def test_bench_bad_backend_is_one_line_error(tmp_path):
    res = run_cli("bench", "--out", str(tmp_path), "--backends", "vulkan", "--no-scaling")
    assert res.exit_code == 2 and "unknown backend 'vulkan'" in res.output


def test_bench_unknown_method_is_one_line_error(tmp_path):
    res = run_cli(
        *[
            "bench",
            "--out",
            str(tmp_path),
            "--backends",
            "numpy",
            "--methods",
            "localized,nosuch",
            "--no-scaling",
        ],
    )
    assert res.exit_code == 2 and "unknown method 'nosuch'" in res.output
    assert not list(tmp_path.iterdir())  # refused before anything was timed or written


def test_median_time_evaluates_every_call():
    """median_time: every call's outputs finished, one sync per repeat (plus warm-ups), and the median per call
    of a call that sleeps 2 ms is about 2 ms (not the repeat's total)."""
    calls, finished, syncs = [], [], []

    def call():
        calls.append(1)
        time.sleep(0.002)
        return len(calls)

    def finish(out):
        (syncs if out is None else finished).append(out)

    t = median_time(call, finish, repeats=3, warmup=2, min_repeat_s=0.05)  # several calls a repeat, also
    assert 0.0019 <= t <= 0.04  # on a loaded machine
    assert finished == list(range(1, len(calls) + 1))  # each call's own output, in order
    assert len(syncs) == 2 + 1 + 3 and len(calls) > 3 + 3


@pytest.mark.slow
def test_scaling_tiny_writes_plot(tmp_path):
    """The scaling studies on tiny sizes: every study present, the room grows by the requested triangles, the
    method's cost is reported at every triangle count (it does not trace the triangles), and the knob study
    covers localized's declared ladder plus the extra values."""
    from study.harness.config import load_figure_config

    _, scene, _ = load_figure_config("configs/fig4.toml")
    opt = BenchOptions(
        scene_res=16,
        synthetic=1024,
        methods=("localized", "classical"),
        ladder=False,
        cube_res=16,
        backends=("numpy",),
        repeats=1,
        numpy_max_rays=1024,
        ray_counts=(256, 1024),
        knob_extra=(2,),
        cube_resolutions=(8, 16),
        triangles=(0, 2000),
        tag="t",
    )
    rows, scaling, info = run_bench(scene, opt, log=lambda s: None)
    assert {r["label"] for r in rows if not r["label"].startswith("exact")} == {
        "localized(iterations=10)",
        "classical",
    }
    files = write_outputs(rows, scaling, info, tmp_path)
    assert (tmp_path / "scaling-t.png").stat().st_size > 10_000 and len(files) == 4
    assert {r["study"] for r in scaling} == {"rays", "knob", "cube_res", "triangles"}
    knob = [r for r in scaling if r["study"] == "knob"]
    assert [r["value"] for r in knob] == sorted({*methods.REGISTRY["localized"].knob.ladder, 2})
    assert all(r["label"] == f"localized(iterations={r['value']})" for r in knob)
    tris = sorted({r["value"] for r in scaling if r["study"] == "triangles"})
    assert tris[0] == 12 and 1900 <= tris[1] - 12 <= 2100
    for n in tris:
        assert any(
            r["value"] == n and r["label"].startswith("localized")
            for r in scaling
            if r["study"] == "triangles"
        )


def test_heightfield_room_distances_match_the_box():
    """Embree distances of the bench's impostor in the bare room equal the analytic box distances (1e-4 m)."""
    from conftest import small_scene_dict

    from study.scene import scene_from_dict

    scene = scene_from_dict(small_scene_dict())
    V, F = room_triangles(scene)
    tex = distance_texels(Tracer.from_triangles(V, F), scene.reference.point, 16)
    exact = analytic.box_impostor(16, BOX_LO, BOX_HI)
    np.testing.assert_allclose(tex[..., 3], exact[..., 3], atol=1e-4)
    Vh, Fh = room_triangles(scene, 500)
    assert len(Fh) - len(F) == 2 * 16**2 and Vh[len(V) :, 1].max() < 0.11  # 2k² triangles, below 11 cm


def test_tracer_from_triangles_threaded_distance_matches_intersect():
    """Tracer.from_triangles on raw (V, F): distance() cast in chunks on 3 threads equals the single-threaded
    intersect()'s t (float64, inf on a miss) and the analytic box distances; rays leaving the box miss."""
    from conftest import small_scene_dict

    from study.scene import scene_from_dict

    scene = scene_from_dict(small_scene_dict())
    mesh, o = scene.mesh(), np.asarray(scene.reference.point)
    x, d = analytic.random_rays(10_000, extent=0.8, seed=3)  # relative to o, as BOX_LO/HI
    d[:100] = x[:100] / np.linalg.norm(x[:100], axis=1, keepdims=True)  # some rays start outside, leaving
    x[:100] = x[:100] / np.linalg.norm(x[:100], axis=1, keepdims=True) * 10
    x = x + o
    tr = Tracer.from_triangles(mesh.vertices, mesh.faces, threads=3)
    t = tr.distance(x, d)
    assert tr.threads == 3 and t.dtype == np.float64 and t.shape == (10_000,)
    np.testing.assert_array_equal(t, Tracer(mesh).intersect(x, d)["t"])
    np.testing.assert_array_equal(t, Tracer(mesh, threads=1).distance(x, d))
    assert np.all(np.isinf(t[:100])) and np.all(np.isfinite(t[100:]))
    box = analytic.box_hit_t(x[100:] - o, d[100:], BOX_LO, BOX_HI)
    np.testing.assert_allclose(t[100:], box, atol=1e-4)


@needs_llvm
def test_frozen_and_recorded_paths_equal_plain():
    """localized(10) on Dr.Jit LLVM: the recorded loop (dr.while_loop), the unrolled Python loop and the frozen
    function (replayed) give the same shown points (1e-5
    relative), radiance and validity; and they match numpy on ≥ 99.9 % of the rays to 1e-4."""
    tex = analytic.box_impostor(64, BOX_LO, BOX_HI)
    x, d = analytic.random_rays(4000, extent=0.8, seed=7)
    m = methods.make("localized", iterations=10)
    B = backends.get("llvm")

    def run(frozen, symbolic, n):
        B.symbolic_loops = symbolic
        try:
            call, finish = method_runner(m, B, tex, x[:n], d[:n], frozen=frozen)
            out = call()
            finish(out)
            if frozen:
                out = call()
                finish(out)  # a replay, not the recording
            shown, rad, ratio, valid, _ = out  # and the lookups spent
            return B.to_numpy(shown), B.to_numpy(rad), B.numpy(valid)
        finally:
            B.symbolic_loops = True

    plain = run(False, True, 4000)
    for other in (run(False, False, 4000), run(True, True, 4000)):
        rel = np.linalg.norm(other[0] - plain[0], axis=1) / np.linalg.norm(plain[0], axis=1)
        assert np.nanmax(rel) <= 1e-5
        np.testing.assert_allclose(other[1], plain[1], rtol=1e-5)
        assert np.array_equal(other[2], plain[2])
    np.testing.assert_allclose(run(True, True, 1000)[0], run(False, True, 1000)[0], rtol=1e-5)
    nb = backends.get("numpy")
    env = EnvMap(tex, nb)
    ref = nb.to_numpy(m.trace(nb, env, nb.vec(x), nb.vec(d)).shown)
    rel = np.linalg.norm(ref - plain[0], axis=1) / np.linalg.norm(ref, axis=1)
    assert np.mean(rel <= 1e-4) >= 0.999


@needs_llvm
def test_frozen_function_replays():
    """dr.freeze records the search once and replays it on the same inputs (no Python re-tracing); on new
    batches (other sizes too) it gives the plain results (it may record again: seen with drjit 1.5 for arrays
    made from numpy)."""
    tex = analytic.box_impostor(32, BOX_LO, BOX_HI)
    m = methods.make("localized", iterations=5)
    B = backends.get("llvm")
    env = EnvMap(tex, B)

    def trace(t, dist, X, R):
        env.tex, env.dist = t, dist
        return m.trace(B, env, X, R).shown

    fr = B.freeze(trace)
    x, d = analytic.random_rays(3000, extent=0.8, seed=1)
    X, R = B.vec(x), B.vec(d)
    first = B.to_numpy(fr(env.tex, env.dist, X, R))
    for _ in range(3):
        np.testing.assert_array_equal(B.to_numpy(fr(env.tex, env.dist, X, R)), first)
    assert fr.n_recordings == 1
    for n, seed in ((500, 2), (3000, 3)):
        x, d = analytic.random_rays(n, extent=0.8, seed=seed)
        X, R = B.vec(x), B.vec(d)
        got = B.to_numpy(fr(env.tex, env.dist, X, R))
        want = B.to_numpy(trace(env.tex, env.dist, X, R))
        np.testing.assert_allclose(got, want, rtol=1e-5)


@needs_llvm
@pytest.mark.parametrize("name", ["linear_secant", "layered", "multi_probe", "sdf", "ssr_sdf"])
def test_marching_methods_frozen_equal_plain_and_numpy(name):
    """The marching methods as the bench runs them (issue 15: their searches are one symbolic loop, and layered is
    frozen too, its layers coming in through the frozen function's arguments): the frozen call, replayed, gives
    the plain call's shown points, and both match numpy (the same operations, another float order) on ≥ 99 % of
    the rays."""
    tex = analytic.box_impostor(32, BOX_LO, BOX_HI)
    x, d = analytic.random_rays(2000, extent=0.8, seed=9)
    m = methods.make(name)
    B = backends.get("llvm")
    out = {}
    for frozen in (False, True):
        call, finish = method_runner(m, B, tex, x, d, frozen=frozen)
        o = call()
        finish(o)
        o = call()
        finish(o)  # frozen: a replay
        out[frozen] = B.to_numpy(o[0])
    np.testing.assert_allclose(out[True], out[False], rtol=1e-6)
    nb = backends.get("numpy")
    call, finish = method_runner(m, nb, tex, x, d, frozen=False)
    ref = nb.to_numpy(call()[0])
    rel = np.linalg.norm(ref - out[False], axis=1) / np.linalg.norm(ref, axis=1)
    assert np.mean(rel <= 1e-4) >= 0.99 and np.isfinite(ref).all(axis=1).mean() > 0.9


# ---------------------------------------------------------------------------------------------- floors (issue 15)
def test_method_floor_is_fetches_times_cost_plus_bytes_over_bandwidth():
    """The floor model by hand: localized(10) reads the distance texture 3 + 10 times (its lookups) + 1 (origin
    check), the colour once, and moves 53 bytes; with 1 ns per fetch and 1 GB/s that is (14 + 1 + 53) ns a ray."""
    from study.bench.floors import BYTES_PER_RAY, method_floor

    fl = {
        "fetch_1ch_random": 1e9,
        "fetch_4ch_random": 1e9,
        "bandwidth": 1e9,
        "fetch_1ch_coherent": 2e9,
        "fetch_4ch_coherent": 1e9,
    }
    m = methods.make("localized", iterations=10)
    assert BYTES_PER_RAY == 53
    assert math.isclose(method_floor(m, fl, "random", 1000), 1000 * (14 + 1 + 53) * 1e-9, rel_tol=1e-12)
    assert math.isclose(method_floor(m, fl, "coherent", 1000), 1000 * (7 + 1 + 53) * 1e-9, rel_tol=1e-12)
    assert method_floor(methods.make("localized", iterations=20), fl, "random", 1) > method_floor(
        m, fl, "random", 1
    )


def test_sdf_floor_prices_its_3d_fetches_at_the_3d_rate():
    """sdf's bound (1 + 96 + 1 + 4 = 102 3D fetches, 1 impostor lookup) by hand: with 3D fetches at 0.5 ns and 2D
    at 1 ns, (102 · 0.5 + (1 + 1) · 1 + 1 + 53) ns a ray; without a measured 3D rate (floors measured before) the
    2D rate stands in. ssr_sdf's fallback fetches are priced the same way."""
    from study.bench.floors import method_floor

    fl = {"fetch_1ch_random": 1e9, "fetch_4ch_random": 1e9, "bandwidth": 1e9, "fetch_3d_random": 2e9}
    m = methods.make("sdf")
    assert m.volume_lookups() == 102 and m.lookups_per_ray() == 103
    assert math.isclose(method_floor(m, fl, "random", 1), (51 + 2 + 1 + 53) * 1e-9, rel_tol=1e-12)
    old = {k: v for k, v in fl.items() if k != "fetch_3d_random"}
    assert math.isclose(method_floor(m, old, "random", 1), (102 + 2 + 1 + 53) * 1e-9, rel_tol=1e-12)
    assert methods.make("ssr_sdf").volume_lookups() == 102 and methods.make("ssr").volume_lookups() == 0


def test_probe_blend_floor_reads_a_colour_per_probe_it_weighs():
    """A blend reads the colour of every probe it weighs (issue 56): at 1 ns per fetch, 5 lookups spent of its
    bound 9 (8 probes and the global one) are (5 + 1) distance fetches, 5 colour fetches, + 53 bytes at 1 GB/s; a
    method that reads one colour (localized) still counts 1. Planted (checked): the colour counted once gives 60."""
    from study.bench.floors import method_floor

    fl = {"fetch_1ch_random": 1e9, "fetch_4ch_random": 1e9, "bandwidth": 1e9}
    m = methods.make("probe_blend")
    assert m.lookups_per_ray() == m.colour_lookups() == 9
    assert math.isclose(method_floor(m, fl, "random", 1, lookups=5.0), (6 + 5 + 53) * 1e-9, rel_tol=1e-12)
    loc = methods.make("localized", iterations=10)
    assert loc.colour_lookups() == 0
    assert math.isclose(method_floor(loc, fl, "random", 1), (14 + 1 + 53) * 1e-9, rel_tol=1e-12)


@pytest.mark.skipif("llvm" not in BACKENDS, reason="needs Dr.Jit LLVM")
def test_measured_floors_are_positive_rates():
    """Fetch rates and copy bandwidth measured on LLVM: positive and finite, every pattern and channel count."""
    from study.bench.floors import floor_rows, measure

    fl = measure(backends.get("llvm"), 16, n_lanes=1 << 12, fetches=8, copy_floats=1 << 18, repeats=1)
    assert set(fl) == {f"fetch_{c}ch_{p}" for c in (1, 4) for p in ("coherent", "random", "scattered")} | {
        "bandwidth",
        "fetch_3d_coherent",
        "fetch_3d_random",
    }
    assert all(math.isfinite(v) and v > 0 for v in fl.values()), fl
    rows = floor_rows(fl, 16, "llvm")
    assert len(rows) == 9 and sum(r["quantity"].startswith("trilinear") for r in rows) == 2


def test_direction_sorted_batch_is_a_permutation_in_texel_order():
    """Ray reordering keeps every ray (same origin with its direction) and orders them by cube face and texel."""
    from study.bench.batches import Batch, direction_sorted
    from study.impostor import cubemap

    x, d = analytic.random_rays(5000, extent=0.5, seed=3)
    s = direction_sorted(Batch("synthetic 5000", x, d), res=8)
    assert s.name.endswith("sorted by direction")
    a = np.lexsort(np.concatenate([x, d], 1).T)
    b = np.lexsort(np.concatenate([s.x, s.R], 1).T)
    assert np.array_equal(np.concatenate([x, d], 1)[a], np.concatenate([s.x, s.R], 1)[b])
    face, u, v = cubemap.face_uv(backends.get("numpy"), *s.R.T)
    key = (face * 8 + np.minimum(v * 8, 7).astype(int)) * 8 + np.minimum(u * 8, 7).astype(int)
    assert np.all(np.diff(key) >= 0)
    assert not np.all(np.diff(s.R[:, 0]) == 0)


def test_rt_cores_line_names_gpus_without_rt_cores():
    from study.bench.machine import rt_cores_line

    assert "no RT cores" in rt_cores_line("NVIDIA H100 80GB HBM3, 580.159.04, 81559 MiB")
    assert "on an RT-core GPU the exact side would be faster" in rt_cores_line("NVIDIA H200, 580, 143771 MiB")
    assert "RT cores assumed present" in rt_cores_line("NVIDIA GeForce RTX 4090, 550, 24564 MiB")
    assert "no GPU" in rt_cores_line("")


def test_flip_on_the_mask_bounding_box_equals_the_whole_frame():
    """FLIP is computed on the mask's bounding box + 24 px (the per-case cost of sweeps, issue 15): the masked
    pixels' errors are those of the whole frame, bit for bit (a 8 px margin would not be: FLIP's filters reach
    ~12 px)."""
    from study.measure.metrics import flip, flip_map

    rng = np.random.default_rng(4)
    yy, xx = np.mgrid[:160, :200]
    mask = (yy - 70) ** 2 + (xx - 120) ** 2 < 30**2
    ref = rng.uniform(0, 1.2, (160, 200, 3)).astype(np.float32)
    test = np.clip(ref + rng.normal(0, 0.1, ref.shape), 0, None).astype(np.float32)
    whole = flip_map(ref, test)
    assert flip(ref, test, mask=mask) == float(whole[mask].mean())
    y0, x0 = 70 - 30 - 8, 120 - 30 - 8  # the failing case: too small a margin
    tight = flip_map(ref[y0 : y0 + 77, x0 : x0 + 77], test[y0 : y0 + 77, x0 : x0 + 77])
    assert float(tight[mask[y0 : y0 + 77, x0 : x0 + 77]].mean()) != float(whole[mask].mean())


def test_ssim_and_psnr_on_the_mask_equal_the_whole_frame():
    """SSIM is computed on the mask's bounding box + 8 px and PSNR on the masked pixels (issue 15): the values are
    those of scikit-image on the whole frame (SSIM to float64 rounding: its box filters are running sums; no
    margin, inside the 7×7 window's reach, is not), also for a mask touching the frame's edge."""
    from skimage.metrics import peak_signal_noise_ratio, structural_similarity

    from study.measure.metrics import psnr, ssim, to_ldr

    rng = np.random.default_rng(5)
    yy, xx = np.mgrid[:160, :200]
    ref = rng.uniform(0, 1.2, (160, 200, 3)).astype(np.float32)
    test = np.clip(ref + rng.normal(0, 0.1, ref.shape), 0, None).astype(np.float32)
    _, smap = structural_similarity(to_ldr(ref), to_ldr(test), channel_axis=-1, data_range=1.0, full=True)
    for mask in ((yy - 70) ** 2 + (xx - 120) ** 2 < 30**2, (yy < 20) & (xx > 150)):
        assert abs(ssim(ref, test, mask=mask) - float(smap.mean(axis=-1)[mask].mean())) < 1e-12
        want = peak_signal_noise_ratio(to_ldr(ref)[mask], to_ldr(test)[mask], data_range=1.0)
        assert psnr(ref, test, mask=mask) == want
    box = (slice(40, 100), slice(90, 150))  # the failing case: a square mask, cut without margin
    mask = np.zeros(yy.shape, bool)
    mask[box] = True
    _, tight = structural_similarity(
        to_ldr(ref[box]), to_ldr(test[box]), channel_axis=-1, data_range=1.0, full=True
    )
    assert abs(float(tight.mean()) - float(smap.mean(axis=-1)[mask].mean())) > 1e-4
    assert abs(ssim(ref, test, mask=mask) - float(smap.mean(axis=-1)[mask].mean())) < 1e-12


def test_traced_is_priced_with_its_shading_and_hit_cache_with_its_read():
    """Issue 56: ``traced``'s bench row is the full ray_intersect plus the shading a renderer does at the hit (the
    material and the shadow ray: path ``shaded``), its bare query stated beside it (``query_ms_per_frame``);
    ``hit_cache`` is the bare query plus its cache read as fetches; ``traced_glossy(samples=K)`` K times traced's.
    Known times stand in for the measured ones, so the sums are checked exactly."""
    from types import SimpleNamespace

    from study.bench.run import exact_query_row
    from study.bench.timing import ms_per_frame

    n = 1 << 16
    b = SimpleNamespace(name="fig4 close-up", x=np.zeros((n, 3)), R=np.ones((n, 3)))
    q = {"ray_intersect": 3e-3, "ray_intersect_preliminary": 1e-3, "ray_test": 5e-4}
    sh = {"shade_material": 4e-4, "shadow_ray": 6e-4}
    exact = SimpleNamespace(
        mitsuba=lambda b, v, query="ray_intersect": q[query],
        mitsuba_kernels=lambda b, v, query="ray_intersect": q[query] / 2,
        shading=lambda b, v, light: (sh, {k: t / 2 for k, t in sh.items()}),
        embree=lambda b: 2e-3,
    )
    floors = {"fetch_4ch_coherent": 1e9, "bandwidth": 1e12}
    light = ((0.0, 2.6, 0.0), (6.0, 6.0, 6.0))
    row = exact_query_row(methods.make("traced"), exact, b, "cuda", 12, floors, light=light)
    assert row["path"] == "shaded"
    assert row["ms_per_frame"] == pytest.approx(ms_per_frame(3e-3 + 4e-4 + 6e-4, n))
    assert row["kernel_ms_per_frame"] == pytest.approx(ms_per_frame((3e-3 + 4e-4 + 6e-4) / 2, n))
    assert row["query_ms_per_frame"] == pytest.approx(ms_per_frame(1e-3, n))
    glossy = exact_query_row(
        methods.make("traced_glossy", samples=4), exact, b, "cuda", 12, floors, light=light
    )
    assert glossy["ms_per_frame"] == pytest.approx(4 * row["ms_per_frame"])
    cache = exact_query_row(methods.make("hit_cache"), exact, b, "cuda", 12, floors, light=light)
    from study.bench import floors as floor_model

    read = n * (1 / 1e9 + floor_model.BYTES_PER_RAY / 1e12)
    assert cache["path"] == "ray_intersect_preliminary"
    assert cache["ms_per_frame"] == pytest.approx(ms_per_frame(1e-3 + read, n))
    cpu = exact_query_row(methods.make("traced"), exact, b, "numpy", 12, None, light=light)
    assert cpu["ms_per_frame"] == pytest.approx(ms_per_frame(2e-3 + 1e-3, n))  # Embree + the shading on LLVM
