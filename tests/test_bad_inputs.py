"""The bad-input corpus: every invalid config or input gives one line naming the file, the key and what is
allowed, exit code 2, no traceback, and leaves what was already written untouched."""
import hashlib
from pathlib import Path

import pytest
from typer.testing import CliRunner

from study.cli import app

ROOT = Path(__file__).resolve().parents[1]
runner = CliRunner()

FIG = """
positions = [{pos}]
grid = ["classical"]
{extra_top}
[scene]
room = {{ min = [-2.0, 0.0, -2.0], max = [2.0, 3.0, 2.0] }}
light = {{ position = [0.3, 2.6, -0.4], intensity = [7.0, 7.0, 7.0] }}
reference = {{ point = {ref} }}
object = {{ center = {center}, radius = {radius}, material = {{ type = "mirror" }} }}
camera = {{ eye = [-0.3, 1.7, -1.9], target = [0.6, 1.1, 0.6], up = {up}, fov = 75.0, width = 24, height = 24 }}
render = {{ cube_res = {cube_res}, cube_spp = 2, spp = 2, max_depth = 3, supersample = 1 }}
{columns}
[[methods]]
name = "{method}"
{method_params}
"""
DEFAULT = dict(pos="[0.6, 1.2, 0.3]", center="[0.6, 1.2, 0.3]", extra_top="", ref="[0.0, 1.5, 0.0]", radius="0.4", up="[0.0, 1.0, 0.0]",
               cube_res="16", columns="", method="classical", method_params="")
COLUMN = '[[scene.columns]]\ncenter = [{c}]\nfootprint = [0.6, 0.6]\nheight = 2.0\n'

SWEEP = """
scene = "{scene}"
{top}
[axes]
{axes}
[[methods]]
name = "localized"
"""

# (id, kind, changes, expected words: file-relative key and what is allowed)
FIGURE_CASES = [
    ("unknown-scene-key", dict(ref="[0.0, 1.5, 0.0], colour = 1"), "scene.reference.colour: unknown key; allowed: point"),
    ("wrong-type", dict(radius='"big"'), "scene.object.radius: Input should be a valid number"),
    ("nan-radius", dict(radius="nan"), "scene.object.radius: Input should be a finite number"),
    ("negative-radius", dict(radius="-0.4"), "scene.object.radius: Input should be greater than 0"),
    ("object-outside-room", dict(pos="[1.9, 1.2, 0.3]"),
     "positions[0]: object.center: the sphere (radius 0.4) must lie inside"),
    ("object-in-column", dict(columns=COLUMN.format(c="0.6, 0.3"), pos="[0.6, 1.2, 0.3]"),
     "scene.object.center: the sphere overlaps columns[0]"),
    ("reference-in-column", dict(columns=COLUMN.format(c="0.0, 0.0"), pos="[1.2, 1.2, 1.2]", center="[1.2, 1.2, 1.2]"),
     "scene.reference.point: lies inside columns[0]"),
    ("reference-outside", dict(ref="[0.0, 3.5, 0.0]"), "scene.reference.point: must lie strictly inside the room"),
    ("iterations-negative", dict(method="localized", method_params="iterations = [-1]"),
     "methods[0].iterations: Input should be greater than or equal to 0"),
    ("cube-res-zero", dict(cube_res="0"), "scene.render.cube_res: Input should be greater than or equal to 4"),
    ("cube-res-float", dict(cube_res="64.5"), "scene.render.cube_res: Input should be a valid integer"),
    ("unknown-method", dict(method="raytrace"), "methods[0].name: unknown method 'raytrace'; allowed: classical"),
    ("unknown-method-param", dict(method="localized", method_params="iters = 3"),
     "methods[0].iters: unknown parameter (parameters of 'localized': iterations"),
    ("up-parallel", dict(up="[0.9, -0.6, 2.5]"), "scene.camera.up: must not be parallel to the viewing direction"),
    ("unknown-top-key", dict(extra_top="colour = 1"), "colour: unknown key; allowed: scene, overrides, positions"),
    ("empty-positions", dict(pos=""), "positions: List should have at least 1 item"),
    ("grid-unknown", dict(extra_top="", method="localized"), "grid: grid names 'classical', which is not among"),
]


@pytest.fixture
def workdir(tmp_path):
    """An output directory holding earlier results, whose bytes must survive every failed command."""
    out = tmp_path / "out"
    out.mkdir()
    (out / "metrics.csv").write_text("case,method\nold,classical\n")
    (out / "fig4.png").write_bytes(b"\x89PNG earlier figure")
    return tmp_path


def digest(d: Path) -> dict:
    return {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in sorted(d.rglob("*")) if p.is_file()}


def assert_one_line_error(res, words, before, out):
    text = res.output.strip()
    assert res.exit_code == 2, res.output
    assert text.startswith("error: ") and "\n" not in text, text
    assert words in text, text
    assert "Traceback" not in text
    assert digest(out) == before


@pytest.mark.parametrize("case_id, changes, words", FIGURE_CASES, ids=[c[0] for c in FIGURE_CASES])
def test_bad_figure_config(workdir, case_id, changes, words):
    cfg = workdir / "bad.toml"
    cfg.write_text(FIG.format(**{**DEFAULT, **changes}))
    before = digest(workdir / "out")
    res = runner.invoke(app, ["figure", "fig4", "--config", str(cfg), "--out", str(workdir / "out"),
                              "--cache", str(workdir / "cache")])
    sep = " " if words.startswith("positions[") else ": "
    assert_one_line_error(res, f"{cfg}{sep}{words}" if not words.startswith("grid") else words, before,
                          workdir / "out")


