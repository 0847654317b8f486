"""`study check` fails, naming the metric, on a planted regression (the localized method forced to fewer
iterations); that it passes on unmodified code is what `.ci/run` checks, once. `study report` builds from results
only."""

import pytest
from typer.testing import CliRunner

from study.cli import app
from study.methods.localized import Localized
from study.outputs.check import Tolerance, compare

runner = CliRunner()


@pytest.fixture(scope="module")
def cache(tmp_path_factory):
    return tmp_path_factory.mktemp("check-cache")


@pytest.mark.slow
def test_planted_regression_fails_naming_the_metric(cache, monkeypatch):
    original = Localized.localize

    def fewer_iterations(self, B, env, x, R):
        return original(Localized(iterations=self.params.iterations // 4), B, env, x, R)

    monkeypatch.setattr(Localized, "localize", fewer_iterations)
    res = runner.invoke(app, ["check", "--cache", str(cache)])
    assert res.exit_code == 1, res.output
    out = res.output.replace("\n", " ")
    assert "regression: angle_median_deg of localized(iterations=10)" in out
    assert "tolerance ±" in out and "check failed" in out


def test_compare_tolerances():
    base = [{"case": "c0", "label": "m", "x": 1.0}]
    tol = {"x": Tolerance(abs=0.1, rel=0.1)}
    assert compare([{"case": "c0", "label": "m", "x": 1.19}], base, tol) == []
    fails = compare([{"case": "c0", "label": "m", "x": 1.21}], base, tol)
    assert len(fails) == 1 and "x of m in c0 moved from 1 to 1.21" in fails[0].message
    assert "not in the baseline" in compare([{"case": "c1", "label": "m", "x": 1.0}], base, tol)[0].message


def test_compare_within_the_baseline_interval():
    """A move beyond the fixed tolerance but inside the baseline's own 95 % interval (sampling noise of its rays)
    passes; one outside both fails and names the interval; ``interval = false`` keeps the fixed tolerance alone."""
    base = [{"case": "c0", "label": "m", "x": 0.10, "x_lo": 0.07, "x_hi": 0.14}]
    tol = {"x": Tolerance(abs=0.001, rel=0.0)}
    assert compare([{"case": "c0", "label": "m", "x": 0.13}], base, tol) == []
    fails = compare([{"case": "c0", "label": "m", "x": 0.16}], base, tol)
    assert len(fails) == 1 and "baseline interval [0.07, 0.14]" in fails[0].message
    strict = {"x": Tolerance(abs=0.001, rel=0.0, interval=False)}
    assert len(compare([{"case": "c0", "label": "m", "x": 0.13}], base, strict)) == 1
    no_ci = [{"case": "c0", "label": "m", "x": 0.10, "x_lo": float("nan"), "x_hi": 0.14}]
    assert len(compare([{"case": "c0", "label": "m", "x": 0.13}], no_ci, tol)) == 1


def test_bad_check_file(tmp_path):
    p = tmp_path / "c.toml"
    p.write_text(
        'sweep = "x.toml"\nbaseline = "b"\nclaims = ["nope"]\n[tolerance]\nx = { abs = 0, rel = 0 }\n'
    )
    res = runner.invoke(app, ["check", "--config", str(p)])
    assert res.exit_code == 2 and "claims[0]: unknown claim 'nope'; allowed: beats-classical" in res.output


def test_report_from_results(tmp_path):
    import shutil

    shutil.copytree("reports/baseline", tmp_path / "sweep-check")
    res = runner.invoke(app, ["report", "--reports", str(tmp_path)])
    assert res.exit_code == 0, res.output
    text = (tmp_path / "index.md").read_text()
    assert "| Localized lookup is more accurate than classical" in text and "| ✓ |" in text
    assert "sweep-check/results.csv" in text
