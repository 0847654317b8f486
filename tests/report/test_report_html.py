"""The report's outputs for people, without a browser: index.html's structure (every link resolves, tables sortable,
one viewer per case), the per-case EXRs (they hold the images the metrics measured), the viewer's RGBE images,
Parquet beside every results table, strict JSON, the summary written from the numbers, and a report that degrades
gracefully where viewer images or EXRs are missing. The browser test is tests/report/test_html_browser.py."""

import fcntl
import io
import json
import math
import os
import re
import shutil
from html.parser import HTMLParser
from pathlib import Path

import numpy as np
import pytest
from conftest import run_cli
from typer.testing import CliRunner

from study.io import file_stem, json_text, read_exr_layers
from study.outputs import viewer
from study.report import pareto
from study.tables import read_csv, to_parquet, write_table

SMALL = """
positions = [[0.6, 1.2, 0.3], [1.1, 0.9, 0.6]]
grid = ["classical", "localized(iterations=10)"]

[scene]
room = { min = [-2.0, 0.0, -2.0], max = [2.0, 3.0, 2.0] }
light = { position = [0.3, 2.6, -0.4], intensity = [7.0, 7.0, 7.0] }
reference = { point = [0.0, 1.5, 0.0] }
object = { center = [0.6, 1.2, 0.3], radius = 0.6, material = { type = "mirror" } }
camera = { eye = [-0.3, 1.7, -1.9], target = [0.6, 1.1, 0.6], fov = 60.0, width = 32, height = 32 }
render = { cube_res = 16, cube_spp = 4, spp = 4, max_depth = 3, supersample = 1 }

[[methods]]
name = "classical"

[[methods]]
name = "localized"
iterations = [1, 10]
"""
runner = CliRunner()


