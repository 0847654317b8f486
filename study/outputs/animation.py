"""Motion: curved objects (Figure 4's sphere, a torus) moving along a path, every method side by side with its
errors, as an animation, judged on the object's pixels over seed replicates.

Config (``configs/motion.toml``)::

    scene = "../scenes/room.toml"
    path = [[0.0, 1.5, 0.0], [1.5, 0.6, 1.0]]     # object centres passed through, in order (a polyline)
    frames = 24                                     # positions, evenly spaced along the path by arc length
    fps = 8
    methods = [{ name = "classical" }, { name = "localized", iterations = 10 }]
    seeds = [0, 1, 2]                               # replicates (render.seed of each)
    sequences = [{ name = "sphere" }, { name = "torus", "object.shape" = "torus" }]   # one per object
    [overrides]                                     # dotted scene keys (camera size, cube_res, spp, …)

Each sequence (``sequences``: an object with its scene keys) is rendered once per seed (``seeds``: replicates,
``render.seed``), each frame one case through the harness (:func:`study.measure.case.run_case`, cached). The
animation shows each sequence's first seed: top row the methods and Mitsuba, bottom row each method with its
per-pixel outcome over it (:mod:`study.measure.outcomes`) and its wrong-hit fraction. Outputs, one set
(:func:`study.io.write_set`): ``motion.gif`` and/or ``motion.mp4``, ``frames.csv`` (one row per sequence × seed ×
frame × method, with ``path_m``, the distance travelled, and the step's E_warp), ``motion.png`` (wrong hits along
the path), ``motion.csv`` and ``metadata.json``.

``motion.csv`` judges each sequence on the object's pixels, per method and for the noise floor (``truth_at_hit``),
as means over the seeds with 95 % intervals from them (:func:`motion_table`): FLIP against truth_at_hit, E_warp
along the exact motion (torch-free, :mod:`study.measure.temporal`) and ColorVideoVDP's JOD against truth_at_hit
and against Mitsuba (:mod:`study.measure.video`); without the extra ``study[video]`` the JOD columns say "cvvdp
not installed". ``metadata.json``'s ``motion_claim`` holds the verdicts (:func:`study.measure.video.motion_claim`).
"""

from __future__ import annotations

import json
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from study import progress as pg
from study import stats
from study.cache import Cache
from study.errors import StudyError
from study.harness import budget
from study.harness.config import PLAIN_NAME, MethodSpecs, configured_scene, expand_methods
from study.harness.runner import metadata
from study.io import atomic_savefig, locked, write_set
from study.measure import temporal, video
from study.measure.case import CaseOutput
from study.measure.metrics import to_ldr
from study.measure.outcomes import NAMES as OUTCOME_NAMES
from study.outputs.figures import OUTCOME_COLORS, run_config_case
from study.scene import Scene, Vec3
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
    kind: Literal["animation"] = "animation"  # the figure kind (study.report.kinds.animation)
    #: the replicates: the whole sequence rendered once per seed (``render.seed``); intervals come from them
    seeds: list[int] = Field([0], min_length=1, max_length=16)
    #: the objects moved along the path, one sequence each: a name and dotted scene keys (``object.shape``, …)
    sequences: list[dict[str, Any]] = Field([{"name": "object"}], min_length=1, max_length=8)


