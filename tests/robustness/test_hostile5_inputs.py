"""Hostile round 5 (issue 51, items 5, 6, 7, 9 and the scene file's folder rule): each break reproduced, now one
line naming the file and the key, exit 2, before any work — a sky map checked before Mitsuba reads it, a figure
kind's failures named, a figure too long for its limit refused from its config, notes that say what is wrong."""

import os
import struct
import time
from pathlib import Path

import numpy as np
import pytest

from study.errors import BAD_INPUT, StudyError
from study.scene import load_scene_file

ROOT = Path(__file__).resolve().parents[2]

GROUND = "v -2 0 -2\nv 2 0 -2\nv 2 0 2\nv -2 0 2\nf 1 3 2\nf 1 4 3\n"  # a 4 m floor facing up
SCENE = """[environment]
type = "mesh"
file = "{file}"
sky = "{sky}"
[reference]
point = [0, 1.0, 0]
box = [[-4, -0.01, -4], [4, 6, 4]]
[object]
center = [0, 1.0, 0]
radius = 0.4
[camera]
eye = [0, 1.2, -2.0]
target = [0, 1.0, 0]
width = 16
height = 16
fov = 40
[render]
cube_res = 8
cube_spp = 1
spp = 1
supersample = 1
"""


def exr(path: Path, value=0.5, h=8, w=16, at=None) -> Path:
    """An EXR of ``value`` everywhere (``at``: (row, col, channel, value) planted)."""
    from study.io import write_exr

    a = np.full((h, w, 3), value, np.float32)
    if at is not None:
        a[at[0], at[1], at[2]] = at[3]
    write_exr(path, a)
    return path


def with_window(data: bytes, w: int, h: int) -> bytes:
    """An EXR's bytes with its dataWindow and displayWindow claiming w × h texels (the pixels left as they are)."""
    for name in (b"dataWindow\0box2i\0", b"displayWindow\0box2i\0"):
        i = data.index(name) + len(name) + 4
        data = data[:i] + struct.pack("<4i", 0, 0, w - 1, h - 1) + data[i + 16 :]
    return data


def scene_with_sky(folder: Path, sky: str) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "ground.obj").write_text(GROUND)
    path = folder / "scene.toml"
    path.write_text(SCENE.format(file="ground.obj", sky=sky))
    return path


def refused(path: Path, *words: str) -> str:
    t = time.perf_counter()
    with pytest.raises(StudyError) as e:
        load_scene_file(path)
    msg = str(e.value)
    assert e.value.code == BAD_INPUT and "\n" not in msg, msg
    assert str(path) in msg and "environment.sky" in msg, msg
    assert all(w in msg for w in words), msg
    assert time.perf_counter() - t < 30
    return msg


