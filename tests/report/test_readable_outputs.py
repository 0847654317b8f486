"""Outputs a reader can read (issue 54, item 4): ``study run``'s grids wrap so that every panel stays wide and no
two titles collide, however many methods; the report page is in sections, long tables and several figures' viewers
folded until opened; its inline Markdown renders (bold around code too); it names the folder its tables came from;
and a clone without the untracked pictures (issue 55) still makes a page that says how to get them."""

import numpy as np
import pytest

from study.outputs import figures, html
from study.outputs.markup import inline
from tests.report.test_report_html import _fake_case, small_report

LABELS = [
    "classical",
    "layered(steps_per_texel=1.0)",
    "linear_secant(steps_per_texel=1.0)",
    "localized(iterations=10)",
    "multi_probe(steps_per_texel=1.0)",
    "probe_blend(blend=0.25)",
    "proxy_box",
    "proxy_sphere",
    "sdf(res=64)",
    "ssr(max_steps=512)",
    "ssr_hiz(max_iterations=128)",
    "ssr_sdf(max_steps=512)",
    "traced",
    "oracle_map",
]


def _grids(monkeypatch, **kw):
    """The matplotlib figures image_grids draws (drawn, so their text has extents), by part."""
    figs = []
    real = figures.png_bytes

    def keep(fig, **k):
        fig.canvas.draw()
        figs.append(fig)
        return real(fig, **k)

    monkeypatch.setattr(figures, "png_bytes", keep)
    case = _fake_case(LABELS, np.random.default_rng(0))
    title = (
        "room.toml: box environment, sphere (radius 0.4, conductor), camera 96×96, cube 32², backend numpy, "
        * 2
    )
    files = figures.image_grids("run", [case], LABELS, title=title, occlusion_panel=True,
                                outcome_panel=True, row_labels=["run"], **kw)  # fmt: skip
    return files, figs


def _overlaps(a, b) -> bool:
    return a.x0 < b.x1 - 1 and b.x0 < a.x1 - 1 and a.y0 < b.y1 - 1 and b.y0 < a.y1 - 1


def test_a_runs_grids_wrap_so_every_panel_is_legible_and_no_titles_collide(monkeypatch):
    """14 methods (once 44 panels ≈ 100 px wide in two rows): every panel ≥ 200 px wide, the PNGs within the page's
    width, and no panel title overlapping another or another panel."""
    files, figs = _grids(monkeypatch, wrap=True)
    assert sorted(files) == ["run-errors.png", "run.png"] and len(figs) == 2
    for fig in figs:
        assert fig.get_figwidth() * figures._DPI <= figures.MAX_WIDTH_PX
        panels = [ax for ax in fig.axes if ax.get_visible() and ax.axison and ax.images and ax.get_title()]
        assert len(panels) >= 14
        boxes = [ax.get_window_extent() for ax in panels]
        titles = [ax.title.get_window_extent() for ax in panels]
        assert min(b.width for b in boxes) >= 200, min(b.width for b in boxes)
        head = fig._suptitle.get_window_extent()  # a long title over several lines: above every panel
        assert not any(_overlaps(head, b) for b in [*boxes, *titles]), "the figure's title runs into a panel"
        for i, t in enumerate(titles):
            for j in range(len(panels)):
                if j != i:
                    assert not _overlaps(t, titles[j]), (panels[i].get_title(), panels[j].get_title())
                    assert not _overlaps(t, boxes[j]), (panels[i].get_title(), "over a panel")

    # the figures' grids (several cases, one row each) keep their layout: one row per case, no wrap
    _, figs = _grids(monkeypatch, wrap=False)
    panels = [ax for ax in figs[0].axes if ax.images]
    assert len({round(ax.get_position().y0, 3) for ax in panels}) == 1


def test_bold_around_code_renders():
    """The Summary's items: **bold with `code` inside** (once shown as literal asterisks)."""
    got = inline("**by absolute RMSE `sdf(res=64)` is lower** (absolute errors scale), *a `b`*")
    assert got == (
        "<strong>by absolute RMSE <code>sdf(res=64)</code> is lower</strong> (absolute errors scale), "
        "<em>a <code>b</code></em>"
    )
    assert "**" not in inline("x **a `b` c** y `**literal**`".replace("`**literal**`", ""))
    assert inline("`**kept**`") == "<code>**kept**</code>"


