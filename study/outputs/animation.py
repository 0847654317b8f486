"""Motion: the sphere of Figure 4 moving along a path, every method side by side with its errors, as an animation.

Config (``configs/motion.toml``)::

    scene = "../scenes/room.toml"
    path = [[0.0, 1.5, 0.0], [1.5, 0.6, 1.0]]     # object centres passed through, in order (a polyline)
    frames = 24                                     # positions, evenly spaced along the path by arc length
    fps = 8
    methods = [{ name = "classical" }, { name = "localized", iterations = 10 }]
    [overrides]                                     # dotted scene keys (camera size, cube_res, spp, …)

Each frame is one case run through the harness (:func:`study.measure.case.run_case`, with the cache): top row
the methods' images and Mitsuba's render (the truth), bottom row each method's image with its per-pixel outcome
blended over it (:mod:`study.measure.outcomes`: wrong depth orange, wrong surface red, no hit grey; correct
pixels left as they are) and its wrong-hit fraction. Outputs, one set (:func:`study.io.write_set`: made first, then
written and swapped in together): ``motion.gif`` and/or ``motion.mp4``, ``frames.csv`` (the cases' rows: one per frame ×
method, with ``frame`` and ``path_m``, the distance travelled, and the step's E_warp from the frame before),
``motion.png`` (wrong-hit fraction per method along the path), ``motion.csv`` and ``metadata.json``.

``motion.csv`` judges each method's sequence, and the noise floor's (``truth_at_hit``: exact hits, Mitsuba's
shading), as a sequence: ``flip_truth`` (per-frame FLIP against truth_at_hit, the frames' mean), ``ewarp_l2`` and
``ewarp_flip`` (the temporal error along the exact motion, torch-free: :mod:`study.measure.temporal`) and the JOD
of ColorVideoVDP against Mitsuba's sequence (:mod:`study.measure.video`) — where the extra ``study[video]`` is not
installed, the JOD columns say "cvvdp not installed", and ``metadata.json``'s ``video_metric`` says which it was.
"""

from __future__ import annotations

import json
import tempfile
import time
from pathlib import Path
from typing import Any, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from study import progress as pg
from study.cache import Cache
from study.errors import StudyError
from study.harness import budget
from study.harness.config import MethodSpecs, configured_scene, expand_methods
from study.harness.runner import metadata
from study.io import atomic_savefig, locked, write_set
from study.measure import temporal, video
from study.measure.case import CaseOutput
from study.measure.metrics import to_ldr
from study.measure.outcomes import NAMES as OUTCOME_NAMES
from study.outputs.figures import OUTCOME_COLORS, run_config_case
from study.scene import Vec3
from study.tables import to_csv
from study.validation import validate_file

OPACITY = 0.6  # opacity of an outcome colour over the image
#: what ``metadata.json`` (``video_metric``, ``temporal_metric``) and the report say was measured
VIDEO_METRIC = f"ColorVideoVDP (cvvdp {video.VERSION})"
NO_CVVDP = "cvvdp not installed"
TEMPORAL_METRIC = "E_warp along the exact motion (study.measure.temporal)"


class MotionConfig(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)
    scene: str | dict[str, Any]
    overrides: dict[str, Any] = {}
    path: list[Vec3] = Field(min_length=2)
    frames: int = Field(24, ge=2, le=480)
    fps: float = Field(8.0, gt=0, le=60)
    methods: MethodSpecs = [
        {"name": "classical"},
        {"name": "localized", "iterations": 10},
        {"name": "proxy_box"},
        {"name": "layered"},
    ]
    formats: list[Literal["gif", "mp4"]] = Field(["gif", "mp4"], min_length=1)
    kind: Literal["animation"] = "animation"  # the figure kind (study.outputs.kinds.animation)


