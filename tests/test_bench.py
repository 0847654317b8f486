"""`study bench` end to end on a tiny batch, and the fast Dr.Jit paths against the plain one.

Expected outcomes are stated per test; exact values come from study.analytic (the box room), not from the code
under test.
"""
import math

import numpy as np
import pytest
from typer.testing import CliRunner

from study import analytic, bench, methods
from study import backend as backends
from study.cli import app
from study.results import read_csv

from conftest import BACKENDS, BOX_HI, BOX_LO

needs_llvm = pytest.mark.skipif("llvm" not in BACKENDS, reason="needs Dr.Jit's LLVM backend")


def test_bench_cli_tiny_writes_tables(tmp_path):
    """A tiny bench writes bench-cpu.csv and .md: one exact Embree row per batch (3 batches), every registered
    method on every backend asked for, positive times, and speed-ups consistent with the exact rows."""
    names = ",".join(BACKENDS)
    res = CliRunner().invoke(app, ["bench", "--out", str(tmp_path), "--scene-res", "32", "--rays", "2048",
                                   "--cube-res", "16", "--repeats", "1", "--iterations", "0,3", "--no-scaling",
                                   "--backends", names, "--tag", "cpu"])
    assert res.exit_code == 0, res.output
    rows = read_csv(tmp_path / "bench-cpu.csv")
    md = (tmp_path / "bench-cpu.md").read_text()
    assert "drjit" in md and "| batch | backend |" in md
    batches = {r["batch"] for r in rows}
    assert len(batches) == 3
    assert sum(r["label"] == "exact: Embree" for r in rows) == 3
    labels = {r["label"] for r in rows}
    for name in methods.names():
        assert any(lab.startswith(name) for lab in labels), name
    assert {"localized(iterations=0)", "localized(iterations=3)"} <= labels
    assert {r["backend"] for r in rows if not r["label"].startswith("exact")} == set(BACKENDS)
    for r in rows:
        assert r["ms_per_call"] > 0 and math.isclose(r["ms_per_frame"], r["ms_per_call"] / r["rays"] * 1024 ** 2,
                                                     rel_tol=1e-6)
    for r in rows:
        if not r["label"].startswith("exact"):
            emb = next(e for e in rows if e["batch"] == r["batch"] and e["label"] == "exact: Embree")
            assert math.isclose(r["x_vs_embree"], emb["ms_per_frame"] / r["ms_per_frame"], rel_tol=1e-6)


def test_bench_bad_backend_is_one_line_error(tmp_path):
    res = CliRunner().invoke(app, ["bench", "--out", str(tmp_path), "--backends", "vulkan", "--no-scaling"])
    assert res.exit_code == 2 and "unknown backend 'vulkan'" in res.output


def test_scaling_tiny_writes_plot(tmp_path):
    """The scaling studies on tiny sizes: every study present, the room grows by the requested triangles, and
    the method's cost is reported at every triangle count (it does not trace the triangles)."""
    from study.config import load_figure_config
    _, scene, _ = load_figure_config("configs/fig4.toml")
    opt = bench.BenchOptions(scene_res=16, synthetic=1024, iterations=(1,), cube_res=16, backends=("numpy",),
                             repeats=1, numpy_max_rays=1024, ray_counts=(256, 1024), scaling_iterations=(0, 2),
                             cube_resolutions=(8, 16), triangles=(0, 2000), tag="t")
    rows, scaling, info = bench.run_bench(scene, opt, log=lambda s: None)
    files = bench.write_outputs(rows, scaling, info, tmp_path)
    assert (tmp_path / "scaling-t.png").stat().st_size > 10_000 and len(files) == 4
    assert {r["study"] for r in scaling} == {"rays", "iterations", "cube_res", "triangles"}
    tris = sorted({r["value"] for r in scaling if r["study"] == "triangles"})
    assert tris[0] == 12 and 1900 <= tris[1] - 12 <= 2100


def test_heightfield_room_distances_match_the_box():
    """Embree distances of the bench's impostor in the bare room equal the analytic box distances (1e-4 m)."""
    from study.scene import scene_from_dict
    from conftest import small_scene_dict
    scene = scene_from_dict(small_scene_dict())
    V, F = bench.room_triangles(scene)
    tex = bench.distance_texels(V, F, scene.reference.point, 16)
    exact = analytic.box_impostor(16, BOX_LO, BOX_HI)
    np.testing.assert_allclose(tex[..., 3], exact[..., 3], atol=1e-4)
    Vh, Fh = bench.room_triangles(scene, 500)
    assert len(Fh) - len(F) == 2 * 16 ** 2 and Vh[len(V):, 1].max() < 0.11      # 2k² triangles, below 11 cm


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
            call, finish = bench._method_runner(m, B, tex, x[:n], d[:n], frozen=frozen)
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
    env = backends.EnvMap(tex, nb)
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
    env = backends.EnvMap(tex, B)

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