def small_report(tmp_path_factory) -> Path:
    """A reports directory with a tiny fig4 (2 positions, cube 16², camera 32²) and its report, built once per test
    session (shared by xdist workers through a lock). Returns a fresh copy, so tests may change it."""
    uid = os.environ.get("PYTEST_XDIST_TESTRUNUID")  # set by xdist, the same in every worker
    base = tmp_path_factory.getbasetemp()
    root = base.parent / f"study-small-report-{uid}" if uid else base / "study-small-report"
    root.mkdir(exist_ok=True)
    with open(root / ".lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if not (root / "reports" / "index.html").is_file():
            (root / "small.toml").write_text(SMALL)
            res = run_cli(
                *[
                    "figure",
                    "fig4",
                    "--config",
                    str(root / "small.toml"),
                    "--out",
                    str(root / "reports" / "fig4"),
                    "--cache",
                    str(root / "cache"),
                ],
            )
            assert res.exit_code == 0, res.output
            res = run_cli("report", "--reports", str(root / "reports"))
            assert res.exit_code == 0 and "report: wrote" in res.output, res.output
    copy = tmp_path_factory.mktemp("reports") / "reports"
    shutil.copytree(root / "reports", copy)
    return copy


@pytest.fixture(scope="module")
def reports(tmp_path_factory):
    return small_report(tmp_path_factory)


class _Links(HTMLParser):
    def __init__(self):
        super().__init__()
        self.refs, self.tags = [], []

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        self.tags.append((tag, a))
        for k in ("src", "href"):
            if a.get(k) and not a[k].startswith(("#", "http", "data:")):
                self.refs.append(a[k])


def _manifest(html_text: str) -> dict:
    m = re.search(r'<script type="application/json" id="study-manifest">(.*?)</script>', html_text, re.S)
    return json.loads(m.group(1))


def test_html_structure_links_and_viewers(reports):
    text = (reports / "index.html").read_text()
    p = _Links()
    p.feed(text)
    missing = [r for r in p.refs if not (reports / r.split("#")[0]).exists()]
    assert not missing, missing
    assert sum(t == "table" and "sortable" in a.get("class", "") for t, a in p.tags) >= 4
    assert not any(a.get("src", "").startswith("http") for _, a in p.tags), "nothing from the network"
    m = _manifest(text)
    cases = m["fig4"]["cases"]
    assert [c["id"] for c in cases] == ["fig4-p0", "fig4-p1"]
    assert text.count('class="viewer"') == 2
    for c in cases:
        assert (reports / c["script"]).is_file() and not c["missing"]
        sources = {la["source"] for la in c["layers"]}
        assert {"truth_at_hit", "oracle_map", "mitsuba", "classical", "localized(iterations=10)"} <= sources
        assert {la["layer"] for la in c["layers"]} >= {"image", "angle", "outcome", "hidden"}
        assert all(la["have"] and (reports / la["exr"]).is_file() for la in c["layers"])
    assert "## Summary" in (reports / "index.md").read_text()
    assert "[index.html](index.html#viewers-fig4)" in (reports / "index.md").read_text()


def test_exrs_hold_what_the_metrics_measured(reports):
    """rmse_oracle and rmse_mitsuba of metrics.csv, recomputed from the EXRs alone (method, oracle_map, mitsuba,
    mask): the files are the images the table measured, full frame, float32."""
    rows = read_csv(reports / "fig4" / "metrics.csv")
    checked = 0
    for r in rows:
        if r["method"] in ("oracle_map", "truth_at_hit"):
            continue
        layers = read_exr_layers(reports / "fig4" / "exr" / f"{r['case']}.exr")
        img, orc, mit = (layers[n] for n in (file_stem(r["label"]), "oracle_map", "mitsuba"))
        mask = layers["held"][..., 0] > 0.5  # the *_oracle columns: the pixels whose hits the views hold
        assert img.shape == (32, 32, 3) and mask.sum() >= 4
        assert np.array_equal(mask, layers["mask"][..., 0] > 0.5)  # fig4's room hides nothing
        for ref, col in ((orc, "rmse_oracle"), (mit, "rmse_mitsuba")):  # rmse_mitsuba: over the mask
            dd = (img.astype(float) - ref)[mask]
            assert math.sqrt(np.mean(dd * dd)) == pytest.approx(r[col], rel=1e-5, abs=1e-7), (r["label"], col)
        checked += 1
    assert checked == 6
    layers = read_exr_layers(reports / "fig4" / "exr" / "fig4-p0.exr")
    assert "localized-iterations-10" in layers and "angle-localized-iterations-10" in layers
    assert not [p for p in (reports / "fig4").rglob("*") if set(p.name) & set("()= ")], "shell-hostile names"
    a = layers["angle-classical"]
    assert a.shape == (32, 32, 1) and np.nanmax(a) > 1  # classical is degrees off here
    oc = layers["outcome-classical"][..., 0]
    assert set(np.unique(oc[np.isfinite(oc)])) <= {0.0, 1.0, 2.0, 3.0}


def test_viewer_images_decode_to_the_exrs(reports):
    """The viewer's RGBE images, decoded as the page decodes them, are the EXRs' crops within RGBE precision."""
    import base64
    import io

    from PIL import Image

    m = json.loads((reports / "fig4" / viewer.MANIFEST).read_text())
    c = m["cases"][1]
    urls = json.loads((reports / "fig4" / c["script"]).read_text().split("] = ", 1)[1].rstrip().rstrip(";"))
    y0, x0, h, w = c["crop"]
    for la, url in zip(c["layers"], urls):
        b = np.asarray(Image.open(io.BytesIO(base64.b64decode(url.split(",", 1)[1]))))
        got = viewer.unrgbe(b if b.ndim == 3 else b[..., None])
        want = read_exr_layers(reports / "fig4" / la["exr"])[la["exr_layer"]][y0 : y0 + h, x0 : x0 + w]
        assert got.shape == want.shape, la
        assert np.array_equal(np.isnan(got), np.isnan(want)), la
        ok = np.isfinite(want)
        tol = np.max(np.where(ok, np.abs(want), 0), axis=-1, keepdims=True) * 2.0**-8 + 1e-30
        assert np.all(np.abs(got - want)[ok] <= np.broadcast_to(tol, want.shape)[ok]), la


def test_rgbe_round_trip_and_a_wrong_decoder_is_caught():
    rng = np.random.default_rng(3)
    a = rng.lognormal(-1, 3, (7, 9, 3))
    a[0, 0] = 0.0
    a[0, 1] = [np.nan, 1, 1]
    a[0, 2] = [5.0, 0.0, 0.0]
    b = viewer.rgbe(a)
    assert b.shape == (7, 18, 3) and b.dtype == np.uint8
    got = viewer.unrgbe(b)
    ok = np.isfinite(a).all(-1) & (np.nan_to_num(a).max(-1) > 0)
    rel = np.abs(got - a)[ok] / a[ok].max(-1, keepdims=True)
    assert rel.max() <= 2.0**-8 and np.isnan(got[0, 1]).all() and (got[0, 0] == 0).all()
    assert got[0, 2].tolist() == [5.0, 0.0, 0.0]
    off_by_one = b.copy()
    off_by_one[:, 9:] += 1  # an exponent one off: twice the value
    assert (np.abs(viewer.unrgbe(off_by_one) - a)[ok] / a[ok].max(-1, keepdims=True)).max() > 0.5


def test_parquet_beside_every_table_round_trips_with_pandas(reports, tmp_path):
    pd = pytest.importorskip("pandas")
    csv, pq = reports / "fig4" / "metrics.csv", reports / "fig4" / "metrics.parquet"
    a, b = pd.read_csv(csv), pd.read_parquet(pq)
    assert list(a.columns) == list(b.columns) and len(a) == len(b) == 10
    for col in a.columns:
        if a[col].dtype.kind in "fi":
            assert np.allclose(a[col], b[col].astype(float), equal_nan=True, rtol=0, atol=0), col
        else:
            assert a[col].fillna("").astype(str).tolist() == b[col].fillna("").astype(str).tolist(), col
    rows = [
        {"case": "c", "x": 1, "y": float("nan"), "z": math.inf, "w": "a"},
        {"case": "d", "x": 2, "y": 0.5},
    ]
    write_table(rows, tmp_path / "results.csv")
    t = pd.read_parquet(tmp_path / "results.parquet")
    assert t["x"].dtype.kind == "i" and np.isnan(t["y"][0]) and t["z"][0] == math.inf and np.isnan(t["z"][1])
    assert t["w"][0] == "a" and t["w"].isna().tolist() == [False, True]
    assert to_parquet(rows)[:4] == b"PAR1"


def test_json_is_strict(reports, tmp_path):
    """metadata.json, the viewer manifest and a sweep's case files: no NaN/Infinity tokens (NaN → null; in case
    files "NaN"/"Infinity" text, which the runner reads back as the numbers)."""

    def strict(text):
        return json.loads(text, parse_constant=lambda c: (_ for _ in ()).throw(ValueError(c)))

    for p in [reports / "fig4" / "metadata.json", reports / "fig4" / viewer.MANIFEST]:
        strict(p.read_text())
    data = {"a": float("nan"), "b": np.float32("inf"), "c": [np.float64(1.5), np.nan], "d": np.arange(2)}
    assert strict(json_text(data)) == {"a": None, "b": None, "c": [1.5, None], "d": [0, 1]}
    with pytest.raises(ValueError):
        strict(json.dumps(data["a"]))  # what the plain json module writes is caught
    from study.harness import runner
    from study.harness.sweep import Case

    case = Case(index=0, id="c0", scene=None, labels={}, key="k")
    (tmp_path / "cases").mkdir()
    row = {"label": "m", "v": float("nan"), "psnr": math.inf, "low": -math.inf}
    runner_text = json_text({"key": "k", "rows": [row]}, nonfinite="text")  # as the runner writes case files
    (tmp_path / "cases" / "k.json").write_text(strict(runner_text) and runner_text)
    rows = runner._load_case(tmp_path, case)
    assert rows and math.isnan(rows[0]["v"]) and rows[0]["psnr"] == math.inf and rows[0]["low"] == -math.inf


def test_pareto_front_keeps_what_nothing_beats():
    """The rows no other row beats on both cost and error, cheapest first: 900 lookups for 95 % is beaten by 1 for
    90 %."""
    front = pareto.pareto_front(
        [{"c": 1, "e": 0.9}, {"c": 6, "e": 0.2}, {"c": 900, "e": 0.95}, {"c": 2451, "e": 0.01}], "c", "e"
    )
    assert [r["c"] for r in front] == [1, 6, 2451]


def test_report_degrades_gracefully(reports):
    """Without EXRs the page says so (and links none); without a case's viewer script that viewer says what is
    missing; without any viewer images (a figure made before them) the figure still shows, with a note; a broken
    viewer manifest is as good as none — never an error."""
    shutil.rmtree(reports / "fig4" / "exr")
    (reports / "fig4" / "viewer" / "fig4-p1.js").unlink()
    res = run_cli("report", "--reports", str(reports))
    assert res.exit_code == 0, res.output
    text = (reports / "index.html").read_text()
    links = _Links()
    links.feed(text)
    assert "EXR files are not in this copy" in text and not [r for r in links.refs if "/exr/" in r]
    cases = _manifest(text)["fig4"]["cases"]
    assert [c["missing"] for c in cases] == [False, True]
    assert "are not in this copy" in (reports / "index.md").read_text()
    (reports / "fig4" / viewer.MANIFEST).write_text("{not json")
    res = run_cli("report", "--reports", str(reports))
    assert res.exit_code == 0, res.output
    text = (reports / "index.html").read_text()
    assert "No per-case images for fig4 in this copy" in text and 'class="viewer"' not in text
    assert '<img src="fig4/fig4.png"' in text


def test_animation_and_fig8_images_are_linked(reports):
    """What the other kinds of figure write beside the grids, found by their files (study.report.kinds):
    ``animation/*.gif|mp4`` (and its plot) beside ``frames.csv``, ``fig8/*.png`` beside ``fig8.csv``."""
    from PIL import Image

    (reports / "animation").mkdir()
    Image.new("RGB", (8, 8), "red").save(reports / "animation" / "motion.gif")
    (reports / "animation" / "motion.mp4").write_bytes(b"\x00" * 16)
    (reports / "fig8").mkdir()
    Image.new("RGB", (8, 8), "blue").save(reports / "fig8" / "fig8.png")
    res = run_cli("report", "--reports", str(reports))
    assert "fig8/fig8.png" not in (reports / "index.md").read_text()  # without their files: no kind's folders
    (reports / "animation" / "frames.csv").write_text("frame,label\n")
    (reports / "fig8" / "fig8.csv").write_text("label\n")
    res = run_cli("report", "--reports", str(reports))
    assert res.exit_code == 0, res.output
    text = (reports / "index.html").read_text()
    assert '<img src="animation/motion.gif"' in text and '<video src="animation/motion.mp4"' in text
    assert '<img src="fig8/fig8.png"' in text
    md = (reports / "index.md").read_text()
    assert "(animation/motion.gif)" in md and "![fig8](fig8/fig8.png)" in md


def _fake_case(labels, rng, binary_hidden=True):
    from types import SimpleNamespace

    H = W = 24
    mask = np.zeros((H, W), bool)
    mask[6:18, 6:18] = True
    occ = (rng.random((H, W)) > 0.7).astype(np.float32) if binary_hidden else rng.random((H, W))
    img = lambda: rng.random((H, W, 3)).astype(np.float32)  # noqa: E731
    amap = lambda: np.where(mask, rng.random((H, W)) * 10, np.nan)  # noqa: E731
    return SimpleNamespace(
        scene=SimpleNamespace(object=SimpleNamespace(center=(0.0, 1.0, 0.0), alpha=0.0)),
        images={lab: img() for lab in labels},
        truth=img(),
        oracle=img(),
        mitsuba=img(),
        angle_maps={lab: amap() for lab in labels},
        outcome_maps={lab: np.where(mask, rng.integers(0, 4, (H, W)), np.nan) for lab in labels},
        flip_maps={},
        occluded=np.where(mask, occ, 0),
        mask=mask,
    )


def test_wide_figures_split_into_image_and_error_grids_that_fit():
    """A figure of 11 methods with outcome and hidden panels (once 4807 px wide, shown at 1397): an image grid
    and an error grid, each at most MAX_WIDTH_PX wide; a narrow figure stays one PNG."""
    from PIL import Image

    from study.outputs import figures

    rng = np.random.default_rng(0)
    labels = [f"m{i}(k={i})" for i in range(11)]
    cases = [_fake_case(labels, rng) for _ in range(2)]
    kw = dict(title="wide", occlusion_panel=True, outcome_panel=True, row_labels=["a", "b"])
    pngs = figures.image_grids("figW", cases, labels, **kw)
    assert sorted(pngs) == ["figW-errors.png", "figW.png"]
    for data in pngs.values():
        w, h = Image.open(io.BytesIO(data)).size
        assert w <= figures.MAX_WIDTH_PX, w
    narrow = figures.image_grids(
        "figN", [_fake_case(labels[:2], rng)], labels[:2], title="n", row_labels=["a"]
    )
    assert list(narrow) == ["figN.png"]


def test_binary_hidden_map_is_two_classes():
    rng = np.random.default_rng(1)
    for binary, kind in ((True, "classes"), (False, "linear")):
        case = _fake_case(["classical"], rng, binary_hidden=binary)
        _, entry = viewer.case_files("f", "c", case, ["classical"])
        hidden = next(la for la in entry["layers"] if la["layer"] == "hidden")
        assert hidden["display"]["type"] == kind
        if binary:
            assert hidden["display"]["names"] == list(viewer.HIDDEN_NAMES)


def test_a_figure_with_an_error_split_shows_it(tmp_path):
    """A figure folder with ``split.csv`` beside its table (the ``glossy`` kind's) is that kind's and gets an
    'Error split' heading and the split as a table; one without is a grid and gets neither."""
    from study.report.kinds import folder_kind

    d = tmp_path / "fig_x"
    d.mkdir()
    (d / "metadata.json").write_text("{}")
    (d / "metrics.csv").write_text("case,label\n")
    assert folder_kind(d).name == "grid"
    section = folder_kind(d).section
    assert not any(b[0] == "h" and b[2] == "Error split" for b in section(tmp_path, d, [], []))
    (d / "split.csv").write_text("alpha,where,prefiltering,localization\n0.05,near,0.047,0.609\n")
    assert folder_kind(d).name == "glossy"
    blocks = folder_kind(d).section(tmp_path, d, [], [])
    assert ("h", 3, "Error split") in blocks
    table = [b for b in blocks if b[0] == "table"][-1]
    assert table[1][0]["localization"] == 0.609 and table[2] == [
        "alpha",
        "where",
        "prefiltering",
        "localization",
    ]


def test_numpy_floats_are_written_as_plain_numbers():
    """numpy 2's repr of np.float64 is 'np.float64(0.5)': a table cell is the number alone."""
    from study.tables import to_csv

    assert "np.float64" not in to_csv([{"a": np.float64(0.5), "b": 0.25}])
