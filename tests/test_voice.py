"""Voice (issue 44, item 7): every stage says when it starts, a long one says every few seconds that it still runs
(with how far it is, where it says) also when stderr is a file, numpy's warnings do not leak from the layered
impostor, and the API names the valid keys of a mistyped scene key as the command line does."""

import io
import os
import re
import subprocess
import sys
import time
import warnings
from pathlib import Path

import numpy as np
import pytest
from rich.console import Console

from study import progress
from study.cli.progress import Lines
from tests.conftest import run_cli, scene_toml, small_scene_dict

ROOT = Path(__file__).resolve().parents[1]
STAMP = re.compile(r"^\[\s*(\d+\.\d) s\] (.*)$")
CASE = ["load", "capture", "probes", "references", "methods", "metrics"]


def _said(con) -> list[tuple[float, str]]:
    return [
        (float(m.group(1)), m.group(2)) for ln in con.file.getvalue().splitlines() if (m := STAMP.match(ln))
    ]


def test_a_long_stage_says_it_runs_every_few_seconds_without_a_terminal():
    con = Console(file=io.StringIO(), width=200, force_terminal=False, color_system=None)
    with progress.reporting(Lines(con, every=0.2)), progress.task("job", 1):
        with progress.item("case-a"):
            mark = progress.Stages()
            mark("load")
            mark("probes")
            progress.note("probe 1/2: its cube map, path traced")
            time.sleep(0.75)  # a render: nothing else is printed meanwhile
            mark.end()
        progress.advance("case-a")
    said = [text for _, text in _said(con)]
    assert said[:3] == ["job 1/1 case-a: load …", said[1], "job 1/1 case-a: probes …"], said
    assert re.fullmatch(r"job 1/1 case-a: load \d+\.\d s", said[1])
    beats = [s for s in said if "running for" in s]
    assert len(beats) >= 2, said  # every 0.2 s of 0.75 s
    assert beats[0].startswith("job 1/1 case-a: probes running for 0.") and beats[0].endswith(
        "(probe 1/2: its cube map, path traced)"
    )
    assert said.index(beats[-1]) < said.index(next(s for s in said if re.search(r"probes \d+\.\d s$", s)))
    n = len(con.file.getvalue())
    time.sleep(0.5)
    assert len(con.file.getvalue()) == n  # the task ended: no line after it, the thread is gone
    assert not [t for t in __import__("threading").enumerate() if t.name == "study-progress"]


def test_a_stage_that_failed_is_not_said_to_run():
    con = Console(file=io.StringIO(), width=200, force_terminal=False, color_system=None)
    with progress.reporting(Lines(con, every=0.1)), progress.task("job", 2):
        with pytest.raises(ValueError), progress.item("bad"):
            mark = progress.Stages()
            mark("capture")
            raise ValueError
        time.sleep(0.4)  # the next case has not begun: nothing runs
        t = progress.current()
        assert t is not None and t.stage == ""
    assert not [s for _, s in _said(con) if "running for" in s], con.file.getvalue()


def test_study_run_with_stderr_in_a_file_speaks_every_stage_and_keeps_talking(tmp_path):
    """The command itself, stderr redirected to a file (no terminal): a start line and an end line for every
    stage, and no silence longer than a few heartbeats while the renders run."""
    (tmp_path / "tiny.toml").write_text(scene_toml(small_scene_dict()))
    err = tmp_path / "stderr.txt"
    # a heartbeat every 0.1 s: the tiny case's stages take 0.3 s each on an idle machine (the batched columns and
    # the shared capture), so one every second could fall between them
    env = {**os.environ, "PYTHONPATH": str(ROOT), "STUDY_PROGRESS_EVERY": "0.1"}
    args = ["run", "tiny.toml", "-m", "classical", "-m", "layered", "--set", "render.cube_res=24"]
    with open(err, "w") as f:
        rc = subprocess.run(
            [sys.executable, "-m", "study.cli", *args, "--cache", "c"], cwd=tmp_path, stderr=f, env=env
        ).returncode
    text = err.read_text()
    assert rc == 0, text
    said = [m.groups() for ln in text.splitlines() if (m := STAMP.match(ln))]
    for s in CASE:
        start = next(i for i, (_, t) in enumerate(said) if t.endswith(f": {s} …"))
        end = next(i for i, (_, t) in enumerate(said) if re.search(rf": {s} \d+\.\d s$", t))
        assert start < end, (s, text)
    assert any("running for" in t for _, t in said), text  # a stage took more than 0.1 s
    stamps = [float(s) for s, _ in said]
    gaps = np.diff(stamps)
    assert gaps.max() <= 6.0, (gaps.max(), text)  # a line at least every few seconds (every 0.1 s asked)


def test_the_layered_impostor_leaks_no_numpy_warning():
    """A mesh with a degenerate (zero-area) triangle: its normal was 0/0 (RuntimeWarning at layers.py:47)."""
    from study.impostor.layers import peel
    from study.reference.embree import Tracer
    from study.scene import scene_from_dict
    from study.scene.room import RoomMesh

    m = scene_from_dict(small_scene_dict()).mesh()
    v = np.vstack([m.vertices, [[0.1, 0.1, 0.1]] * 3]).astype(np.float32)
    n = len(m.vertices)
    mesh = RoomMesh(
        v,
        np.vstack([m.faces, [[n, n + 1, n + 2]]]).astype(np.int32),
        np.vstack([m.uv, np.zeros((3, 2))]).astype(np.float32),
        np.append(m.surface, m.surface[0]).astype(np.int32),
        m.surfaces,
    )
    dirs = np.array([[1.0, 0, 0], [0, 1.0, 0], [0, 0, -1.0]])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        dist, _, normal, new = peel(Tracer(mesh), np.array([0.0, 1.5, 0.0]), dirs, 2)
    assert new[0].all() and np.allclose(np.linalg.norm(normal[0], axis=1), 1.0)


@pytest.mark.parametrize("key", ["object.radiu", "camera.widht"])
def test_the_api_names_the_valid_keys_as_the_cli_does(key, tmp_path):

    import study
    from study.errors import StudyError

    with pytest.raises(StudyError) as err:
        study.load_scene("scenes/room.toml", **{key: 0.3})
    msg = str(err.value)
    table = key.split(".")[0]
    assert f"{key}: unknown scene key; allowed: " in msg, msg
    allowed = msg.split("allowed: ", 1)[1]
    assert ("radius" if table == "object" else "width") in allowed and "center" in allowed or "eye" in allowed
    res = run_cli(
        *["run", str(ROOT / "scenes" / "room.toml"), "--set", f"{key}=0.3", "--out", str(tmp_path / "o")]
    )
    assert res.exit_code == 2 and msg in res.output, (msg, res.output)
