"""The declared columns (study/columns.py, issue 41): every column a case writes is declared, the printed tables and
the API read their columns from the table, and a column added by a plug-in — one declaration, one producer — reaches
the CSV, the Parquet, the API's table and shown columns and ``study run``'s printed table with no other file touched."""

import subprocess
import sys
import textwrap
import tomllib
from pathlib import Path

import pytest
from conftest import scene_toml, small_scene_dict

from study import columns
from study.tables import COLUMNS

ROOT = Path(__file__).resolve().parents[2]


def test_the_leading_columns_are_the_results_tables_order():
    assert COLUMNS[:3] == ["case", "method", "label"] and COLUMNS[-1] == "seconds"
    assert len(set(columns.column_names())) == len(columns.column_names())  # one declaration per name


def test_directions_follow_what_the_columns_measure():
    for c in columns.TABLE:
        n = c.name
        if n.startswith(("wrong_fraction", "rmse_", "flip_", "dist_p", "dec_search", "relmse")):
            assert c.lower_is_better is True, n
        if n.startswith(("psnr_", "ssim_", "correct_")):
            assert c.lower_is_better is False, n


def test_every_column_a_case_writes_is_declared():
    """A mirror, a rough and a glass object: each key of each row (intervals through their column) is declared."""
    from study.harness.config import expand_methods
    from study.measure.case import run_case
    from study.scene import scene_from_dict

    obj = small_scene_dict()["object"]
    objects = [obj, {**obj, "alpha": 0.2}, {**obj, "material": {"type": "dielectric", "ior": 1.5}}]
    meths = [["classical", "localized", "layered", "ssr"], ["glossy"], ["classical"]]
    undeclared = set()
    for o, m in zip(objects, meths):
        sc = scene_from_dict(small_scene_dict(object=o), source="s.toml")
        for row in run_case(sc, expand_methods(m, source="x"), keep_images=False).rows:
            undeclared |= {k for k in row if columns.declared(k) is None}
    refraction = {
        "refraction",
        "exit",
        "exit_lookups_per_ray",
        "tir_fraction",
        "dropped_fraction",
    }  # rays.stats
    assert undeclared <= refraction, sorted(undeclared - refraction)


def test_check_tolerances_name_declared_columns():
    tol = tomllib.loads((ROOT / "configs" / "check.toml").read_text())["tolerance"]
    assert not [k for k in tol if columns.declared(k) is None]


def test_the_printed_tables_read_the_declared_views():
    from study.api import Result  # noqa: F401 - the API reads the view when it shows a table

    assert columns.view("run")[0] == "label" and "wrong_fraction" in columns.view("run")
    assert columns.headers()["wrong_fraction"] == "wrong"


PLUGIN = textwrap.dedent(
    """
    \"\"\"A per-ray column in one file: the share of rays whose shown point lies above their shading point.\"\"\"
    import numpy as np
    from study.columns import TableColumn, declare
    from study.measure.case import producer

    declare(TableColumn("above_fraction", "fraction", None, "above", ("run", "summary"), note="shown point above x"))


    @producer(columns=("above_fraction",))
    def above(ctx):
        return {"above_fraction": float(np.mean(ctx.shown[:, 1] > ctx.x[:, 1]))}
    """
)
#: One process (imports paid once): ``study run``, the API, ``study report`` and ``study check`` with the plug-in
#: loaded by ``$STUDY_PLUGINS`` (docs/extend.md); the expected share is recomputed from the case's own rays.
E2E = textwrap.dedent(
    """
    import sys
    from pathlib import Path
    import numpy as np, pandas as pd
    from typer.testing import CliRunner
    import study
    from study.cli import app
    from study.measure import producers
    from study.outputs.markup import md_esc
    from study.tables import read_csv

    tmp, run = Path(sys.argv[1]), CliRunner().invoke
    common = ["--cache", str(tmp / "c")]
    r = run(app, ["run", str(tmp / "s.toml"), "-m", "classical", "--out", str(tmp / "reports" / "run1"), *common])
    assert r.exit_code == 0, r.output
    assert "above" in r.output.split("label", 1)[1].splitlines()[0], r.output  # study run's printed header
    csv = read_csv(tmp / "reports" / "run1" / "table.csv")
    assert all(0 <= row["above_fraction"] <= 1 for row in csv)

    seen = {}
    producers.PRODUCERS.append(lambda ctx: seen.setdefault(ctx.label, ctx) and {})
    res = study.evaluate(study.load_scene(str(tmp / "s.toml")), methods=["classical"])
    ctx = seen["classical"]
    want = float(np.mean(ctx.shown[:, 1] > ctx.x[:, 1]))
    got = res.table.set_index("label")["above_fraction"]
    assert got["classical"] == want and "above_fraction" in res.shown().columns, (got, want)
    assert got["truth_at_hit"] == float(np.mean(ctx.exact[:, 1] > ctx.x[:, 1]))  # a reference shows the exact hit
    res.save(str(tmp / "api"))
    assert pd.read_parquet(tmp / "api" / "table.parquet").set_index("label")["above_fraction"]["classical"] == want

    r = run(app, ["report", "--reports", str(tmp / "reports")])
    assert r.exit_code == 0, r.output
    assert md_esc("above_fraction") in (tmp / "reports" / "index.md").read_text()  # the run's summary table

    r = run(app, ["check", "--config", str(tmp / "check.toml"), "--update", *common])
    assert r.exit_code == 0, r.output
    assert "above_fraction" in read_csv(tmp / "baseline" / "results.csv")[0]
    r = run(app, ["check", "--config", str(tmp / "check.toml"), *common])
    assert r.exit_code == 0 and "check passed" in r.output, r.output
    print("ok")
    """
)


