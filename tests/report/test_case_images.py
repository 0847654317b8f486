"""Per-case images off the critical path (study.outputs.case_images): ``--images none|viewer|all`` for figures and
sweeps writes what it says and leaves every table value-identical; a sweep's images are written by a background
writer the command waits for, and the EXR's layers are the case's arrays, bit for bit."""

import math
import threading

import numpy as np
import pytest

from study import methods as registry
from study.cache import Cache
from study.io import read_exr_layers
from study.measure.case import run_case
from study.outputs import case_images, viewer
from study.scene import scene_from_dict
from study.tables import read_csv
from tests.conftest import run_cli, small_scene_dict
from tests.test_cli import SMALL
from tests.test_sweep import write as write_sweep


def same_rows(a, b):
    assert [r["label"] for r in a] == [r["label"] for r in b]
    for ra, rb in zip(a, b):
        assert ra.keys() == rb.keys()
        for k in ra:
            if k not in ("seconds", "case_seconds"):
                va, vb = ra[k], rb[k]
                assert va == vb or (isinstance(va, float) and math.isnan(va) and math.isnan(vb)), k


@pytest.fixture(scope="module")
def small_case():
    scene = scene_from_dict(small_scene_dict())
    ms = [registry.make("classical"), registry.make("localized", iterations=3)]
    return run_case(scene, ms, cache=Cache(None), case_id="c 0"), [m.label for m in ms]


def test_exr_layers_are_the_arrays_and_written_in_the_background(small_case, tmp_path, monkeypatch):
    case, labels = small_case
    threads = []
    real = case_images._write
    monkeypatch.setattr(
        case_images, "_write", lambda *a: (threads.append(threading.current_thread()), real(*a))
    )
    case_images.write_case(case, "c 0", str(tmp_path), labels, "all", True)
    assert case_images.finish(tmp_path, "s") == 1  # waited for the writer, then the manifest
    assert threads and threads[0] is not threading.main_thread()
    layers = read_exr_layers(tmp_path / "exr" / "c-0.exr")
    stems = viewer.source_stems(labels)
    for source, layer, a in viewer.case_layers(case, labels):
        got = layers[viewer.exr_layer(source, layer, stems)]
        want = np.asarray(a, np.float32).reshape(got.shape)
        assert np.array_equal(got, want, equal_nan=True), (source, layer)
    assert np.array_equal(layers["mask"][..., 0], case.mask.astype(np.float32))
    assert (tmp_path / "viewer" / "c-0.js").is_file() and (tmp_path / viewer.MANIFEST).is_file()


def test_viewer_only_writes_no_exr(small_case, tmp_path):
    case, labels = small_case
    case_images.write_case(case, "c 0", str(tmp_path), labels, "viewer", False)
    assert case_images.finish(tmp_path, "s") == 1
    assert not (tmp_path / "exr").exists() and (tmp_path / "viewer" / "c-0.js").is_file()


@pytest.fixture(scope="module")
def figures(tmp_path_factory):
    d = tmp_path_factory.mktemp("fig")
    cfg = d / "f.toml"
    cfg.write_text(
        SMALL.format(iterations="[10]")
        .replace("width = 48, height = 48", "width = 24, height = 24")
        .replace("[[0.0, 1.5, 0.0], [0.8, 1.1, 0.5], ", "[")  # one position
    )
    out = {}
    for images in ("all", "viewer", "none"):
        o = d / images
        res = run_cli("figure", "fig4", "--config", str(cfg), "--out", str(o), "--cache", str(d / "c"),
                                  "--images", images)  # fmt: skip
        assert res.exit_code == 0, res.output
        out[images] = o
    return out


def test_figure_images_option(figures):
    assert len(list((figures["all"] / "exr").glob("*.exr"))) == 1
    assert len(list((figures["all"] / "viewer").glob("*.js"))) == 1
    assert (
        not (figures["viewer"] / "exr").exists()
        and len(list((figures["viewer"] / "viewer").glob("*.js"))) == 1
    )
    assert not (figures["none"] / "exr").exists() and not (figures["none"] / "viewer").exists()
    for images in ("viewer", "none"):  # the table does not depend on the images
        same_rows(read_csv(figures["all"] / "metrics.csv"), read_csv(figures[images] / "metrics.csv"))


def test_sweep_images_option(tmp_path):
    cfg = write_sweep(tmp_path)
    cfg.write_text(cfg.read_text().replace("steps = 3", "steps = 1").replace("[16, 24]", "[16]"))
    outs = {}
    for images in ("none", "all"):
        outs[images] = tmp_path / images
        res = run_cli("sweep", str(cfg), "--out", str(outs[images]), "--cache", str(tmp_path / "c"),
                                  "--images", images, "--no-plots")  # fmt: skip
        assert res.exit_code == 0, res.output
    assert not (outs["none"] / "exr").exists() and not (outs["none"] / "viewer").exists()
    assert len(list((outs["all"] / "exr").glob("*.exr"))) == 1
    assert viewer.read_manifest(outs["all"]) is not None
    same_rows(read_csv(outs["none"] / "results.csv"), read_csv(outs["all"] / "results.csv"))


@pytest.mark.parametrize("command", ["figure fig4", "sweep configs/sweep.toml"])
def test_bad_images_value_is_one_line(command):
    res = run_cli(*command.split(), "--images", "some")
    assert res.exit_code != 0
    assert "unknown --images 'some'; allowed: none, viewer, all" in res.output


def test_exr_bytes_are_the_file_mitsuba_writes(tmp_path):
    """The in-memory EXR (the stream's buffer, its first size() bytes) is byte for byte the file Mitsuba's Bitmap
    writes to disk itself, for a buffer that grew past its first capacity (a 1.5 MB image)."""
    from study import io, runtime

    mi = runtime.mitsuba()
    rng = np.random.default_rng(3)
    a = rng.random((256, 256, 6)).astype(np.float32)
    names = [f"{layer}.{c}" for layer in ("one", "two") for c in "RGB"]
    mi.Bitmap(a, pixel_format=mi.Bitmap.PixelFormat.MultiChannel, channel_names=names).write(
        str(tmp_path / "direct.exr")
    )
    assert io.exr_bytes(a, names) == (tmp_path / "direct.exr").read_bytes()


def test_layers_exr_holds_each_layer_cast_to_float32_and_refuses_mixed_sizes(tmp_path):
    from study import io

    rng = np.random.default_rng(4)
    layers = {
        "rgb": rng.random((24, 16, 3)),
        "y": rng.random((24, 16)).astype(np.float32),
        "c": rng.random((24, 16, 1)),
    }
    (tmp_path / "a.exr").write_bytes(io.layers_exr_bytes(layers))
    back = read_exr_layers(tmp_path / "a.exr")
    for name, a in layers.items():
        want = np.asarray(a, np.float32)
        np.testing.assert_array_equal(back[name].reshape(want.shape), want)
    with pytest.raises(ValueError, match="different sizes"):
        io.layers_exr_bytes({"a": np.zeros((4, 4)), "b": np.zeros((4, 5, 3))})
