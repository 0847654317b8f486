"""The Python API (study.load_scene, study.evaluate → Result): its maps agree with the table that run_case's metrics
computed on their own (FLIP map mean = flip_truth, RMS of the error map = rmse_truth), save() round-trips and is
one output set, sources and overrides are read as the CLI reads them, and examples/quickstart.py runs (a method
registered there is measured)."""

import json
import runpy
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import study
from study import methods
from study.errors import StudyError
from tests.conftest import scene_toml, small_scene_dict

ROOT = Path(__file__).resolve().parents[1]
TINY = {"render.cube_res": 16, "camera.width": 32, "camera.height": 32}


@pytest.fixture(scope="module")
def result(tmp_path_factory):
    d = small_scene_dict()
    return study.evaluate(
        d, ["classical", "localized(iterations=3)"], overrides=TINY, cache=tmp_path_factory.mktemp("cache")
    )


def test_import_study_stays_light():
    """``import study`` imports neither the API nor pandas, mitsuba or the scene model until asked."""
    code = (
        "import sys, study; heavy = [m for m in ('study.api', 'pandas', 'mitsuba', 'study.scene') "
        "if m in sys.modules]; print(heavy); assert not heavy; study.load_scene; assert 'study.api' in sys.modules"
    )
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT)
    assert res.returncode == 0, res.stdout + res.stderr


def test_table_rows_and_maps(result):
    t = result.table
    assert list(t["label"]) == ["oracle_map", "truth_at_hit", "classical", "localized(iterations=3)"]
    assert {"wrong_fraction", "rmse_truth", "flip_truth", "family", "knob_value"} <= set(t.columns)
    mask = result.mask
    assert mask.shape == (32, 32) and mask.sum() > 20
    for label in ["classical", "localized(iterations=3)", "oracle_map"]:
        row = t.set_index("label").loc[label]
        assert result.images[label].shape == (32, 32, 3)
        # the API's maps against the table's numbers (computed by metrics.image_errors on their own)
        assert np.nanmean(result.flip_maps[label][mask]) == pytest.approx(row["flip_truth"], rel=1e-5)
        assert np.sqrt(np.mean(result.error_maps[label][mask] ** 2)) == pytest.approx(
            row["rmse_truth"], rel=1e-6
        )
        assert (
            np.isnan(result.error_maps[label][~mask]).all() and np.isnan(result.flip_maps[label][~mask]).all()
        )
    for label in ["classical", "localized(iterations=3)"]:
        row = t.set_index("label").loc[label]
        assert np.nanmedian(result.angle_maps[label][mask]) == pytest.approx(row["angle_median_deg"], rel=0.5)
        codes = result.outcome_maps[label][mask]
        assert set(np.unique(codes)) <= {0, 1, 2, 3}
    # classical is clearly wrong off the reference point, localized is not: the maps say so pixel by pixel
    assert np.nanmean(result.outcome_maps["classical"][mask] != 0) > 0.5
    assert np.nanmean(result.outcome_maps["localized(iterations=3)"][mask] != 0) < 0.1
    assert {"mitsuba", "truth_at_hit", "oracle_map"} <= set(result.images)


def test_repr_and_html(result):
    text = repr(result)
    assert text.startswith("Result(box environment, sphere") and "localized(iterations=3)" in text
    html = result._repr_html_()
    assert "<table" in html and html.count("<img") == 5 and "classical" in html


def test_save_round_trip_and_failure_keeps_previous(result, tmp_path, monkeypatch):
    import pandas as pd

    from study import io
    from study.io import read_exr_layers
    from study.tables import read_csv

    out = tmp_path / "run"
    files = result.save(out)
    names = {f.relative_to(out).as_posix() for f in files}
    assert {
        "table.csv",
        "table.parquet",
        "scene.json",
        "index.json",
        "exr/run.exr",
        "run.png",
        "index.html",
    } <= names
    assert not [n for n in names if set(n) & set("()= ")], (
        names
    )  # one naming convention, as the CLI's figures
    rows = read_csv(out / "table.csv")
    assert [r["label"] for r in rows] == list(result.table["label"])
    assert rows[2]["rmse_truth"] == pytest.approx(result.table["rmse_truth"][2])
    pd.testing.assert_frame_equal(pd.read_parquet(out / "table.parquet"), result.table)
    index = json.loads((out / "index.json").read_text())
    layers = read_exr_layers(out / index["exr"])
    img = layers[index["layers"]["image"]["localized(iterations=3)"]]
    assert index["layers"]["image"]["localized(iterations=3)"] == "localized-iterations-3"
    assert np.array_equal(img, result.images["localized(iterations=3)"].astype(np.float32))
    fm = layers[index["layers"]["flip"]["classical"]][..., 0]
    assert np.array_equal(np.isnan(fm), ~result.mask)
    assert np.array_equal(layers["mask"][..., 0] > 0.5, result.mask)
    assert study.load_scene(json.loads((out / "scene.json").read_text())) == result.scene
    before = {p: p.read_bytes() for p in files}

    def broken(array, channels=None):  # the EXR cannot be made
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(io, "exr_bytes", broken)
    with pytest.raises(OSError):
        result.save(out)
    assert {p: p.read_bytes() for p in files} == before