def test_a_per_ray_column_in_one_file_reaches_every_output(tmp_path):
    """One scratch module, loaded as a plug-in (``$STUDY_PLUGINS``), adds a per-ray column: it is in the CSV and the
    Parquet, the API's table (its value recomputed from the trace's rays, a reference's from the exact hits) and
    shown columns, ``study run``'s printed table, the report's page, and ``study check`` accepts a tolerance on it
    and compares it with the baseline it wrote. Without the plug-in the same check file is refused."""
    from study.errors import StudyError
    from study.report.check import load_check

    (tmp_path / "colplug.py").write_text(PLUGIN)
    scene = small_scene_dict()
    scene["render"]["cube_res"] = 16
    (tmp_path / "s.toml").write_text(scene_toml(scene))
    (tmp_path / "sweep.toml").write_text(
        'scene = "s.toml"\nmethods = ["classical"]\n\n[axes]\n"object.center" = [[0.6, 1.2, 0.3]]\n'
    )
    (tmp_path / "check.toml").write_text(
        'sweep = "sweep.toml"\nbaseline = "baseline"\nseeds = [0, 1, 2]\n\n[tolerance]\n'
        "above_fraction = { abs = 1e-9, rel = 0.0 }\n"
    )
    (tmp_path / "e2e.py").write_text(E2E)
    env = {"PYTHONPATH": f"{tmp_path}:{ROOT}", "PATH": "/usr/bin:/bin", "HOME": str(tmp_path),
           "STUDY_PLUGINS": "colplug"}  # fmt: skip
    r = subprocess.run([sys.executable, str(tmp_path / "e2e.py"), str(tmp_path)], capture_output=True, text=True,
                       env=env, cwd=tmp_path, timeout=600)  # fmt: skip
    assert r.returncode == 0 and "ok" in r.stdout, r.stdout[-2000:] + r.stderr[-3000:]
    with pytest.raises(StudyError, match="'above_fraction' is not a declared column"):
        load_check(tmp_path / "check.toml")  # this process never loaded the plug-in


def test_an_undeclared_column_from_a_producer_is_one_line(tmp_path):
    (tmp_path / "badplug.py").write_text(
        "from study.measure.case import producer\n@producer\ndef f(ctx):\n    return {'mystery': 1.0}\n"
    )
    (tmp_path / "s.toml").write_text(scene_toml(small_scene_dict()))
    env = {"PYTHONPATH": f"{tmp_path}:{ROOT}", "PATH": "/usr/bin:/bin", "HOME": str(tmp_path)}
    cli = [sys.executable, "-m", "study.cli", "--plugin", "badplug", "run", str(tmp_path / "s.toml"), "-m",
           "classical", "--out", str(tmp_path / "o"), "--cache", str(tmp_path / "c")]  # fmt: skip
    r = subprocess.run(cli, capture_output=True, text=True, env=env, cwd=tmp_path, timeout=600)
    assert r.returncode == 2 and "badplug.f writes the column 'mystery', which is not declared" in r.stderr, (
        r.stderr[-2000:]
    )