# ---------------------------------------------------------------------------------------------- 5: sky maps
@pytest.mark.parametrize(
    "make, words",
    [
        (lambda d: exr(d / "sky.exr", -5.0), ["sky.exr", "128 of 128 texels are negative", "R = -5"]),
        (lambda d: exr(d / "sky.exr", at=(3, 4, 1, np.nan)), ["sky.exr", "1 of 128 texels are not finite",
                                                               "row 3, column 4: G = nan"]),
        (lambda d: exr(d / "sky.exr", at=(0, 2, 2, np.inf)), ["sky.exr", "not finite", "B = inf"]),
        (lambda d: (d / "sky.exr").write_bytes(b"\x76\x2f\x31\x01" + b"garbage" * 20), ["sky.exr", "damaged"]),
        (lambda d: (d / "sky.hdr").write_bytes(b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 10 +X 10\n" + b"\1" * 7),
         ["sky.hdr", "damaged image"]),
        (lambda d: (d / "sky.hdr").write_bytes(b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 30000 +X 60000\n"),
         ["sky.hdr", "60000 × 30000 texels", "8192 × 4096"]),
    ],
    ids=["negative", "nan", "inf", "corrupt-exr", "corrupt-hdr", "hdr-60000x30000"],
)  # fmt: skip
def test_a_bad_sky_map_is_refused_naming_the_sky_file_and_key(tmp_path, make, words):
    """Before: the negative map was rendered (−5 radiance in every image), NaN/inf blamed on the mesh file, the
    damaged files ended in exit 4 inside Mitsuba."""
    d = tmp_path / "scene"
    d.mkdir()
    make(d)
    name = next(p.name for p in d.iterdir() if p.suffix in (".exr", ".hdr"))
    msg = refused(scene_with_sky(d, name), *words)
    assert "ground.obj" not in msg  # the sky is to blame, not the mesh


@pytest.mark.parametrize("w, h", [(60000, 30000), (100000, 100000)])
def test_an_exr_header_claiming_too_many_texels_is_refused_before_mitsuba_reads_it(
    tmp_path, monkeypatch, w, h
):
    """A 1 KiB file whose header claims 60000 × 30000 (Mitsuba would allocate 120 GB for it)."""
    from study import runtime

    d = tmp_path / "scene"
    d.mkdir()
    good = exr(d / "good.exr").read_bytes()
    (d / "sky.exr").write_bytes(with_window(good, w, h))
    monkeypatch.setattr(runtime, "mitsuba", lambda *a, **k: pytest.fail("Mitsuba read the claimed texels"))
    refused(scene_with_sky(d, "sky.exr"), f"{w} × {h} texels", "8192 × 4096")


def test_a_symlink_to_a_text_file_is_refused_naming_both(tmp_path):
    d = tmp_path / "scene"
    d.mkdir()
    (d / "notes.txt").write_text("not an image\n")
    os.symlink(d / "notes.txt", d / "sky.exr")
    refused(scene_with_sky(d, "sky.exr"), "sky.exr (a symlink to", "notes.txt", "neither an OpenEXR nor")


def test_a_good_sky_map_still_loads_and_an_edited_one_is_checked_again(tmp_path):
    d = tmp_path / "scene"
    d.mkdir()
    exr(d / "sky.exr", 0.25)
    path = scene_with_sky(d, "sky.exr")
    assert load_scene_file(path).environment.sky == str(d / "sky.exr")
    exr(d / "sky.exr", -1.0, h=4, w=8)  # the same name, other bytes: not taken from the memo
    refused(path, "32 of 32 texels are negative")


def test_a_bad_sky_on_the_command_line_is_exit_2_and_one_line(tmp_path):
    from conftest import run_cli

    d = tmp_path / "scene"
    d.mkdir()
    exr(d / "sky.exr", -5.0)
    res = run_cli("run", scene_with_sky(d, "sky.exr"), "-m", "classical", "--out", tmp_path / "out")
    assert res.exit_code == 2, res.output
    line = res.output.strip().splitlines()[-1]
    assert line.startswith("error: ") and "environment.sky" in line and "negative" in line, line
    assert not (tmp_path / "out").exists()


# ---------------------------------------------------------------------------------------------- the folder rule
@pytest.mark.parametrize(
    "key, value",
    [("sky", "../outside.exr"), ("sky", "ABS"), ("sky", "~/outside.exr"), ("file", "../ground.obj"),
     ("file", "ABS_OBJ")],
)  # fmt: skip
def test_a_scene_file_names_no_file_outside_its_folder(tmp_path, key, value):
    """Before: ``environment.sky = "../x.exr"`` and absolute paths were read from anywhere."""
    exr(tmp_path / "outside.exr")
    (tmp_path / "ground.obj").write_text(GROUND)
    d = tmp_path / "scene"
    path = scene_with_sky(d, "#808080")
    value = {"ABS": str(tmp_path / "outside.exr"), "ABS_OBJ": str(tmp_path / "ground.obj")}.get(value, value)
    text = path.read_text().replace(
        f'{key} = "{"ground.obj" if key == "file" else "#808080"}"', f'{key} = "{value}"'
    )
    path.write_text(text)
    with pytest.raises(StudyError) as e:
        load_scene_file(path)
    msg = str(e.value)
    assert e.value.code == BAD_INPUT and "\n" not in msg
    assert msg.startswith(f"{path}: environment.{key}: ") and str(d) in msg, msg
    assert "absolute path" in msg or "leaves the scene's folder" in msg, msg


def test_the_command_line_may_name_a_file_elsewhere(tmp_path):
    """The map the scene file may not name (outside its folder) the user may name (an override, the API); a
    subfolder is inside."""
    import study

    exr(tmp_path / "outside.exr", 0.3)
    d = tmp_path / "scene"
    (d / "maps").mkdir(parents=True)
    exr(d / "maps" / "sky.exr", 0.2)
    with pytest.raises(StudyError, match="leaves the scene's folder"):
        load_scene_file(scene_with_sky(d, "../outside.exr"))
    path = scene_with_sky(d, "maps/sky.exr")
    assert load_scene_file(path).environment.sky == str(d / "maps" / "sky.exr")
    sc = study.load_scene(path, **{"environment.sky": str(tmp_path / "outside.exr")})
    assert sc.environment.sky == str(tmp_path / "outside.exr")


# ---------------------------------------------------------------------------------------------- 6: figure kinds
KIND = """
import sys
from study.report.kinds import FigureKind, register_kind


def run(config, out, *, name, backend, cache, quality):
    {body}


register_kind(FigureKind(name="{name}", run=run, files=("made.txt",), section=lambda *a: []))
"""


@pytest.mark.parametrize(
    "body, words",
    [
        ('raise KeyError("oops")', "run() failed: KeyError: 'oops'"),
        ("return None", "run() returned None; a kind's run returns a list of rows"),
        ('return "rows"', "run() returned a str ('rows'); a kind's run returns a list"),
        ("return [1, 2]", "run() returned a list holding an int (1)"),
        ("sys.exit(0)", "run() called sys.exit(0)"),
        ("sys.exit(3)", "run() called sys.exit(3)"),
    ],
    ids=["raises", "none", "garbage", "not-dicts", "exit-0", "exit-3"],
)
def test_a_plugin_kind_that_fails_is_one_line_naming_it(tmp_path, monkeypatch, body, words):
    """Before: exit 4 (an internal error) for the exception and the garbage, exit 0 with nothing written for
    sys.exit(0)."""
    import sys

    from conftest import run_cli

    from study.report import kinds

    name = f"bad_{abs(hash(body)) % 10**6}"
    (tmp_path / f"{name}.py").write_text(KIND.replace("{body}", body).replace("{name}", name))
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setenv("STUDY_PLUGINS", "")
    monkeypatch.chdir(tmp_path)
    (tmp_path / "fig.toml").write_text(f'kind = "{name}"\n')
    try:
        res = run_cli("--plugin", name, "figure", "--config", "fig.toml", "--out", tmp_path / "out")
    finally:
        kinds.KINDS.pop(name, None)
        sys.modules.pop(name, None)
    line = res.output.strip().splitlines()[-1] if res.output.strip() else ""
    assert res.exit_code == 2, res.output
    assert line.startswith(f"error: figure kind '{name}' (plug-in {name}): "), line
    assert words in line, line


@pytest.mark.parametrize(
    "kind, words",
    [
        (
            'FigureKind(name="k", run=print, files=(), section=print)',
            "figure kind 'k' declares no files: files",
        ),
        ('FigureKind(name="k", run=print, files="a.txt", section=print)', "declares no files"),
        ('FigureKind(name="k", run=print, files=("../x",), section=print)', "relative to the run's folder"),
        ('FigureKind(name="", run=print, files=("a",), section=print)', "a figure kind's name is the word"),
        ('{"name": "k"}', "register_kind takes a study.report.kinds.FigureKind, not a dict"),
    ],
    ids=["no-files", "files-str", "files-up", "no-name", "a-dict"],
)
def test_a_kind_that_cannot_be_registered_says_why_in_a_sentence(kind, words):
    """Before: the message was the dataclass's repr (``FigureKind(name='k', run=<built-in …>, …) is no …``)."""
    from study.report.kinds import FigureKind, register_kind

    k = eval(kind, {"FigureKind": FigureKind})
    with pytest.raises(StudyError) as e:
        register_kind(k)
    msg = str(e.value)
    assert words in msg and "FigureKind(" not in msg and "<built-in" not in msg, msg


# ---------------------------------------------------------------------------------------------- 7: many seeds
def seeds_config(tmp_path: Path, n: int, positions: int = 2) -> Path:
    pos = ", ".join(f"[{0.1 * i:.1f}, 1.5, 0.0]" for i in range(positions))
    path = tmp_path / f"seeds{n}.toml"
    path.write_text(
        f'scene = "{(ROOT / "scenes" / "room.toml").as_posix()}"\npositions = [{pos}]\nmethods = ["classical"]\n'
        f"seeds = {list(range(n))}\n"
    )
    return path


@pytest.mark.parametrize("n", [100_000, 8_000])
def test_a_figure_with_thousands_of_seeds_is_refused_from_its_config(tmp_path, monkeypatch, n):
    """Before: 100 000 seeds were not refused within 180 s, 8 000 after 45 s blaming camera.width × camera.height
    (every case's scene was validated and priced first). Now the estimate prices the first seed's positions and
    multiplies: at most ESTIMATE_SAMPLE scenes are built, and the refusal names seeds and the limit."""
    from study.harness import config
    from study.scene.schema import Scene

    path = seeds_config(tmp_path, n)
    built = []
    real = Scene.with_updates

    def counted(self, *a, **k):
        built.append(1)
        if len(built) > 2 * config.ESTIMATE_SAMPLE:
            raise AssertionError(f"{len(built)} cases built before the refusal")
        return real(self, *a, **k)

    monkeypatch.setattr(Scene, "with_updates", counted)
    config.load_figure_config(
        ROOT / "configs" / "fig4.toml"
    )  # a shipped figure passes (one scene per position)
    built.clear()
    t = time.perf_counter()
    with pytest.raises(StudyError) as e:
        config.load_figure_config(path)
    took = time.perf_counter() - t
    msg = str(e.value)
    assert e.value.key == "seeds" and "\n" not in msg and msg.startswith(f"{path}: seeds: "), msg
    assert f"2 positions × {n:,} seeds = {2 * n:,} cases" in msg, msg
    assert "over the limit of 120 min (--max-minutes)" in msg and "the axis that costs is seeds" in msg, msg
    assert len(built) <= 2 and took < 15, (len(built), took)  # reading 10⁵ numbers of TOML is most of it


def test_the_estimate_is_the_first_seeds_cases_times_the_seeds(tmp_path):
    """``figure_estimate(config)``: seconds, cases and the breakdown, before any case is built; the seeds multiply the
    first seed's cases (priced one by one by the budget), which the breakdown names."""
    from study.harness import budget, config
    from study.methods import make

    path = seeds_config(tmp_path, 3, positions=4)
    est = config.figure_estimate(path)
    seconds, cases, b = est
    assert cases == 12 and b["axes"] == {"positions": 4, "seeds": 3} and len(b["priced"]) == 4
    scene = config.configured_scene(config.validate_file(config.FigureConfig, path), path)
    own, seen = 0.0, set()
    for i in range(4):
        sc = scene.with_updates({"object.center": [0.1 * i, 1.5, 0.0], "render.seed": 0})
        k = budget.impostor_key(sc)
        own += budget.estimate(sc, [make("classical")], impostor=k not in seen).seconds
        seen.add(k)
    assert seconds == pytest.approx(3 * own, rel=1e-9)
    assert b["per_case"] == pytest.approx(seconds / 12) and sum(b["parts"].values()) == pytest.approx(seconds)


# ---------------------------------------------------------------------------------------------- 9: notes
def test_a_black_reference_is_said_to_be_black_naming_the_key_not_spp_inf():
    """Before: "the truth's own noise is inf% … render.spp ≥ inf (now 2) would bring it under" for a room whose
    only light is off. Every pixel of that render is 0 (no light reaches anything), so every error is 0."""
    import study

    sc = study.load_scene(
        "scenes/room.toml",
        **{"light.enabled": False, "camera.width": 24, "camera.height": 24, "render.cube_res": 8,
           "render.spp": 2, "render.cube_spp": 1, "render.supersample": 1},
    )  # fmt: skip
    res = study.evaluate(sc, ["classical"], backend="numpy")
    assert float(np.abs(res.images["mitsuba"]).max()) == 0.0  # the truth this test is about: black
    notes = res.notes()
    assert len(notes) == 1 and "inf" not in notes[0], notes
    assert notes[0].startswith("Mitsuba's reference is black") and "light.enabled = false" in notes[0], notes


def test_a_truth_black_on_the_object_says_so_and_no_spp():
    """A lit frame (fireflies measured) whose object shows nothing lit: every row's relMSE and the truth's noise 0."""
    import study
    from study.measure import lighting

    sc = study.load_scene("scenes/room.toml")
    rows = [
        {"label": lab, "relmse_truth_exposed": 0.0, "truth_noise_relmse": 0.0, "firefly_fraction": 0.0}
        for lab in ("oracle_map", "truth_at_hit", "classical")
    ]
    assert lighting.noise_note(rows, 2) == ""
    notes = lighting.notes(rows, sc)
    assert (
        len(notes) == 1 and notes[0].startswith("the truth is black on the object") and "inf" not in notes[0]
    )
    rows[2]["relmse_truth_exposed"] = 0.5  # a method that errs: nothing is black, no note
    assert lighting.notes(rows, sc) == []
