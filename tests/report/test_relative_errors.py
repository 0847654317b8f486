"""Errors that mean the same in a dark scene (study.measure.exposure, study.report.summary).

``relmse_truth_exposed`` is relMSE after the exposure normalisation (the truth's median at 0.18, ε = 0.01): a scene
× 1e-3 keeps every value and ranking while RMSE and the absolute-ε relMSE move; the summary ranks image error on it,
so a method with many wrong hits in dark pixels (low absolute RMSE) ranks below one with few in bright pixels.
Checked on planted images whose errors are known, and end to end on the McGuire Cornell box and that box with its
light × 1e-3 (Mitsuba is linear in the emission, so every image scales exactly)."""

from pathlib import Path

import numpy as np
import pytest

from study.measure import exposure, truth
from study.report import summary

ROOT = Path(__file__).resolve().parents[2]
CORNELL = ROOT / "tests/assets/corpus/obj/mcguire-cornell"
H = W = 40


def dark_room(case: int, scale: float = 1.0):
    """A truth of 10 % bright pixels (1.0) over 90 % dark ones (0.02), and two methods' images: "classical" wrong
    on 56 % of the pixels, all dark (it shows black there: 100 % relative error, 0.02 absolute), "localized"
    wrong on 9 %, all bright (it shows 0.8: 20 % relative, 0.2 absolute). ``case`` seeds which pixels."""
    rng = np.random.default_rng(case)
    n = H * W
    order = rng.permutation(n)
    bright, dark = order[: n // 10], order[n // 10 :]
    ref = np.full((n, 3), 0.02)
    ref[bright] = 1.0
    classical, localized = ref.copy(), ref.copy()
    classical[dark[: int(0.56 * n)]] = 0.0
    localized[bright[: int(0.09 * n)]] = 0.8
    shape = (H, W, 3)
    return {
        k: v.reshape(shape) * scale
        for k, v in (("truth", ref), ("classical", classical), ("localized", localized))
    }


def columns(imgs: dict) -> dict[str, dict]:
    """Per method: RMSE, the absolute-ε relMSE and the exposed relMSE against the truth over every pixel."""
    mask = np.ones((H, W), bool)
    ev = exposure.object_exposure(imgs["truth"], mask)
    zero = np.zeros_like(imgs["truth"])
    out = {}
    for m in ("classical", "localized"):
        d = imgs[m] - imgs["truth"]
        out[m] = {
            "rmse_truth_debiased": float(np.sqrt(np.mean(d * d))),
            "relmse_truth": truth.relmse(imgs[m], imgs["truth"], mask),
            **exposure.exposed_columns(imgs[m], imgs["truth"], zero, mask=mask, ev=ev),
        }
    return out


def table(scale: float, cases: int = 6) -> list[dict]:
    rows = []
    for c in range(cases):
        cols = columns(dark_room(c, scale))
        for m, wrong, cost in (("classical", 0.56, 1.0), ("localized", 0.09, 13.0)):
            rows.append({"case": f"c{c}", "label": m, "method": m, "wrong_fraction": wrong + 0.001 * c,
                         "lookups_per_ray": cost, "n_rays": 4000, **cols[m]})  # fmt: skip
    return rows


def test_the_planted_errors_are_what_the_columns_say():
    col = columns(dark_room(0))
    # by hand: exposure EV 0 (p95 of the luminance is the bright 1.0: it may not pass 1)
    assert exposure.object_exposure(dark_room(0)["truth"], np.ones((H, W), bool)) == pytest.approx(0.0)
    assert col["classical"]["relmse_truth_exposed"] == pytest.approx(
        0.56 * 0.02**2 / (0.02**2 + 0.01), rel=1e-3
    )
    assert col["localized"]["relmse_truth_exposed"] == pytest.approx(0.09 * 0.2**2 / (1.0 + 0.01), rel=1e-3)
    assert col["classical"]["rmse_truth_debiased"] == pytest.approx(np.sqrt(0.56 * 0.02**2), rel=1e-3)
    assert col["localized"]["rmse_truth_debiased"] == pytest.approx(np.sqrt(0.09 * 0.2**2), rel=1e-3)


def test_a_scene_1e3_darker_keeps_the_relative_column_and_its_ranking():
    bright, dark = columns(dark_room(1)), columns(dark_room(1, 1e-3))
    for m in bright:
        assert dark[m]["relmse_truth_exposed"] == pytest.approx(bright[m]["relmse_truth_exposed"], rel=1e-9)
        assert dark[m]["rmse_truth_debiased"] == pytest.approx(
            1e-3 * bright[m]["rmse_truth_debiased"], rel=1e-9
        )
    rank = lambda cols, c: sorted(cols, key=lambda m: cols[m][c])  # noqa: E731
    assert (
        rank(bright, "relmse_truth_exposed")
        == rank(dark, "relmse_truth_exposed")
        == ["localized", "classical"]
    )
    # the absolute-ε relMSE is no such thing: in the dark it is the MSE / ε and its ranking flips (the planted
    # error the exposed column is built against)
    assert rank(bright, "relmse_truth") == ["localized", "classical"]
    assert rank(dark, "relmse_truth") == ["classical", "localized"]
    # and without the exposure (EV 0 in both) the exposed column would flip too: the normalisation does the work
    zero, mask = np.zeros((H, W, 3)), np.ones((H, W), bool)
    raw = {m: exposure.exposed_columns(dark_room(1, 1e-3)[m], dark_room(1, 1e-3)["truth"], zero, mask=mask, ev=0.0)
           for m in ("classical", "localized")}  # fmt: skip
    assert rank(raw, "relmse_truth_exposed") == ["classical", "localized"]


def test_the_summary_ranks_image_error_on_the_relative_column():
    for scale in (1.0, 1e-3):
        tab = table(scale)
        assert summary.image_column(tab) == summary.RELATIVE
        by_rel = [r["label"] for r in summary.ranking(tab, summary.RELATIVE)]
        by_abs = [r["label"] for r in summary.ranking(tab, summary.IMAGE)]
        assert by_rel == ["localized", "classical"]  # classical: more wrong hits, ranked below
        assert by_abs == ["classical", "localized"]  # the absolute RMSE would put it first
        text = summary.table_sentence("dark room", tab)
        assert "lowest image error (relMSE after exposure, ε = 0.01): `localized`" in text
        assert "by absolute RMSE `classical` is lower" in text
    bright, dark = (summary.ranking(table(s), summary.IMAGE) for s in (1.0, 1e-3))
    assert dark[0]["median"] == pytest.approx(1e-3 * bright[0]["median"])  # RMSE moves with the light
    rows = summary.interval_rows({"dark room": table(1e-3)})
    assert {r["method"]: r["relmse"] for r in rows}["localized"] < {r["method"]: r["relmse"] for r in rows}[
        "classical"
    ]


def test_tables_without_the_relative_column_rank_on_the_rmse_as_before():
    tab = [{k: v for k, v in r.items() if k not in ("relmse_truth_exposed",)} for r in table(1.0)]
    assert summary.image_column(tab) == summary.IMAGE
    text = summary.table_sentence("old", tab)
    assert "lowest image error (RMSE vs truth, noise-debiased): `classical`" in text


def _dim_cornell(tmp: Path, factor: float) -> Path:
    mtl = (CORNELL / "CornellBox-Original.mtl").read_text().replace("Ke 17 12 4", f"Ke {17 * factor} {12 * factor} "
                                                                              f"{4 * factor}")  # fmt: skip
    (tmp / "dim.mtl").write_text(mtl)
    obj = (CORNELL / "CornellBox-Original.obj").read_text().replace("CornellBox-Original.mtl", "dim.mtl")
    (tmp / "dim.obj").write_text(obj)
    return tmp / "dim.obj"


def test_the_cornell_box_1e3_darker_ranks_alike_end_to_end(tmp_path):
    from study.api import evaluate

    over = {"camera.width": 40, "camera.height": 40, "render.spp": 8, "render.cube_spp": 8, "render.cube_res": 32,
            "light.enabled": False}  # the file's own light alone, in both  # fmt: skip
    files = [CORNELL / "CornellBox-Original.obj", _dim_cornell(tmp_path, 1e-3)]
    tabs = [
        evaluate(f, ["classical", "localized"], overrides=over, cache=tmp_path / "c").table for f in files
    ]
    bright, dark = (t.set_index("label") for t in tabs)
    methods = ["classical", "localized(iterations=10)"]
    for m in methods:
        assert dark.loc[m, "relmse_truth_exposed"] == pytest.approx(
            bright.loc[m, "relmse_truth_exposed"], rel=1e-3
        )
        assert dark.loc[m, "rmse_truth"] == pytest.approx(1e-3 * bright.loc[m, "rmse_truth"], rel=1e-3)
    assert dark.loc[methods[0], "truth_exposure_ev"] == pytest.approx(
        bright.loc[methods[0], "truth_exposure_ev"] + np.log2(1e3), abs=1e-3
    )
    order = lambda t: list(t.loc[methods, "relmse_truth_exposed"].sort_values().index)  # noqa: E731
    assert order(bright) == order(dark)