def positions(path: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """``n`` points evenly spaced by arc length along the polyline ``path`` (K, 3), both ends included:
    (n, 3) points and (n,) the distance travelled to each, metres."""
    seg = np.linalg.norm(np.diff(path, axis=0), axis=-1)
    cum = np.concatenate([[0.0], np.cumsum(seg)])
    s = np.linspace(0.0, cum[-1], n)
    k = np.clip(np.searchsorted(cum, s, side="right") - 1, 0, len(seg) - 1)
    f = np.where(seg[k] > 0, (s - cum[k]) / np.where(seg[k] > 0, seg[k], 1), 0.0)
    return path[k] + f[:, None] * (path[k + 1] - path[k]), s


def load_motion_config(path: str | Path):
    """(config, [(case id, scene) per frame], methods, distance travelled per frame)."""
    path = Path(path)
    cfg = validate_file(MotionConfig, path)
    scene = configured_scene(cfg, path)
    pts, s = positions(np.asarray(cfg.path, float), cfg.frames)
    scenes = [
        (
            f"motion-f{i:03d}",
            scene.with_updates({"object.center": [float(x) for x in p]}, source=f"{path} path"),
        )
        for i, p in enumerate(pts)
    ]
    return cfg, scenes, expand_methods(cfg.methods, source=str(path)), s


# ---------------------------------------------------------------------------------------------- one frame
def overlay(image: np.ndarray, outcome: np.ndarray) -> np.ndarray:
    """sRGB image (H, W, 3) in [0, 1] with the outcome classes other than *correct* blended over it."""
    from matplotlib.colors import to_rgb

    out = image.copy()
    for code, color in enumerate(OUTCOME_COLORS):
        m = outcome == code
        if code > 0 and m.any():
            out[m] = (1 - OPACITY) * out[m] + OPACITY * np.asarray(to_rgb(color))
    return out


def motion_crop(masks: list[np.ndarray], margin: float = 0.25) -> tuple[slice, slice]:
    """One square of the camera's frame around the object's pixels in every frame (their union), with a margin:
    the view stays still while the object moves."""
    ys, xs = np.nonzero(np.any(masks, axis=0))
    H, W = masks[0].shape
    if ys.size == 0:
        return slice(0, H), slice(0, W)
    half = min(max(np.ptp(ys), np.ptp(xs)) / 2 * (1 + margin) + 2, H / 2, W / 2)
    y0 = int(np.clip((ys.min() + ys.max()) / 2 - half, 0, H - 2 * half))
    x0 = int(np.clip((xs.min() + xs.max()) / 2 - half, 0, W - 2 * half))
    return slice(y0, y0 + int(2 * half)), slice(x0, x0 + int(2 * half))


def frame_image(
    case: CaseOutput, labels: list[str], *, title: str, crop: tuple[slice, slice] = (slice(None), slice(None))
) -> np.ndarray:
    """One frame (H, W, 3) uint8: methods and Mitsuba on top, outcome overlays and the legend below; the images
    cut to ``crop`` (rows, columns)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Patch

    n = len(labels) + 1
    fig, ax = plt.subplots(2, n, figsize=(1.6 * n, 3.6), dpi=100)
    rows = {r["label"]: r for r in case.rows}
    for c, lab in enumerate(labels):
        img = to_ldr(case.images[lab])[crop]
        ax[0, c].imshow(img, interpolation="nearest")
        ax[0, c].set_title(lab.replace("(", "\n("), fontsize=6.5)
        ax[1, c].imshow(overlay(img, case.outcome_maps[lab][crop]), interpolation="nearest")
        ax[1, c].set_title(f"wrong hits {100 * rows[lab]['wrong_fraction']:.1f} %", fontsize=6.5)
    ax[0, -1].imshow(to_ldr(case.mitsuba)[crop], interpolation="nearest")
    ax[0, -1].set_title("Mitsuba\n(path traced)", fontsize=6.5)
    ax[1, -1].axis("off")
    ax[1, -1].legend(
        handles=[Patch(facecolor=c, label=nm) for c, nm in zip(OUTCOME_COLORS[1:], OUTCOME_NAMES[1:])],
        loc="center",
        fontsize=6,
        frameon=False,
        title="outcome",
        title_fontsize=6.5,
    )
    for a in ax.ravel():
        a.set_xticks([])
        a.set_yticks([])
    fig.suptitle(title, fontsize=7)
    fig.subplots_adjust(left=0.01, right=0.99, bottom=0.01, top=0.84, wspace=0.05, hspace=0.25)
    fig.canvas.draw()
    img = np.asarray(fig.canvas.buffer_rgba())[..., :3].copy()
    plt.close(fig)
    return img


# ---------------------------------------------------------------------------------------------- the animation
def plot(rows: list[dict], labels: list[str], path: Path) -> None:
    """Wrong-hit fraction of each method against the distance travelled."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.4, 3.6))
    for k, lab in enumerate(labels):
        rs = [r for r in rows if r["label"] == lab]
        ax.plot(
            [r["path_m"] for r in rs],
            [100 * r["wrong_fraction"] for r in rs],
            marker="osD^v<>"[k % 7],
            ls=("-", "--", ":", "-.")[k % 4],
            ms=4,
            label=lab,
        )
    ax.set_xlabel("distance travelled along the path (m)")
    ax.set_ylabel("wrong hits (% of rays)")
    ax.set_ylim(bottom=0)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7)
    fig.tight_layout()
    atomic_savefig(fig, path, dpi=110)


