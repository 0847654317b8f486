"""``study animate``: positions along the path (analytic), the outcome overlay, and a tiny animation end to end —
the GIF and MP4 decode with imageio, with one frame per position, of one size, and the frames differ; bad configs
are one line with exit 2 and leave earlier outputs as they were."""

import json
from pathlib import Path

import numpy as np
import pytest
from conftest import error_output, run_cli

from study.outputs import animation
from study.tables import read_csv

ROOM = Path(__file__).resolve().parents[2] / "scenes" / "room.toml"
TINY = f"""
scene = "{ROOM}"
path = [[0.0, 1.5, 0.0], [0.75, 1.05, 0.5], [1.5, 0.6, 1.0]]
frames = 3
methods = [{{ name = "classical" }}, {{ name = "localized", iterations = 10 }}]
seeds = [0, 1]
sequences = [{{ name = "ball" }}, {{ name = "ring", "object.shape" = "torus", "object.rotation" = [60.0, 0.0, 20.0] }}]
{{extra}}
[overrides]
"camera.width" = 32
"camera.height" = 32
"render.cube_res" = 16
"render.cube_spp" = 4
"render.spp" = 4
"render.supersample" = 1
"""


def test_positions_are_evenly_spaced_along_the_polyline():
    """Corners of an L of legs 1 and 2 m: 4 points at 0, 1, 2, 3 m → the corner and the leg's middle, exactly."""
    pts, s = animation.positions(np.array([[0.0, 0, 0], [1, 0, 0], [1, 2, 0]]), 4)
    np.testing.assert_allclose(s, [0, 1, 2, 3])
    np.testing.assert_allclose(pts, [[0, 0, 0], [1, 0, 0], [1, 1, 0], [1, 2, 0]], atol=1e-12)
    pts, s = animation.positions(np.array([[0.0, 0, 0], [3, 4, 0]]), 6)  # a line of 5 m
    np.testing.assert_allclose(np.linalg.norm(np.diff(pts, axis=0), axis=-1), 1.0)


def test_overlay_colours_only_the_wrong_pixels():
    img = np.full((4, 4, 3), 0.5)
    oc = np.full((4, 4), np.nan)  # off the object
    oc[1, 1], oc[1, 2], oc[2, 1], oc[2, 2] = 0, 1, 2, 3
    out = animation.overlay(img, oc)
    changed = np.any(out != img, axis=-1)
    assert changed.sum() == 3 and not changed[1, 1] and changed[1, 2] and changed[2, 1] and changed[2, 2]
    assert out[2, 1, 0] > out[2, 1, 1]  # wrong surface is red


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    d = tmp_path_factory.mktemp("motion")
    (d / "motion.toml").write_text(TINY.replace("{extra}", ""))
    res = run_cli(
        *[
            "animate",
            "--config",
            str(d / "motion.toml"),
            "--out",
            str(d / "out"),
            "--cache",
            str(d / "cache"),
        ],
    )
    assert res.exit_code == 0, res.output
    return d


