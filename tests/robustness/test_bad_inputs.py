"""The bad-input corpus: every invalid config or input gives one line naming the file, the key and what is
allowed, exit code 2 (3 for a problem of the environment: libLLVM, GPU, disk, lock), no traceback, and leaves
what was already written untouched (byte for byte, no temporary or lock file left)."""

import errno
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import pytest
from conftest import assert_one_line_error, digest, run_cli

ROOT = Path(__file__).resolve().parents[2]

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
DEFAULT = dict(
    pos="[0.6, 1.2, 0.3]",
    center="[0.6, 1.2, 0.3]",
    extra_top="",
    ref="[0.0, 1.5, 0.0]",
    radius="0.4",
    up="[0.0, 1.0, 0.0]",
    cube_res="16",
    columns="",
    method="classical",
    method_params="",
)
COLUMN = "[[scene.columns]]\ncenter = [{c}]\nfootprint = [0.6, 0.6]\nheight = 2.0\n"

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
    (
        "unknown-scene-key",
        dict(ref="[0.0, 1.5, 0.0], colour = 1"),
        "scene.reference.colour: unknown key; allowed: point",
    ),
    ("wrong-type", dict(radius='"big"'), "scene.object.radius: Input should be a valid number"),
    ("nan-radius", dict(radius="nan"), "scene.object.radius: Input should be a finite number"),
    ("negative-radius", dict(radius="-0.4"), "scene.object.radius: Input should be greater than 0"),
    (
        "object-outside-room",
        dict(pos="[1.9, 1.2, 0.3]"),
        "positions[0]: object.center: the sphere (radius 0.4) must lie inside",
    ),
    (
        "object-in-column",
        dict(columns=COLUMN.format(c="0.6, 0.3"), pos="[0.6, 1.2, 0.3]"),
        "scene.object.center: the sphere overlaps columns[0]",
    ),
    (
        "reference-in-column",
        dict(columns=COLUMN.format(c="0.0, 0.0"), pos="[1.2, 1.2, 1.2]", center="[1.2, 1.2, 1.2]"),
        "scene.reference.point: lies inside columns[0]",
    ),
    (
        "reference-outside",
        dict(ref="[0.0, 3.5, 0.0]"),
        "scene.reference.point: must lie strictly inside the room",
    ),
    (
        "iterations-negative",
        dict(method="localized", method_params="iterations = [-1]"),
        "methods[0].iterations: Input should be greater than or equal to 0",
    ),
    (
        "cube-res-zero",
        dict(cube_res="0"),
        "scene.render.cube_res: Input should be greater than or equal to 4",
    ),
    ("cube-res-float", dict(cube_res="64.5"), "scene.render.cube_res: Input should be a valid integer"),
    (
        "unknown-method",
        dict(method="raytrace"),
        "methods[0].name: unknown method 'raytrace'; allowed: classical",
    ),
    (
        "unknown-method-param",
        dict(method="localized", method_params="iters = 3"),
        "methods[0].iters: unknown parameter (parameters of 'localized': iterations",
    ),
    (
        "up-parallel",
        dict(up="[0.9, -0.6, 2.5]"),
        "scene.camera.up: must not be parallel to the viewing direction",
    ),
    (
        "unknown-top-key",
        dict(extra_top="colour = 1"),
        "colour: unknown key; allowed: scene, overrides, positions",
    ),
    ("empty-positions", dict(pos=""), "positions: List should have at least 1 item"),
    (
        "grid-unknown",
        dict(extra_top="", method="localized"),
        "grid: grid names 'classical', which is not among",
    ),
]


@pytest.fixture
def workdir(tmp_path):
    """An output directory holding earlier results, whose bytes must survive every failed command."""
    out = tmp_path / "out"
    out.mkdir()
    (out / "metrics.csv").write_text("case,method\nold,classical\n")
    (out / "fig4.png").write_bytes(b"\x89PNG earlier figure")
    return tmp_path


