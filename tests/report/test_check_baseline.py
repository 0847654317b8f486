"""`study check` validates its baseline as a whole before anything runs (issue 51, break 2): a spread that its own
seeds could not have given (one row's sd of 1e6 or 1e308, a mean of 1e-300 with an sd of 1) is bad input (exit 2,
one line naming the file, the row and the column), never a pass of a 10× regression through the pooled sd nor an
OverflowError after the sweep. And the backend-sensitive columns (issue 55): marked in the column table, compared
with a stated floor when the check runs on another backend than its baseline's, ranked by nothing."""

import math
from pathlib import Path

import pytest
from conftest import run_cli
from test_check import _planted_baseline, _with_cell

from study import columns
from study.report.check import (
    BACKEND_FLOOR_TEXELS,
    POOLED_RATIO_MAX,
    Tolerance,
    backend_floor,
    compare,
    pooled_relative_sd,
)

#: tampered cells of the committed spread table → what the one line must say (line 6: linear_secant in c0000)
TAMPERED = {
    "rmse_mitsuba_sd 1e6": (
        _with_cell("rmse_mitsuba_sd", "1000000.0"),
        "line 6, column 'rmse_mitsuba_sd' (case 'c0000', label 'linear_secant(steps_per_texel=1.0)') holds 1e+06, "
        "more than 5 seeds of a metric ≥ 0",
    ),
    "mitsuba_noise_frame_sd 1e308": (
        _with_cell("mitsuba_noise_frame_sd", "1e308", line=9),
        "line 9, column 'mitsuba_noise_frame_sd'",
    ),
    "psnr_mitsuba_sd 1e6 (a metric of any sign)": (
        _with_cell("psnr_mitsuba_sd", "1000000.0"),
        "line 6, column 'psnr_mitsuba_sd' (case 'c0000', label 'linear_secant(steps_per_texel=1.0)') holds 1e+06, "
        "whose sd / |mean|",
    ),
    "rmse_oracle mean 1e-300, sd 1": (
        lambda h, rows: _with_cell("rmse_oracle_sd", "1.0")(
            h, _rows(_with_cell("rmse_oracle", "1e-300")(h, rows))
        ),
        "line 6, column 'rmse_oracle_sd'",
    ),
    "psnr_mitsuba mean 1e-300, sd 1": (
        lambda h, rows: _with_cell("psnr_mitsuba_sd", "1.0")(
            h, _rows(_with_cell("psnr_mitsuba", "1e-300")(h, rows))
        ),
        "line 6, column 'psnr_mitsuba_sd'",
    ),
    "a negative RMSE": (
        _with_cell("rmse_mitsuba", "-3.0"),
        "line 6, column 'rmse_mitsuba' (case 'c0000', label 'linear_secant(steps_per_texel=1.0)') holds -3; "
        "rmse_mitsuba (linear RGB) is never negative",
    ),
    "seeds not a count": (_with_cell("seeds", "1.5"), "line 6, column 'seeds'"),
}


def _rows(data: bytes) -> list[list[str]]:
    import csv
    import io

    return list(csv.reader(io.StringIO(data.decode())))[1:]


@pytest.mark.parametrize("case", TAMPERED)
def test_a_spread_its_seeds_could_not_give_is_refused_before_the_sweep(case, tmp_path, monkeypatch):
    edit, expected = TAMPERED[case]
    config, baseline = _planted_baseline(tmp_path, edit)
    monkeypatch.setattr("study.report.check.run_sweep", lambda *a, **k: pytest.fail("the sweep ran"))
    res = run_cli("check", "--config", config)
    assert res.exit_code == 2, res.output
    line = " ".join(res.output.split())
    assert line.startswith(f"error: {baseline}: malformed baseline: "), line
    assert expected in line, line


def _base(n=20, rel=0.1):
    """n rows of a metric ≥ 0 with means 1..n and a relative sd of ``rel`` each (5 seeds)."""
    return [
        {
            "case": f"c{i}",
            "label": "m",
            "seeds": 5.0,
            "rmse_mitsuba": float(i + 1),
            "rmse_mitsuba_sd": rel * (i + 1),
        }
        for i in range(n)
    ]


