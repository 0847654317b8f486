"""Hostile round 5, items 3, 4 and 8 (issue 51): no forged or impossible number reaches a verdict.

The tables ``study report`` (its claims register, summary and headline), ``scripts/headline.py`` and ``study
pareto`` read are checked on read against the declared columns (:func:`study.columns.domain`,
:func:`study.tables.check_rows`): a fraction outside [0, 1], a negative count, lookup or RMSE, an infinite value, a
(case, label) twice, a bench time of −5, 0, NaN or ∞ ms, a bench table of random bytes or UTF-16 are each one line
naming the file, line and column (exit 2), and nothing is written. A run folder's ``index.json`` (or a figure's
``metadata.json``, its viewer manifest) nested 10⁵ deep is one line too, not a RecursionError (exit 4)."""

import csv
import io
import subprocess
import sys
from pathlib import Path

import pytest
from conftest import assert_one_line_error, digest, run_cli

ROOT = Path(__file__).resolve().parents[2]
FIG = ROOT / "reports" / "fig4" / "metrics.csv"
BENCH = ROOT / "reports" / "performance" / "bench-gpu.csv"


def read(path: Path) -> tuple[list[str], list[list[str]]]:
    rows = list(csv.reader(io.StringIO(path.read_text(encoding="utf-8"), newline="")))
    return rows[0], rows[1:]


def write(path: Path, header: list[str], rows: list[list[str]]) -> None:
    buf = io.StringIO()
    csv.writer(buf, lineterminator="\n").writerows([header, *rows])
    path.write_text(buf.getvalue(), encoding="utf-8")


def method_line(header, rows, label="classical") -> int:
    """The index (in ``rows``) of the first row of ``label``."""
    return next(i for i, r in enumerate(rows) if r[header.index("label")] == label)


@pytest.fixture
def reports(tmp_path):
    """A reports folder holding one figure: a copy of the committed fig4 table."""
    d = tmp_path / "reports"
    (d / "fig4").mkdir(parents=True)
    (d / "fig4" / "metrics.csv").write_bytes(FIG.read_bytes())
    return d


def tamper(reports: Path, column: str, value: str) -> int:
    """Set ``column`` of classical's first row of fig4's table to ``value``; the file's line number."""
    path = reports / "fig4" / "metrics.csv"
    header, rows = read(path)
    i = method_line(header, rows)
    rows[i][header.index(column)] = value
    write(path, header, rows)
    return i + 2


def duplicate_with_zero(reports: Path) -> int:
    """Every row twice, the copy with wrong_fraction 0 (what once flipped the monotone-wrong claim)."""
    path = reports / "fig4" / "metrics.csv"
    header, rows = read(path)
    j = header.index("wrong_fraction")
    copies = [[*r[:j], "0", *r[j + 1 :]] for r in rows]
    write(path, header, rows + copies)
    return len(rows) + 2


TAMPERED = {
    "wrong_fraction=inf": (lambda d: tamper(d, "wrong_fraction", "inf"), "column 'wrong_fraction'"),
    "wrong_fraction=-1": (lambda d: tamper(d, "wrong_fraction", "-1"), "column 'wrong_fraction'"),
    "wrong_fraction=2": (lambda d: tamper(d, "wrong_fraction", "2"), "column 'wrong_fraction'"),
    "duplicated-with-0%": (duplicate_with_zero, "repeats case"),
    "lookups_per_ray=-100": (lambda d: tamper(d, "lookups_per_ray", "-100"), "column 'lookups_per_ray'"),
    "rmse_mitsuba=-3": (lambda d: tamper(d, "rmse_mitsuba", "-3"), "column 'rmse_mitsuba'"),
}


@pytest.mark.parametrize("case", list(TAMPERED))
def test_report_refuses_a_tampered_table(reports, case):
    """``study report`` over a forged ``metrics.csv``: exit 2, one line naming the file, the line and the column
    (before: a flipped claim, a headline at −100 lookups/ray, or exit 4 from scipy's binomtest), nothing written."""
    make, words = TAMPERED[case]
    line = make(reports)
    before = digest(reports)
    res = run_cli("report", "--reports", reports)
    assert_one_line_error(res, words, before, reports)
    assert f"line {line}" in res.output and "metrics.csv" in res.output
    assert not (reports / "index.md").exists()


@pytest.mark.parametrize("case", ["wrong_fraction=inf", "duplicated-with-0%", "lookups_per_ray=-100"])
def test_headline_script_refuses_a_tampered_table(reports, case):
    """``scripts/headline.py`` reads the same tables the same way: exit 2 and one ``error:`` line, no headline."""
    make, words = TAMPERED[case]
    make(reports)
    res = subprocess.run(
        [sys.executable, str(ROOT / "scripts" / "headline.py"), str(reports)],
        capture_output=True,
        text=True,
        cwd=ROOT,
        env={"PYTHONPATH": str(ROOT), "PATH": "/usr/bin:/bin"},
        timeout=120,
    )
    assert res.returncode == 2, res.stdout + res.stderr
    err = res.stderr.strip()
    assert err.startswith("error: ") and "\n" not in err and words in err, err
    assert "lookups/ray" not in res.stdout


