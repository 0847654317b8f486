"""The CLI end to end on a small Figure-4 config, and its error behaviour (one line, exit code 2)."""

import tomllib

import numpy as np
import pytest
from conftest import run_cli

from study.tables import read_csv

SMALL = """
positions = [[0.0, 1.5, 0.0], [0.8, 1.1, 0.5], [1.4, 0.7, 1.0]]
grid = ["classical", "localized(iterations=10)"]
outcome_panel = true

[scene]
room = {{ min = [-2.0, 0.0, -2.0], max = [2.0, 3.0, 2.0] }}
light = {{ position = [0.3, 2.6, -0.4], intensity = [7.0, 7.0, 7.0] }}
reference = {{ point = [0.0, 1.5, 0.0] }}
object = {{ center = [0.6, 1.2, 0.3], radius = 0.4, material = {{ type = "mirror" }} }}
camera = {{ eye = [-0.3, 1.7, -1.9], target = [0.6, 1.1, 0.6], fov = 75.0, width = 48, height = 48 }}
render = {{ cube_res = 64, cube_spp = 4, spp = 4, max_depth = 3, supersample = 1 }}

[[methods]]
name = "classical"

[[methods]]
name = "localized"
iterations = {iterations}
"""


@pytest.fixture(scope="module")
def fig4_small(tmp_path_factory):
    d = tmp_path_factory.mktemp("fig4")
    cfg = d / "small.toml"
    cfg.write_text(SMALL.format(iterations="[0, 1, 3, 10]"))
    res = run_cli(
        *["figure", "fig4", "--config", str(cfg), "--out", str(d / "out"), "--cache", str(d / "cache")]
    )
    assert res.exit_code == 0, res.output
    return d, read_csv(d / "out" / "metrics.csv")


def test_fig4_small_writes_grid_and_table(fig4_small):
    d, rows = fig4_small
    assert (d / "out" / "fig4.png").stat().st_size > 10_000
    assert len(rows) == 3 * 7  # 3 positions × (oracle_map + truth_at_hit + 5 methods)
    for col in (
        "case",
        "method",
        "knob",
        "knob_value",
        "angle_median_deg",
        "angle_p95_deg",
        "angle_max_deg",
        "dist_median",
        "rmse_oracle",
        "psnr_mitsuba",
        "ssim_mitsuba",
        "flip_mitsuba",
        "occluded_fraction",
    ):
        assert col in rows[0]


def test_fig4_small_outcome_columns(fig4_small):
    """Every row carries the outcome classes (study.measure.outcomes) right after dist_median; the oracle is
    correct on every ray; nothing is hidden in this convex room, so the hidden columns are empty (NaN)."""
    d, rows = fig4_small
    header = (d / "out" / "metrics.csv").read_text().splitlines()[0].split(",")
    outcome_cols = [
        "correct_fraction",
        "wrong_fraction",
        "wrong_depth_fraction",
        "wrong_surface_fraction",
        "no_hit_fraction",
        "wrong_fraction_visible",
        "wrong_fraction_hidden",
        "hidden_fraction",
        "dist_p50",
        "dist_p95",
        "dist_p99",
        "depth_error_p95",
        "angle_p95_visible_deg",
        "angle_p95_hidden_deg",
    ]
    i = header.index("dist_median")
    assert header[i + 1 : i + 1 + len(outcome_cols)] == outcome_cols
    for r in rows:
        fr = [
            r[c]
            for c in ("correct_fraction", "wrong_depth_fraction", "wrong_surface_fraction", "no_hit_fraction")
        ]
        assert sum(fr) == pytest.approx(1.0) and r["wrong_fraction"] == pytest.approx(
            1 - r["correct_fraction"]
        )
        assert r["hidden_fraction"] == 0 and np.isnan(r["wrong_fraction_hidden"])
        if r["method"] == "oracle_map":
            assert r["correct_fraction"] == 1.0 and r["dist_p95"] == 0.0


def test_fig4_small_paper_claims(fig4_small):
    """Off the reference point localized(10) beats classical, and its error falls 0 → 1 → 3 → 10 iterations;
    (Even at the reference point the rays start on the sphere, 0.4 m from it, so classical is not exact.)"""
    _, rows = fig4_small
    by = {(r["case"], r["label"]): r for r in rows}
    cases = sorted({r["case"] for r in rows})
    for c in cases:
        med = [by[(c, f"localized(iterations={n})")]["angle_median_deg"] for n in (0, 1, 3, 10)]
        assert med[3] < by[(c, "classical")]["angle_median_deg"]
        assert med[0] > med[1] > med[2] >= med[3], med


