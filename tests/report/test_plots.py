"""Plots that read well (study/outputs/plots.py): distinct styles for many series, nothing hidden below the log
axis, and the error-versus-cost plot's Pareto front against a brute-force one."""

import numpy as np

from study.outputs import plots
from study.tables import read_csv


def test_forty_series_never_share_colour_marker_and_line():
    styles = {tuple(plots.style(i).values()) for i in range(40)}
    assert len(styles) == 40
    assert len({plots.style(i)["color"] for i in range(60)}) == 60  # every series its own colour


def test_pareto_front_equals_brute_force():
    rng = np.random.default_rng(5)
    for _ in range(20):
        pts = [tuple(p) for p in rng.integers(0, 8, (12, 2)).astype(float)]
        front = set(plots.pareto_indices(pts))
        brute = {
            i
            for i, (c, e) in enumerate(pts)
            if not any((c2 <= c and e2 < e) or (c2 < c and e2 <= e) for c2, e2 in pts)
        }
        # ties: of equal points the front keeps one; every kept point is undominated, every undominated value kept
        assert front <= brute
        assert {pts[i] for i in front} == {pts[i] for i in brute}


def test_values_below_the_axis_are_marked_not_hidden(tmp_path):
    series = {"a": [(0, 0.0), (1, 1e-3), (2, 1e-2)], "b": [(0, 1e-9), (1, 1e-2), (2, np.nan)]}
    n = plots._plot(tmp_path / "x.png", series, xlabel="x", metric="angle_p95_deg", title="t")
    assert n == 2 and (tmp_path / "x.png").stat().st_size > 5000


def test_sweep_plots_write_knob_and_cost_plots_with_their_tables(tmp_path):
    rows = []
    for label, method, knob, cost, err in [
        ("loc(1)", "loc", 1, 4, 0.3),
        ("loc(3)", "loc", 3, 6, 0.05),
        ("loc(10)", "loc", 10, 13, 0.0),
        ("slow", "slow", np.nan, 800, 0.1),
    ]:
        rows.append(
            {
                "case": "c0",
                "method": method,
                "label": label,
                "family": method,
                "cube_res": 64,
                "knob": "iterations" if method == "loc" else "",
                "knob_value": float(knob),
                "lookups_per_ray": cost,
                "wrong_fraction": err,
                "angle_median_deg": err,
                "angle_p95_deg": err * 2,
                "displacement": 0.1,
            }
        )
    made = {p.name for p in plots.sweep_plots(rows, tmp_path)}
    assert {
        "wrong_fraction_vs_iterations.png",
        "wrong_fraction_vs_lookups.png",
        "angle_p95_deg_vs_lookups.png",
    } <= made
    cost = {r["method"]: r for r in read_csv(tmp_path / "wrong_fraction_vs_lookups.csv")}
    assert cost["loc(10)"]["pareto"] == "True" and cost["slow"]["pareto"] == "False"  # dearer and worse


def test_hidden_fraction_colour_bar_stays_inside_a_tall_figure():
    """The continuous hidden-fraction bar sits a fixed distance in inches under its panel, inside the figure
    (as a fraction of the height it fell off the bottom of fig5's 15-inch error grid)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    from study.outputs.figures import _hidden_legend

    for height in (4.0, 16.0):
        fig, axes = plt.subplots(6, 2, figsize=(5, height))
        fig.subplots_adjust(bottom=0.75 / height)
        im = axes[-1, -1].imshow(np.random.default_rng(0).random((8, 8)))
        _hidden_legend(fig, axes[-1, -1], False, im)
        cax = fig.axes[-1]
        y0 = cax.get_position().y0
        assert 0 < y0 < axes[-1, -1].get_position().y0, (height, y0)
        plt.close(fig)