def test_the_page_is_in_sections_with_long_tables_folded():
    rows = [{"case": f"c{i}", "x": float(i)} for i in range(html.OPEN_ROWS + 1)]
    blocks = [
        ("h", 1, "T"),
        ("h", 2, "One"),
        ("table", rows[:3], ["case", "x"]),
        ("h", 2, "Two"),
        ("table", rows, ["case", "x"]),
    ]
    page = html.page(blocks, html.Path("."), title="t")
    assert page.count("<section>") == 2 and page.count("</section>") == 2
    assert page.count("<details") == 1 and f"{len(rows)} rows × 2 columns" in page
    body = page[page.index("<main>") : page.index("</main>")]
    assert body.index('id="two"') < body.index("<details")


def test_the_report_names_its_folder_and_folds_several_figures_viewers(tmp_path_factory):
    import shutil

    from study.report.report import build_report

    reports = small_report(tmp_path_factory)
    mine = reports.parent / "mine"
    shutil.copytree(reports, mine)
    shutil.copytree(reports / "fig4", mine / "fig4b")  # a second figure with viewers
    for p in (mine / "fig4b" / "viewer").glob("index.json"):
        p.write_text(p.read_text().replace('"fig4"', '"fig4b"'))
    build_report(mine)
    md = (mine / "index.md").read_text()
    assert f"`{mine.as_posix()}/`" in md and "tables under `reports/`" not in md
    page = (mine / "index.html").read_text()
    assert page.count('<details class="viewers-box">') == 2
    single = (reports / "index.html").read_text()  # one figure: its viewers open, as before
    assert '<details class="viewers-box">' not in single


def test_a_clone_without_the_untracked_pictures_still_makes_a_page(tmp_path_factory):
    """Viewer images, Parquet, plots gone (as in a fresh clone): the page is written, says how to get them."""
    from study.report.report import build_report

    reports = small_report(tmp_path_factory)
    for pat in ("*/viewer/*.js", "*/*.parquet", "*/exr/*", "*/*.png"):
        for p in reports.glob(pat):
            p.unlink()
    assert build_report(reports) is not None
    md = (reports / "index.md").read_text()
    assert "where one is absent, `bash scripts/reproduce.sh` makes it" in md
    page = (reports / "index.html").read_text()
    assert 'id="viewers-fig4"' in page


@pytest.mark.parametrize("part", ["viewer", "paper", "parquet", "plots", "index.html"])
def test_generated_files_are_not_tracked(part):
    """The light repository: what `scripts/reproduce.sh` makes (viewer images, the paper set, Parquet copies, the
    sweeps' plots, the HTML page) is ignored by git, so a regeneration never adds it."""
    import subprocess

    from tests.report.test_provenance import ROOT

    path = {
        "viewer": "reports/fig4/viewer/fig4-p0.js",
        "paper": "reports/paper/fig4/metrics.csv",
        "parquet": "reports/fig4/metrics.parquet",
        "plots": "reports/sweep-sweep/plots/wrong_fraction_vs_res.png",
        "index.html": "reports/index.html",
    }[part]
    r = subprocess.run(["git", "check-ignore", "-q", "--no-index", path], cwd=ROOT)
    assert r.returncode == 0, f"{path} is not ignored"
    tracked = subprocess.run(["git", "ls-files", path], cwd=ROOT, capture_output=True, text=True).stdout
    assert not tracked.strip(), f"{path} is tracked"


def test_the_tracked_tree_is_light():
    """≤ 25 MB tracked, so the lent GPU machine takes a plain copy (its limit is 64 MiB with the wheels)."""
    import subprocess

    from tests.report.test_provenance import ROOT

    files = subprocess.run(["git", "ls-files", "-z"], cwd=ROOT, capture_output=True, check=True).stdout.split(
        b"\0"
    )
    size = sum((ROOT / f.decode()).stat().st_size for f in files if f and (ROOT / f.decode()).is_file())
    assert size <= 25_000_000, size


def test_a_figures_grid_comes_before_its_error_grid(tmp_path):
    from study.report import sections

    d = tmp_path / "fig4"
    d.mkdir()
    for name in ("fig4-errors.png", "fig4.png"):
        (d / name).write_bytes(b"")
    assert [b[1] for b in sections._images(d, "fig4")] == ["fig4/fig4.png", "fig4/fig4-errors.png"]


