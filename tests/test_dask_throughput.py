"""Dask sweeps: the fixed cost (cluster start, warm-up) apart from the steady throughput, in the metadata and the
printed line; the warm-up once per worker process; the table identical to the single-process one.

Provenance: the sweep is tests/test_sweep.py's (room scene, 24² camera, 3 positions × cube 16², 24²; classical and
localized 0/3, seed 0), run once in this process and once on a local Dask cluster of 2 worker processes."""

import json

import pytest

from study.harness.cluster import throughput, timing_line
from study.harness.runner import run_sweep
from tests.test_sweep import per_case, same_table, write


def test_throughput_splits_fixed_cost_from_steady_rate():
    """Marks written by hand: the cluster is ready 2 s after the request, the last worker finishes its first case
    at 5 s, 6 more cases end by 8 s, the cluster is closed at 8.5 s → cluster 2, warm-up 3, shutdown 0.5, fixed 5.5,
    steady 6 cases / 3 s = 2 cases/s; a case that ends exactly at the warm-up's end is not a steady one."""
    marks = {"startup": 1.25, "enter": 10.0, "ready": 12.0, "last": 18.0, "closed": 18.5}
    done = [13.0, 15.0, 15.5, 16.0, 16.5, 17.0, 17.5, 18.0]
    first = {"tcp://a": 13.0, "tcp://b": 15.0}
    rec = {
        "tcp://b": {"runs": 1, "seconds": 0.5, "cases": 4},
        "tcp://a": {"runs": 1, "seconds": 0.25, "cases": 4},
    }
    t = throughput(marks, done, first, rec)
    assert (t["cluster_s"], t["warmup_s"], t["shutdown_s"], t["fixed_s"]) == (2.0, 3.0, 0.5, 5.5)
    assert (t["steady_cases"], t["steady_s"], t["steady_cases_per_s"], t["cases"]) == (6, 3.0, 2.0, 8)
    assert t["startup_s"] == 1.25 and list(t["workers"]) == ["tcp://a", "tcp://b"]
    line = timing_line(t)
    assert "2 workers" in line and "fixed cost 5.5 s" in line and "2.00 cases/s (6 cases in 3.0 s)" in line
    none = throughput(marks, [13.0, 15.0], first, rec)  # every case ended in the warm-up: no steady rate
    assert (
        none["steady_cases"] == 0
        and none["steady_cases_per_s"] is None
        and "not reached" in timing_line(none)
    )


@pytest.mark.slow
def test_dask_sweep_same_table_warm_once_and_timing_in_metadata(tmp_path):
    """(≈ 3 min on 2 busy cores: -m slow, as tests/test_sweep.py's Dask test.)"""
    pytest.importorskip("distributed")
    cfg = write(tmp_path)
    ref, _ = run_sweep(cfg, tmp_path / "single", cache=tmp_path / "cache1")
    got, stats = run_sweep(cfg, tmp_path / "dask", cache=tmp_path / "cache2", jobs=2, dask="local")
    assert stats["computed"] == 6 and len(got) == 6 * per_case(got)
    same_table(ref, got)  # every column but the timings, bit for bit, in case order
    meta = json.loads((tmp_path / "dask" / "metadata.json").read_text())
    t = meta["dask"]
    assert t == stats["dask"]
    assert t["cases"] == 6 and t["fixed_s"] > 0 and t["cluster_s"] > 0 and t["warmup_s"] > 0
    assert abs(t["fixed_s"] - (t["cluster_s"] + t["warmup_s"] + t["shutdown_s"])) < 0.01
    busy = sum(
        1 for w in t["workers"].values() if w["cases"]
    )  # each one's first case ends within the warm-up
    assert t["startup_s"] > 0 and busy >= 1 and 0 <= t["steady_cases"] <= 6 - busy
    if t["steady_cases"]:  # none when the last worker's first case is the sweep's last (6 cases: it happens)
        assert (
            abs(t["steady_cases_per_s"] - t["steady_cases"] / t["steady_s"]) < 0.01 * t["steady_cases_per_s"]
        )
    else:
        assert t["steady_cases_per_s"] is None
    # warm-up once per worker process: 2 workers, each warmed exactly once although every case asks for it
    assert len(t["workers"]) == 2
    assert [w["runs"] for w in t["workers"].values()] == [1, 1]
    assert all(w["seconds"] > 0 for w in t["workers"].values())
    assert sum(w["cases"] for w in t["workers"].values()) == 6