def test_load_scene_sources_and_overrides(tmp_path, monkeypatch):
    (tmp_path / "s.toml").write_text(scene_toml(small_scene_dict()))
    a = study.load_scene(tmp_path / "s.toml", **{"object.radius": 0.3})
    b = study.load_scene(str(tmp_path / "s.toml"), overrides={"object.radius": 0.3})
    c = study.load_scene(small_scene_dict(), {"object.radius": 0.3})
    assert a == b == c and a.object.radius == 0.3
    assert study.load_scene(a) is a and study.load_scene(a, **{"camera.fov": 50.0}).camera.fov == 50.0
    monkeypatch.chdir(tmp_path)  # shipped scenes from any working directory
    assert study.load_scene("scenes/room.toml").render.cube_res == 256
    with pytest.raises(StudyError, match=r"s.toml: object.radiu: unknown scene key"):
        study.load_scene("s.toml", **{"object.radiu": 0.3})
    with pytest.raises(StudyError, match=r"object.radius: Input should be greater than 0"):
        study.load_scene(small_scene_dict(), **{"object.radius": -1})
    with pytest.raises(StudyError, match=r"nothing.toml: scene source not found"):
        study.load_scene("nothing.toml")
    (tmp_path / "x.csv").write_text("a\n")
    with pytest.raises(StudyError, match=r"x.csv: not a scene source; allowed: .toml, .obj"):
        study.load_scene("x.csv")
    with pytest.raises(StudyError, match="a scene source is a path, a dict or a Scene"):
        study.load_scene(3)


def test_method_list():
    ms = study.method_list(
        [
            "classical",
            "localized( iterations = 3 )",
            {"name": "localized", "iterations": [1, 3]},
            methods.make("proxy_box"),
        ]
    )
    assert [m.label for m in ms] == [
        "classical",
        "localized(iterations=3)",
        "localized(iterations=1)",
        "proxy_box",
    ]
    assert [m.name for m in study.method_list("all")] == [  # an experiment of its own (hit_cache) aside
        n
        for n in methods.names()
        if not methods.REGISTRY[n].glossy and getattr(methods.REGISTRY[n], "in_all", True)
    ]
    for bad, words in [
        (["classical", "nope"], r"methods\[1\]: unknown method 'nope'"),
        ("localized(iterations=-1)", r"methods: iterations: Input should be greater than or equal"),
        ("localized(iterations=)", r"methods: the parameters of .* are not TOML values"),
        ("9x", "not a method name or label"),
        (3, "not a method: 3"),
    ]:
        with pytest.raises(StudyError, match=words):
            study.method_list(bad)


def test_quickstart_example_runs(tmp_path, monkeypatch):
    """The example as a user runs it (from another directory): its own method is measured beside the others and
    its outputs are written."""
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(sys, "argv", ["quickstart.py", str(tmp_path / "qs")])
    try:
        ns = runpy.run_path(str(ROOT / "examples" / "quickstart.py"), run_name="__main__")
    finally:
        methods.REGISTRY.pop("halfway_probe", None)
    t = ns["res"].table.set_index("label")
    assert t.loc["halfway_probe", "angle_median_deg"] > t.loc["localized(iterations=3)", "angle_median_deg"]
    assert (tmp_path / "qs" / "table.csv").is_file()


XML = """<scene version="3.0.0">
    <bsdf type="diffuse" id="wall"><rgb name="reflectance" value="0.5, 0.4, 0.3"/></bsdf>
    {walls}
    <emitter type="point"><point name="position" x="0.3" y="2.6" z="-0.4"/><rgb name="intensity" value="7"/></emitter>
</scene>"""
#: a 4 × 3 × 4 m room of six inward-facing rectangles: (scale x y, rotation axis and angle, translation)
WALLS = [
    ("2 2", "x -90", "0 0 0"),
    ("2 2", "x 90", "0 3 0"),
    ("2 1.5", "y 90", "-2 1.5 0"),
    ("2 1.5", "y -90", "2 1.5 0"),
    ("2 1.5", "y 0", "0 1.5 -2"),
    ("2 1.5", "y 180", "0 1.5 2"),
]


