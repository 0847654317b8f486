"""The exact row never ranks below a stand-in on a column that measures the method (issue 54, item 5), in the
L-shaped room in millimetres 10⁵ mm from the origin (measured in its moved frame, :mod:`study.scene.frame`), lit
by the point light alone with one bounce (``render.max_depth = 2``: the radiance along a ray exact, not path
traced) and path traced with three bounces (``max_depth = 4``). ``traced`` (the exact query) shades its hits with
truth_at_hit's own samples (:func:`study.measure.inputs.exact_shading`), so its image is the truth's: first or tied
on every column against the truth or the exact hits, at both depths. Before that change it was shaded with a
seed of its own, and at ``max_depth = 4`` its path-tracing noise ranked it below localized and proxy_box on
rmse_truth (0.049 against 0.040 and 0.043): the ``[4-numpy]`` case failed.

Columns a stand-in can beat it on, by what they measure, not by the method: ``*_mitsuba`` against Mitsuba's render
with the object (light no method models), ``seconds`` the cost. The exact row leaves out (NaN) the columns taken
against the cube map at the exact hit, ``*_oracle`` and the split ``dec_*``: it reads no cube map, and with its
image the truth's they would measure the map's own error (``Method.reads_views``).

Where the exact row is not the exact image (a glass torus's rays through its own distance map, a rough object's K
lobe rays), a stand-in can beat it on a column of the method: the run's notes say so for that row, naming the
columns and the cause (:mod:`study.measure.exact_rows`), and the summary's ranking leaves it out; with the exact
exit the glass torus's traced is the truth's image again and nothing is said."""

import math
from pathlib import Path

import pytest

import study
from study import columns

ROOM = Path(__file__).resolve().parents[2] / "scenes" / "rooms" / "l_room.ply"
DIRECT = {
    "camera.width": 48,
    "camera.height": 48,
    "render.cube_res": 64,
    "render.spp": 4,
    "render.cube_spp": 4,
    "render.supersample": 1,
    "render.max_depth": 2,
}
REFERENCES = ("oracle_map", "truth_at_hit", "mitsuba")


def not_of_the_method(col: str) -> bool:
    return "oracle" in col or "mitsuba" in col or col.startswith("dec_search") or col == "seconds"


@pytest.mark.parametrize(("max_depth", "backend"), [(2, "numpy"), (4, "numpy"), (4, "llvm")])
def test_the_exact_row_ranks_first_on_every_column_that_measures_the_method(max_depth, backend):
    env = {"type": "mesh", "file": str(ROOM), "scale": 1e-3, "translate": [1e5] * 3}
    res = study.evaluate(
        {"environment": env},
        ["traced", "classical", "localized", "proxy_box"],
        cache=None,
        overrides={**DIRECT, "render.max_depth": max_depth},
        backend=backend,  # Dr.Jit's float32 rays (as on CUDA) are still the truth's rays
    )
    assert "rescaled by 1000" in res.scene.units_line()
    t = res.table.set_index("label")
    stand = [lab for lab in t.index if lab not in (*REFERENCES, "traced")]
    assert len(stand) == 3
    checked = []
    for col in t.columns:
        d = columns.declared(col)
        if d is None or d.lower_is_better is None or not_of_the_method(col):
            continue
        v = float(t.loc["traced", col])
        if math.isnan(v):  # left out of the exact row (the oracle's and the split's columns: asserted below)
            continue
        others = t.loc[stand, col].astype(float)
        tie = 1e-6 + 1e-6 * abs(v) if math.isfinite(v) else 0.0  # psnr_truth: +inf where the images are equal
        beaten = others[others < v - tie] if d.lower_is_better else others[others > v + tie]
        assert beaten.empty, (col, v, beaten.to_dict())
        checked.append(col)
    for col in (
        "wrong_fraction",
        "rmse_truth",
        "relmse_truth_exposed",
        "flip_truth",
        "ssim_truth",
        "psnr_truth",
    ):
        assert col in checked, col
    assert float(t.loc["traced", "rmse_truth"]) < 1e-6 < 1e-3 < float(t.loc["classical", "rmse_truth"])
    from study.measure import exact_rows

    assert (
        exact_rows.outranked(res.table.to_dict("records")) == {}
    )  # so the run says nothing of the exact row
    assert not [ln for ln in res.notes() if "not the exact image" in ln]
    for col in ("rmse_oracle", "flip_oracle", "dec_search", "dec_total", "dec_residual"):
        assert math.isnan(float(t.loc["traced", col])), col  # not of the method: left out of its row
        assert t.loc[stand, col].astype(float).notna().all(), col  # the stand-ins read the map: measured
    for col in ("rmse_mitsuba", "truth_noise_rmse"):  # against Mitsuba: the truth's own values
        assert float(t.loc["traced", col]) == pytest.approx(float(t.loc["truth_at_hit", col]), rel=1e-5), col


