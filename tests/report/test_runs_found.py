"""No run lost, every run found (issue 44, item 6): ``study run`` writes one folder per scene file (two files named
``room.*`` never replace each other's results, a re-run of the same file replaces its own), and ``study report``
finds runs by their own files in any folder under ``--reports``, names each run's file in its titles, warns in one
line when it finds nothing, and writes no empty section."""

import json
import shutil
from pathlib import Path

import pytest
from typer.testing import CliRunner

from study.cli import app
from study.outputs.run_files import default_folder
from tests.conftest import scene_toml, small_scene_dict

run = CliRunner().invoke
FAST = [
    "-m",
    "classical",
    "--set",
    "render.cube_res=16",
    "--set",
    "camera.width=32",
    "--set",
    "camera.height=32",
]


def test_the_default_folder_is_one_per_scene_file(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    for f in ("a/room.glb", "b/room.obj", "c/room.glb"):
        (tmp_path / f).parent.mkdir(exist_ok=True)
        (tmp_path / f).write_text("")
    a, b, c = (default_folder(f) for f in ("a/room.glb", "b/room.obj", "c/room.glb"))
    assert len({a, b, c}) == 3 and all(
        p.name.startswith("run-room-") and p.parent == Path("reports") for p in (a, b, c)
    )
    assert (
        default_folder("b/../a/room.glb") == a == default_folder(tmp_path / "a" / "room.glb")
    )  # the same file


@pytest.fixture(scope="module")
def two_rooms(tmp_path_factory):
    """Two scene files both named room.toml, each run with the default --out, the first one twice."""
    root = tmp_path_factory.mktemp("rooms")
    for sub, x in (("a", 0.6), ("b", 0.5)):
        (root / sub).mkdir()
        d = small_scene_dict()
        d["object"]["center"] = [x, 1.2, 0.3]
        (root / sub / "room.toml").write_text(scene_toml(d))
    cwd = Path.cwd()
    try:
        import os

        os.chdir(root)
        for f in ("a/room.toml", "b/room.toml", "a/room.toml"):
            res = run(app, ["run", f, *FAST, "--cache", str(root / "cache")])
            assert res.exit_code == 0, res.output
    finally:
        os.chdir(cwd)
    return root


def test_two_files_of_one_name_keep_their_runs(two_rooms):
    runs = sorted((two_rooms / "reports").iterdir())
    assert [p.name.rsplit("-", 1)[0] for p in runs] == [
        "run-room",
        "run-room",
    ]  # the second did not replace it
    centers = {json.loads((p / "scene.json").read_text())["object"]["center"][0] for p in runs}
    assert centers == {0.6, 0.5}
    for p in runs:  # each names its file, resolved
        index = json.loads((p / "index.json").read_text())
        assert index["name"] == "room.toml" and Path(index["file"]).parent.name in ("a", "b")


def test_report_finds_runs_by_their_files_in_any_folder_and_names_them(two_rooms, tmp_path):
    reports = tmp_path / "results"
    a, b = sorted((two_rooms / "reports").iterdir())
    shutil.copytree(a, reports / "my runs" / "first")  # any name, any depth
    shutil.copytree(b, reports / "second")
    shutil.copytree(b, reports / "not-a-run")
    (reports / "not-a-run" / "scene.json").unlink()  # index.json and a table, but not a run's own files
    shutil.copytree(b, reports / ".hidden")
    res = run(app, ["report", "--reports", str(reports)])
    assert res.exit_code == 0, res.output
    page = (reports / "index.html").read_text()
    assert '<h2 id="my-runs-first-room-toml">my runs/first: room.toml</h2>' in page
    assert '<h2 id="second-room-toml">second: room.toml</h2>' in page
    assert "not-a-run" not in page and ".hidden" not in page
    assert page.count("room.toml: images per case") == 2 and ": images per case" not in page.replace(
        "room.toml: images per case", ""
    )
    assert 'data-fig="my runs/first"' in page
    manifest = json.loads(page.split('id="study-manifest">', 1)[1].split("</script>", 1)[0])
    assert all(c["title"].startswith("room.toml: ") for m in manifest.values() for c in m["cases"])
    md = (reports / "index.md").read_text()
    assert "## my runs/first: room.toml" in md


def test_a_report_of_runs_only_has_no_empty_section(two_rooms, tmp_path):
    reports = tmp_path / "reports"
    shutil.copytree(two_rooms / "reports", reports)
    res = run(app, ["report", "--reports", str(reports)])
    assert res.exit_code == 0, res.output
    page = (reports / "index.html").read_text()
    for empty in (
        "The paper&#x27;s claims",
        "The paper's claims",
        "Method comparison",
        "Versions and commands",
    ):
        assert f">{empty}</h2>" not in page, empty
    assert "<tbody></tbody>" not in page
    assert page.count('<div class="viewer"') == 2


def test_a_runs_own_page_names_its_file(two_rooms):
    d = next((two_rooms / "reports").iterdir())
    page = (d / "index.html").read_text()
    assert "room.toml: images per case" in page and ".: images per case" not in page
    assert "<title>study run: room.toml: " in page


def test_report_of_nothing_warns_in_one_line_and_writes_nothing(tmp_path):
    (tmp_path / "empty" / "run-old").mkdir(parents=True)  # a run-* name alone is not a run
    res = run(app, ["report", "--reports", str(tmp_path / "empty")])
    assert res.exit_code == 0, res.output
    lines = [ln for ln in res.stderr.splitlines() if not ln.startswith("[")]
    assert len(lines) == 1 and lines[0].startswith("warning: found no results under "), res.stderr
    assert not list((tmp_path / "empty").glob("index.*"))
    assert "report: wrote" not in res.stdout


def test_report_refuses_to_write_over_a_runs_own_page(two_rooms, tmp_path):
    d = tmp_path / "run"
    shutil.copytree(next((two_rooms / "reports").iterdir()), d)
    before = (d / "index.html").read_bytes()
    res = run(app, ["report", "--reports", str(d)])
    assert res.exit_code == 2 and "is the folder of one `study run`" in res.output, res.output
    assert (d / "index.html").read_bytes() == before
