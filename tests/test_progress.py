"""Progress by stage (study.progress, study.cli.progress): a long command tells on stderr which stage of which
case it finished, with its time, and after each case how many are done and the ETA; tables stay on stdout, whole,
in a log; ``--quiet`` leaves only the tables.

The ETA is checked against the definition written in study.progress (mean seconds per unit finished in this run ×
units left) with a clock the test controls."""

import json
import re

import pytest

from study import progress
from study.cli.progress import Bar, Lines, duration
from tests.conftest import run_cli, scene_toml, small_scene_dict

CASE = ["load", "capture", "probes", "references", "methods", "metrics"]
STAMP = re.compile(r"^\[\s*\d+\.\d s\] ")


@pytest.fixture(scope="module")
def figure_run(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("progress")
    scene = small_scene_dict()
    scene["render"]["cube_res"] = 16
    (tmp / "scene.toml").write_text(scene_toml(scene))
    (tmp / "fig_tiny.toml").write_text(
        'scene = "scene.toml"\npositions = [[0.6, 1.2, 0.3], [0.5, 1.1, 0.2]]\n'
        'methods = ["classical", "localized", "proxy_sphere"]\n'
    )
    args = [
        "figure",
        "--config",
        str(tmp / "fig_tiny.toml"),
        "--out",
        str(tmp / "out"),
        "--cache",
        str(tmp / "c"),
    ]
    loud = run_cli(*args)
    meta = json.loads((tmp / "out" / "metadata.json").read_text())
    quiet = run_cli("--quiet", *args)
    return loud, quiet, meta


def test_figure_reports_every_stage_of_every_case_in_order_with_times(figure_run):
    res, _, _ = figure_run
    assert res.exit_code == 0, res.output
    lines = res.stderr.splitlines()
    assert lines and all(STAMP.match(line) for line in lines), lines
    stages = [
        (m.group(1), m.group(2))
        for m in (re.search(r"\] fig_tiny (\d/2 fig_tiny-p\d): (\w+) \d+\.\d s$", line) for line in lines)
        if m
    ]
    assert stages == [("1/2 fig_tiny-p0", s) for s in CASE] + [("2/2 fig_tiny-p1", s) for s in CASE]
    text = res.stderr
    # first the estimate of the whole figure (study.harness.estimate), then the first stage starts
    assert "] estimate: about " in lines[0] and "for 2 cases" in lines[0], lines[0]
    lines = lines[1:]
    assert lines[0].endswith("fig_tiny 1/2 fig_tiny-p0: load …")
    assert lines[1].endswith("fig_tiny 1/2 fig_tiny-p0: load " + lines[1].rsplit(" ", 2)[1] + " s")
    started = [
        m.group(1) for m in (re.search(r"\] fig_tiny \d/2 fig_tiny-p\d: (\w+) …$", ln) for ln in lines) if m
    ]
    assert started == CASE + CASE  # every stage says when it starts
    done1 = re.search(r"\] fig_tiny: 1/2 done \(fig_tiny-p0\), ETA (\d+\.\d) s\n", text)
    assert done1 and text.index(done1.group(0)) > text.index("fig_tiny-p0: metrics")
    assert text.index(done1.group(0)) < text.index("fig_tiny-p1: load")
    assert re.search(r"\] fig_tiny 2/2: outputs \d+\.\d s\n.*\] fig_tiny: finished in ", text, re.S)
    stamps = [float(STAMP.match(line).group(0)[1:-3]) for line in lines]
    assert stamps == sorted(stamps)  # times since the command began, never backwards


def test_tables_stay_on_stdout_whole_and_quiet_leaves_only_them(figure_run):
    res, quiet, meta = figure_run
    assert isinstance(meta["exposure_ev"], float) and "99th percentile" in meta["exposure_rule"]  # stated
    assert "fig_tiny-p0: capture" not in res.stdout  # progress never in the tables
    for label in ("classical", "localized", "proxy_sphere", "angle_median_deg", "occluded_fraction"):
        assert label in res.stdout  # full labels: no cell cut to fit 80 columns in a log
    assert "…" not in res.stdout
    assert quiet.exit_code == 0, quiet.output
    assert quiet.stderr == ""
    timed = ("fig_tiny: wrote", "fig_tiny: time split")  # the lines stating times, which differ

    def table(out: str) -> list[str]:
        return [ln for ln in out.splitlines() if not ln.startswith(timed)]

    assert table(quiet.stdout) == table(res.stdout)  # the same table


def test_eta_is_mean_time_per_unit_run_here_times_units_left(monkeypatch):
    monkeypatch.setattr(progress.time, "perf_counter", lambda: 130.0)  # asked at t = 130 s
    t = progress.Task(
        "sweep", total=10, done=4, start=4, t0=100.0
    )  # begun at 100 s; 4 done by an earlier run
    t.done = 7  # 3 finished in 30 s → 10 s each, 3 left
    assert t.eta == pytest.approx(30.0)
    assert progress.Task("x", total=None).eta is None and progress.Task("x", total=5).eta is None


def test_nothing_is_reported_without_a_reporter_and_lines_name_task_item_and_stage():
    import io

    from rich.console import Console

    with progress.task("quiet", 2), progress.item("a"), progress.stage("load"):
        pass  # no reporter: a no-op
    for kind, tty in (
        (Lines, False),
        (Bar, True),
    ):  # plain lines in a log; the same above a bar on a terminal
        con = Console(file=io.StringIO(), width=200, force_terminal=tty, color_system=None)
        with progress.reporting(kind(con)), progress.task("job", 2):
            with progress.item("case-a"):
                mark = progress.Stages()
                mark("load")
                mark("capture")
                mark.end()
            progress.advance("case-a")
        text = re.sub(r"\x1b\[[0-9;?]*[A-Za-z]", "", con.file.getvalue())  # the bar's cursor moves out
        lines = [ln.rsplit("\r", 1)[-1] for ln in text.split("\n")]  # a line printed over the bar
        said = [ln.split("] ", 1)[1] for ln in lines if STAMP.match(ln)]
        assert said[0] == "job 1/2 case-a: load …" and said[2] == "job 1/2 case-a: capture …", (kind, said)
        assert re.fullmatch(r"job 1/2 case-a: load \d+\.\d s", said[1]), (kind, said)
        assert re.fullmatch(r"job 1/2 case-a: capture \d+\.\d s", said[3])
        assert re.fullmatch(r"job: 1/2 done \(case-a\), ETA \d+\.\d s", said[4])
        assert re.fullmatch(r"job: finished in \d+\.\d s", said[5]) and len(said) == 6
    con = Console(file=io.StringIO(), width=200)
    with pytest.raises(ValueError), progress.reporting(Lines(con)), progress.task("job", 2):
        raise ValueError  # a failed task: the error says why, no "finished" line
    assert con.file.getvalue() == ""
    assert duration(42.04) == "42.0 s" and duration(192) == "3 min 12 s" and duration(3720) == "1 h 02 min"
