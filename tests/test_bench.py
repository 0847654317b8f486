"""`study bench` end to end on a tiny batch, its timing harness and exact tracer, and the fast Dr.Jit paths
against the plain one.

Expected outcomes are stated per test; exact values come from study.impostor.analytic (the box room), not from the
code under test.
"""
import math
import time

import numpy as np
import pytest
from conftest import BACKENDS, BOX_HI, BOX_LO
from typer.testing import CliRunner

from study import backend as backends
from study import methods
from study.bench.batches import distance_texels, room_triangles
from study.bench.output import write_outputs
from study.bench.run import BenchOptions, method_list, run_bench
from study.bench.timing import median_time, method_runner
from study.cli import app
from study.impostor import analytic
from study.impostor.envmap import EnvMap
from study.reference.embree import Tracer
from study.tables import read_csv

needs_llvm = pytest.mark.skipif("llvm" not in BACKENDS, reason="needs Dr.Jit's LLVM backend")


def test_bench_cli_tiny_writes_tables(tmp_path):
    """A tiny bench (--no-ladder) writes bench-cpu.csv and .md: one exact Embree row per batch (3 batches), one
    row per registered method (its defaults) × backend × batch, plus the plain path of localized on Dr.Jit,
    positive times, and speed-ups finite and consistent with the exact rows."""
    names = ",".join(BACKENDS)
    res = CliRunner().invoke(app, ["bench", "--out", str(tmp_path), "--scene-res", "32", "--rays", "2048",
                                   "--cube-res", "16", "--repeats", "1", "--no-ladder", "--no-scaling",
                                   "--backends", names, "--tag", "cpu"])
    assert res.exit_code == 0, res.output
    rows = read_csv(tmp_path / "bench-cpu.csv")
    md = (tmp_path / "bench-cpu.md").read_text()
    assert "drjit" in md and "| batch | backend |" in md
    batches = {r["batch"] for r in rows}
    assert len(batches) == 3
    assert sum(r["label"] == "exact: Embree" for r in rows) == 3
    timed = [r for r in rows if not r["label"].startswith("exact")]
    defaults = {m.label for m in methods.all_methods()}
    assert len(defaults) == len(methods.names())
    focus = methods.make("localized").label
    for b in batches:
        for nm in BACKENDS:
            got = [r["label"] for r in timed if r["batch"] == b and r["backend"] == nm]
            assert sorted(got) == sorted([*defaults] + ([focus] if nm != "numpy" else [])), (b, nm)
            if nm != "numpy":
                assert {r["path"] for r in timed if r["batch"] == b and r["backend"] == nm
                        and r["label"] == focus} == {"frozen", "plain"}
    for r in rows:
        assert r["ms_per_call"] > 0 and math.isclose(r["ms_per_frame"], r["ms_per_call"] / r["rays"] * 1024 ** 2,
                                                     rel_tol=1e-6)
    for r in timed:
        emb = next(e for e in rows if e["batch"] == r["batch"] and e["label"] == "exact: Embree")
        assert math.isfinite(r["x_vs_embree"]) and r["x_vs_embree"] > 0
        assert math.isclose(r["x_vs_embree"], emb["ms_per_frame"] / r["ms_per_frame"], rel_tol=1e-6)
        mit = [e for e in rows if e["batch"] == r["batch"] and e["label"] == "exact: Mitsuba llvm_ad_rgb"]
        if mit:                                    # Mitsuba's LLVM variant present: the ratio is finite and right
            assert math.isclose(r["x_vs_mitsuba"], mit[0]["ms_per_frame"] / r["ms_per_frame"], rel_tol=1e-6)


def test_method_list_is_every_method_at_every_knob_value():
    """The methods timed: every registered method at each value of its declared knob's ladder (none looked up by
    parameter name), the defaults only with ladder=False, just the named ones with ``methods``."""
    got = [m.label for m in method_list(BenchOptions())]
    want = []
    for name in methods.names():
        cls = methods.REGISTRY[name]
        want += ([methods.make(name, **{cls.knob.param: v}).label for v in cls.knob.ladder] if cls.knob
                 else [methods.make(name).label])
    assert got == want and len(got) > len(methods.names())
    assert [m.label for m in method_list(BenchOptions(ladder=False))] == [m.label for m in methods.all_methods()]
    assert [m.label for m in method_list(BenchOptions(methods=("localized", "classical")))] == \
        [f"localized(iterations={n})" for n in methods.REGISTRY["localized"].knob.ladder] + ["classical"]