def test_one_large_spread_does_not_widen_every_row():
    """The pooled sd is robust: one row's sd (here 1e6 × its mean, which validation refuses; compare() called
    directly) lifts it to at most POOLED_RATIO_MAX × the rows' median, so a 10× regression of another row
    fails; before, the root mean square carried 1e6 / √20 to every row."""
    base = _base()
    base[0]["rmse_mitsuba_sd"] = 1e6
    assert pooled_relative_sd(base, "rmse_mitsuba") == pytest.approx(POOLED_RATIO_MAX * 0.1)
    new = [{**r, "rmse_mitsuba": r["rmse_mitsuba"] * (10 if i == 5 else 1)} for i, r in enumerate(base)]
    (fail,) = compare(new, base, {"rmse_mitsuba": Tolerance(abs=0, rel=0)})
    assert "rmse_mitsuba of m in c5 moved from 6 to 60" in fail.message
    base[0]["rmse_mitsuba"], base[0]["rmse_mitsuba_sd"] = 1e-300, 1.0  # 1e300 relative: no OverflowError
    assert math.isfinite(pooled_relative_sd(base, "rmse_mitsuba"))


def test_the_pooled_sd_of_a_sound_baseline_is_the_root_mean_square():
    """The cap changes nothing where the rows' spreads are alike (the committed baseline's: at most 6.2 ×)."""
    base = _base()
    base[3]["rmse_mitsuba_sd"] = 0.6 * 4.0  # 6 × the others' relative sd
    rms = math.sqrt((19 * 0.1**2 + 0.6**2) / 20)
    assert pooled_relative_sd(base, "rmse_mitsuba") == pytest.approx(rms)


def test_a_signed_metric_pools_its_sd_as_it_is():
    """pool = "absolute" (the radiance bias: signed, near 0): the rows' sds themselves, not over |mean|."""
    base = [{"case": f"c{i}", "label": "m", "x": m, "x_sd": 0.01} for i, m in enumerate((1e-6, -0.02, 0.03))]
    assert pooled_relative_sd(base, "x", "absolute") == pytest.approx(0.01)
    tol = {"x": Tolerance(abs=0, rel=0, pool="absolute")}
    assert compare([{"case": "c0", "label": "m", "x": 0.049}], base[:1], tol) == []
    assert compare([{"case": "c0", "label": "m", "x": 0.051}], base[:1], tol)


# ---------------------------------------------------------------------------------------------- issue 55, item 3
def test_backend_sensitive_columns_are_marked_in_the_table():
    for name in ("angle_median_deg", "angle_p95_deg", "dist_median", "dist_p95", "lookups_per_ray"):
        assert columns.declared(name).backend_sensitive, name
    for name in ("wrong_fraction", "rmse_truth_debiased", "relmse_truth_exposed", "radiance_bias_truth"):
        assert not columns.declared(name).backend_sensitive, name


def test_a_backend_sensitive_column_gets_its_stated_floor_on_another_backend():
    """angle_median_deg at cube_res 64: the floor is 2 % of the texel's angle, 0.02 × degrees(2 / 64) = 0.0358°,
    on another backend only; the check file's floor (5e-5°) on the baseline's own."""
    texel = 2 / 64 * 180 / math.pi
    assert backend_floor("angle_median_deg", {"cube_res": 64}) == pytest.approx(BACKEND_FLOOR_TEXELS * texel)
    assert backend_floor("dist_median", {"cube_res": 64}) == pytest.approx(BACKEND_FLOOR_TEXELS * 2 / 64)
    assert backend_floor("wrong_fraction", {"cube_res": 64}) == 0.0
    base = [{"case": "c0", "label": "m", "angle_median_deg": 0.2}]
    tol = {"angle_median_deg": Tolerance(abs=5e-5, rel=0.0)}
    moved = [{"case": "c0", "label": "m", "cube_res": 64, "angle_median_deg": 0.2 + 0.03}]
    assert compare(moved, base, tol, other_backend=True) == []
    (fail,) = compare(moved, base, tol)
    assert "tolerance ±5e-05, its floor" in fail.message
    far = [{**moved[0], "angle_median_deg": 0.2 + 0.04}]
    assert compare(far, base, tol, other_backend=True)