@pytest.mark.parametrize("col", ["rmse_oracle", "dec_search", "rmse_mitsuba", "seconds"])
def test_the_columns_a_stand_in_may_win_are_not_of_the_method(col):
    assert not_of_the_method(col)
    assert not not_of_the_method("rmse_truth")


GLASS_TORUS = {"object.shape": "torus", "object.material": {"type": "dielectric", "ior": 1.5}}
NOT_EXACT = [
    # a glass torus: its far side from its own distance map (the default for meshes); traced follows those rays
    ("glass", GLASS_TORUS, ["traced", "classical", "localized", "proxy_box"], "distance map"),
    # a rough sphere: traced_glossy's one lobe ray a pixel against the truth's lobe average
    (
        "rough",
        {"object.alpha": 0.2},
        ["traced_glossy(samples=1)", "prefiltered", "proxy_box_prefiltered"],
        "lobe",
    ),
]


@pytest.mark.parametrize(("kind", "over", "methods", "cause"), NOT_EXACT, ids=[k[0] for k in NOT_EXACT])
def test_where_a_stand_in_beats_the_exact_row_the_run_says_so_for_that_row_and_no_ranking_holds_it(
    kind, over, methods, cause
):
    """Issue 54, item 5, where the exact row is not the exact image (a glass object's rays through its distance
    map, a rough object's K lobe rays): a stand-in beats it on columns that measure the method (rmse_truth, …),
    so the run's notes name that row, how many such columns (study run's first) and the cause (one line), and the
    summary's ranking leaves it out. Before, the table showed ``traced`` below ``localized`` on the glass torus's
    rmse_truth (0.225 against 0.196) and nothing said why."""
    from study.measure import exact_rows
    from study.report import summary

    res = study.evaluate(
        "scenes/room.toml", methods, cache=None, overrides={**DIRECT, "render.max_depth": 4, **over}
    )
    rows = res.table.to_dict("records")
    beaten = exact_rows.outranked(rows)
    (exact,) = [r["label"] for r in rows if r["method"] in ("traced", "traced_glossy")]
    assert list(beaten) == [exact]  # the premise: a stand-in is better on some column of the method
    cols = [c for c, *_ in beaten[exact]]
    assert "rmse_truth" in cols or "relmse_truth_exposed" in cols, cols
    lines = [ln for ln in res.notes() if ln.startswith(f"{exact} is not the exact image")]
    assert len(lines) == 1 and "\n" not in lines[0], res.notes()
    assert cause in lines[0] and f"on {len(cols)} column" in lines[0], lines[0]
    assert all(c in lines[0] for c in cols[: exact_rows.NAMED]), lines[0]  # study run's columns first
    tab = [{**r, "case": "c0"} for r in rows]
    for col in ("wrong_fraction", "relmse_truth_exposed", "rmse_truth"):
        ranked = [r["label"] for r in summary.ranking(tab, col)]
        assert ranked and exact not in ranked, (col, ranked)


def test_the_glass_torus_with_the_exact_exit_is_the_truths_image_and_nothing_is_said():
    """The same glass torus with ``render.exit = "exact"`` (the exact refracted rays): traced is the truth's
    image, no stand-in beats it on a column of the method and no note is made."""
    from study.measure import exact_rows

    over = {**DIRECT, "render.max_depth": 4, **GLASS_TORUS, "render.exit": "exact"}
    res = study.evaluate("scenes/room.toml", ["traced", "localized", "proxy_box"], cache=None, overrides=over)
    rows = res.table.to_dict("records")
    assert exact_rows.outranked(rows) == {}
    assert not [ln for ln in res.notes() if "not the exact image" in ln]
    assert float(res.table.set_index("label").loc["traced", "rmse_truth"]) < 1e-6


def test_only_columns_of_the_method_are_judged():
    from study.measure import exact_rows

    for col in (
        "rmse_truth",
        "relmse_truth_exposed",
        "wrong_fraction",
        "flip_truth",
        "psnr_truth",
        "dist_p95",
    ):
        assert exact_rows.measures_the_method(col), col
    for col in ("rmse_oracle", "dec_search", "rmse_mitsuba", "seconds", "lookups_per_ray", "black_share", "label",
                "rmse_truth_lo"):  # fmt: skip
        assert not exact_rows.measures_the_method(col), col
