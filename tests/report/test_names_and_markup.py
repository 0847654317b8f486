"""Names are data (issue 22): case names that are equal after a file-name rule get distinct files; a name or a
path carrying Markdown, HTML or Rich markup is printed and shown as text (no link to ``javascript:``, no script
in index.md or index.html, no crash of the CLI after the outputs were written); tables printed into a log are
never cut. The same report in headless Chromium runs no script from a name: tests/report/test_html_browser.py."""

import json
import re
from pathlib import Path

import numpy as np
import pytest
from conftest import run_cli

from study.io import file_stem, file_stems, read_exr_layers
from study.outputs import markup, viewer

EVIL = ["a b", "a_b", "a-b", "[x](javascript:alert(1))", "<img src=x onerror=alert(1)>[/x]"]
CFG = """
methods = [{{ name = "classical" }}]

[scene]
room = {{ min = [-2.0, 0.0, -2.0], max = [2.0, 3.0, 2.0] }}
light = {{ position = [0.3, 2.6, -0.4], intensity = [7.0, 7.0, 7.0] }}
reference = {{ point = [0.0, 1.5, 0.0] }}
object = {{ center = [0.6, 1.2, 0.3], radius = 0.5, material = {{ type = "mirror" }} }}
camera = {{ eye = [-0.3, 1.7, -1.9], target = [0.6, 1.1, 0.6], fov = 60.0, width = 16, height = 16 }}
render = {{ cube_res = 8, cube_spp = 2, spp = 2, max_depth = 2, supersample = 1 }}
{cases}
"""


def evil_report(root: Path) -> Path:
    """A figure whose cases carry hostile names, a sweep whose config name carries backticks and a link, and the
    report of both, under ``root/reports`` ("[bold]" in the output path)."""
    cases = "".join(
        f'\n[[cases]]\nname = {json.dumps(n)}\n"object.center" = [{0.3 + 0.15 * i}, 1.2, 0.3]\n'
        for i, n in enumerate(EVIL)
    )
    (root / "evil.toml").write_text(CFG.format(cases=cases))
    reports = root / "reports"
    out = reports / "fig-evil[bold]"
    res = run_cli(
        *["figure", "--config", str(root / "evil.toml"), "--out", str(out), "--cache", str(root / "cache")],
    )
    assert res.exit_code == 0, res.output
    assert f"evil: wrote {out}" in " ".join(res.output.split()), res.output
    sw = reports / "sweep-x"
    sw.mkdir()
    (sw / "results.csv").write_text(
        "case,method,label,cube_res,angle_median_deg,occluded_fraction\n"
        'c0,classical,"<script>alert(2)</script>",16,1.5,0.1\n'
    )
    (sw / "metadata.json").write_text(json.dumps({"config": "s`[y](javascript:alert(3))`.toml", "cases": 1}))
    res = run_cli("report", "--reports", str(reports))
    assert res.exit_code == 0, res.output
    return reports


@pytest.fixture(scope="module")
def reports(tmp_path_factory):
    return evil_report(tmp_path_factory.mktemp("evil"))


def test_file_stems_are_plain_and_distinct():
    assert file_stem("localized(iterations=10)") == "localized-iterations-10"
    assert file_stem("a b") == "a-b" and file_stem("../x") == "x" and file_stem("") == "_"
    stems = file_stems(["a b", "a-b", "A-B", "a_b", "a b"])
    assert stems == {"a b": "a-b", "a-b": "a-b-2", "A-B": "A-B-3", "a_b": "a_b"}


def test_distinct_cases_get_distinct_files(reports):
    """Case names equal after the file-name rule ("a b" / "a-b") once shared one viewer script and EXR: the first
    case showed the second's images."""
    fig = next(reports.glob("fig-evil*"))
    m = json.loads((fig / viewer.MANIFEST).read_text())
    cases = m["cases"]
    assert [c["id"] for c in cases] == [f"evil-{n}" for n in EVIL]
    for k in ("script", "exr", "key"):
        assert len({c[k] for c in cases}) == len(EVIL), [c[k] for c in cases]
    assert not [p for p in fig.rglob("*") if re.search(r"[^A-Za-z0-9._-]", p.name) and p.name != ".lock"]
    images = [read_exr_layers(fig / c["exr"])["classical"] for c in cases]
    assert all(not np.array_equal(images[0], b) for b in images[1:])  # each case its own images
    for c in cases:
        assert f'"{c["key"]}"' in (fig / c["script"]).read_text()