SWEEP_CASES = [
    ("sweep-unknown-key", dict(top="colour = 1", axes=""), "colour: unknown key; allowed: scene, seed"),
    ("sweep-empty-axis", dict(top="", axes='"render.cube_res" = []'), "axes.render.cube_res: an axis needs at least"),
    ("sweep-zip-mismatch", dict(top='zip = [["render.cube_res", "object.radius"]]',
                                axes='"render.cube_res" = [16, 32]\n"object.radius" = [0.3]'),
     "zip[0]: zipped axes need the same number of values"),
    ("sweep-bad-axis-key", dict(top="", axes='"object.radiuss" = [0.3]'), "axes.object.radiuss: unknown scene key"),
    ("sweep-axis-value-invalid", dict(top="", axes='"object.radius" = [0.3, 5.0]'),
     "axes.object.center: the sphere (radius 5.0) must lie inside"),
    ("sweep-negative-seed", dict(top="seed = -1", axes=""), "seed: Input should be greater than or equal to 0"),
]


@pytest.mark.parametrize("case_id, changes, words", SWEEP_CASES, ids=[c[0] for c in SWEEP_CASES])
def test_bad_sweep_config(workdir, case_id, changes, words):
    cfg = workdir / "bad.toml"
    cfg.write_text(SWEEP.format(scene=ROOT / "scenes" / "room.toml", **changes))
    before = digest(workdir / "out")
    res = runner.invoke(app, ["sweep", str(cfg), "--out", str(workdir / "out"), "--cache", str(workdir / "cache")])
    assert_one_line_error(res, f"{cfg}: {words}", before, workdir / "out")


def test_missing_files_and_bad_toml(workdir):
    before = digest(workdir / "out")
    for args, words in [
        (["figure", "fig4", "--config", str(workdir / "nope.toml")], "nope.toml: config file not found"),
        (["sweep", str(workdir / "nope.toml")], "nope.toml: config file not found"),
        (["check", "--config", str(workdir / "nope.toml")], "nope.toml: config file not found"),
    ]:
        assert_one_line_error(runner.invoke(app, args), words, before, workdir / "out")
    bad = workdir / "broken.toml"
    bad.write_text("positions = [[0, 1")
    assert_one_line_error(runner.invoke(app, ["figure", "fig4", "--config", str(bad)]), "broken.toml: not valid TOML",
                          before, workdir / "out")
    cfg = workdir / "s.toml"
    cfg.write_text(FIG.format(**DEFAULT).replace("[scene]\n", "scene = \"missing-scene.toml\"\n[x]\n", 1)
                   .split("[x]")[0] + "\n[[methods]]\nname = \"classical\"\n")
    assert_one_line_error(runner.invoke(app, ["figure", "fig4", "--config", str(cfg)]),
                          "missing-scene.toml: scene file not found", before, workdir / "out")


def test_unwritable_output_and_bad_options(workdir):
    before = digest(workdir / "out")
    blocker = workdir / "a-file"
    blocker.write_text("not a directory")
    cfg = workdir / "ok.toml"
    cfg.write_text(FIG.format(**DEFAULT))
    res = runner.invoke(app, ["figure", "fig4", "--config", str(cfg), "--out", str(blocker / "sub")])
    assert_one_line_error(res, "cannot create the output directory", before, workdir / "out")
    res = runner.invoke(app, ["figure", "fig4", "--config", str(cfg), "--backend", "opengl"])
    assert_one_line_error(res, "backend: unknown backend 'opengl'; allowed: numpy, llvm, cuda", before,
                          workdir / "out")
    res = runner.invoke(app, ["figure", "fig9"])
    assert_one_line_error(res, "name: unknown figure 'fig9'; allowed: fig4", before, workdir / "out")


def test_corrupted_cached_impostor_is_recomputed_not_trusted(workdir):
    """A damaged cache entry is never trusted: the figure is recomputed and comes out identical."""
    from study.tables import read_csv
    cfg = workdir / "ok.toml"
    cfg.write_text(FIG.format(**DEFAULT))
    args = ["figure", "fig4", "--config", str(cfg), "--cache", str(workdir / "cache")]
    assert runner.invoke(app, args + ["--out", str(workdir / "a")]).exit_code == 0
    for exr in (workdir / "cache" / "radiance").glob("*.exr"):
        data = bytearray(exr.read_bytes())
        data[len(data) // 2:] = bytes(len(data) - len(data) // 2)        # zero the second half
        exr.write_bytes(bytes(data))
    for js in (workdir / "cache" / "distance").glob("*.json"):
        js.write_text("{not json")
    assert runner.invoke(app, args + ["--out", str(workdir / "b")]).exit_code == 0
    a, b = read_csv(workdir / "a" / "metrics.csv"), read_csv(workdir / "b" / "metrics.csv")
    keys = [k for k in a[0] if k not in ("seconds", "case_seconds")]
    assert [[r[k] for k in keys] for r in a] == [[r[k] for k in keys] for r in b]
