"""Sweeps: expansion of axes, resume after SIGKILL, atomic table, lock, errors."""

import fcntl
import json
import math
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from study.errors import StudyError
from study.harness.runner import run_sweep
from study.harness.sweep import load_sweep
from study.tables import read_csv

ROOT = Path(__file__).resolve().parents[1]

SWEEP = """
scene = "{scene}"
seed = 0
zip = {zip}

[overrides]
"camera.width" = 24
"camera.height" = 24
"render.cube_spp" = 2
"render.spp" = 2
"render.supersample" = 1

[axes]
"object.center" = {{ line = {{ from = [0.3, 1.4, 0.1], to = [1.2, 0.9, 0.7], steps = 3 }} }}
"render.cube_res" = [16, 24]

[[methods]]
name = "classical"

[[methods]]
name = "localized"
iterations = [0, 3]
"""


def write(tmp_path, name="s.toml", zip="[]", **extra):
    p = tmp_path / name
    p.write_text(SWEEP.format(scene=ROOT / "scenes" / "room.toml", zip=zip) + extra.get("tail", ""))
    return p


def per_case(rows) -> int:
    """Rows per case: one per method (3 here) and run_case's reference rows (the oracle's), as many as it makes."""
    n = {r["case"] for r in rows}
    assert len(rows) % len(n) == 0 and len(rows) // len(n) > 3
    return len(rows) // len(n)


def same_table(a, b):
    assert [r["case"] for r in a] == [r["case"] for r in b]
    for ra, rb in zip(a, b):
        assert ra.keys() == rb.keys()
        for k in ra:
            if k in ("seconds", "case_seconds"):
                continue
            va, vb = ra[k], rb[k]
            assert va == vb or (isinstance(va, float) and math.isnan(va) and math.isnan(vb)), (ra["case"], k)


def test_cartesian_and_zipped_axes(tmp_path):
    sw = load_sweep(write(tmp_path))
    assert len(sw.cases) == 6 and len(sw.methods) == 3
    assert sw.cases[0].labels == {"object.center": "(0.3, 1.4, 0.1)", "render.cube_res": "16"}
    assert sw.cases[5].scene.object.center == (1.2, 0.9, 0.7) and sw.cases[5].scene.render.cube_res == 24
    with pytest.raises(StudyError, match=r"s.toml: zip\[0\]: zipped axes need the same number of values"):
        load_sweep(write(tmp_path, zip='[["object.center", "render.cube_res"]]'))


@pytest.mark.parametrize(
    "tail, key, words",
    [
        ("\n[axes2]\nx = 1\n", "axes2", "unknown key; allowed: scene, seed"),
        ('"object.centre" = [[0, 1, 0]]\n', "axes.object.centre", "unknown scene key"),
        ('"object.radius" = [0.4, -1.0]\n', "axes.object.radius", "greater than 0"),
        ('"object.radius" = [2.5]\n', "axes.object.center", "inside the room"),
    ],
)
def test_bad_sweep_files(tmp_path, tail, key, words):
    text = SWEEP.format(scene=ROOT / "scenes" / "room.toml", zip="[]")
    if tail.startswith('"'):
        text = text.replace("[axes]\n", "[axes]\n" + tail)
    else:
        text += tail
    p = tmp_path / "bad.toml"
    p.write_text(text)
    with pytest.raises(StudyError) as e:
        load_sweep(p)
    assert str(e.value).startswith(f"{p}: {key}: ") and words in str(e.value), str(e.value)


@pytest.fixture(scope="module")
def reference_run(tmp_path_factory):
    d = tmp_path_factory.mktemp("sweep")
    cfg = write(d)
    rows, stats = run_sweep(cfg, d / "ref", cache=d / "cache")
    assert stats == {**stats, "cases": 6, "cached": 0, "computed": 6}
    return d, cfg, rows


