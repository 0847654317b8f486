"""The report's sections for what commands wrote under ``reports/``: a grid figure's, each sweep, ``study run``
output, the figures at the paper's resolution, and the versions table (the other kinds of figure bring their own:
:mod:`study.report.kinds`). Names from files and metadata are text (escaped,
:mod:`study.outputs.markup`); links go to the report's own files only."""

from __future__ import annotations

from pathlib import Path

from study.io import read_json
from study.outputs import html
from study.outputs.markup import Md, code, link, md_esc
from study.tables import REFERENCE_ROWS


def meta(d: Path) -> dict:
    try:
        m = read_json(d / "metadata.json", what="metadata.json")  # nested 10⁵ deep: one line, exit 2
    except (OSError, ValueError):
        return {}
    return m if isinstance(m, dict) else {}


def shown(paths) -> list[Path]:
    """The files a report links, sorted: never a hidden or temporary one (what a killed writer may leave)."""
    return sorted(p for p in paths if not p.name.startswith(".") and ".tmp" not in p.name)


def _images(d: Path, rel: str) -> list[tuple]:
    """A directory's PNGs (the grid first, then e.g. its error grid) as image blocks."""
    pngs = sorted(
        shown(d.glob("*.png")), key=lambda p: (p.stem != d.name, p.name)
    )  # fig4.png before fig4-errors
    return [("img", f"{rel}/{png.name}", png.stem) for png in pngs]


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
    return out + [("table", rows, ["case", "label", *cols])]


def _json(path: Path) -> dict:
    try:
        m = read_json(path, what=path.name)  # nested 10⁵ deep: one line, exit 2
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


def pareto_plot(reports: Path, name: str) -> list[tuple]:
    """The table's equal-cost front (``study pareto``: ``pareto/<name>.png`` under ``reports``), where written."""
    if not (reports / "pareto" / f"{name}.png").is_file():
        return []
    page = link("pareto/pareto.md", "pareto/pareto.md")
    return [
        (
            "p",
            f"Equal-cost front: error against measured ms per 1080p frame, budgets and the exact query ({page}).",
        ),
        ("img", f"pareto/{name}.png", f"{name}: equal-cost front"),
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


def paper_section(reports: Path) -> list[tuple]:
    """Figures at the paper's resolution made on a GPU machine (``study figure NAME --quality paper``, by default
    into ``reports/paper/<name>/``; found one level down by their metadata's ``quality``, whatever the folders are
    called): their grids, the command and the seconds each took, from their metadata."""
    under = {d for d in shown(reports.glob("*")) if d.is_dir()}  # not inside a hidden or half-written folder
    dirs = shown(d for d in reports.glob("*/*") if d.parent in under and meta(d).get("quality") == "paper")
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
                    f"table: {link('metrics.csv', f'{_rel(reports, d)}/metrics.csv')}"
                ),
            )
        )
        out += [("img", f"{_rel(reports, d)}/{p.name}", f"{d.name} at 1024²") for p in shown(d.glob("*.png"))]
    return out


def _rel(reports: Path, d: Path) -> str:
    return d.relative_to(reports).as_posix()


def _machine(m: dict) -> str:
    """A run's machine in words, from its metadata: cores, Python and backend."""
    return f"{m.get('cpus', '?')} cores, Python {m.get('python', '?')}, backend {m.get('backend', '?')}"


def _device(m: dict) -> str:
    """The machine a table was made on, from its metadata: the GPU's name on cuda, else the CPU and its cores."""
    d = m.get("device") if isinstance(m.get("device"), dict) else {}
    if d.get("gpu"):
        return str(d["gpu"])
    if d.get("cpu"):
        return f"{d['cpu']} ({d.get('cores', '?')} cores)"
    return f"{m.get('cpus', '?')} cores"


def code_mark(m: dict, repo: Path | None = None) -> str:
    """``current`` where the table's code hash matches the code of its commit
    (:func:`study.harness.provenance.code_status`), else ``stale: <why>``."""
    from study.harness import provenance

    why = provenance.code_status(m, **({"repo": repo} if repo is not None else {}))
    return "current" if why is None else f"stale: {why}"


def versions_section(dirs: list[Path]) -> list[tuple]:
    rows = []
    for d in dirs:
        m = meta(d)
        dirty = m.get("git_dirty")
        rows.append(
            {
                "table": d.name,
                "command": Md(code(m.get("command") or "?")),
                "config sha256": str(m.get("config_sha256", "?")),
                "seed": str(m.get("seed", "?")),
                "backend": str(m.get("backend", "?")),
                "device": _device(m),
                "git commit": str(m.get("git_commit", "?"))[:10] + (" (dirty)" if dirty else ""),
                "code": code_mark(m),
                "versions": ", ".join(f"{k} {v}" for k, v in m.get("versions", {}).items() if v),
            }
        )
    if not rows:
        return []
    cols = [
        "table",
        "command",
        "config sha256",
        "seed",
        "backend",
        "device",
        "git commit",
        "code",
        "versions",
    ]
    return [
        ("h", 2, "Versions and commands"),
        (
            "p",
            "Written by the commands that made each table (study/harness/provenance.py), none by hand. *code*: "
            "*current* where the table's code hash equals the hash of the files it lists as its commit holds them; "
            "*stale* (with why) where it does not, where its commit is not in this repository's history, or where "
            "its metadata has no code hash (made before study wrote one): remake such a table before trusting it "
            "to describe this code.",
        ),
        ("table", rows, cols),
        ("p", "Regenerate everything: `bash scripts/reproduce.sh` (figures, the main sweep, this report)."),
    ]