@dataclass(frozen=True)
class MotionRun:
    """One sequence (object) at one seed: its frames' (case id, scene)."""

    sequence: str
    seed: int
    scenes: list[tuple[str, Scene]]


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
    """(config, [MotionRun per sequence × seed], methods, distance travelled per frame)."""
    path = Path(path)
    cfg = validate_file(MotionConfig, path)
    base = configured_scene(cfg, path)
    pts, s = positions(np.asarray(cfg.path, float), cfg.frames)
    if len(set(cfg.seeds)) != len(cfg.seeds):
        raise StudyError(
            f"seeds: {cfg.seeds} repeats a seed; give distinct seeds", file=str(path), key="seeds"
        )
    runs, names = [], []
    for k, spec in enumerate(cfg.sequences):
        name = spec.get("name")
        where = f"sequences[{k}]"
        if not isinstance(name, str) or not PLAIN_NAME.fullmatch(name) or name in names:
            raise StudyError(
                f"{where}.name: {name!r} must be a plain, distinct name (letters, digits, '_', '.', '-')",
                file=str(path),
                key=f"{where}.name",
            )
        names.append(name)
        keys = {key: v for key, v in spec.items() if key != "name"}
        scene = base.with_updates(keys, source=f"{path} {where}") if keys else base
        for seed in cfg.seeds:
            at = scene.with_updates({"render.seed": seed}, source=f"{path} seeds")
            frames = [
                (
                    f"motion-{name}-s{seed}-f{i:03d}",
                    at.with_updates({"object.center": [float(x) for x in p]}, source=f"{path} path"),
                )
                for i, p in enumerate(pts)
            ]
            runs.append(MotionRun(name, seed, frames))
    return cfg, runs, expand_methods(cfg.methods, source=str(path)), s


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
    """Wrong-hit fraction of each method against the distance travelled, one panel per sequence (its first
    seed)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    seqs = list(dict.fromkeys(r.get("sequence", "") for r in rows))
    fig, axes = plt.subplots(1, len(seqs), figsize=(6.4 * len(seqs), 3.6), squeeze=False)
    for ax, seq in zip(axes[0], seqs):
        mine = [r for r in rows if r.get("sequence", "") == seq]
        seed = mine[0].get("seed")
        for k, lab in enumerate(labels):
            rs = [r for r in mine if r["label"] == lab and r.get("seed") == seed]
            ax.plot(
                [r["path_m"] for r in rs],
                [100 * r["wrong_fraction"] for r in rs],
                marker="osD^v<>"[k % 7],
                ls=("-", "--", ":", "-.")[k % 4],
                ms=4,
                label=lab,
            )
        ax.set_title(f"{seq} (seed {seed})", fontsize=9)
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
    """Render every frame of every sequence and seed of a motion config and write the animation (each sequence's
    first seed, one after the other), ``frames.csv``, ``motion.png``, ``motion.csv`` and ``metadata.json`` into
    ``out``. Returns the rows. Progress: one unit per frame (:mod:`study.progress`)."""
    with pg.task("animate", None) as job:
        return _animate(config, out, backend, cache, progress, job)


@dataclass
class _Frame:
    """What the motion's judgement keeps of one frame's case (the whole case only for the animation's frames)."""

    images: dict[str, np.ndarray]
    truth: np.ndarray
    mitsuba: np.ndarray
    mask: np.ndarray


def _animate(config, out, backend, cache, progress, job: pg.Task) -> list[dict]:
    import imageio.v3 as iio

    cfg, runs, methods, travelled = load_motion_config(config)
    every = [sc for run in runs for sc in run.scenes]
    job.total = len(every)
    labels = [m.label for m in methods]
    budget.check_backend(backend)
    budget.check_cases(every, methods, source=str(config))
    store, rows, frames, done = Cache(cache), [], [], 0
    kept: dict[str, dict[int, list[_Frame]]] = {}  # sequence → seed → frames
    shown: dict[str, list[CaseOutput]] = {}  # sequence → its first seed's cases (the animation's frames)
    t0 = time.perf_counter()
    owns = ["motion.gif", "motion.mp4", "motion.png", "frames.csv", "metadata.json", "motion.csv", "jod.csv"]
    with locked(out):  # one command at a time here; the files are made first, then written together
        for run in runs:
            for i, (case_id, sc) in enumerate(run.scenes):
                with pg.item(case_id):
                    case = run_config_case(
                        sc,
                        methods,
                        backend=backend,
                        cache=store,
                        case_id=case_id,
                        where=f"{config} {run.sequence} seed {run.seed} path (frame {i})",
                    )()  # finished at once
                for r in case.rows:
                    rows.append({"sequence": run.sequence, "seed": run.seed, "frame": i,
                                 "path_m": float(travelled[i]), **r})  # fmt: skip
                kept.setdefault(run.sequence, {}).setdefault(run.seed, []).append(
                    _Frame({k: case.images[k] for k in labels}, case.truth, case.mitsuba, case.mask)
                )
                if run.seed == cfg.seeds[0]:
                    shown.setdefault(run.sequence, []).append(case)
                done += 1
                pg.advance(case_id)
                if progress:
                    progress(done, len(every))
        first = {run.sequence: [sc for _, sc in run.scenes] for run in runs if run.seed == cfg.seeds[0]}
        for seq, cases in shown.items():
            crop = motion_crop([c.mask for c in cases])
            for i, (case, sc) in enumerate(zip(cases, first[seq])):
                cx, cy, cz = sc.object.center
                frames.append(
                    frame_image(
                        case,
                        labels,
                        crop=crop,
                        title=f"{seq} ({sc.object.shape}), frame {i + 1}/{len(cases)}: at "
                        f"({cx:.2f}, {cy:.2f}, {cz:.2f}), {travelled[i]:.2f} m along the path; "
                        f"cube {sc.render.cube_res}², seed {sc.render.seed}, backend {backend}",
                    )
                )
        shown.clear()  # the cases' images are no longer needed
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
        table, claim = motion_table(kept, first, labels, rows, fps=cfg.fps)
        files["frames.csv"] = to_csv(rows)
        files["motion.csv"] = to_csv(table)
        meta = metadata(
            config,
            backend=backend,
            seed=cfg.seeds[0],
            methods=labels,
            cases=len(every),
            kind="animation",
            seconds=round(time.perf_counter() - t0, 1),
        )
        meta["seeds"] = list(cfg.seeds)
        meta["sequences"] = {s: sc[0].object.shape for s, sc in first.items()}
        meta["video_metric"] = VIDEO_METRIC if video.available() else NO_CVVDP
        meta["temporal_metric"] = TEMPORAL_METRIC
        if claim:
            meta["motion_claim"] = claim
            meta["jod_display"] = video.CVVDP_DISPLAY
            meta["jod_bound"] = video.BOUND_JOD
        files["metadata.json"] = json.dumps(meta, indent=2)
        write_set(out, files, owns, lock=False)
    return rows


def motion_table(
    kept: dict[str, dict[int, list]],
    scenes: dict[str, list],
    labels: list[str],
    rows: list[dict],
    *,
    fps: float,
) -> tuple[list[dict], list[str]]:
    """(``motion.csv``'s rows, the motion claim's sentences): per sequence (object) and method, and for the noise
    floor (``truth_at_hit``), the means over seeds with their 95 % intervals (:func:`stats.seed_interval`) of the
    per-frame FLIP against truth_at_hit on the object (``flip_truth``), E_warp on the object's pixels along the
    exact motion and — with ColorVideoVDP — the JOD on the object's pixels (a crop around them) against
    truth_at_hit (``jod``; the floor's: truth_at_hit of the next seed), its ``gap`` below the floor (paired by
    seed) and the JOD against Mitsuba's render on the object (``jod_mitsuba``). ``kept``: sequence → seed → the
    frames (images, truth, mitsuba, mask); ``scenes``: sequence → its frames' scenes; ``rows`` (frames.csv's)
    gain each step's E_warp."""
    table: list[dict] = []
    at = {(r["sequence"], r["seed"], r["frame"], r["label"]): r for r in rows}
    metric = video._metric() if video.available() else None
    for seq, by_seed in kept.items():
        seeds = list(by_seed)
        flows = temporal.sequence_flows(scenes[seq])
        masks = np.stack([f.mask for f in by_seed[seeds[0]]])
        crop = motion_crop(list(masks))
        per: dict[str, dict[str, list[float]]] = {lab: {} for lab in [*labels, video.FLOOR]}
        for s in seeds:
            seqs = {lab: [f.images[lab] for f in by_seed[s]] for lab in labels}
            seqs[video.FLOOR] = [f.truth for f in by_seed[s]]
            for lab, frames in seqs.items():
                whole, steps = temporal.sequence_ewarp(frames, flows)
                for i, step in enumerate(steps, start=1):
                    if (seq, s, i, lab) in at:
                        at[(seq, s, i, lab)].update(step)
                flips = [r.get("flip_truth", np.nan) for r in rows
                         if r["sequence"] == seq and r["seed"] == s and r["label"] == lab]  # fmt: skip
                for k, v in {**whole, "flip_truth": float(np.nanmean(flips))}.items():
                    per[lab].setdefault(k, []).append(v)
            if metric is None:
                continue
            ldr = {lab: np.stack([to_ldr(f) for f in frames]) for lab, frames in seqs.items()}
            nxt = by_seed[seeds[(seeds.index(s) + 1) % len(seeds)]]
            ref, mits = ldr[video.FLOOR], np.stack([to_ldr(f.mitsuba) for f in by_seed[s]])
            floor = np.nan
            if len(seeds) > 1:  # the noise floor: truth_at_hit of the next seed against this seed's
                other = np.stack([to_ldr(f.truth) for f in nxt])
                floor = video.object_jod(other, ref, masks, crop, fps=fps, metric=metric)
            for lab in seqs:
                q = floor if lab == video.FLOOR else video.object_jod(ldr[lab], ref, masks, crop, fps=fps,
                                                                       metric=metric)  # fmt: skip
                qm = video.object_jod(ldr[lab], mits, masks, crop, fps=fps, metric=metric)
                for k, v in {
                    "jod": q,
                    "gap": floor - q if lab != video.FLOOR else np.nan,
                    "jod_mitsuba": qm,
                }.items():
                    per[lab].setdefault(k, []).append(v)
        side = int(crop[0].stop - crop[0].start)
        for lab, vals in per.items():
            row = {"sequence": seq, "label": lab, "frames": len(masks), "seeds": len(seeds),
                   "object_pixels": float(masks.sum(axis=(1, 2)).mean()), "crop": f"{side}x{side}"}  # fmt: skip
            for k in ("flip_truth", "ewarp_l2", "ewarp_flip", "jod", "gap", "jod_mitsuba"):
                if k in vals:
                    row[k], row[f"{k}_lo"], row[f"{k}_hi"] = stats.seed_interval(vals[k])
                else:
                    row[k] = row[f"{k}_lo"] = row[f"{k}_hi"] = NO_CVVDP
            row |= (
                {"display": video.CVVDP_DISPLAY, "cvvdp": video.VERSION}
                if metric
                else {"display": "", "cvvdp": ""}
            )
            table.append(row)
    return table, (video.motion_claim(table) if metric else [])


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