def test_animation_files_decode_with_the_right_frames(tiny):
    import imageio.v2 as iio2
    import imageio.v3 as iio

    out = tiny / "out"
    gif = iio.imread(out / "motion.gif")
    assert gif.ndim == 4 and gif.shape[0] == 6 and gif.shape[-1] in (3, 4)  # 3 frames of each object
    with iio2.get_reader(out / "motion.mp4", format="FFMPEG") as reader:
        mp4 = np.stack(list(reader.iter_data()))
    assert mp4.shape[0] == 6
    assert mp4.shape[1:3] == gif.shape[1:3]  # frames are even-sized already
    for frames in (gif[..., :3].astype(float), mp4.astype(float)):
        frames = frames[:, frames.shape[1] // 5 :]  # below the title (frame number, position)
        assert np.abs(frames[1] - frames[0]).mean() > 1 and np.abs(frames[2] - frames[1]).mean() > 1
    every = read_csv(out / "frames.csv")
    assert {(r["sequence"], r["seed"]) for r in every} == {("ball", 0), ("ball", 1), ("ring", 0), ("ring", 1)}
    rows = [r for r in every if r["sequence"] == "ball" and r["seed"] == 0]
    assert sorted({r["frame"] for r in rows}) == [0, 1, 2]
    labels = ["classical", "localized(iterations=10)"]
    assert [r["label"] for r in rows if r["frame"] == 0 and r["label"] in labels] == labels
    leg = np.sqrt(0.75**2 + 0.45**2 + 0.5**2)  # the path's two legs are equal
    assert [r["path_m"] for r in rows if r["label"] == "classical"] == pytest.approx(
        [0, leg, 2 * leg], rel=1e-9
    )
    wrong = {r["frame"]: r["wrong_fraction"] for r in rows if r["label"] == "classical"}
    assert wrong[2] > wrong[0]  # far from the reference point, environment mapping misses
    assert (out / "motion.png").stat().st_size > 0 and (out / "metadata.json").exists()


def test_motion_table_has_the_temporal_error_of_every_sequence(tiny):
    """Torch-free, with or without study[video]: motion.csv has, per object, per-frame FLIP and E_warp on the
    object for each method and the noise floor as means over the seeds with their interval; frames.csv each
    step's E_warp (none for the first frame, which has no frame before it)."""
    out = tiny / "out"
    rows = {(r["sequence"], r["label"]): r for r in read_csv(out / "motion.csv")}
    labels = {"classical", "localized(iterations=10)", "truth_at_hit"}
    assert set(rows) == {(s, lab) for s in ("ball", "ring") for lab in labels}
    for r in rows.values():
        assert r["frames"] == 3 and r["seeds"] == 2 and r["ewarp_l2"] >= 0 and 0 <= r["ewarp_flip"] <= 1, r
        assert r["ewarp_l2_lo"] <= r["ewarp_l2"] <= r["ewarp_l2_hi"] and 0 < r["object_pixels"] < 32 * 32, r
    assert rows[("ball", "truth_at_hit")]["flip_truth"] == 0 and rows[("ball", "classical")]["flip_truth"] > 0
    frames = read_csv(out / "frames.csv")
    per_seed = []
    for seed in (0, 1):
        steps = [
            r for r in frames if r["label"] == "classical" and r["sequence"] == "ball" and r["seed"] == seed
        ]
        assert np.isnan(steps[0]["ewarp_l2"]) and all(r["ewarp_pixels"] > 0 for r in steps[1:])
        per_seed.append(np.mean([r["ewarp_l2"] for r in steps[1:]]))
    assert per_seed[0] != per_seed[1]  # the replicates differ
    assert np.mean(per_seed) == pytest.approx(rows[("ball", "classical")]["ewarp_l2"])
    meta = json.loads((out / "metadata.json").read_text())
    assert meta["temporal_metric"] == animation.TEMPORAL_METRIC
    assert not (out / "jod.csv").exists()  # one table


def test_motion_jod_table_and_claim(tiny):
    """With study[video]: a JOD row per method and the noise floor (truth_at_hit), each within (0, 10] with its
    interval around it (or none for a sequence too short to split), and the motion claim's verdicts."""
    from study.measure import video

    if not video.available():
        pytest.skip("needs the extra study[video] (cvvdp, PyTorch): bash scripts/setup.sh --video")
    out = tiny / "out"
    rows = {(r["sequence"], r["label"]): r for r in read_csv(out / "motion.csv")}
    assert len(rows) == 6
    assert all(0 < r["jod"] <= 10 and r["display"] == video.CVVDP_DISPLAY for r in rows.values())
    for seq in ("ball", "ring"):  # the floor is the truth against a replicate of itself: close to 10
        floor, cl = rows[(seq, "truth_at_hit")], rows[(seq, "classical")]
        assert floor["jod_lo"] <= floor["jod"] <= floor["jod_hi"] and floor["jod"] > cl["jod"]
        assert cl["gap"] == pytest.approx(floor["jod"] - cl["jod"], abs=1e-9)
    meta = json.loads((out / "metadata.json").read_text())
    assert meta["video_metric"] == f"ColorVideoVDP (cvvdp {video.VERSION})" and meta["jod_bound"] == 1.0
    claims = meta["motion_claim"]
    assert (
        len(claims) == 6
        and sum("the claim" in c for c in claims) == 4
        and claims[0].startswith("ball: noise")
    )
    from study.report.kinds.animation import motion_claim_section

    text = " ".join(str(p) for block in motion_claim_section(out, out / "motion.csv") for p in block)
    assert f"measured with the extra study[video] installed: ColorVideoVDP (cvvdp {video.VERSION})" in text


def test_without_cvvdp_the_jod_columns_say_so(tiny, monkeypatch):
    """Without study[video] (made so here where it is installed): the animation still runs, its JOD columns say
    "cvvdp not installed", no claim is judged in JOD, and the report says which metric was used."""
    from study.measure import video
    from study.report.kinds.animation import media_section

    monkeypatch.setattr(video, "available", lambda: False)
    reports = tiny / "reports"
    one = "\n".join(ln for ln in TINY.splitlines() if not ln.startswith(("seeds", "sequences", "frames")))
    (tiny / "one.toml").write_text("frames = 2\n" + one.replace("{extra}", ""))  # the cached ends, one seed
    res = run_cli("animate", "--config", str(tiny / "one.toml"), "--out", str(reports / "animation"),
         "--cache", str(tiny / "cache"))  # fmt: skip
    assert res.exit_code == 0, res.output
    rows = read_csv(reports / "animation" / "motion.csv")
    assert all(r[k] == "cvvdp not installed" for r in rows for k in ("jod", "jod_lo", "jod_hi"))
    assert all(np.isfinite(r["ewarp_flip"]) for r in rows)
    meta = json.loads((reports / "animation" / "metadata.json").read_text())
    assert meta["video_metric"] == "cvvdp not installed" and "motion_claim" not in meta
    text = " ".join(str(p) for block in media_section(reports, reports / "animation", [], []) for p in block)
    assert "ColorVideoVDP was not installed when these frames were measured" in text and "E_warp" in text
    assert "(ColorVideoVDP)" not in text and "cvvdp not installed" in text


@pytest.mark.parametrize(
    "extra, words",
    [
        ("fps = 0", "motion.toml: fps: Input should be greater than 0"),
        ('formats = ["avi"]', "motion.toml: formats"),
        ("speed = 2", "motion.toml: speed"),
        ("seeds = []", "motion.toml: seeds"),
        ("seeds = [1, 1]", "seeds: [1, 1] repeats a seed"),
        ('sequences = [{ name = "a/b" }]', "sequences[0].name: 'a/b' must be a plain, distinct name"),
    ],
)
def test_bad_config_is_one_line_and_keeps_outputs(tmp_path, extra, words):
    out = tmp_path / "out"
    out.mkdir()
    (out / "motion.gif").write_bytes(b"earlier")
    text = TINY.replace("{extra}", extra)
    key = extra.split(" ")[0]
    if key in ("seeds", "sequences"):  # instead of the tiny config's own line (top-level keys come first)
        text = extra + "\n" + "\n".join(ln for ln in TINY.splitlines() if not ln.startswith(key))
        text = text.replace("{extra}", "")
    (tmp_path / "motion.toml").write_text(text)
    res = run_cli(
        *[
            "animate",
            "--config",
            str(tmp_path / "motion.toml"),
            "--out",
            str(out),
            "--cache",
            str(tmp_path / "cache"),
        ],
    )
    assert res.exit_code == 2, res.output
    assert words in res.output.replace("\n", ""), res.output
    assert len(error_output(res).splitlines()) == 1 and "Traceback" not in res.output
    assert (out / "motion.gif").read_bytes() == b"earlier"


def test_shipped_motion_config_is_valid():
    cfg, runs, methods, _ = animation.load_motion_config(ROOM.parents[1] / "configs" / "motion.toml")
    assert len(cfg.seeds) >= 3 and len(runs) == len(cfg.seeds) * len(cfg.sequences)
    shapes = {r.sequence: r.scenes[0][1].object.shape for r in runs}
    assert shapes["sphere"] == "sphere" and len(set(shapes.values())) == 2  # two curved objects
    assert [m.name for m in methods] == ["classical", "localized", "proxy_box", "layered"]
    for run in runs:
        assert len(run.scenes) == cfg.frames and all(sc.render.seed == run.seed for _, sc in run.scenes)
        np.testing.assert_allclose(run.scenes[0][1].object.center, cfg.path[0])
        np.testing.assert_allclose(run.scenes[-1][1].object.center, cfg.path[-1])


def test_crop_box_holds_the_object_in_every_frame():
    a, b = np.zeros((64, 64), bool), np.zeros((64, 64), bool)
    a[10:20, 10:20], b[30:40, 40:50] = True, True
    sy, sx = animation.motion_crop([a, b])
    for m in (a, b):
        assert m[sy, sx].sum() == m.sum()  # nothing of either object cut off
    assert sy.stop - sy.start == sx.stop - sx.start < 64  # square, smaller than the frame