def test_no_literal_asterisks_in_the_column_notes():
    """The comparison's notes render: no emphasis left as literal asterisks outside code spans (once `*dec_**`;
    a lone `angle_*` is a name with a wildcard, shown as written)."""
    import re

    from study.report import table_notes

    for note in table_notes.column_notes():
        text = re.sub(r"<code>.*?</code>", "", inline(note))
        assert "**" not in text and not re.search(r"(?<![\w*])\*\w[^*]*\*\*", text), text[:200]


def test_the_built_page_renders_its_markdown_and_is_in_sections(tmp_path_factory):
    """The page ``study report --reports DIR`` writes: index.md's emphasis is rendered in index.html (no literal
    ``**`` outside code, preformatted text and scripts: the Summary's bold items once showed as asterisks), its
    sections navigable from a bar of links, and the folder named as given."""
    import re

    from conftest import run_cli

    built = small_report(tmp_path_factory)
    reports = built.rename(built.parent / "elsewhere")  # the page made again for a folder of another name
    res = run_cli("report", "--reports", reports)
    assert res.exit_code == 0, res.output
    md = (reports / "index.md").read_text()
    page = (reports / "index.html").read_text()
    assert "**" in md  # the premise: the Markdown has bold text
    body = page[page.index("<main>") : page.index("</main>")]
    prose = re.sub(r"<(code|pre|script)\b[^>]*>.*?</\1>", "", body, flags=re.S)
    assert "**" not in prose, prose[max(0, prose.find("**") - 200) : prose.find("**") + 200]
    assert "<strong>" in body
    ids = re.findall(r'<section>\s*<h2 id="([^"]+)"', body)
    assert len(ids) >= 3, ids
    head = page[: page.index("<main>")]
    assert all(f'href="#{i}"' in head for i in ids), ids
    assert f"`{reports.as_posix()}/`" in md and f"{reports.as_posix()}/" in page


def test_a_run_with_eight_methods_writes_wrapped_grids(tmp_path):
    """What ``study run`` writes (Result.save), not only the grid function: with 8 methods run.png and
    run-errors.png stay within the page's width in several rows of panels. On 635ec81 run.png was one row of
    shrunk panels, 1500 × 232 px (here 1265 × 660)."""
    import struct

    import study

    methods = ["classical", "proxy_box", "proxy_sphere", "localized(iterations=3)", "localized(iterations=10)",
               "traced", "linear_secant", "probe_blend"]  # fmt: skip
    over = {"camera.width": 32, "camera.height": 32, "render.cube_res": 32, "render.spp": 2, "render.cube_spp": 2,
            "render.supersample": 1}  # fmt: skip
    study.evaluate("scenes/room.toml", methods, cache=None, overrides=over).save(tmp_path / "run")
    for name in ("run.png", "run-errors.png"):
        w, h = struct.unpack(">II", (tmp_path / "run" / name).read_bytes()[16:24])  # the PNG's IHDR
        assert w <= figures.MAX_WIDTH_PX and h >= 0.4 * w, (name, w, h)  # rows of panels, not one shrunk row


def test_a_saved_figure_is_matplotlibs_pixels_in_rgb_and_lighter(tmp_path):
    """study.io stores an opaque figure as RGB with an optimized deflate: the same pixels as matplotlib's RGBA
    PNG, fewer bytes (the tracked tree's weight); a figure with a transparent face keeps its alpha."""
    import io

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np
    from PIL import Image

    from study.io import atomic_savefig, png_bytes

    def figure(transparent=False):
        fig, ax = plt.subplots(figsize=(3, 2))
        ax.imshow(np.random.default_rng(0).random((20, 30)), cmap="viridis")
        ax.set_title("a title")
        if transparent:
            fig.patch.set_alpha(0.0)
        return fig

    plain = io.BytesIO()
    fig = figure()
    fig.savefig(plain, dpi=80, format="png")
    plt.close(fig)
    atomic_savefig(figure(), tmp_path / "a.png", dpi=80)
    ours = Image.open(tmp_path / "a.png")
    theirs = Image.open(io.BytesIO(plain.getvalue()))
    assert ours.mode == "RGB" and theirs.mode == "RGBA"
    assert np.array_equal(np.asarray(ours), np.asarray(theirs)[..., :3])
    assert (tmp_path / "a.png").stat().st_size < len(plain.getvalue())
    assert Image.open(io.BytesIO(png_bytes(figure(transparent=True), dpi=80))).mode == "RGBA"