@pytest.mark.parametrize("case_id, changes, words", FIGURE_CASES, ids=[c[0] for c in FIGURE_CASES])
def test_bad_figure_config(workdir, case_id, changes, words):
    cfg = workdir / "bad.toml"
    cfg.write_text(FIG.format(**{**DEFAULT, **changes}))
    before = digest(workdir / "out")
    res = run_cli(
        *[
            "figure",
            "fig4",
            "--config",
            str(cfg),
            "--out",
            str(workdir / "out"),
            "--cache",
            str(workdir / "cache"),
        ],
    )
    sep = " " if words.startswith("positions[") else ": "
    assert_one_line_error(
        res, f"{cfg}{sep}{words}" if not words.startswith("grid") else words, before, workdir / "out"
    )


SWEEP_CASES = [
    ("sweep-unknown-key", dict(top="colour = 1", axes=""), "colour: unknown key; allowed: scene, seed"),
    (
        "sweep-empty-axis",
        dict(top="", axes='"render.cube_res" = []'),
        "axes.render.cube_res: an axis needs at least",
    ),
    (
        "sweep-zip-mismatch",
        dict(
            top='zip = [["render.cube_res", "object.radius"]]',
            axes='"render.cube_res" = [16, 32]\n"object.radius" = [0.3]',
        ),
        "zip[0]: zipped axes need the same number of values",
    ),
    (
        "sweep-bad-axis-key",
        dict(top="", axes='"object.radiuss" = [0.3]'),
        "axes.object.radiuss: unknown scene key",
    ),
    (
        "sweep-axis-value-invalid",
        dict(top="", axes='"object.radius" = [0.3, 5.0]'),
        "axes.object.center: the sphere (radius 5.0) must lie inside",
    ),
    (
        "sweep-negative-seed",
        dict(top="seed = -1", axes=""),
        "seed: Input should be greater than or equal to 0",
    ),
]


@pytest.mark.parametrize("case_id, changes, words", SWEEP_CASES, ids=[c[0] for c in SWEEP_CASES])
def test_bad_sweep_config(workdir, case_id, changes, words):
    cfg = workdir / "bad.toml"
    cfg.write_text(SWEEP.format(scene=ROOT / "scenes" / "room.toml", **changes))
    before = digest(workdir / "out")
    res = run_cli("sweep", str(cfg), "--out", str(workdir / "out"), "--cache", str(workdir / "cache"))
    assert_one_line_error(res, f"{cfg}: {words}", before, workdir / "out")


def test_missing_files_and_bad_toml(workdir):
    before = digest(workdir / "out")
    for args, words in [
        (["figure", "fig4", "--config", str(workdir / "nope.toml")], "nope.toml: config file not found"),
        (["sweep", str(workdir / "nope.toml")], "nope.toml: config file not found"),
        (["check", "--config", str(workdir / "nope.toml")], "nope.toml: config file not found"),
    ]:
        assert_one_line_error(run_cli(*args), words, before, workdir / "out")
    bad = workdir / "broken.toml"
    bad.write_text("positions = [[0, 1")
    assert_one_line_error(
        run_cli("figure", "fig4", "--config", str(bad)),
        "broken.toml: not valid TOML",
        before,
        workdir / "out",
    )
    cfg = workdir / "s.toml"
    cfg.write_text(
        FIG.format(**DEFAULT).replace("[scene]\n", 'scene = "missing-scene.toml"\n[x]\n', 1).split("[x]")[0]
        + '\n[[methods]]\nname = "classical"\n'
    )
    assert_one_line_error(
        run_cli("figure", "fig4", "--config", str(cfg)),
        "missing-scene.toml: scene file not found",
        before,
        workdir / "out",
    )