def test_rerun_recomputes_nothing(reference_run):
    d, cfg, rows = reference_run
    again, stats = run_sweep(cfg, d / "ref", cache=d / "cache")
    assert stats["computed"] == 0 and stats["cached"] == 6
    same_table(rows, again)
    same_table(read_csv(d / "ref" / "results.csv"), read_csv(d / "ref" / "results.csv"))
    assert len(read_csv(d / "ref" / "results.csv")) == len(rows) == 6 * per_case(rows)
    meta = json.loads((d / "ref" / "metadata.json").read_text())
    assert meta["seed"] == 0 and meta["versions"]["mitsuba"] and meta["config_sha256"] and meta["code_hash"]


def test_sigkill_and_resume_gives_the_same_table(reference_run, tmp_path):
    """Kill the sweep with SIGKILL after its first finished case (cache warm, so cases are quick); the rerun
    computes only the missing cases and its table equals the uninterrupted run's (all but the timings)."""
    d, cfg, rows = reference_run
    out = tmp_path / "killed"
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "study.cli",
            "sweep",
            str(cfg),
            "--out",
            str(out),
            "--cache",
            str(d / "cache"),
            "--no-plots",
        ],
        cwd=ROOT,
        env=env,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    deadline = time.time() + 120
    while time.time() < deadline and not list(out.glob("cases/*.json")):
        time.sleep(0.01)
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    finished = {p.name: p.stat().st_mtime_ns for p in (out / "cases").glob("*.json")}
    assert 1 <= len(finished) < 6, "the sweep should have been killed mid-run"
    if (out / "results.csv").exists():  # the table follows the case files; the kill may fall between
        partial = read_csv(out / "results.csv")
        n = per_case(rows)
        assert len(partial) % n == 0 and len(partial) <= n * len(finished)  # whole cases only, never half
    again, stats = run_sweep(cfg, out, cache=d / "cache")
    assert stats["cached"] == len(finished) and stats["computed"] == 6 - len(finished)
    assert {
        p.name: p.stat().st_mtime_ns for p in (out / "cases").glob("*.json") if p.name in finished
    } == finished
    same_table(rows, again)
    same_table(read_csv(d / "ref" / "results.csv"), read_csv(out / "results.csv"))


def test_second_sweep_on_the_same_directory_stops(reference_run):
    d, cfg, _ = reference_run
    with open(d / "ref" / ".lock", "a+") as f:
        fcntl.flock(f, fcntl.LOCK_EX | fcntl.LOCK_NB)
        with pytest.raises(StudyError, match="another study command is writing to this directory"):
            run_sweep(cfg, d / "ref", cache=d / "cache")