def animate(
    config: str | Path,
    out: str | Path,
    *,
    backend: str = "numpy",
    cache: str | Path | None = ".cache",
    progress=None,
) -> list[dict]:
    """Render every frame of a motion config and write the animation, ``frames.csv``, ``motion.png`` and
    ``metadata.json`` into ``out``. Returns the rows. Progress: one unit per frame (:mod:`study.progress`)."""
    with pg.task("animate", None) as job:
        return _animate(config, out, backend, cache, progress, job)


def _animate(config, out, backend, cache, progress, job: pg.Task) -> list[dict]:
    import imageio.v3 as iio

    cfg, scenes, methods, travelled = load_motion_config(config)
    job.total = len(scenes)
    labels = [m.label for m in methods]
    budget.check_backend(backend)
    budget.check_cases(scenes, methods, source=str(config))
    store, rows, frames, cases = Cache(cache), [], [], []
    t0 = time.perf_counter()
    owns = ["motion.gif", "motion.mp4", "motion.png", "frames.csv", "metadata.json", "motion.csv", "jod.csv"]
    with locked(out):  # one command at a time here; the files are made first, then written together
        for i, (case_id, sc) in enumerate(scenes):
            with pg.item(case_id):
                case = run_config_case(
                    sc,
                    methods,
                    backend=backend,
                    cache=store,
                    case_id=case_id,
                    where=f"{config} path (frame {i})",
                )
            for r in case.rows:
                rows.append({"frame": i, "path_m": float(travelled[i]), **r})
            cases.append(case)
            pg.advance(case_id)
            if progress:
                progress(i + 1, len(scenes))
        crop = motion_crop([c.mask for c in cases])
        for i, (case, (_, sc)) in enumerate(zip(cases, scenes)):
            cx, cy, cz = sc.object.center
            frames.append(
                frame_image(
                    case,
                    labels,
                    crop=crop,
                    title=f"frame {i + 1}/{len(scenes)}: sphere at "
                    f"({cx:.2f}, {cy:.2f}, {cz:.2f}), {travelled[i]:.2f} m along the path; "
                    f"cube {sc.render.cube_res}², backend {backend}",
                )
            )
        stack = np.stack(frames)
        files: dict[str, bytes | str] = {}
        with tempfile.TemporaryDirectory(prefix="study-animation-") as scratch:  # encoders want a file name
            d = Path(scratch)
            if "gif" in cfg.formats:
                iio.imwrite(d / "motion.gif", stack, extension=".gif", duration=1000 / cfg.fps, loop=0)
            if "mp4" in cfg.formats:
                _mp4(d / "motion.mp4", stack, cfg.fps)
            plot(rows, labels, d / "motion.png")
            files.update({p.name: p.read_bytes() for p in d.iterdir() if p.name in owns})
        table, claim = motion_table(cases, [sc for _, sc in scenes], labels, rows, fps=cfg.fps)
        files["frames.csv"] = to_csv(rows)
        files["motion.csv"] = to_csv(table)
        meta = metadata(
            config,
            backend=backend,
            seed=scenes[0][1].render.seed,
            methods=labels,
            cases=len(scenes),
            kind="animation",
            seconds=round(time.perf_counter() - t0, 1),
        )
        meta["video_metric"] = VIDEO_METRIC if video.available() else NO_CVVDP
        meta["temporal_metric"] = TEMPORAL_METRIC
        if claim:
            meta["motion_claim"] = claim
            meta["jod_display"] = video.CVVDP_DISPLAY
        files["metadata.json"] = json.dumps(meta, indent=2)
        write_set(out, files, owns, lock=False)
    return rows