def test_names_are_text_in_the_report(reports):
    html = (reports / "index.html").read_text()
    md = (reports / "index.md").read_text()
    body = html.split('<script type="application/json"', 1)[0]
    assert "javascript:" not in "".join(re.findall(r'(?:href|src)="([^"]*)"', html))
    assert "<script>alert" not in html and "<img src=x" not in body
    assert "&lt;img src=x onerror=alert(1)&gt;" in body and "&lt;script&gt;alert(2)&lt;/script&gt;" in body
    assert not re.search(r"(?<!\\)<(script|img)", md) and not re.search(r"(?<!\\)\]\(javascript:", md)
    assert r"\<img src=x onerror=alert\(1\)\>" in md and r"\<script\>alert\(2\)\</script\>" in md


def test_result_repr_html_escapes_labels():
    import pandas as pd

    from study.api import Result, load_scene
    from tests.conftest import small_scene_dict

    lab = "<script>alert(1)</script>"
    res = Result(
        load_scene(small_scene_dict()),
        pd.DataFrame([{"label": lab, "wrong_fraction": 0.5}]),
        images={lab: np.zeros((4, 4, 3), np.float32)},
    )
    text = res._repr_html_()
    assert "<script>" not in text and text.count("&lt;script&gt;alert(1)&lt;/script&gt;") == 2


def test_inline_links_only_to_own_files():
    assert markup.inline("[t](fig4/metrics.csv)") == '<a href="fig4/metrics.csv">t</a>'
    for bad in (
        "javascript:alert(1)",
        "JaVaScRiPt:x",
        "data:text/html,x",
        "http://x.org",
        "/etc/passwd",
        "../x",
    ):
        assert "<a" not in markup.inline(f"[t]({bad})"), bad
    assert markup.inline(markup.md_esc("[x](y) *z* `c` <b>")) == "[x](y) *z* `c` &lt;b&gt;"


def test_cli_prints_markup_as_text_and_tables_whole_in_a_log(tmp_path):
    """Rich markup in names and paths is text ("[/x]" once crashed the CLI after the outputs were written), and
    a table printed where stdout is no terminal keeps every label whole (Rich cut cells at 80 columns)."""
    import subprocess
    import sys

    from tests.conftest import scene_toml, small_scene_dict

    (tmp_path / "s[b].toml").write_text(scene_toml(small_scene_dict()))
    out = tmp_path / "o[/x]"
    args = ["run", str(tmp_path / "s[b].toml"), "-m", "localized(iterations=10)", "-m", "classical"]
    args += ["--set", "render.cube_res=8", "--set", "camera.width=16", "--set", "camera.height=16"]
    res = subprocess.run(
        [sys.executable, "-m", "study.cli", *args, "--out", str(out), "--cache", str(tmp_path / "c")],
        capture_output=True,
        text=True,
        timeout=300,
        env={**__import__("os").environ, "COLUMNS": "80"},
    )
    assert res.returncode == 0, res.stderr
    assert f"run: wrote {out}" in res.stdout and "Traceback" not in res.stderr
    assert "localized(iterations=10)" in res.stdout and "…" not in res.stdout, res.stdout
    assert (out / "table.csv").is_file()


def test_figures_are_discovered_from_configs(tmp_path, monkeypatch):
    """`study figure NAME` knows every configs/fig*.toml (here one in the working directory), no built-in list."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "configs").mkdir()
    (tmp_path / "configs" / "fig_mine.toml").write_text(
        'scene = "nowhere.toml"\npositions = [[0.0, 1.5, 0.0]]\n'
    )
    res = run_cli("figure", "fig_mine")
    assert res.exit_code == 2 and "nowhere.toml" in res.output and "scene file not found" in res.output
    res = run_cli("figure", "fig_nope")
    assert res.exit_code == 2 and "unknown figure 'fig_nope'" in res.output and "fig_mine" in res.output
    assert "fig4" in res.output  # the shipped ones too
