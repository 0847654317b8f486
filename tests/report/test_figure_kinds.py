"""Figure kinds (study.report.kinds): a config names its kind, ``study figure`` runs that kind's runner, and the
report finds a kind's folder by the files its runs write, whatever the folder's name. A kind from a scratch module
(a plug-in) is run and reported with no file of study touched."""

import textwrap
from pathlib import Path

import pytest
from conftest import run_cli

from study.report import kinds

ROOT = Path(__file__).resolve().parents[2]

TALLY = '''
"""A scratch figure kind: counts the config's words into tally.txt; its report section says the count."""
from pathlib import Path

from study.report.kinds import FigureKind, register_kind


def run(config, out, *, name, backend, cache, quality):
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    n = len(Path(config).read_text().split())
    (out / "tally.txt").write_text(str(n))
    return [{"label": "words", "count": n}]


def section(reports, d, table, cols):
    return [("h", 2, f"Tally of {d.name}"), ("p", f"{(d / 'tally.txt').read_text()} words.")]


register_kind(
    FigureKind(name="tally", run=run, files=("tally.txt",), section=section, lines=lambda rows: ["tallied"])
)
'''


@pytest.fixture
def scratch(tmp_path, monkeypatch):
    """A plug-in module ``tally_kind`` on the path; the kind and the module are gone again after the test."""
    (tmp_path / "tally_kind.py").write_text(textwrap.dedent(TALLY))
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setenv("STUDY_PLUGINS", "")
    monkeypatch.chdir(tmp_path)
    yield tmp_path
    kinds.KINDS.pop("tally", None)
    import sys

    sys.modules.pop("tally_kind", None)


def test_a_kind_from_a_scratch_module_is_run_and_reported(scratch):
    (scratch / "fig_tally.toml").write_text('kind = "tally"\nwhat = "one two three"\n')
    out = scratch / "reports" / "mine"
    res = run_cli("--plugin", "tally_kind", "figure", "--config", "fig_tally.toml", "--out", str(out))
    assert res.exit_code == 0, res.output
    assert (out / "tally.txt").read_text() == "8" and "tallied" in res.output and "wrote" in res.output
    res = run_cli("report", "--reports", str(scratch / "reports"))
    assert res.exit_code == 0, res.output
    page = (scratch / "reports" / "index.md").read_text()
    assert "## Tally of mine" in page and "8 words." in page
    assert "Tally of mine" in (scratch / "reports" / "index.html").read_text()


def test_an_unknown_kind_is_one_line(scratch):
    (scratch / "fig_x.toml").write_text('kind = "tallly"\n')
    res = run_cli("figure", "--config", "fig_x.toml", "--out", "reports/x")
    assert res.exit_code == 2
    line = res.output.strip()
    allowed = "allowed: animation, caustics, convergence, glossy, grid"
    assert f"fig_x.toml: kind: unknown figure kind 'tallly'; {allowed}" in line
    assert len(line.splitlines()) == 1 and not (scratch / "reports").exists()


def test_a_name_is_registered_once():
    grid = kinds.KINDS["grid"]
    assert kinds.register_kind(grid) is grid  # the same kind again: fine (a module imported twice)
    import dataclasses

    with pytest.raises(Exception, match="registered twice"):
        kinds.register_kind(dataclasses.replace(grid, files=("other.csv",)))


def test_shipped_configs_and_committed_folders_have_their_kinds():
    """The configs say their kinds (a grid says none), and the committed reports' folders are found as the kinds
    that wrote them: Figure 8's, the animation's, the glossy figure's (its split beside it), the grids."""
    named = {
        c: kinds.config_kind(ROOT / "configs" / f"{c}.toml").name for c in ("fig4", "fig8", "fig_glossy")
    }
    assert named == {"fig4": "grid", "fig8": "caustics", "fig_glossy": "glossy"}
    assert kinds.config_kind(ROOT / "configs" / "motion.toml").name == "animation"
    made = {d.name: k.name for k, d in kinds.found(ROOT / "reports")}
    assert made["fig8"] == "caustics" and made["animation"] == "animation" and made["fig_glossy"] == "glossy"
    assert made["fig4"] == "grid" and "sweep-sweep" not in made and "paper" not in made
    order = [d.name for _, d in kinds.found(ROOT / "reports")]
    assert order.index("fig_probes") < order.index("fig8") < order.index("animation")  # after the sweeps