@pytest.mark.parametrize("name", ["wrong_fraction_texel_lo", "dec_search_hi"])
def test_an_interval_column_resolves_to_its_column(name):
    assert columns.declared(name) is columns.declared(name.rsplit("_", 1)[0])


def test_a_producer_declaring_a_built_in_column_is_one_line_at_registration():
    """A plug-in producer that declares ``wrong_fraction`` fails when it registers, naming itself and the built-in
    writer; on main it registered and replaced the outcome classes' value in every row."""
    from study.errors import StudyError
    from study.measure import case, producers  # noqa: F401 - case registers the built-in groups

    def scratch(ctx):
        return {"wrong_fraction": 0.0}

    before, writers = list(producers.PRODUCERS), dict(producers.WRITERS)
    with pytest.raises(StudyError) as err:
        producers.producer(columns=("wrong_fraction",))(scratch)
    line = str(err.value)
    assert "\n" not in line and "scratch writes the column 'wrong_fraction'" in line, line
    assert "which the built-in group study.measure.groups.outcome_classes already writes" in line, line
    assert producers.PRODUCERS == before and producers.WRITERS == writers


def test_two_producers_declaring_one_column_is_one_line_at_registration():
    from study.columns import TableColumn, declare
    from study.errors import StudyError
    from study.measure import producers

    def first(ctx):
        return {"twice_fraction": 0.0}

    def second(ctx):
        return {"twice_fraction": 1.0}

    if columns.declared("twice_fraction") is None:
        declare(TableColumn("twice_fraction", "fraction"))
    try:
        producers.producer(columns=["twice_fraction"])(first)
        with pytest.raises(
            StudyError, match=r"second writes the column 'twice_fraction', which .*first already"
        ):
            producers.producer(columns=["twice_fraction"])(second)
    finally:
        producers.PRODUCERS[:] = [p for p in producers.PRODUCERS if p is not first]
        producers.WRITERS.pop("twice_fraction", None)


def test_a_bare_producer_writing_a_built_in_column_is_one_line(tmp_path):
    """The old ``@producer`` shape (no declared columns) is checked when it first writes: exit 2, one line."""
    (tmp_path / "clash.py").write_text(
        "from study.measure.case import producer\n@producer\ndef f(ctx):\n    return {'wrong_fraction': 0.0}\n"
    )
    (tmp_path / "s.toml").write_text(scene_toml(small_scene_dict()))
    env = {"PYTHONPATH": f"{tmp_path}:{ROOT}", "PATH": "/usr/bin:/bin", "HOME": str(tmp_path)}
    cli = [sys.executable, "-m", "study.cli", "--plugin", "clash", "run", str(tmp_path / "s.toml"), "-m",
           "classical", "--out", str(tmp_path / "o"), "--cache", str(tmp_path / "c")]  # fmt: skip
    r = subprocess.run(cli, capture_output=True, text=True, env=env, cwd=tmp_path, timeout=600)
    assert (
        r.returncode == 2
        and "clash.f writes the column 'wrong_fraction', which the built-in group study.measure.groups.outcome_classes"
        in r.stderr
    ), r.stderr[-2000:]


def test_the_hand_lists_read_the_table():
    """The report's tables, the plots' metrics, the pareto axis and the convergence panels are views of the declared
    table: their columns and labels come from the rows (one axis label per column, as the row spells it)."""
    from study.outputs import convergence, plots
    from study.report import pareto, report

    assert set(report.VIEWS) <= set(columns.ORDER) and columns.view("decomposition")[0] == "dec_total"
    assert columns.view("summary")[:3] == [
        "wrong_fraction",
        "wrong_fraction_visible",
        "wrong_fraction_hidden",
    ]
    for view in ("summary", "decomposition", "comparison", "plots", "pareto", "convergence", "run", "figure"):
        assert all(view in c.views for c in columns.in_view(view)), view
    assert plots.METRICS["wrong_fraction"] == (columns.axis("wrong_fraction"), 1e-4)
    assert pareto.ERRORS["wrong_fraction_1cm"].startswith(columns.axis("wrong_fraction_1cm"))
    assert (
        dict((c, a) for c, a, _ in convergence.PANELS)["angle_p95_deg"] == plots.METRICS["angle_p95_deg"][0]
    )
    assert convergence.CURVE_COLUMNS == tuple(columns.view("curves"))
    assert all(columns.declared(c) for c in convergence.CURVE_COLUMNS)  # _lo/_hi through their column
    drawn = [*plots.METRICS, *pareto.ERRORS, *(c for c, _, _ in convergence.PANELS)]
    assert all(columns.declared(c).axis for c in drawn), [c for c in drawn if not columns.declared(c).axis]


