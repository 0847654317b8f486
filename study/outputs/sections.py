"""The report's sections for what commands wrote under ``reports/``: each figure, sweep, ``study run`` output,
fig8's caustics, animations, and the versions table. Names from files and metadata are text (escaped,
:mod:`study.outputs.markup`); links go to the report's own files only."""

from __future__ import annotations

import json
from pathlib import Path

from study.outputs import html
from study.outputs.check import read_table
from study.outputs.markup import Md, code, link, md_esc
from study.tables import REFERENCE_ROWS, read_csv

CAUSTIC_COLS = [
    "caustic_res",
    "label",
    "photons",
    "lm_rmse",
    "lm_relmse",
    "img_rmse_mitsuba",
    "img_sum_ratio_mitsuba",
    "mitsuba_noise_rmse",
    "photon_angle_p95_deg",
    "seconds_per_map",
]


def meta(d: Path) -> dict:
    try:
        m = json.loads((d / "metadata.json").read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return {}
    return m if isinstance(m, dict) else {}


def shown(paths) -> list[Path]:
    """The files a report links, sorted: never a hidden or temporary one (what a killed writer may leave)."""
    return sorted(p for p in paths if not p.name.startswith(".") and ".tmp" not in p.name)


def _images(d: Path, rel: str) -> list[tuple]:
    """A directory's PNGs (the grid first, then e.g. its error grid) as image blocks."""
    return [("img", f"{rel}/{png.name}", png.stem) for png in shown(d.glob("*.png"))]


def figure_section(reports: Path, d: Path, rows: list[dict], cols: list[str]) -> list[tuple]:
    m = meta(d)
    parquet = (
        f" ({link('Parquet', f'{d.name}/metrics.parquet')})" if (d / "metrics.parquet").is_file() else ""
    )
    out = [
        ("h", 2, md_esc(d.name)),
        (
            "p",
            f"Config {code(m.get('config', '?'))}, backend {md_esc(m.get('backend', '?'))}; table: "
            f"{link(f'{d.name}/metrics.csv', f'{d.name}/metrics.csv')}{parquet}.",
        ),
        *_images(d, d.name),
        ("p", html.SHADOW_NOTE),
        ("viewer", d.name),
    ]
    return out + [("table", rows, ["case", "label", *cols])] + _split_tables(d)


def _split_tables(d: Path) -> list[tuple]:
    """A figure's error split where one was written beside it (``split.csv``: ``scripts/glossy_split.py`` for
    the glossy figure): a heading, the source and the table."""
    f = d / "split.csv"
    rows = read_csv(f) if f.is_file() else []
    if not rows:  # no section of an empty table
        return []
    return [
        ("h", 3, "Error split"),
        (
            "p",
            f"Prefiltering, localization, visibility and noise with 95 % intervals over blocks of pixels "
            f"({link(f'{d.name}/split.csv', f'{d.name}/split.csv')}; scripts/glossy_split.py).",
        ),
        ("table", rows, list(rows[0])),
    ]


def _json(path: Path) -> dict:
    try:
        m = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return {}
    return m if isinstance(m, dict) else {}


def find_runs(reports: Path) -> list[Path]:
    """Every folder under ``reports``, at any depth and of any name (hidden ones aside), that ``study run`` or
    :meth:`study.api.Result.save` wrote, known by its own files: ``index.json`` naming its EXR and layers, beside
    ``table.csv`` and ``scene.json``."""
    hidden = lambda d: any(p.startswith(".") or ".tmp" in p for p in d.relative_to(reports).parts)  # noqa: E731
    return sorted(i.parent for i in reports.rglob("index.json") if not hidden(i.parent) and is_run(i.parent))


def is_run(d: Path) -> bool:
    """Whether folder ``d`` holds one run's results (:func:`find_runs`)."""
    m = _json(d / "index.json")
    return isinstance(m.get("layers"), dict) and "exr" in m and all((d / f).is_file() for f in RUN_FILES)


#: The files beside ``index.json`` that make a folder a run's (:meth:`study.api.Result.save` writes them).
RUN_FILES = ("table.csv", "scene.json")


def run_file(d: Path) -> str | None:
    """The name of the scene file a run folder's results are of (``index.json``'s ``name``; older runs: their
    environment's file in ``scene.json``), None where neither says."""
    name = _json(d / "index.json").get("name")
    if not name:
        env = _json(d / "scene.json").get("environment")
        name = Path(env["file"]).name if isinstance(env, dict) and isinstance(env.get("file"), str) else None
    return str(name) if name else None


def run_section(reports: Path, d: Path, rows: list[dict], cols: list[str]) -> list[tuple]:
    """What ``study run`` wrote (a folder :func:`find_runs` found): its grid, viewer and table, like a figure's;
    titled by the folder and the scene file it measured."""
    rel = d.relative_to(reports).as_posix()
    name = run_file(d)
    page = (
        f" Its own page: {link(f'{rel}/index.html', f'{rel}/index.html')}."
        if (d / "index.html").is_file()
        else ""
    )
    what = f"{code(name)}, one scene" if name else "One scene"
    return [
        ("h", 2, md_esc(f"{rel}: {name}" if name else rel)),
        ("p", f"{what}, `study run`; table: {link(f'{rel}/table.csv', f'{rel}/table.csv')}.{page}"),
        *_images(d, rel),
        ("viewer", rel, f"{name or rel}: images per case"),
        ("table", rows, ["label", *cols]),
    ]


def sweep_section(d: Path, rows: list[dict]) -> list[tuple]:
    m = meta(d)
    rel = d.name
    parquet = f" ({link('Parquet', f'{rel}/results.parquet')})" if (d / "results.parquet").is_file() else ""
    methods = [str(x) for x in m.get("methods", [])]
    out = [
        ("h", 2, f"Sweep {code(m.get('config', d.name))}"),
        (
            "p",
            f"{md_esc(m.get('cases', '?'))} cases × {len(methods)} methods "
            f"({md_esc(', '.join(methods))}); table: {link(f'{rel}/results.csv', f'{rel}/results.csv')}{parquet}.",
        ),
    ]
    out += [("img", f"{rel}/plots/{png.name}", png.stem) for png in shown((d / "plots").glob("*.png"))]
    # one compact table: per axis combination at the largest cube resolution, median angular error per method
    axes = [k for k in rows[0] if k.startswith("axis:") and k != "axis:render.cube_res"] if rows else []
    top = max((r["cube_res"] for r in rows), default=None)
    sel = [r for r in rows if r["cube_res"] == top and r["method"] not in REFERENCE_ROWS]
    labels = list(dict.fromkeys(r["label"] for r in sel))
    groups: dict[tuple, dict] = {}
    for r in sel:
        g = groups.setdefault(tuple(r[a] for a in axes), {a.removeprefix("axis:"): r[a] for a in axes})
        g[r["label"]] = r["angle_median_deg"]
        g["occluded"] = r["occluded_fraction"]
    if groups:
        out += [
            ("p", f"Median angular error (degrees) at cube resolution {top:g}:"),
            ("table", list(groups.values()), [a.removeprefix("axis:") for a in axes] + ["occluded"] + labels),
        ]
    return out


def caustics_section(reports: Path) -> list[tuple]:
    """Figure 8 (``study caustics-sweep`` → reports/fig8/): light-map error against exact photon tracing (a),
    image error against Mitsuba's ptracer (b), time per caustic map."""
    d = reports / "fig8"
    pngs = shown(d.glob("*.png"))
    if not (d / "sweep" / "results.csv").is_file():
        return (
            [("h", 2, "fig8: caustics"), *[("img", f"fig8/{p.name}", "fig8") for p in pngs]] if pngs else []
        )
    rows = read_table(d / "sweep" / "results.csv", required=("label",), numeric=["caustic_res"])
    out = [
        ("h", 2, "fig8: caustics"),
        (
            "p",
            "Glass sphere (n = 1.3) focusing the point light; caustic map from the light, photon hits localized "
            "in the distance impostor, splatted into light maps (study/caustics/photons.py, "
            "study/caustics/lightmap.py). "
            "lm_* = light-map error against exact photon tracing (a), W/m²; img_* = caustic-only image against "
            "Mitsuba ptracer (b); mitsuba_noise_rmse = Mitsuba's own noise (two seeds). "
            "Table: [fig8/sweep/results.csv](fig8/sweep/results.csv).",
        ),
    ]
    out += [("img", f"fig8/{p.name}", "fig8") for p in pngs]
    return out + [("table", rows, CAUSTIC_COLS)]


def media_section(reports: Path) -> list[tuple]:
    """Animations another command wrote (``reports/animation/*.gif|*.mp4``, ``study animate``), and its plots."""
    d = reports / "animation"
    files = shown(p for p in d.glob("*") if p.suffix.lower() in (".gif", ".mp4", ".webm"))
    if not files:
        return []
    out = [
        ("h", 2, "Animations"),
        *[("media", f"animation/{p.name}", p.stem) for p in files],
        *[("img", f"animation/{p.name}", p.stem) for p in shown(d.glob("*.png"))],
    ]
    table = next((t for t in (d / "motion.csv", d / "jod.csv") if t.is_file()), None)  # jod.csv: older runs
    return out + (motion_claim_section(d, table) if table else [])


def motion_claim_section(d: Path, table: Path) -> list[tuple]:
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
            f"{first}{ewarp} Table: [animation/{table.name}](animation/{table.name}).",
        ),
        *([("list", [md_esc(c) for c in m["motion_claim"]])] if m.get("motion_claim") else []),
        ("table", rows, cols),
    ]


