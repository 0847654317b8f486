"""Outputs as transactions (issue 12): every command writes its whole output set into a fresh directory beside the
target and swaps it in at the end (study.io.output_set), so a failed, interrupted or killed command leaves the
previous outputs byte for byte and no temporary file; one command at a time writes to a directory."""

import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from conftest import run_cli

from study import io
from study.errors import EnvironmentProblem
from study.harness.runner import run_sweep
from study.tables import read_csv

ROOT = Path(__file__).resolve().parents[2]

FIG = """
positions = [[0.6, 1.2, 0.3], [1.1, 0.9, 0.6]]
methods = [{ name = "classical" }, { name = "localized" }]

[scene]
room = { min = [-2.0, 0.0, -2.0], max = [2.0, 3.0, 2.0] }
light = { position = [0.3, 2.6, -0.4], intensity = [7.0, 7.0, 7.0] }
reference = { point = [0.0, 1.5, 0.0] }
object = { center = [0.6, 1.2, 0.3], radius = 0.4, material = { type = "mirror" } }
camera = { eye = [-0.3, 1.7, -1.9], target = [0.6, 1.1, 0.6], fov = 75.0, width = 24, height = 24 }
render = { cube_res = 16, cube_spp = 2, spp = 2, max_depth = 3, supersample = 1 }
"""
SWEEP = """
scene = "{scene}"
methods = [{{ name = "classical" }}]

[overrides]
"camera.width" = 24
"camera.height" = 24
"render.cube_res" = 16
"render.cube_spp" = 2
"render.spp" = 2
"render.supersample" = 1

[axes]
"object.center" = [[0.3, 1.4, 0.1], [0.75, 1.15, 0.4]]
"""
OLD = {
    "metrics.csv": b"case,method\nold,classical\n",
    "metadata.json": b'{"old": true}\n',
    "fig4.png": b"old png",
}


def files(d: Path) -> dict[str, bytes]:
    """The files under ``d`` but the list of those study wrote (:data:`study.io.OUTPUTS`)."""
    return {
        p.relative_to(d).as_posix(): p.read_bytes()
        for p in sorted(d.rglob("*"))
        if p.is_file() and p.name != io.OUTPUTS
    }


def temp_files(parent: Path) -> list[str]:
    """Temporary files or directories under ``parent`` (the lock file of a killed run is no temporary file)."""
    return [
        str(p.relative_to(parent))
        for p in parent.rglob("*")
        if p.name.startswith(".")
        and p.name not in (".lock", io.OUTPUTS)
        or ".new-" in p.name
        or p.suffix == ".tmp"
    ]


def write(d: Path, content: dict[str, bytes]) -> None:
    d.mkdir(parents=True, exist_ok=True)
    for name, data in content.items():
        (d / name).parent.mkdir(parents=True, exist_ok=True)
        (d / name).write_bytes(data)


# ---------------------------------------------------------------------------------------------- output_set
@pytest.mark.parametrize("swap", [True, False], ids=["exchange", "renames"])
def test_output_set_replaces_what_it_owns_and_keeps_the_rest(tmp_path, monkeypatch, swap):
    """Owned entries are replaced (or removed when this run did not write them and study listed them as its own:
    no stale plot), the rest stays (a file of the user's inside an owned folder too), with the one atomic
    directory exchange or, where it cannot be used, one rename per output."""
    if not swap:
        monkeypatch.setattr(io, "_exchange", lambda a, b: False)
    out = tmp_path / "sw"
    write(
        out,
        {
            "results.csv": b"old",
            "metadata.json": b"old",
            "plots/a.png": b"old",
            "cases/k.json": b"case",
            "notes.txt": b"mine",
            "plots/mine.png": b"mine",  # not on the list of study's files: kept (issue 51)
            io.OUTPUTS: json.dumps({"files": ["results.csv", "metadata.json", "plots/a.png"]}).encode(),
        },
    )
    with io.output_set(out, ["results.csv", "metadata.json", "plots"], keeps=["cases"]) as tmp:
        write(tmp, {"results.csv": b"new", "metadata.json": b"new"})
    assert files(out) == {
        "cases/k.json": b"case",
        "metadata.json": b"new",
        "notes.txt": b"mine",
        "plots/mine.png": b"mine",
        "results.csv": b"new",
    }
    assert sorted(p.name for p in tmp_path.iterdir()) == ["sw"] and not temp_files(tmp_path)


def test_output_set_unknown_directory_falls_back_to_renames(tmp_path):
    """A directory the command neither owns nor keeps (someone else's) is never swapped away: renames instead."""
    out = tmp_path / "reports"
    write(out, {"index.md": b"old", "fig4/metrics.csv": b"fig"})
    inode = out.stat().st_ino
    with io.output_set(out, ["index.md"]) as tmp:
        write(tmp, {"index.md": b"new"})
    assert files(out) == {"fig4/metrics.csv": b"fig", "index.md": b"new"} and out.stat().st_ino == inode