def test_unwritable_output_and_bad_options(workdir):
    before = digest(workdir / "out")
    blocker = workdir / "a-file"
    blocker.write_text("not a directory")
    cfg = workdir / "ok.toml"
    cfg.write_text(FIG.format(**DEFAULT))
    res = run_cli("figure", "fig4", "--config", str(cfg), "--out", str(blocker / "sub"))
    assert_one_line_error(res, "cannot create the output directory", before, workdir / "out")
    res = run_cli("figure", "fig4", "--config", str(cfg), "--backend", "opengl")
    assert_one_line_error(
        res, "backend: unknown backend 'opengl'; allowed: numpy, llvm, cuda", before, workdir / "out"
    )
    res = run_cli("figure", "fig9")
    assert_one_line_error(res, "name: unknown figure 'fig9'; allowed: fig4", before, workdir / "out")


def test_corrupted_cached_impostor_is_recomputed_not_trusted(workdir):
    """A damaged cache entry is never trusted: the figure is recomputed and comes out identical."""
    from study.tables import read_csv

    cfg = workdir / "ok.toml"
    cfg.write_text(FIG.format(**DEFAULT))
    args = ["figure", "fig4", "--config", str(cfg), "--cache", str(workdir / "cache")]
    assert run_cli(*args + ["--out", str(workdir / "a")]).exit_code == 0
    for arr in (workdir / "cache" / "radiance").glob("*.npy"):
        data = bytearray(arr.read_bytes())
        data[len(data) // 2 :] = bytes(len(data) - len(data) // 2)  # zero the second half
        arr.write_bytes(bytes(data))
    for js in (workdir / "cache" / "distance").glob("*.json"):
        js.write_text("{not json")
    assert run_cli(*args + ["--out", str(workdir / "b")]).exit_code == 0
    a, b = read_csv(workdir / "a" / "metrics.csv"), read_csv(workdir / "b" / "metrics.csv")
    keys = [k for k in a[0] if k not in ("seconds", "case_seconds")]
    assert [[r[k] for k in keys] for r in a] == [[r[k] for k in keys] for r in b]


# ---------------------------------------------------------------------------------------------- more classes
def fig_args(w: Path, **changes) -> list[str]:
    cfg = w / "bad.toml"
    cfg.write_text(FIG.format(**{**DEFAULT, **changes}))
    return ["figure", "fig4", "--config", str(cfg), "--out", str(w / "out"), "--cache", str(w / "cache")]


def over(text: str) -> dict:
    """Scene overrides of the figure config (its [overrides] table, inline)."""
    return dict(extra_top=f"overrides = {{ {text} }}")


def sweep_args(w: Path, top: str = "", axes: str = "") -> list[str]:
    cfg = w / "bad.toml"
    cfg.write_text(SWEEP.format(scene=ROOT / "scenes" / "room.toml", top=top, axes=axes))
    return ["sweep", str(cfg), "--out", str(w / "out"), "--cache", str(w / "cache")]


def scene_file(w: Path, data: bytes | None) -> list[str]:
    """A figure config whose scene file is a directory (``data`` None) or holds ``data``."""
    scene = w / "scene.toml"
    scene.mkdir() if data is None else scene.write_bytes(data)
    cfg = w / "bad.toml"
    cfg.write_text(f'scene = "{scene}"\npositions = [[0.6, 1.2, 0.3]]\n')
    return ["figure", "fig4", "--config", str(cfg), "--out", str(w / "out")]


def bench_args(w: Path, *opts: str) -> list[str]:
    return ["bench", "--out", str(w / "out"), *opts]


def check_args(w: Path, baseline: str | bytes, tolerance: str = "abs = 0.1, rel = 0.0") -> list[str]:
    """A check file whose baseline (its spread table, under out/, beside the earlier results) holds
    ``baseline``."""
    (w / "out" / "spread.csv").write_bytes(baseline.encode() if isinstance(baseline, str) else baseline)
    cfg = w / "check.toml"
    cfg.write_text(
        f'sweep = "{ROOT / "configs" / "check_sweep.toml"}"\nbaseline = "out"\n'
        f"[tolerance]\nangle_median_deg = {{ {tolerance} }}\n"
    )
    return ["check", "--config", str(cfg), "--cache", str(w / "cache")]


def report_args(w: Path, table: bytes) -> list[str]:
    (w / "fig9").mkdir()
    (w / "fig9" / "metrics.csv").write_bytes(table)
    return ["report", "--reports", str(w)]


def llvm(w: Path, mp, path) -> list[str]:
    mp.setenv("DRJIT_LIBLLVM_PATH", str(path(w)) if callable(path) else path)
    return fig_args(w)


def fake_lib(name: str, data: bytes = b"not a shared library\n"):
    def make(w: Path) -> Path:
        (w / name).write_bytes(data)
        return w / name

    return make


def fail_os(mp, target: str, err: int) -> None:
    """Make ``tempfile.<target>`` (every temporary directory or file study writes through) fail with ``err``."""

    def boom(*a, **k):
        raise OSError(err, os.strerror(err))

    mp.setattr(tempfile, target, boom)


def hold_lock(w: Path, mp) -> list[str]:
    import fcntl

    f = open(w / "out" / ".lock", "a+")
    fcntl.flock(f, fcntl.LOCK_EX | fcntl.LOCK_NB)
    mp.setattr(sys.modules[__name__], "_held", f, raising=False)  # kept open for the test, closed at its end
    return fig_args(w)


BASE_HEADER = "case,method,label,angle_median_deg\n"

# (id, args(workdir, monkeypatch), words, exit code)
MORE_CASES = [
    # strict types: booleans and strings are not numbers
    (
        "radius-bool",
        lambda w, mp: fig_args(w, radius="true"),
        "scene.object.radius: Input should be a valid number, not a boolean",
        2,
    ),
    (
        "radius-string",
        lambda w, mp: fig_args(w, radius='"0.4"'),
        "scene.object.radius: Input should be a valid number, not a string",
        2,
    ),
    (
        "cube-res-bool",
        lambda w, mp: fig_args(w, cube_res="true"),
        "scene.render.cube_res: Input should be a valid integer, not a boolean",
        2,
    ),
    (
        "up-string",
        lambda w, mp: fig_args(w, up='[0.0, "1", 0.0]'),
        "scene.camera.up.1: Input should be a valid number, not a string",
        2,
    ),
    (
        "panel-not-bool",
        lambda w, mp: fig_args(w, extra_top='occlusion_panel = "yes"'),
        "occlusion_panel: Input should be a valid boolean",
        2,
    ),
    # seeds and sample counts beyond 32 bits
    (
        "seed-overflow",
        lambda w, mp: fig_args(w, **over('"render.seed" = 4294967296')),
        "[overrides]: render.seed: Input should be less than or equal to 2147483647",
        2,
    ),
    (
        "spp-overflow",
        lambda w, mp: fig_args(w, **over('"render.spp" = 1099511627776')),
        "[overrides]: render.spp: Input should be less than or equal to 2147483647",
        2,
    ),
    (
        "sweep-seed-overflow",
        lambda w, mp: sweep_args(w, top="seed = 4294967296"),
        "bad.toml: seed: Input should be less than or equal to 2147483647",
        2,
    ),
    # method parameters: inf, nan, booleans, strings
    (
        "param-inf",
        lambda w, mp: fig_args(w, method="localized", method_params="band_hi = inf"),
        "bad.toml: methods[0].band_hi: Input should be a finite number, got inf",
        2,
    ),
    (
        "param-nan",
        lambda w, mp: fig_args(w, method="localized", method_params="band_lo = nan"),
        "methods[0].band_lo: Input should be a finite number",
        2,
    ),
    (
        "param-inf-in-list",
        lambda w, mp: fig_args(w, method="localized", method_params="iterations = [1, inf]"),
        "methods[0].iterations: Input should be a finite number",
        2,
    ),
    (
        "param-bool",
        lambda w, mp: fig_args(w, method="localized", method_params="iterations = true"),
        "methods[0].iterations: Input should be a valid number, not a boolean",
        2,
    ),
    (
        "param-string",
        lambda w, mp: fig_args(w, method="localized", method_params='iterations = "3"'),
        "methods[0].iterations: Input should be a valid number, not a string",
        2,
    ),
    # files that are directories or not UTF-8
    (
        "scene-is-directory",
        lambda w, mp: scene_file(w, None),
        "scene.toml: is a directory, expected a scene file",
        2,
    ),
    (
        "scene-not-utf8",
        lambda w, mp: scene_file(w, b"[room]\nmin = \xff\xfe\n"),
        "scene.toml: not UTF-8 text, expected a scene file",
        2,
    ),
    (
        "config-is-directory",
        lambda w, mp: ["figure", "fig4", "--config", str(w)],
        "is a directory, expected a config file",
        2,
    ),
    # in range but empty or overflowing
    (
        "object-out-of-view",
        lambda w, mp: fig_args(w, **over('"camera.target" = [-0.3, 1.7, -3.0]')),
        "bad.toml: object.center: the camera does not see the object (case fig4-p0)",
        2,
    ),
    (
        "too-few-object-pixels",
        lambda w, mp: fig_args(w, radius="0.05"),
        "bad.toml positions[0]: object.center: the camera sees 1 pixel(s) fully on the object, at least 4",
        2,
    ),
    (
        "light-overflows-float32",
        lambda w, mp: fig_args(w, **over('"light.intensity" = [1e39, 1e39, 1e39]')),
        "bad.toml positions[0]: light.intensity: the impostor radiance is not finite",
        2,
    ),
    (
        "sweep-out-of-view",
        lambda w, mp: sweep_args(w, axes='"camera.target" = [[0.0, 1.5, -3.0]]'),
        "bad.toml: object.center: the camera does not see the object (case c0000)",
        2,
    ),
    # the resource guard
    (
        "memory-budget",
        lambda w, mp: fig_args(
            w, **over('"camera.width" = 4096, "camera.height" = 4096, "render.supersample" = 8')
        ),
        "bad.toml: render.supersample: case fig4-p0 would need about",
        2,
    ),
    (
        "time-budget",
        lambda w, mp: fig_args(w, **over('"render.spp" = 2000000000')),
        "bad.toml: render.spp: case fig4-p0 would take about",
        2,
    ),
    (
        "sweep-time-budget",
        lambda w, mp: sweep_args(w, axes='"render.spp" = [2, 2000000000]'),
        "bad.toml: render.spp: 2 cases would take about",
        2,
    ),
    (
        "max-memory-option",
        lambda w, mp: ["--max-memory", "0.1", *fig_args(w)],
        "over the limit of 0.1 GiB (--max-memory)",
        2,
    ),
    (
        "max-minutes-option",
        lambda w, mp: ["--max-minutes", "0.001", *fig_args(w)],
        "over the limit of 0.001 min (--max-minutes)",
        2,
    ),
    (
        "max-minutes-zero",
        lambda w, mp: ["--max-minutes", "0", *fig_args(w)],
        "--max-minutes: must be a positive number of minutes, got 0.0",
        2,
    ),
    (
        "max-memory-nan",
        lambda w, mp: ["--max-memory", "nan", *fig_args(w)],
        "--max-memory: must be a positive number of GiB",
        2,
    ),
    # bench options: 0, negative or huge
    (
        "bench-repeats-zero",
        lambda w, mp: bench_args(w, "--repeats", "0"),
        "--repeats: must be an integer in 1..1000, got 0",
        2,
    ),
    (
        "bench-repeats-negative",
        lambda w, mp: bench_args(w, "--repeats", "-3"),
        "--repeats: must be an integer",
        2,
    ),
    (
        "bench-rays-huge",
        lambda w, mp: bench_args(w, "--rays", str(10**12)),
        "--rays: must be an integer in 1..",
        2,
    ),
    (
        "bench-scene-res-zero",
        lambda w, mp: bench_args(w, "--scene-res", "0"),
        "--scene-res: must be an integer",
        2,
    ),
    (
        "bench-cube-res-huge",
        lambda w, mp: bench_args(w, "--cube-res", "100000"),
        "--cube-res: must be an integer",
        2,
    ),
    (
        "bench-numpy-rays-zero",
        lambda w, mp: bench_args(w, "--numpy-max-rays", "0"),
        "--numpy-max-rays: must be",
        2,
    ),
    ("bench-tag-path", lambda w, mp: bench_args(w, "--tag", "../x"), "--tag: must be letters, digits", 2),
    (
        "bench-position",
        lambda w, mp: bench_args(w, "--position", "99"),
        "positions: position 99 out of range",
        2,
    ),
    (
        "bench-memory",
        lambda w, mp: ["--max-memory", "2", *bench_args(w, "--scene-res", "4096")],  # fig4's case: 1.1 GiB
        "--scene-res: the ray batches would need about",
        2,
    ),
    # check and report: malformed tables are bad input (2), never a regression (1)
    (
        "check-baseline-not-utf8",
        lambda w, mp: check_args(w, b"case,label\n\xff\xfe\n"),
        "spread.csv: not UTF-8 text, expected a spread table",
        2,
    ),
    (
        "check-baseline-no-columns",
        lambda w, mp: check_args(w, "a,b\n1,2\n"),
        "spread.csv: malformed spread table: no column 'case'",
        2,
    ),
    (
        "check-baseline-ragged",
        lambda w, mp: check_args(w, BASE_HEADER + "c0,m,m,1.0,extra\n"),
        "malformed spread table: line 2 has 5 cells, the header 4",
        2,
    ),
    (
        "check-baseline-not-number",
        lambda w, mp: check_args(w, BASE_HEADER + "c0,m,m,fast\n"),
        "line 2, column 'angle_median_deg' holds 'fast', not a number",
        2,
    ),
    ("check-baseline-empty", lambda w, mp: check_args(w, ""), "malformed spread table: no column 'case'", 2),
    (
        "check-tolerance-bool",
        lambda w, mp: check_args(w, BASE_HEADER, "abs = true, rel = 0.0"),
        "tolerance.angle_median_deg.abs: Input should be a valid number, not a boolean",
        2,
    ),
    (
        "report-malformed-table",
        lambda w, mp: report_args(w, b"case,label\nc0,m,oops\n"),
        "fig9/metrics.csv: malformed results table: line 2 has 3 cells",
        2,
    ),
    ("report-not-utf8", lambda w, mp: report_args(w, b"\xff\xfe\x00"), "fig9/metrics.csv: not UTF-8 text", 2),
    (
        "report-missing-directory",
        lambda w, mp: ["report", "--reports", str(w / "nope")],
        "nope: no such directory",
        2,
    ),
    # the environment (exit 3): libLLVM, GPU, disk, permissions, another command
    ("llvm-not-a-library", lambda w, mp: llvm(w, mp, fake_lib("libLLVM-19.so")), "DRJIT_LIBLLVM_PATH=", 3),
    (
        "llvm-15-by-name",
        lambda w, mp: llvm(w, mp, fake_lib("libLLVM-15.so")),
        "it is libLLVM 15, Dr.Jit needs >= 16",
        3,
    ),
    (
        "llvm-missing",
        lambda w, mp: llvm(w, mp, lambda w: w / "libLLVM-18.so"),
        "cannot use it for Dr.Jit's LLVM backend: no such file",
        3,
    ),
    ("llvm-not-llvm", lambda w, mp: llvm(w, mp, "/lib/x86_64-linux-gnu/libc.so.6"), "not a libLLVM", 3),
    (
        "output-read-only",
        lambda w, mp: (fail_os(mp, "mkdtemp", errno.EROFS), fig_args(w))[1],
        "cannot write beside the output directory (Read-only file system)",
        3,
    ),
    (
        "output-disk-full",
        lambda w, mp: (fail_os(mp, "mkstemp", errno.ENOSPC), fig_args(w))[1],
        "No space left on device",
        3,
    ),
    ("output-locked", hold_lock, "out: another study command is writing to this directory", 3),
]


@pytest.mark.parametrize("case_id, args, words, code", MORE_CASES, ids=[c[0] for c in MORE_CASES])
def test_bad_input_classes(workdir, monkeypatch, case_id, args, words, code):
    if case_id == "llvm-not-llvm" and not Path("/lib/x86_64-linux-gnu/libc.so.6").exists():
        pytest.skip("no glibc at the Debian path")
    out = workdir / "out"
    argv = args(workdir, monkeypatch)
    before = digest(out)
    res = run_cli(*argv)
    monkeypatch.undo()
    if case_id == "output-locked":
        before.pop(".lock")
        (out / ".lock").unlink()
    assert_one_line_error(res, words, before, out, code=code)
    assert not [p for p in workdir.iterdir() if p.name.startswith(".")], (
        "temporary files left beside the outputs"
    )
    assert not (workdir / "index.md").exists()


def test_cuda_without_a_gpu_is_the_environment(workdir):
    from study import backend

    try:
        backend.get("cuda")
        pytest.skip("this machine has a GPU")
    except Exception:
        pass
    before = digest(workdir / "out")
    res = run_cli(*fig_args(workdir) + ["--backend", "cuda"])
    assert_one_line_error(
        res, "backend: the cuda backend needs an NVIDIA GPU", before, workdir / "out", code=3
    )


def test_corpus_size():
    assert len(FIGURE_CASES) + len(SWEEP_CASES) + len(MORE_CASES) >= 45


def test_internal_error_is_one_line_unless_debug(workdir, monkeypatch):
    """An unexpected exception (a bug) is one line with exit code 4; --debug lets its traceback through."""

    def broken(*a, **k):
        raise ValueError("something\nunexpected")

    # inside study's own grid runner (a plug-in kind's exception is bad input, exit 2: study.report.kinds)
    monkeypatch.setattr("study.outputs.figures._figure", broken)
    before = digest(workdir / "out")
    res = run_cli(*fig_args(workdir))
    assert_one_line_error(
        res, "internal error (ValueError: something); please report it", before, workdir / "out", code=4
    )
    res = run_cli("--debug", *fig_args(workdir))
    assert isinstance(res.exception, ValueError)


def test_usage_error_is_one_line():
    """Typer's own errors (an option that is not a number) are one line too from the `study` executable."""
    res = subprocess.run(
        [sys.executable, "-m", "study.cli", "bench", "--repeats", "many"],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert res.returncode == 2, res.stderr
    text = (res.stdout + res.stderr).strip()
    assert (
        text.startswith("error: ") and "\n" not in text and "'--repeats'" in text and "valid integer" in text
    ), text


def test_methods_by_bare_name_and_a_misspelt_one():
    """``methods = ["classical", …]`` names a method with its defaults; a misspelt name is one line listing names."""
    from study.errors import StudyError
    from study.harness.config import expand_methods

    assert [
        m.label for m in expand_methods(["classical", {"name": "localized", "iterations": 2}], source="c")
    ] == ["classical", "localized(iterations=2)"]
    with pytest.raises(StudyError) as e:
        expand_methods(["all", "clasical"], source="c.toml")
    assert str(e.value).startswith(
        'c.toml: methods[1]: unknown method \'clasical\'; allowed: "all", "glossy", classical'
    )


def test_a_cache_that_cannot_be_written_ends_the_command_on_one_line(workdir):
    """The cache's entries are written off the case's thread (study.cache's writer): a write that fails still ends
    the command with one line naming the cache, exit 2, and the earlier outputs untouched."""
    cfg = workdir / "ok.toml"
    cfg.write_text(FIG.format(**DEFAULT))
    (workdir / "plain").write_text("a file where the cache's directory would be")
    before = digest(workdir / "out")
    res = run_cli("figure", "fig4", "--config", str(cfg), "--cache", str(workdir / "plain" / "cache"),
                  "--out", str(workdir / "out"))  # fmt: skip
    assert_one_line_error(res, "cannot write the cache", before, workdir / "out")