@pytest.mark.slow
def test_five_random_kills_then_resume(reference_run, tmp_path):
    """SIGKILL the sweep at 5 random moments (seeded), with a cold cache so kills also land in impostor and
    render writes; resume each time. The final table equals the uninterrupted run's, with no duplicate or
    partial row, and every cache entry left behind loads and validates."""
    import numpy as np

    from study.cache import Cache

    d, cfg, rows = reference_run
    out, cache = tmp_path / "out", tmp_path / "cache"
    rng = np.random.default_rng(11)
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    finished_counts = []
    for delay in rng.uniform(1.0, 6.0, 5):
        proc = subprocess.Popen(
            [
                sys.executable,
                "-m",
                "study.cli",
                "sweep",
                str(cfg),
                "--out",
                str(out),
                "--cache",
                str(cache),
                "--no-plots",
            ],
            cwd=ROOT,
            env=env,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
        time.sleep(delay)
        proc.send_signal(signal.SIGKILL)
        proc.wait()
        finished_counts.append(len(list(out.glob("cases/*.json"))))
        if (out / "results.csv").exists():
            part = read_csv(out / "results.csv")
            assert len(part) % per_case(rows) == 0 and len({(r["case"], r["label"]) for r in part}) == len(
                part
            )
    print("finished cases after each kill:", finished_counts)
    assert finished_counts[0] < 6, "the first kill should land mid-run"
    again, stats = run_sweep(cfg, out, cache=cache)
    assert stats["cached"] == finished_counts[-1]
    same_table(rows, again)
    final = read_csv(out / "results.csv")
    assert len(final) == len(rows) and len({(r["case"], r["label"]) for r in final}) == len(rows)
    store = Cache(cache)
    for meta in cache.glob("*/*.json"):
        assert store.load(meta.parent.name, meta.stem) is not None, meta


def test_jobs_1_and_2_give_identical_tables(reference_run, tmp_path):
    """numpy backend: bit for bit across runs and across --jobs 1 / --jobs 2 (timings aside)."""
    d, cfg, rows = reference_run
    two, stats = run_sweep(cfg, tmp_path / "two", cache=d / "cache", jobs=2)
    assert stats["computed"] == 6
    same_table(rows, two)


def test_drjit_runs_agree_within_1e5(reference_run, tmp_path):
    import numpy as np

    pytest.importorskip("drjit")
    from conftest import BACKENDS

    if "llvm" not in BACKENDS:
        pytest.skip("no working LLVM for Dr.Jit")
    d, cfg, rows = reference_run
    a, _ = run_sweep(cfg, tmp_path / "a", cache=d / "cache", backend="llvm")
    b, _ = run_sweep(cfg, tmp_path / "b", cache=d / "cache", backend="llvm")
    for ra, rb in zip(a, b):
        for k, va in ra.items():
            if isinstance(va, float) and k not in ("seconds", "case_seconds") and np.isfinite(va):
                assert abs(va - rb[k]) <= 1e-5 * max(abs(va), 1e-12) + 1e-12, k


@pytest.mark.slow
def test_dask_local_cluster_gives_the_same_table(reference_run, tmp_path):
    """Scale-out: the same sweep on a local Dask distributed cluster (2 worker processes)."""
    pytest.importorskip("distributed")
    d, cfg, rows = reference_run
    got, stats = run_sweep(cfg, tmp_path / "dask", cache=d / "cache", jobs=2, dask="local")
    assert stats["computed"] == 6
    same_table(rows, got)


def test_study_profile_writes_one_profile_per_case_and_rows_carry_case_seconds(tmp_path, monkeypatch):
    """STUDY_PROFILE=<dir> (a developer's switch, issue 15): each case's worker leaves <dir>/<case>.prof, a cProfile
    that pstats reads and in which run_case appears; every row carries its case's wall time (case_seconds)."""
    import pstats

    monkeypatch.setenv("STUDY_PROFILE", str(tmp_path / "profs"))
    rows, stats = run_sweep(write(tmp_path), tmp_path / "out", cache=tmp_path / "cache")
    cases = sorted({r["case"] for r in rows})
    assert sorted(p.stem for p in (tmp_path / "profs").glob("*.prof")) == cases
    st = pstats.Stats(str(tmp_path / "profs" / f"{cases[0]}.prof"))
    assert any(fn[2] == "run_case" for fn in st.stats)
    assert all(r["case_seconds"] > 0 for r in rows)


def test_worker_threads_share_the_cores(monkeypatch):
    """A sweep worker takes its share of the cores for Embree ($STUDY_THREADS) and OpenMP (FLIP) unless the user
    set OMP_NUM_THREADS; a local-gpus Dask worker's share comes from $STUDY_WORKER_THREADS."""
    from study.harness import runner

    for var in ("OMP_NUM_THREADS", "STUDY_WORKER_THREADS", "STUDY_THREADS"):
        monkeypatch.delenv(var, raising=False)
    import drjit

    counts = []
    monkeypatch.setattr(drjit, "set_thread_count", counts.append)  # not this test process's pool
    monkeypatch.setattr(os, "cpu_count", lambda: 16)
    runner._limit_threads(8)
    assert os.environ["STUDY_THREADS"] == "2" and os.environ["OMP_NUM_THREADS"] == "2"
    monkeypatch.setenv("OMP_NUM_THREADS", "5")
    monkeypatch.setenv("STUDY_WORKER_THREADS", "3")
    runner._limit_threads(4)
    assert os.environ["STUDY_THREADS"] == "3" and os.environ["OMP_NUM_THREADS"] == "5"
    assert counts == [2, 3]
