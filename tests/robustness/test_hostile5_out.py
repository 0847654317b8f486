"""Hostile round 5, item 1 (issue 51): nothing of the user's is deleted by an output folder.

An empty ``--out ""`` (a shell variable left unset) was the current directory: ``study figure``/``run`` replaced
its ``exr/`` and ``viewer/`` whole and overwrote ``metrics.csv``; ``Result.save("")`` wrote into the process's
cwd. Now it is one line, exit 2, nothing touched. An ``--out`` that already holds files study did not write keeps
them: study removes or replaces only the files it lists as its own (:data:`study.io.OUTPUTS`), never a directory
whole, and a folder of the user's where an output file goes is refused before anything changes."""

import json
from pathlib import Path

import pytest
from conftest import assert_one_line_error, digest, run_cli, scene_toml, small_scene_dict

from study import io
from study.errors import StudyError

FIG = """
positions = [[0.6, 1.2, 0.3]]
methods = [{ name = "classical" }]

[scene]
room = { min = [-2.0, 0.0, -2.0], max = [2.0, 3.0, 2.0] }
light = { position = [0.3, 2.6, -0.4], intensity = [7.0, 7.0, 7.0] }
reference = { point = [0.0, 1.5, 0.0] }
object = { center = [0.6, 1.2, 0.3], radius = 0.4, material = { type = "mirror" } }
camera = { eye = [-0.3, 1.7, -1.9], target = [0.6, 1.1, 0.6], fov = 75.0, width = 16, height = 16 }
render = { cube_res = 16, cube_spp = 2, spp = 2, max_depth = 3, supersample = 1 }
"""

#: what a user keeps in a folder: files of the names study writes, inside the folders study writes
USERS = {
    "exr/mine.txt": b"my notes on the EXRs",
    "viewer/mine.js": b"// my viewer script",
    "metrics.csv": b"case,label\nmine,mine\n",
    "table.csv": b"mine\n",
    "index.html": b"<p>my page</p>",
}


def plant(d: Path, content: dict[str, bytes]) -> None:
    for rel, data in content.items():
        (d / rel).parent.mkdir(parents=True, exist_ok=True)
        (d / rel).write_bytes(data)


def files(d: Path) -> dict[str, bytes]:
    return {p.relative_to(d).as_posix(): p.read_bytes() for p in sorted(d.rglob("*")) if p.is_file()}


@pytest.fixture
def cwd(tmp_path, monkeypatch):
    """A working directory holding the user's files (and a tiny figure config and scene beside it)."""
    work = tmp_path / "work"
    plant(work, USERS)
    (tmp_path / "cfg.toml").write_text(FIG)
    d = small_scene_dict()
    d["camera"].update(width=16, height=16)
    d["render"].update(cube_res=16, cube_spp=2, spp=2)
    (tmp_path / "scene.toml").write_text(scene_toml(d))
    monkeypatch.chdir(work)
    return work


COMMANDS = {
    "figure": lambda t: ["figure", "--config", t / "cfg.toml", "--cache", t / "cache", "--out", ""],
    "run": lambda t: ["run", t / "scene.toml", "-m", "classical", "--cache", t / "cache", "--out", ""],
    "sweep": lambda t: ["sweep", t / "cfg.toml", "--out", ""],
    "pareto-out": lambda t: ["pareto", "--reports", t, "--out", ""],
    "pareto-reports": lambda t: ["pareto", "--reports", "", "--out", t / "p"],
    "report": lambda t: ["report", "--reports", ""],
    "bench": lambda t: ["bench", "--out", ""],
    "animate": lambda t: ["animate", "--out", ""],
    "convergence": lambda t: ["convergence", "--out", ""],
    "caustics-sweep": lambda t: ["caustics-sweep", "--out", ""],
}


@pytest.mark.parametrize("command", list(COMMANDS))
def test_empty_out_is_one_line_and_touches_nothing(cwd, command):
    """``--out ""`` (or ``--reports ""``) is refused before any work: exit 2, one line naming the option; the
    working directory's files (``exr/mine.txt``, ``viewer/mine.js``, ``metrics.csv``, …) are as they were."""
    before = digest(cwd)
    res = run_cli(*COMMANDS[command](cwd.parent))
    key = "--reports" if command in ("report", "pareto-reports") else "--out"
    assert_one_line_error(res, f"{key}: empty path", before, cwd)
    assert files(cwd) == USERS