def test_load_scene_from_mesh_xml_and_mitsuba_dict(tmp_path):
    """Each source gives a validated scene in that environment with the suggested placement inside its bounds
    (the XML room spans [-2, 2] × [0, 3] × [-2, 2]); the Mitsuba dict keeps its own camera; overrides win."""
    from study import runtime

    walls = "\n    ".join(
        f'<shape type="rectangle"><ref id="wall"/><transform name="to_world"><scale x="{s.split()[0]}" '
        f'y="{s.split()[1]}"/><rotate {r.split()[0]}="1" angle="{r.split()[1]}"/><translate x="{t.split()[0]}" '
        f'y="{t.split()[1]}" z="{t.split()[2]}"/></transform></shape>'
        for s, r, t in WALLS
    )
    (tmp_path / "room.xml").write_text(XML.format(walls=walls))
    xml = study.load_scene(tmp_path / "room.xml", **{"object.radius": 0.3})
    assert xml.environment.type == "mitsuba" and xml.environment.file == str(tmp_path / "room.xml")
    assert xml.object.radius == 0.3
    for p in (xml.reference.point, xml.object.center, xml.camera.eye):
        assert np.all(np.array(p) > [-2, 0, -2]) and np.all(np.array(p) < [2, 3, 2])
    ply = study.load_scene(ROOT / "scenes" / "rooms" / "l_room.ply")
    assert ply.environment.type == "mesh" and ply.object.shape == "sphere"
    cornell = runtime.mitsuba().cornell_box()
    cb = study.load_scene(cornell)
    assert cb.environment.type == "mitsuba" and cb.camera.eye == pytest.approx((0.0, 0.0, 3.9))
    (tmp_path / "flat.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    flat = study.load_scene(tmp_path / "flat.obj")  # one triangle: an open scene, the object placed beside it
    assert flat.placement_line().startswith("placement: ") and flat.reference.point[2] != 0


def test_cuda_backend_renders_on_the_gpu_too(monkeypatch):
    """``evaluate(backend="cuda")`` switches Mitsuba and the exact hits to the GPU for the call (as the CLI does)
    and restores the setting after it; here the case itself is replaced (no GPU on this machine)."""
    from study import runtime
    from study.harness import budget
    from study.measure import case as case_mod

    seen = []

    class Stop(Exception):
        pass

    def fake_run_case(*a, **k):
        seen.append(runtime.render_device())
        raise Stop

    monkeypatch.setattr(budget, "check_backend", lambda b: None)
    monkeypatch.setattr(case_mod, "run_case", fake_run_case)
    before = runtime.render_device()
    with pytest.raises(Stop):
        study.evaluate(small_scene_dict(), ["classical"], backend="cuda", cache=None)
    assert seen == ["cuda"] and runtime.render_device() == before


def test_keys_a_person_would_type(result):
    """``res.images["localized"]`` where one parameterisation of localized ran, a label with other spaces, and an
    unknown key: a KeyError naming the valid keys — alike for every mapping of the result."""
    for name in ("images", "error_maps", "flip_maps", "angle_maps", "outcome_maps"):
        maps = getattr(result, name)
        assert maps["localized"] is maps["localized(iterations=3)"] is maps["localized( iterations = 3 )"]
        assert "localized" in maps and maps.get("localized") is maps["localized(iterations=3)"]
        assert "nope" not in maps and maps.get("nope", 7) == 7
        with pytest.raises(KeyError) as err:
            maps["glossy"]
        text = str(err.value)
        assert text.startswith(f"{name}['glossy']: no such key; valid keys: ") and "\n" not in text
        assert "'classical'" in text and "'localized(iterations=3)'" in text
    assert result.images["mitsuba"].shape == (32, 32, 3)
    assert list(result.images)[:3] == ["oracle_map", "truth_at_hit", "mitsuba"]  # iteration: the labels


def test_a_name_that_ran_twice_names_its_labels():
    from study.api import Maps

    maps = Maps({"localized(iterations=1)": 1, "localized(iterations=3)": 3, "localized_prefiltered": 5})
    with pytest.raises(KeyError) as err:
        maps["localized"]
    assert str(err.value) == (
        "maps['localized']: localized ran with 2 parameterisations; name one: "
        "'localized(iterations=1)', 'localized(iterations=3)'"
    )
    assert maps["localized_prefiltered"] == 5 and maps["localized(iterations=1)"] == 1