def test_the_committed_tables_pass_the_check():
    """Every committed figure, sweep and run table is within its declared domains (the check refuses only what
    no run can write)."""
    from study.report.report import results_table

    paths = [
        *sorted((ROOT / "reports").glob("fig*/metrics.csv")),
        *sorted((ROOT / "reports").glob("sweep-*/results.csv")),
    ]
    assert paths
    for p in paths:
        results_table(p)


# ---------------------------------------------------------------------------------------------- pareto
def bench_copy(tmp_path: Path) -> Path:
    d = tmp_path / "bench"
    d.mkdir()
    for suffix in (".csv", ".md"):
        (d / f"bench-gpu{suffix}").write_bytes(BENCH.with_suffix(suffix).read_bytes())
    return d / "bench-gpu.csv"


def tamper_time(bench: Path, value: str) -> int:
    """Set the wall time of the close-up batch's first frozen CUDA row to ``value``; its line number."""
    header, rows = read(bench)
    col = {c: header.index(c) for c in ("batch", "backend", "path", "ms_per_frame")}
    i = next(
        i
        for i, r in enumerate(rows)
        if "close-up" in r[col["batch"]] and r[col["backend"]] == "cuda" and r[col["path"]] == "frozen"
    )
    rows[i][col["ms_per_frame"]] = value
    write(bench, header, rows)
    return i + 2


def rewrite(path: Path, data: bytes) -> None:
    path.write_bytes(data)


BENCHES = {
    "-5 ms": (lambda b: tamper_time(b, "-5"), "holds -5"),
    "0 ms": (lambda b: tamper_time(b, "0"), "holds 0"),
    "NaN ms": (lambda b: tamper_time(b, "nan"), "holds nothing"),
    "empty": (lambda b: tamper_time(b, ""), "holds nothing"),
    "inf ms": (lambda b: tamper_time(b, "inf"), "holds inf"),
    "random bytes": (lambda b: rewrite(b, bytes(range(256)) * 8), "not UTF-8 text"),
    "UTF-16": (lambda b: rewrite(b, b.read_text(encoding="utf-8").encode("utf-16")), "not UTF-8 text"),
}


@pytest.mark.parametrize("case", list(BENCHES))
def test_pareto_refuses_impossible_bench_times(reports, tmp_path, case):
    """``study pareto`` with a bench time of −5, 0, NaN, ∞ ms or a table of random bytes / UTF-16: exit 2, one line
    naming the bench table (and the line and column of a time), no page (before: "Tracing the rays costs -9.9 ms",
    0 accepted, NaN and ∞ dropped in silence, exit 3 with the content shown as a file name)."""
    bench = bench_copy(tmp_path)
    make, words = BENCHES[case]
    line = make(bench)
    out = tmp_path / "pareto"
    res = run_cli("pareto", "--reports", reports, "--out", out, "--benches", bench)
    assert_one_line_error(res, words, {}, out)
    assert str(bench) in res.output and not out.exists()
    if line is not None:
        assert f"line {line}, column 'ms_per_frame'" in res.output


def test_pareto_reads_the_untampered_copies(reports, tmp_path):
    """The same copies, untouched, give the page (the refusals above are the tampering's, not the copies')."""
    out = tmp_path / "pareto"
    res = run_cli("pareto", "--reports", reports, "--out", out, "--benches", bench_copy(tmp_path))
    assert res.exit_code == 0, res.output
    assert (out / "pareto.md").is_file()


# ---------------------------------------------------------------------------------------------- item 8: JSON
DEEP = "[" * 100_000 + "]" * 100_000


def run_folder(reports: Path) -> Path:
    """A folder with a run's own files (table.csv, scene.json) beside a deeply nested index.json."""
    d = reports / "run-room-0123abcd"
    d.mkdir(parents=True)
    header, rows = read(FIG)
    write(d / "table.csv", header, rows[:4])
    (d / "scene.json").write_text("{}")
    (d / "index.json").write_text(DEEP)
    return d / "index.json"


def figure_file(rel: str):
    def make(reports: Path) -> Path:
        path = reports / "fig4" / rel
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(DEEP)
        return path

    return make


@pytest.mark.parametrize(
    "where",
    [run_folder, figure_file("metadata.json"), figure_file("viewer/index.json")],
    ids=["run-index.json", "figure-metadata.json", "figure-viewer-manifest"],
)
def test_report_over_json_nested_1e5_deep_is_one_line(reports, where):
    """A JSON file nested 10⁵ deep where the report reads one: exit 2, one line naming it (before: exit 4,
    RecursionError), nothing written."""
    path = where(reports)
    before = digest(reports)
    res = run_cli("report", "--reports", reports)
    assert_one_line_error(res, "nest too deeply", before, reports)
    assert str(path) in res.output