def test_failed_block_leaves_outputs_byte_identical(tmp_path):
    out = tmp_path / "fig"
    write(out, OLD)
    with pytest.raises(RuntimeError):
        with io.output_set(out, list(OLD)) as tmp:
            write(tmp, {"metrics.csv": b"half"})
            raise RuntimeError("killed")
    assert files(out) == OLD and not temp_files(tmp_path)
    with pytest.raises(RuntimeError):  # a directory it had to create goes again
        with io.output_set(tmp_path / "new" / "dir", ["x"]):
            raise RuntimeError
    assert not (tmp_path / "new").exists()


def test_one_command_at_a_time_and_stale_temporaries_go(tmp_path):
    out = tmp_path / "fig"
    write(out, OLD)
    with io.locked(out):
        with pytest.raises(EnvironmentProblem, match="another study command is writing to this directory"):
            with io.output_set(out, list(OLD)):
                pass
    assert not (out / ".lock").exists()  # removed with the lock
    stale = tmp_path / ".fig.new-abc123"  # what a SIGKILL mid-swap could leave
    write(stale, {"metrics.csv": b"half"})
    io.write_set(out, {"metrics.csv": b"new"})
    assert not stale.exists() and files(out)["metrics.csv"] == b"new"


# ---------------------------------------------------------------------------------------------- commands
@pytest.fixture(scope="module")
def fig(tmp_path_factory):
    """A tiny figure config and a warm cache; ``seconds``: one full run of `study figure` in a subprocess."""
    d = tmp_path_factory.mktemp("fig")
    (d / "cfg.toml").write_text(FIG)
    t0 = time.perf_counter()
    res = subprocess.run(study(d, d / "warm"), cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert res.returncode == 0, res.stderr
    return d, time.perf_counter() - t0


def study(d: Path, out: Path) -> list[str]:
    return [
        sys.executable,
        "-m",
        "study.cli",
        "figure",
        "fig4",
        "--config",
        str(d / "cfg.toml"),
        "--out",
        str(out),
        "--cache",
        str(d / "cache"),
    ]


#: files a finished run writes beside the three of OLD (the table as Parquet, the HTML viewer's images)
NEW = {"metrics.parquet", "viewer/index.json"}


def consistent_new(out: Path) -> bool:
    """The files of one finished run: 2 positions × (2 references + 2 methods) rows, metadata, a PNG, the
    Parquet table and the viewer's manifest."""
    meta = json.loads((out / "metadata.json").read_text())
    return (
        len(read_csv(out / "metrics.csv")) == 8
        and meta["figure"] == "fig4"
        and meta["cases"] == 2
        and (out / "fig4.png").read_bytes()[:4] == b"\x89PNG"
        and all((out / f).is_file() for f in NEW)
    )


@pytest.mark.slow
def test_figure_killed_at_random_moments_is_all_old_or_all_new(fig, tmp_path):
    """SIGKILL `study figure` after random delays (seeded, spread over a whole run): each time its files are all
    the earlier ones byte for byte or all new and consistent. A kill can land in the milliseconds while the
    output set is written (every byte is made before it opens, study.io.write_set): the temporary directory it
    leaves is allowed, and the next run on the same output removes it (run and checked)."""
    d, seconds = fig
    out = tmp_path / "out"
    rng = np.random.default_rng(12)
    seen = {"old": 0, "new": 0}
    for delay in rng.uniform(0.3 * seconds, 1.15 * seconds, 6):
        shutil.rmtree(out, ignore_errors=True)  # only the old files (not a previous run's extras)
        write(out, OLD)
        proc = subprocess.Popen(study(d, out), cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        time.sleep(delay)
        proc.send_signal(signal.SIGKILL)
        proc.wait()
        got = {
            k: v for k, v in files(out).items() if k != ".lock"
        }  # its lock file, free: the next run takes it
        assert set(got) == set(OLD) or set(got) >= set(OLD) | NEW, got.keys()
        if got == OLD:
            seen["old"] += 1
        else:
            assert all(got[k] != OLD[k] for k in OLD) and consistent_new(out), "old and new files mixed"
            seen["new"] += 1
        if left := temp_files(tmp_path):
            seen["left"] = seen.get("left", 0) + 1
            res = subprocess.run(study(d, out), cwd=ROOT, capture_output=True, text=True, timeout=300)
            assert res.returncode == 0 and consistent_new(out), res.stderr
            assert not temp_files(tmp_path), (left, temp_files(tmp_path))
    print("kills that found the old / the new files (left a temporary one):", seen)


def test_sigterm_leaves_the_old_files_and_no_lock(fig, tmp_path):
    d, seconds = fig
    out = tmp_path / "out"
    write(out, OLD)
    proc = subprocess.Popen(
        study(d, out), cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True
    )
    deadline = time.time() + 60
    while not (out / ".lock").exists() and time.time() < deadline:  # running: it holds the directory
        time.sleep(0.02)
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=60)
    if proc.returncode == 0:
        pytest.skip("the run finished before SIGTERM arrived")
    assert proc.returncode == 130 and err.strip().endswith("error: interrupted"), err
    assert files(out) == OLD and not (out / ".lock").exists() and not temp_files(tmp_path)


@pytest.mark.slow
def test_concurrent_figure_runs(fig, tmp_path):
    """Two runs into two directories side by side both succeed (no shared temporary name); two runs into one
    directory: one may be refused (exit 3, the other holds it), the files are one run's, whole."""
    d, _ = fig
    procs = [
        subprocess.Popen(
            study(d, tmp_path / name), cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True
        )
        for name in ("a", "b", "c", "c")
    ]
    codes = [p.wait(timeout=300) for p in procs]
    assert codes[:2] == [0, 0], [p.stderr.read() for p in procs]
    assert sorted(codes[2:]) in ([0, 0], [0, 3])
    for name in ("a", "b", "c"):
        assert set(files(tmp_path / name)) >= set(OLD) | NEW and consistent_new(tmp_path / name)
    assert not temp_files(tmp_path) and not list(tmp_path.rglob(".lock"))


def test_sweep_writes_table_metadata_and_extras_together(tmp_path):
    """A sweep whose last step fails (here: its curves) keeps the earlier table, metadata and curves byte for
    byte; the finished cases stay for the resume, and the resumed run swaps all three in at once."""
    cfg = tmp_path / "s.toml"
    cfg.write_text(SWEEP.format(scene=ROOT / "scenes" / "room.toml"))
    out = tmp_path / "out"
    write(out, {"results.csv": b"old table", "metadata.json": b"old", "plots/curve.png": b"old"})
    before = files(out)

    def broken(rows, d):
        raise RuntimeError("the plot failed")

    with pytest.raises(RuntimeError):
        run_sweep(cfg, out, cache=tmp_path / "cache", extra=broken)
    assert {k: v for k, v in files(out).items() if not k.startswith("cases/")} == before
    assert len(list(out.glob("cases/*.json"))) == 2 and not temp_files(tmp_path)
    rows, stats = run_sweep(
        cfg, out, cache=tmp_path / "cache", extra=lambda rows, d: write(d, {"plots/curve.png": b"new"})
    )
    assert stats["cached"] == 2 and len(read_csv(out / "results.csv")) == len(rows)
    assert json.loads((out / "metadata.json").read_text())["cases"] == 2
    assert (out / "plots" / "curve.png").read_bytes() == b"new"


def test_bench_failure_keeps_the_table(tmp_path):
    """`study bench --repeats 0` once replaced a good table with blanks; now it is refused and the table stays."""

    write(tmp_path / "b", {"bench-cpu.csv": b"good table", "bench-cpu.md": b"# good"})
    before = files(tmp_path / "b")
    res = run_cli("bench", "--out", str(tmp_path / "b"), "--repeats", "0")
    assert res.exit_code == 2 and "--repeats" in res.output and files(tmp_path / "b") == before
    assert os.listdir(tmp_path) == ["b"]


def test_outputs_get_ordinary_permissions(tmp_path):
    """Atomic writes and output sets make files and directories as open() and mkdir() would (umask), not mkstemp's
    private 0600 / 0700."""
    import os

    from study.io import atomic_write, write_set

    umask = os.umask(0)
    os.umask(umask)
    atomic_write(tmp_path / "a.txt", "x")
    assert (tmp_path / "a.txt").stat().st_mode & 0o777 == 0o666 & ~umask
    write_set(tmp_path / "new", {"t.csv": "a,b\n"}, owns=["t.csv"])
    assert (tmp_path / "new").stat().st_mode & 0o777 == 0o777 & ~umask
    assert (tmp_path / "new" / "t.csv").stat().st_mode & 0o777 == 0o666 & ~umask


def test_an_interrupt_right_after_the_lock_file_is_created_leaves_no_lock(tmp_path, monkeypatch):
    """SIGTERM can land between open() creating ``.lock`` and the lock being held (seen once in ten runs of
    test_sigterm_leaves_the_old_files_and_no_lock): the file must still go. Here the interrupt comes exactly there."""
    import builtins

    from study import io as sio

    real_open = builtins.open

    def open_then_interrupt(path, *a, **k):
        f = real_open(path, *a, **k)
        if str(path).endswith(sio.LOCK) and a and a[0] == "a+":
            f.close()
            raise KeyboardInterrupt
        return f

    out = tmp_path / "out"
    out.mkdir()
    monkeypatch.setattr(builtins, "open", open_then_interrupt)
    with pytest.raises(KeyboardInterrupt):
        with sio.locked(out):
            pass
    monkeypatch.setattr(builtins, "open", real_open)
    assert not (out / sio.LOCK).exists()