def test_bench_bad_backend_is_one_line_error(tmp_path):
    res = CliRunner().invoke(app, ["bench", "--out", str(tmp_path), "--backends", "vulkan", "--no-scaling"])
    assert res.exit_code == 2 and "unknown backend 'vulkan'" in res.output


def test_bench_unknown_method_is_one_line_error(tmp_path):
    res = CliRunner().invoke(app, ["bench", "--out", str(tmp_path), "--backends", "numpy", "--methods",
                                   "localized,nosuch", "--no-scaling"])
    assert res.exit_code == 2 and "unknown method 'nosuch'" in res.output
    assert not list(tmp_path.iterdir())                       # refused before anything was timed or written


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

    t = median_time(call, finish, repeats=3, warmup=2, min_repeat_s=0.01)
    assert 0.0019 <= t <= 0.02
    assert finished == list(range(1, len(calls) + 1))          # each call's own output, in order
    assert len(syncs) == 2 + 1 + 3 and len(calls) > 3 + 3


def test_scaling_tiny_writes_plot(tmp_path):
    """The scaling studies on tiny sizes: every study present, the room grows by the requested triangles, the
    method's cost is reported at every triangle count (it does not trace the triangles), and the knob study
    covers localized's declared ladder plus the extra values."""
    from study.harness.config import load_figure_config
    _, scene, _ = load_figure_config("configs/fig4.toml")
    opt = BenchOptions(scene_res=16, synthetic=1024, methods=("localized", "classical"), ladder=False,
                       cube_res=16, backends=("numpy",), repeats=1, numpy_max_rays=1024, ray_counts=(256, 1024),
                       knob_extra=(2,), cube_resolutions=(8, 16), triangles=(0, 2000), tag="t")
    rows, scaling, info = run_bench(scene, opt, log=lambda s: None)
    assert {r["label"] for r in rows if not r["label"].startswith("exact")} == {"localized(iterations=10)",
                                                                                "classical"}
    files = write_outputs(rows, scaling, info, tmp_path)
    assert (tmp_path / "scaling-t.png").stat().st_size > 10_000 and len(files) == 4
    assert {r["study"] for r in scaling} == {"rays", "knob", "cube_res", "triangles"}
    knob = [r for r in scaling if r["study"] == "knob"]
    assert [r["value"] for r in knob] == sorted({*methods.REGISTRY["localized"].knob.ladder, 2})
    assert all(r["label"] == f"localized(iterations={r['value']})" for r in knob)
    tris = sorted({r["value"] for r in scaling if r["study"] == "triangles"})
    assert tris[0] == 12 and 1900 <= tris[1] - 12 <= 2100
    for n in tris:
        assert any(r["value"] == n and r["label"].startswith("localized") for r in scaling
                   if r["study"] == "triangles")


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
    assert len(Fh) - len(F) == 2 * 16 ** 2 and Vh[len(V):, 1].max() < 0.11      # 2k² triangles, below 11 cm


def test_tracer_from_triangles_threaded_distance_matches_intersect():
    """Tracer.from_triangles on raw (V, F): distance() cast in chunks on 3 threads equals the single-threaded
    intersect()'s t (float64, inf on a miss) and the analytic box distances; rays leaving the box miss."""
    from conftest import small_scene_dict

    from study.scene import scene_from_dict
    scene = scene_from_dict(small_scene_dict())
    mesh, o = scene.mesh(), np.asarray(scene.reference.point)
    x, d = analytic.random_rays(10_000, extent=0.8, seed=3)                  # relative to o, as BOX_LO/HI
    d[:100] = x[:100] / np.linalg.norm(x[:100], axis=1, keepdims=True)      # some rays start outside, leaving
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
            out = call(); finish(out)
            if frozen:
                out = call(); finish(out)                 # a replay, not the recording
            shown, rad, ratio, valid = out
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