def test_no_ranking_on_a_backend_sensitive_column():
    from study.report.summary import ranking

    tab = [
        {"case": f"c{i}", "label": lab, "wrong_fraction": w, "angle_median_deg": w, "lookups_per_ray": 1.0}
        for i in range(3)
        for lab, w in (("a", 0.1), ("b", 0.2))
    ]
    assert [r["label"] for r in ranking(tab, "wrong_fraction")] == ["a", "b"]
    assert ranking(tab, "angle_median_deg") == []


def test_the_whole_baseline_set_is_checked_before_the_sweep(tmp_path, monkeypatch):
    """Beside a sound spread table: metadata.json and the replayed seed's results.csv, each refused in one line
    naming its file (and the row and column of a bad cell) before the sweep runs."""
    import json
    import shutil

    config, _ = _planted_baseline(tmp_path, lambda h, rows: _csv_bytes([h, *rows]))
    monkeypatch.setattr("study.report.check.run_sweep", lambda *a, **k: pytest.fail("the sweep ran"))

    def refused(expected: str) -> None:
        res = run_cli("check", "--config", config)
        assert res.exit_code == 2, res.output
        assert expected in " ".join(res.output.split()), res.output

    refused(f"error: {tmp_path / 'metadata.json'}: missing; re-create the baseline")
    (tmp_path / "metadata.json").write_text(json.dumps({"seeds": "0-4"}))
    refused(f"error: {tmp_path / 'metadata.json'}: 'seeds' is 0-4, expected the list of seeds")
    shutil.copy("reports/baseline/metadata.json", tmp_path / "metadata.json")
    refused(f"error: {tmp_path / 'results.csv'}: no replay table")
    text = Path("reports/baseline/results.csv").read_text().splitlines()
    header = text[0].split(",")
    cells = text[3].split(",")
    cells[header.index("rmse_mitsuba")] = "-3.0"
    (tmp_path / "results.csv").write_text("\n".join([text[0], *text[1:3], ",".join(cells), *text[4:]]) + "\n")
    refused(f"error: {tmp_path / 'results.csv'}: malformed baseline: line 4, column 'rmse_mitsuba'")


def _csv_bytes(rows) -> bytes:
    import csv
    import io

    buf = io.StringIO()
    csv.writer(buf, lineterminator="\n").writerows(rows)
    return buf.getvalue().encode()


def test_run_check_replays_seed_0_and_floors_on_another_backend(monkeypatch):
    """run_check with the sweep stood in by the baseline's own seed-0 table, one angle moved by 0.01° (below the
    stated floor of 2 % of a 64² texel, 0.036°): on the baseline's backend (numpy) the replay sees it against
    the 5e-5° floor; on llvm (no replay: its floats differ) the backend-sensitive column passes within its
    stated floor."""
    from study.report import check
    from study.tables import read_csv

    rows = read_csv(Path("reports/baseline/results.csv"))
    target = next(r for r in rows if r["case"] == "c0000" and r["label"] == "localized(iterations=10)")
    target["angle_median_deg"] += 0.01
    meta = {"seed": 0, "methods": ["x"]}
    monkeypatch.setattr(check, "_run_at", lambda *a, **k: (rows, {"cases": 4, "seconds": 0.0}, meta))
    fails, lines = check.run_check("configs/check.toml", backend="numpy")
    assert [f.message.split(" (by")[0] for f in fails] == [
        f"angle_median_deg of localized(iterations=10) in c0000 moved from "
        f"{target['angle_median_deg'] - 0.01:.6g} (the baseline's) to {target['angle_median_deg']:.6g}"
    ]
    assert any("replayed against the baseline's seed 0" in ln for ln in lines), lines
    fails, lines = check.run_check("configs/check.toml", backend="llvm")
    assert fails == [], [f.message for f in fails]
    assert any("(llvm, not the baseline's numpy: within 5 sd" in ln for ln in lines), lines
    assert any("backend-sensitive columns at least their stated floor" in ln for ln in lines), lines
