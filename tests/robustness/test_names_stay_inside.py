"""Names that are paths stay inside: a figure's name becomes one folder under reports/ (and its files' names),
so a name with a separator, ``..``, or a leading ``.``/``-`` is refused like a config's stem could never be —
one line, exit 2, nothing written anywhere (``study figure ../../esc-fig --config …`` used to write two folders
above the working directory). Sweeps and runs are named by their config's or scene's stem: one folder always."""

from pathlib import Path

import pytest
from conftest import error_output, run_cli

from study.errors import StudyError
from study.harness.config import plain_name

TINY = """
positions = [[0.6, 1.2, 0.3]]
grid = ["classical"]
[scene]
room = { min = [-2.0, 0.0, -2.0], max = [2.0, 3.0, 2.0] }
light = { position = [0.3, 2.6, -0.4], intensity = [7.0, 7.0, 7.0] }
reference = { point = [0.0, 1.5, 0.0] }
object = { center = [0.6, 1.2, 0.3], radius = 0.4, material = { type = "mirror" } }
camera = { eye = [-0.3, 1.7, -1.9], target = [0.6, 1.1, 0.6], fov = 75.0, width = 16, height = 16 }
render = { cube_res = 8, cube_spp = 2, spp = 2, max_depth = 2, supersample = 1 }
[[methods]]
name = "classical"
"""

ESCAPES = [
    "../../esc-fig",
    "../esc",
    "a/b",
    "..",
    ".",
    ".hidden",
    "a\\b",
    "/tmp/abs-fig",
    "x\0y",
    " x",
    "x\n",
]


def _tree(root: Path) -> set[str]:
    return {str(p.relative_to(root)) for p in root.rglob("*")}


@pytest.fixture
def nested(tmp_path, monkeypatch):
    """The working directory three folders below ``tmp_path``, with the tiny figure config in it."""
    cwd = tmp_path / "a" / "b" / "c"
    cwd.mkdir(parents=True)
    (cwd / "tiny.toml").write_text(TINY)
    monkeypatch.chdir(cwd)
    return tmp_path


@pytest.mark.parametrize("name", ESCAPES)
def test_a_figure_name_that_is_a_path_is_refused(nested, name):
    before = _tree(nested)
    for extra in ([], ["--out", "out"]):  # the default reports/<name>, and an --out the png would leave
        res = run_cli(*["figure", name, "--config", "tiny.toml", "--cache", str(nested / "cache")] + extra)
        assert res.exit_code == 2, res.output
        text = error_output(res)
        assert text.startswith("error: name: ") and "\n" not in text, text
        assert "is not a plain name" in text and "no path separator, no '..'" in text, text
        assert _tree(nested) == before  # nothing written, inside or outside


def test_the_api_refuses_it_too(tmp_path):
    from study.outputs.figures import figure_positions

    (tmp_path / "tiny.toml").write_text(TINY)
    with pytest.raises(StudyError, match="'../x' is not a plain name"):
        figure_positions(tmp_path / "tiny.toml", tmp_path / "out", name="../x", cache=None)
    assert not (tmp_path / "out").exists() and not (tmp_path / "x.png").exists()


def test_plain_names_pass_and_paths_do_not():
    for ok in ("fig4", "fig_attic", "my-fig.v2", "_x", "été", "a..b"):
        assert plain_name(ok) == ok
    for bad in [*ESCAPES, "-rf", "", "x" * 101]:
        with pytest.raises(StudyError, match="is not a plain name"):
            plain_name(bad)


def test_a_plain_figure_name_lands_under_reports(nested):
    """The control: a plain name runs and writes reports/<name>/<name>.png below the working directory, only."""
    res = run_cli("figure", "my-fig.v2", "--config", "tiny.toml", "--cache", str(nested / "cache"))
    assert res.exit_code == 0, res.output
    cwd = nested / "a" / "b" / "c"
    assert (cwd / "reports" / "my-fig.v2" / "my-fig.v2.png").is_file()
    outside = {p for p in _tree(nested) if not p.startswith(("a/b/c/", "cache"))}
    assert outside == {"a", "a/b", "a/b/c"}, outside