def test_result_save_to_an_empty_path_is_refused(cwd, tmp_path):
    """``Result.save("")`` raises one StudyError naming ``out`` and writes nothing into the cwd."""
    import study

    d = small_scene_dict()
    res = study.evaluate(
        d,
        ["classical"],
        overrides={"render.cube_res": 16, "camera.width": 16, "camera.height": 16},
        cache=tmp_path / "cache",
    )
    with pytest.raises(StudyError, match="^out: empty path"):
        res.save("")
    assert files(cwd) == USERS
    res.save(cwd / "run")  # a folder named: written, the user's files beside it untouched
    assert {k: v for k, v in files(cwd).items() if not k.startswith("run/")} == USERS
    assert (cwd / "run" / "table.csv").is_file()


def test_figure_into_a_users_folder_keeps_every_file_it_did_not_write(cwd):
    """``study figure --out .`` in a folder of the user's, twice: the user's ``exr/mine.txt`` and
    ``viewer/mine.js`` stay (before: ``exr/`` and ``viewer/`` were replaced whole), study's own files are listed
    in ``.study-outputs.json``, and the second run replaces exactly those."""
    t = cwd.parent
    for _ in range(2):
        res = run_cli("figure", "--config", t / "cfg.toml", "--cache", t / "cache", "--out", ".")
        assert res.exit_code == 0, res.output
        now = files(cwd)
        for rel in ("exr/mine.txt", "viewer/mine.js", "index.html", "table.csv"):
            assert now[rel] == USERS[rel], rel
        listed = json.loads(now[io.OUTPUTS])["files"]
        assert "metrics.csv" in listed and any(p.startswith("exr/") for p in listed)
        assert not {"exr/mine.txt", "viewer/mine.js", "index.html", "table.csv"} & set(listed)


@pytest.mark.parametrize("swap", [True, False], ids=["exchange", "renames"])
def test_only_files_study_listed_are_removed(tmp_path, monkeypatch, swap):
    """An owned directory is no longer replaced whole: an earlier output that this run does not write again
    goes (it is on the list), a file the user put beside it stays, with the exchange and with renames."""
    if not swap:
        monkeypatch.setattr(io, "_exchange", lambda a, b: False)
    out = tmp_path / "out"
    io.write_set(out, {"exr/a.exr": b"old a", "exr/b.exr": b"old b", "metrics.csv": b"old"}, ["exr"])
    plant(out, {"exr/mine.txt": b"mine", "viewer/mine.js": b"mine"})
    io.write_set(out, {"exr/a.exr": b"new a", "metrics.csv": b"new"}, ["exr", "viewer"])
    got = files(out)
    assert json.loads(got.pop(io.OUTPUTS))["files"] == ["exr/a.exr", "metrics.csv"]
    assert got == {
        "exr/a.exr": b"new a",
        "exr/mine.txt": b"mine",
        "metrics.csv": b"new",
        "viewer/mine.js": b"mine",
    }
    io.write_set(out, {"metrics.csv": b"newer"}, ["exr"])  # exr/a.exr is stale now: it goes, mine.txt stays
    assert files(out)["exr/mine.txt"] == b"mine" and not (out / "exr" / "a.exr").exists()


@pytest.mark.parametrize("swap", [True, False], ids=["exchange", "renames"])
@pytest.mark.parametrize(
    "planted, words",
    [
        ({"metrics.csv/mine.txt": b"mine"}, "metrics.csv is a folder that study did not write"),
        ({"exr": b"a file of mine"}, "exr is a file that study did not write"),
    ],
    ids=["folder-where-a-file-goes", "file-where-a-folder-goes"],
)
def test_something_of_the_users_in_the_way_is_refused(tmp_path, monkeypatch, swap, planted, words):
    """A folder of the user's named like an output file, or a file named like an output folder: one StudyError
    naming it, before anything changes (before: the folder was swapped away or moved to the trash)."""
    if not swap:
        monkeypatch.setattr(io, "_exchange", lambda a, b: False)
    out = tmp_path / "out"
    plant(out, {**planted, "notes.txt": b"mine"})
    before = files(out)
    with pytest.raises(StudyError, match=words):
        io.write_set(out, {"metrics.csv": b"new", "exr/a.exr": b"new"}, ["exr"])
    assert files(out) == before
