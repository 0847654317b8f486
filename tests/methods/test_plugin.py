"""Extension by one file: a method registered in a throwaway module outside the package (``--plugin``) appears in
a sweep table, a figure table, ``study check``, the report's method comparison and ``study bench`` rows, with no
file of study edited. Its numbers are checked too: it is classical environment mapping under another name, so its
angular errors equal classical's."""

import os
import sys
import textwrap

import pytest
from typer.testing import CliRunner

from study import methods
from study.cli import app
from study.tables import read_csv
from tests.conftest import scene_toml, small_scene_dict

PLUGIN = textwrap.dedent('''
    """A throwaway method: look up the ray direction (classical environment mapping, under another name)."""
    from study.methods import Localization, Method, register


    @register
    class Throwaway(Method):
        name = "throwaway_probe"

        def localize(self, B, env, x, R):
            return Localization(l=R * 1.0, valid=B.isfinite(B.length(R)))

        def lookups_per_ray(self):
            return 1
''')


@pytest.fixture
def plugin(tmp_path, monkeypatch):
    (tmp_path / "throwaway_plugin.py").write_text(PLUGIN)
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.delenv(methods.PLUGIN_ENV, raising=False)
    yield "throwaway_plugin"
    methods.REGISTRY.pop("throwaway_probe", None)
    sys.modules.pop("throwaway_plugin", None)
    os.environ.pop(methods.PLUGIN_ENV, None)


@pytest.mark.slow
def test_plugin_method_reaches_sweep_figure_check_report_bench(tmp_path, plugin):
    assert "throwaway_probe" not in methods.names()
    scene = small_scene_dict()
    scene["render"]["cube_res"] = 16
    (tmp_path / "scene.toml").write_text(scene_toml(scene))
    (tmp_path / "sweep.toml").write_text(
        'scene = "scene.toml"\n\n[axes]\n"object.center" = [[0.6, 1.2, 0.3]]\n'
    )
    (tmp_path / "fig.toml").write_text(
        'scene = "scene.toml"\npositions = [[0.6, 1.2, 0.3]]\ngrid = ["classical", "throwaway_probe"]\n'
    )
    (tmp_path / "check.toml").write_text(
        'sweep = "sweep.toml"\nbaseline = "baseline"\nseeds = [0, 1, 2]\n\n[tolerance]\n'
        "angle_median_deg = { abs = 1e-6, rel = 0.0 }\n"
    )
    run = CliRunner().invoke
    common = ["--cache", str(tmp_path / "cache")]
    reports = tmp_path / "reports"

    res = run(
        app,
        [
            "--plugin",
            plugin,
            "sweep",
            str(tmp_path / "sweep.toml"),
            "--out",
            str(reports / "sweep-x"),
            *common,
        ],
    )
    assert res.exit_code == 0, res.output
    rows = read_csv(reports / "sweep-x" / "results.csv")
    by = {r["method"]: r for r in rows}
    assert set(by) == {
        "oracle_map",
        "truth_at_hit",
        *(m.name for m in methods.all_methods()),
    }  # every registered mirror method ("all"), the plugin's too
    assert by["throwaway_probe"]["angle_median_deg"] == pytest.approx(by["classical"]["angle_median_deg"])
    assert by["throwaway_probe"]["angle_median_deg"] > 1.0  # off the reference point: clearly wrong

    res = run(
        app,
        [
            "--plugin",
            plugin,
            "figure",
            "fig4",
            "--config",
            str(tmp_path / "fig.toml"),
            "--out",
            str(reports / "fig4"),
            *common,
        ],
    )
    assert res.exit_code == 0, res.output
    assert "throwaway_probe" in {r["method"] for r in read_csv(reports / "fig4" / "metrics.csv")}

    res = run(
        app, ["--plugin", plugin, "check", "--config", str(tmp_path / "check.toml"), "--update", *common]
    )
    assert res.exit_code == 0, res.output
    assert "throwaway_probe" in {r["method"] for r in read_csv(tmp_path / "baseline" / "results.csv")}
    res = run(app, ["--plugin", plugin, "check", "--config", str(tmp_path / "check.toml"), *common])
    assert res.exit_code == 0 and "check passed" in res.output, res.output
    res = run(
        app,
        [
            "--plugin",
            plugin,
            "bench",
            "--out",
            str(tmp_path / "bench"),
            "--config",
            str(tmp_path / "fig.toml"),
            "--position",
            "0",
            "--scene-res",
            "16",
            "--rays",
            "512",
            "--cube-res",
            "16",
            "--repeats",
            "1",
            "--no-ladder",
            "--no-scaling",
            "--backends",
            "numpy",
            "--tag",
            "cpu",
        ],
    )
    assert res.exit_code == 0, res.output
    bench = [r for r in read_csv(tmp_path / "bench" / "bench-cpu.csv") if r["label"] == "throwaway_probe"]
    assert len(bench) == 4 and all(r["ms_per_call"] > 0 for r in bench)  # one row per ray batch (4 batches)
    # without the plugin, its baseline rows are missing from the results: check says so and fails
    methods.REGISTRY.pop("throwaway_probe")
    os.environ.pop(methods.PLUGIN_ENV, None)
    res = run(app, ["check", "--config", str(tmp_path / "check.toml"), *common])
    assert res.exit_code == 1 and "throwaway_probe" in res.output, res.output

    res = run(app, ["report", "--reports", str(reports)])
    assert res.exit_code == 0, res.output
    index = (reports / "index.md").read_text()
    # names are Markdown-escaped text in the tables (an underscore as \_)
    assert "| sweep-x | throwaway\\_probe |" in index and "| fig4 | throwaway\\_probe |" in index