def test_the_other_tables_are_declared_the_same_way():
    """The bench's, its floors', the projection's, the caustics' and the power table's columns are rows of declared
    tables (study/column_tables.py), read by the modules that write them."""
    from study.bench import carry, output
    from study.report import power
    from study.report.kinds import caustics

    assert output.BENCH_COLS == columns.table_columns("bench") and output.FLOOR_COLS == columns.table_columns(
        "bench_floors"
    )
    assert output.HEADLINE_COLS == columns.table_columns("bench", "headline") and set(
        output.HEADLINE_COLS
    ) < set(output.BENCH_COLS)
    assert carry.PROJECTION_COLS == columns.table_columns(
        "projection"
    ) and power.POWER_COLUMNS == columns.table_columns("power")
    assert caustics.CAUSTIC_COLS == columns.table_columns("caustics", "report")
    assert "energy_ratio" in caustics.PRINTED and "energy_ratio" not in caustics.CAUSTIC_COLS
    with pytest.raises(KeyError, match="no declared table 'nope'"):
        columns.table_columns("nope")


def test_a_view_naming_an_undeclared_column_fails_at_import(tmp_path):
    src = (ROOT / "study" / "columns.py").read_text()
    bad = src.replace('"plots": ["wrong_fraction",', '"plots": ["no_such_column", "wrong_fraction",')
    assert bad != src
    (tmp_path / "cols.py").write_text(bad)
    r = subprocess.run([sys.executable, "-c", "import cols"], capture_output=True, text=True, cwd=tmp_path,
                       env={"PYTHONPATH": str(ROOT), "PATH": "/usr/bin:/bin"})  # fmt: skip
    assert r.returncode != 0 and "views name undeclared columns" in r.stderr and "no_such_column" in r.stderr


def test_each_built_in_group_writes_what_it_declares():
    """The built-in groups are producers: on a case's traces (a method with flags, the references) each writes
    only columns it declares, every declared column reaches a row, no two groups declare one name, and every built-in
    column of the table is one group's."""
    from study.harness.config import expand_methods
    from study.measure import producers
    from study.measure.case import run_case
    from study.scene import scene_from_dict

    seen = {}

    def keep(ctx):
        seen[ctx.label] = ctx
        return {}

    producers.PRODUCERS.append(keep)
    try:
        sc = scene_from_dict(small_scene_dict(), source="s.toml")
        rows = run_case(
            sc, expand_methods(["classical", "probe_blend"], source="x")
        ).rows  # a figure's: intervals
    finally:
        producers.PRODUCERS.remove(keep)
    groups = producers.GROUPS + producers.AFTER
    declared = [c for g in groups for c in g.columns]
    assert len(declared) == len(set(declared)) and all(columns.declared(c) for c in declared)
    assert set(declared) - {"n_blocks", "object_alpha"} <= {
        k for r in rows for k in r
    }  # old tables; rough objects
    assert columns.BUILTIN - set(declared) == {
        "surface_mismatch"
    }  # every other built-in column has one group;
    # surface_mismatch is marked by study.api on rows scored with --allow-mismatch
    for ctx in seen.values():
        for g in groups:
            if g.columns:
                assert set(g(ctx)) <= set(g.columns), g.__name__


def test_a_registered_producer_changes_the_case_key(tmp_path, monkeypatch):
    """A case cached without a plug-in's column is not resumed once the plug-in is loaded (its rows would lack the
    column): the producer's code is part of every case's key, and editing its file changes the key again."""
    import importlib

    from study.harness.config import expand_methods
    from study.harness.sweep import case_code
    from study.measure import producers

    (tmp_path / "keyplug.py").write_text("def f(ctx):\n    return {}\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    methods = expand_methods(["classical"], source="x")
    before = case_code(methods)
    mod = importlib.import_module("keyplug")
    producers.PRODUCERS.append(mod.f)
    try:
        with_plugin = case_code(methods)
        (tmp_path / "keyplug.py").write_text("def f(ctx):\n    return {}  # edited\n")
        assert before != with_plugin != case_code(methods)
    finally:
        producers.PRODUCERS.remove(mod.f)
        sys.modules.pop("keyplug", None)
    assert case_code(methods) == before