def paper_section(reports: Path) -> list[tuple]:
    """Figures at the paper's resolution made on a GPU machine (``reports/paper/<name>/``, ``study figure NAME
    --quality paper``): their grids, the command and the seconds each took, from their metadata."""
    dirs = shown(d for d in (reports / "paper").glob("*") if (d / "metadata.json").is_file())
    if not dirs:
        return []
    out = [
        ("h", 2, "Paper resolution (1024², made on a GPU)"),
        (
            "p",
            "The preview figures above are what `scripts/reproduce.sh` makes on a CPU; these are the same configs "
            "at the paper's 1024² (`--quality paper`), one ray per pixel. See [paper/README.md](paper/README.md).",
        ),
    ]
    for d in dirs:
        m = meta(d)
        out.append(
            (
                "p",
                Md(
                    f"**{md_esc(d.name)}**: {code(m.get('command') or '?')}, {m.get('seconds', '?')} s on "
                    f"{md_esc(m.get('machine_note') or _machine(m))}; "
                    f"table: {link('metrics.csv', f'paper/{d.name}/metrics.csv')}"
                ),
            )
        )
        out += [("img", f"paper/{d.name}/{p.name}", f"{d.name} at 1024²") for p in shown(d.glob("*.png"))]
    return out


def _machine(m: dict) -> str:
    """A run's machine in words, from its metadata: cores, Python and backend."""
    return f"{m.get('cpus', '?')} cores, Python {m.get('python', '?')}, backend {m.get('backend', '?')}"


def versions_section(dirs: list[Path]) -> list[tuple]:
    rows = []
    for d in dirs:
        m = meta(d)
        rows.append(
            {
                "table": d.name,
                "command": Md(code(m.get("command") or "?")),
                "config sha256": str(m.get("config_sha256", "?")),
                "seed": str(m.get("seed", "?")),
                "backend": str(m.get("backend", "?")),
                "git commit": str(m.get("git_commit", "?"))[:10],
                "versions": ", ".join(f"{k} {v}" for k, v in m.get("versions", {}).items() if v),
            }
        )
    if not rows:
        return []
    return [
        ("h", 2, "Versions and commands"),
        ("table", rows, ["table", "command", "config sha256", "seed", "backend", "git commit", "versions"]),
        ("p", "Regenerate everything: `bash scripts/reproduce.sh` (figures, the main sweep, this report)."),
    ]