def motion_table(
    cases: list[CaseOutput], scenes: list, labels: list[str], rows: list[dict], *, fps: float
) -> tuple[list[dict], list[str]]:
    """(``motion.csv``'s rows, the motion claim's sentences) of the frames' cases (module docstring); ``rows``
    (frames.csv's) gain each step's E_warp. The claim needs ColorVideoVDP: none without it."""
    seqs = {lab: [c.images[lab] for c in cases] for lab in labels}
    seqs["truth_at_hit"] = [c.truth for c in cases]  # the noise floor
    flows = temporal.sequence_flows(scenes)
    table, at = [], {(r["frame"], r["label"]): r for r in rows}
    for lab, frames in seqs.items():
        whole, steps = temporal.sequence_ewarp(frames, flows)
        for i, step in enumerate(steps, start=1):
            if (i, lab) in at:
                at[(i, lab)].update(step)
        flips = [r.get("flip_truth", np.nan) for r in rows if r["label"] == lab]
        table.append({"label": lab, "frames": len(frames), "flip_truth": float(np.nanmean(flips)), **whole})
    claim: list[str] = []
    if video.available():  # ColorVideoVDP (study[video]): JOD of each sequence against Mitsuba's
        ldr = {lab: np.stack([to_ldr(f) for f in frames]) for lab, frames in seqs.items()}
        jods = video.motion_rows(ldr, np.stack([to_ldr(c.mitsuba) for c in cases]), fps=fps)
        claim = video.motion_claim(jods)
        for t, j in zip(table, jods):
            t.update({k: v for k, v in j.items() if k not in ("label", "frames")})
    else:
        for t in table:
            t.update({"jod": NO_CVVDP, "jod_lo": NO_CVVDP, "jod_hi": NO_CVVDP, "display": "", "cvvdp": ""})
    return table, claim


def _mp4(path: Path, frames: np.ndarray, fps: float) -> None:
    """H.264 MP4 (imageio-ffmpeg), frames padded to even sizes, yuv420p so that browsers play it."""
    import imageio.v2 as iio2

    H, W = frames.shape[1:3]
    frames = np.pad(frames, ((0, 0), (0, H % 2), (0, W % 2), (0, 0)), mode="edge")
    try:
        with iio2.get_writer(
            path,
            format="FFMPEG",
            fps=fps,
            codec="libx264",
            pixelformat="yuv420p",
            macro_block_size=1,
            quality=8,
        ) as w:
            for f in frames:
                w.append_data(f)
    except (ImportError, RuntimeError) as err:
        raise StudyError(
            f'cannot write MP4 ({err}); install imageio-ffmpeg or set formats = ["gif"]',
            key="formats",
            code=3,
        ) from None
