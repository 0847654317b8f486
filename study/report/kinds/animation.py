"""The ``animation`` kind (``configs/motion.toml``, ``study animate``): the sphere of Figure 4 moving along a path,
every method beside Mitsuba (:func:`study.outputs.animation.animate`); in the report, the animation, its plot and
whether the error is visible in motion."""

from __future__ import annotations

from pathlib import Path

from study.outputs.animation import animate
from study.outputs.markup import md_esc
from study.report.kinds import AFTER_SWEEPS, FigureKind, register_kind
from study.report.sections import meta, shown
from study.tables import read_csv


def animation_figure(config, out, *, name=None, backend="numpy", cache=".cache", quality="preview"):
    """The motion config's frames into ``out`` (at the config's own resolution whatever the ``quality``)."""
    return animate(config, out, backend=backend, cache=cache)


def animation_lines(rows: list[dict]) -> list[str]:
    """How many frames were made."""
    return [f"{len({r['frame'] for r in rows})} frames"]


def media_section(reports: Path, d: Path, table: list[dict], cols: list[str]) -> list[tuple]:
    """An animation's files (``*.gif|*.mp4|*.webm``, :func:`study.outputs.animation.animate`), its plots and the
    judgement of its sequences."""
    rel = d.relative_to(reports).as_posix()
    files = shown(p for p in d.glob("*") if p.suffix.lower() in (".gif", ".mp4", ".webm"))
    if not files:
        return []
    out = [
        ("h", 2, "Animations"),
        *[("media", f"{rel}/{p.name}", p.stem) for p in files],
        *[("img", f"{rel}/{p.name}", p.stem) for p in shown(d.glob("*.png"))],
    ]
    table = next((t for t in (d / "motion.csv", d / "jod.csv") if t.is_file()), None)  # jod.csv: older runs
    return out + (motion_claim_section(d, table, rel) if table else [])


def motion_claim_section(d: Path, table: Path, rel: str = "animation") -> list[tuple]:
    """The animation's judgement as a sequence: what was measured is said from its metadata (``video_metric``:
    ColorVideoVDP or "cvvdp not installed"; older runs without it had ColorVideoVDP), then the claim and the
    table."""
    m = meta(d)
    rows = read_csv(table)
    used = m.get("video_metric") or f"ColorVideoVDP (cvvdp {rows[0].get('cvvdp', '') if rows else ''})"
    with_jod = "not installed" not in used and any(isinstance(r.get("jod"), float) for r in rows)
    if with_jod:
        first = (
            f"These frames were measured with the extra study[video] installed: {used} scores each method's frame "
            "sequence on the object's pixels (a crop around the object, the rest of it the reference's) against "
            "truth_at_hit (exact hits, Mitsuba's shading) in JOD (10: no visible difference; a difference of 1 JOD: "
            f"75 % of observers notice it, one JND) on its {m.get('jod_display', 'standard_fhd')} display (24-inch "
            "Full HD, 200 cd/m², office light, 0.6 m); jod_mitsuba is the same against Mitsuba's render. The noise "
            "floor is truth_at_hit of another seed against truth_at_hit. Means and 95 % intervals over "
            f"{m.get('seeds') and len(m['seeds']) or 'the'} seed replicates (every render drawn anew). The claim "
            f"holds for a method whose gap below the floor lies under {m.get('jod_bound', 1.0):g} JOD (one JND), "
            "interval included, and only where the floor itself costs at most a third of that."
        )
    else:
        first = (
            "ColorVideoVDP was not installed when these frames were measured (`bash scripts/setup.sh --video` adds "
            "it), so its JOD columns say so and the claim is not judged in JOD."
        )
    ewarp = ""
    if any("ewarp_l2" in r for r in rows):
        ewarp = (
            " Beside it, torch-free: flip_truth, the per-frame FLIP against truth_at_hit (the frames' mean), and "
            "E_warp (study/measure/temporal.py): the frame before warped onto each frame along the exact motion "
            "(the renderer's exact hits moved by the object's step), masked where that point was hidden a frame "
            "earlier or lies off the object; ewarp_l2 is the mean squared sRGB difference, ewarp_flip the FLIP "
            "of the two. E_warp counts every change along the motion, wanted or not: truth_at_hit's holds the "
            "reflection's true slide and its Monte Carlo noise, drawn anew each frame; a method far above it "
            "flickers, one below it changes less than the truth does (steadier, not closer)."
        )
    cols = ["sequence", "label", "flip_truth", "ewarp_l2", "ewarp_flip", "jod", "jod_lo", "jod_hi", "gap",
            "gap_lo", "gap_hi", "jod_mitsuba", "seeds", "frames", "object_pixels"]  # fmt: skip
    cols = [c for c in cols if any(c in r for r in rows)]  # older tables lack some
    return [
        ("h", 3, "Is the error visible in motion?" + (" (ColorVideoVDP)" if with_jod else "")),
        (
            "p",
            "The paper says localization errors of curved moving objects can hardly be recognized visually; "
            "measured on the object's pixels for each object (sequence). "
            f"{first}{ewarp} Table: [{rel}/{table.name}]({rel}/{table.name}).",
        ),
        *([("list", [md_esc(c) for c in m["motion_claim"]])] if m.get("motion_claim") else []),
        ("table", rows, cols),
    ]


ANIMATION = register_kind(
    FigureKind(
        name="animation",
        run=animation_figure,
        files=("frames.csv",),
        section=media_section,
        place=AFTER_SWEEPS,
        rank=20,
        lines=animation_lines,
    )
)