def test_fig4_warm_cache_gives_identical_table(fig4_small, tmp_path):
    d, rows = fig4_small
    res = run_cli(
        *[
            "figure",
            "fig4",
            "--config",
            str(d / "small.toml"),
            "--out",
            str(tmp_path),
            "--cache",
            str(d / "cache"),
        ],
    )
    assert res.exit_code == 0, res.output
    again = read_csv(tmp_path / "metrics.csv")
    skip = {"seconds", "case_seconds"}
    for a, b in zip(rows, again):
        for k in a:
            if k not in skip:
                assert a[k] == b[k] or (isinstance(a[k], float) and np.isnan(a[k]) and np.isnan(b[k])), k


@pytest.mark.parametrize(
    "args, words",
    [
        (["figure", "fig99"], "unknown figure 'fig99'; allowed: fig4, fig5"),
        (["figure", "fig4", "--config", "missing.toml"], "missing.toml: config file not found"),
        (
            ["figure", "fig4", "--backend", "vulkan"],
            "backend: unknown backend 'vulkan'; allowed: numpy, llvm, cuda",
        ),
    ],
)
def test_cli_errors_are_one_line(args, words):
    res = run_cli(*args)
    assert res.exit_code == 2
    assert words in res.output
    assert "Traceback" not in res.output


def test_bad_method_parameter_in_config(tmp_path):
    cfg = tmp_path / "bad.toml"
    cfg.write_text(SMALL.format(iterations="[-1]"))
    res = run_cli("figure", "fig4", "--config", str(cfg), "--out", str(tmp_path / "o"))
    assert res.exit_code == 2
    assert "bad.toml: methods[1].iterations" in res.output.replace("\n", ""), res.output


def test_shipped_fig4_config_is_valid():
    from study.harness.config import load_figure_config

    cfg, scene, methods = load_figure_config("configs/fig4.toml")
    assert len(cfg.positions) >= 3 and scene.reference.point == (0.0, 1.5, 0.0)
    assert {m.label for m in methods} >= {"classical", "localized(iterations=10)"}
    assert tomllib.loads(open("configs/fig4.toml").read())["grid"]


def test_shipped_fig6_config_is_valid():
    """fig6 lists cases (override tables) rather than positions: glass sphere single and double, meshes."""
    from study.harness.config import load_figure_config

    cfg, scene, methods = load_figure_config("configs/fig6.toml")
    names = [n for n, _, _ in cfg.case_list()]
    assert {"glass-sphere-single", "glass-sphere-double"} <= set(names)
    assert any("torus" in n or "knot" in n or "blob" in n for n in names)
    assert {m.label for m in methods} >= {"classical", "localized(iterations=10)"}


def test_figure_with_cases_runs_and_names_rows(tmp_path):
    """A config with two [[cases]] (glass sphere single, mirror torus) writes one CSV row per case × method,
    case ids taken from the case names; giving both positions and cases is an error."""
    cfg = tmp_path / "cases.toml"
    base = SMALL.format(iterations="[10]").replace(
        "positions = [[0.0, 1.5, 0.0], [0.8, 1.1, 0.5], [1.4, 0.7, 1.0]]\n", ""
    )
    base = base.replace("width = 48, height = 48", "width = 24, height = 24")
    cases = (
        '\n[[cases]]\nname = "glass"\n"object.material" = { type = "dielectric", ior = 1.5 }\n'
        '"render.refraction" = "single"\n\n[[cases]]\nname = "torus"\n"object.shape" = "torus"\n'
    )
    cfg.write_text(base + cases)
    res = run_cli(
        *[
            "figure",
            "fig6",
            "--config",
            str(cfg),
            "--out",
            str(tmp_path / "o"),
            "--cache",
            str(tmp_path / "cache"),
        ],
    )
    assert res.exit_code == 0, res.output
    rows = read_csv(tmp_path / "o" / "metrics.csv")
    assert [r["case"] for r in rows[::4]] == ["fig6-glass", "fig6-torus"] and len(
        rows
    ) == 8  # 2 references + 2 methods
    assert (tmp_path / "o" / "fig6.png").exists()
    cfg.write_text("positions = [[0.0, 1.5, 0.0]]\n" + base + cases)
    res = run_cli("figure", "fig6", "--config", str(cfg), "--out", str(tmp_path / "o2"))
    assert res.exit_code == 2 and "either positions or cases" in res.output


def test_metadata_names_the_command_however_study_was_started():
    """The study script, ``python -m study.cli`` (also under cProfile) give the command; pytest's own __main__
    (``python -m pytest``) does not pass for study."""
    from study.harness.runner import _is_study_cli

    assert _is_study_cli("/usr/bin/study") and _is_study_cli("/repo/study/cli/__main__.py")
    assert not _is_study_cli("/venv/lib/python3.11/site-packages/pytest/__main__.py")
    assert not _is_study_cli("/venv/bin/pytest")
