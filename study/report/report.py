"""``reports/index.md`` and ``reports/index.html`` from results only: a summary, figures, metrics tables, the
paper's claims, per-case image viewers, versions and commands.

Nothing is computed here but summaries of the tables under ``reports/``: every figure directory with a
``metrics.csv`` (``reports/fig*/``, and its viewer images ``viewer/`` when the figure command wrote them), every
sweep with a ``results.csv`` (``reports/sweep-*/``), every ``study run`` output (any folder under ``reports/``
that holds a run's own files: ``index.json``, ``table.csv``, ``scene.json``; shown like a figure;
:mod:`study.report.sections`), and any Markdown report another command wrote (e.g.
``reports/performance.md``). Names in them are text, never markup (:mod:`study.outputs.markup`). The report is
a list of blocks (heading, paragraph, table, image, viewer, …) rendered twice from the same numbers: as Markdown
here and as HTML by :mod:`study.outputs.html`. A malformed table is one error naming it (exit 2), and
``index.md`` / ``index.html`` are replaced only when both are complete (:func:`study.io.write_set`, the reports
directory locked).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from study import columns
from study import progress as pg
from study.errors import StudyError
from study.io import locked, write_set
from study.outputs import html
from study.outputs.markup import Md, code, link, md_esc
from study.report import claims as claim_registry
from study.report import kinds, sections, summary, table_notes
from study.report.check import read_table
from study.report.register import bench_sentence, motion_sentences, register_markdown
from study.report.verdicts import verdict_mark
from study.tables import check_rows

#: The report's tables read their columns from the declared table when they are made (study/columns.py, views
#: "summary", "decomposition" and "comparison": a plug-in's column declared in one appears there too): outcome
#: classes first, the error split's, the comparison's fixed tolerances.
VIEWS = ("summary", "decomposition", "comparison")


def _medians(tables: dict[str, list[dict]], cols: list[str]) -> list[dict]:
    """One row per table × method: the median over the table's cases of each column."""
    rows = []
    for name, tab in tables.items():
        for lab in dict.fromkeys(r["label"] for r in tab):
            sel = [r for r in tab if r["label"] == lab]
            row = {"table": name, "method": lab, "cases": len(sel)}
            for m in cols:
                vals = np.array([r.get(m, np.nan) for r in sel], float)
                row[m] = float(np.nanmedian(vals)) if np.isfinite(vals).any() else float("nan")
            rows.append(row)
    return rows


# ---------------------------------------------------------------------------------------------- the summary


# ---------------------------------------------------------------------------------------------- sections
def _claims_section(tables: dict[str, list[dict]]) -> list[tuple]:
    rows, seen = [], set()
    for name, tab in tables.items():
        for cl, v in claim_registry.judge_claims(tab):
            seen.add(cl.id)
            rows.append(
                {
                    "claim": cl.text,
                    "paper": cl.source,
                    "table": name,
                    "holds": verdict_mark(v),
                    "subset": v.subset,
                    "n": v.n,
                    "evidence": str(v.number),
                }
            )
    figs = [n for n in tables if n.startswith("fig")]
    if len(figs) > 1:  # claims that contrast figures (e.g. occluded vs free cases)
        for cl, v in claim_registry.judge_claims([r for n in figs for r in tables[n]]):
            if cl.id not in seen:
                rows.append(
                    {
                        "claim": cl.text,
                        "paper": cl.source,
                        "table": " + ".join(figs),
                        "holds": verdict_mark(v),
                        "subset": v.subset,
                        "n": v.n,
                        "evidence": str(v.number),
                    }
                )
    if not rows:  # no table a claim applies to: no section (an empty table says nothing)
        return []
    return [
        ("h", 2, "The paper's claims"),
        (
            "p",
            "Each claim is checked on every table it applies to (study/report/claims.py), on the rays or pixels "
            "it is about (*subset*, *n*) and on tails — wrong fractions with their 95 % interval over rays, "
            "95th percentiles — not medians; a claim that does not hold says so first (fails: …); a claim the paper "
            "gives no number for is *measured* (no verdict). Each claim's words, place and threshold: "
            "[claims.md](claims.md).",
        ),
        ("table", rows, ["claim", "paper", "table", "holds", "subset", "n", "evidence"]),
    ]


def _decomposition_section(tables: dict[str, list[dict]]) -> list[tuple]:
    rows = [r for r in _medians(tables, columns.view("decomposition")) if np.isfinite(r["dec_total"])]
    if not rows:
        return []
    return [
        ("h", 2, "Where the image error comes from"),
        (
            "p",
            "Per table and method, medians over the cases, over *all* the object's pixels "
            "(study/measure/split.py), in mean squared error (linear radiance², mean over channels). dec_total = "
            "MSE against *truth_at_hit*; dec_search = against *oracle_map* on the pixels whose hits the views hold "
            "(what a better search on the same views could fix); dec_visibility = the error on the pixels with a "
            "hit the views do not hold (hidden from the reference point), noise removed; dec_representation = "
            "what the map cannot hold, measured without the truth: capture noise from a second capture seed "
            "(1/8 of the samples) plus the resolution error from the map at half the resolution (its 2 × 2 texel "
            "means; first-order extrapolation); dec_noise = "
            "truth_at_hit's own noise (two seeds); dec_cross = 2·(method − oracle)·(oracle − truth). dec_residual "
            "= total − the parts; dec_sums = 1 where the parts add up to the total within their 95 % intervals. "
            "Each part from its own experiment: dec_representation_direct = oracle_map against truth_at_hit on the "
            "held pixels, noise removed (the exact hit shaded from the impostor vs from the scene); dec_sums_direct "
            "= 1 where search + visibility + representation_direct + noise meet the total within their intervals "
            "(what is left is the cross term); intervals over the spatially correlated pixels: mean ± t·√variance "
            "from each term's autocovariance (study/stats/spatial.py; in the results tables as dec_*_lo / _hi). "
            "rmse_truth_held / _unheld: RMSE against the truth on the pixels whose hits the views "
            "hold / do not hold. *_debiased = √max(0, RMSE² − σ²) with σ the reference's noise; rmse_mitsuba is "
            "against Mitsuba's own camera render with the object (two seeds), which differs from what the methods "
            "are asked by the object's shadow and one bounce on the reflected path.",
        ),
        ("table", rows, ["table", "method", "cases", *columns.view("decomposition")]),
    ]


def _comparison_section(tables: dict[str, list[dict]]) -> list[tuple]:
    """One row per table × method: the median over the table's cases of each metric, and the cost."""
    rows = _medians(tables, columns.view("comparison"))
    if not rows:
        return []
    return [
        ("h", 2, "Method comparison"),
        (
            "p",
            "Per table and method, the median over the table's cases of each metric. *wrong* = the fraction "
            "of rays whose shown point is farther than ε = max(1 cm, one cube-map texel at the hit) from the exact "
            "hit (wrong depth on the same ray, another surface, or no hit), over all rays, the rays whose exact hit "
            "is visible from the reference point and those whose hit is hidden from it (– where there are none); "
            "dist_p95 = 95th percentile of |shown − exact| (m). The cost is cube-map lookups per ray (the oracle's "
            "single lookup is the radiance read at the exact hit).",
        ),
        ("table", rows, ["table", "method", "cases", *columns.view("comparison")]),
        ("list", table_notes.column_notes()),
    ]


# ---------------------------------------------------------------------------------------------- the report
INTRO = (
    "Outcome per ray (study/measure/outcomes.py): *correct* when the shown point is within ε = max(1 cm, "
    "one cube-map texel at the hit) of the exact (Embree) hit, else *wrong depth* (on the same ray), *wrong "
    "surface* or *no hit*; wrong_fraction = 1 − correct. Angular error: at the shading point, between the "
    "direction to the shown point and the direction to the exact (Embree) hit (blind to a wrong depth on the "
    "same ray). Image errors over the object's pixels: RMSE on linear radiance; PSNR, SSIM (scikit-image) and "
    "FLIP (flip-evaluator, LDR mode) on images clipped at 1 and sRGB-encoded. *oracle_map* = the exact hit "
    "shaded with what the reference point's views hold: the impostor read towards a hit the reference point "
    "sees, the background in the ray's own direction for a ray leaving the scene, and no value (a magenta pixel, "
    "left out of every *_oracle column and of the oracle's own row) for a hit hidden from the reference point; "
    "*truth_at_hit* = exact hit, Mitsuba's radiance "
    "along the same ray (the truth the methods are measured against); *mitsuba* = Mitsuba's camera render "
    "with the object."
)
TITLE = "study: how close do ray-tracing effects without tracing rays come to ray tracing?"


def _figures(reports: Path) -> list[Path]:
    return [d for k, d in kinds.found(reports) if k.tables]


def _sweeps(reports: Path) -> list[Path]:
    return sorted(d for d in reports.glob("sweep-*") if (d / "results.csv").is_file())


def results_table(path: Path) -> list[dict]:
    """A results table read for the report: well formed (:func:`study.report.check.read_table`) and every number
    possible (:func:`study.tables.check_rows`: within its declared column's domain, each case × label once), else
    one StudyError naming the file, line and column (exit 2) before any claim or headline is drawn from it."""
    return check_rows(read_table(path, numeric=["cube_res", *columns.view("summary")]), path)


def tables_of(reports: Path) -> dict[str, list[dict]]:
    """Every figure's and sweep's table under ``reports``, by folder name (what the claims are judged on)."""
    tables = {d.name: results_table(d / "metrics.csv") for d in _figures(reports)}
    tables.update({d.name: results_table(d / "results.csv") for d in _sweeps(reports)})
    return tables


def blocks(reports: Path, tables: dict[str, list[dict]] | None = None) -> list[tuple]:
    """The report as blocks (see :func:`markdown_text` and :func:`study.outputs.html.page`)."""
    made = kinds.found(reports)  # figures of every kind, by the files their runs write (study.report.kinds)
    figs, sweeps = [d for k, d in made if k.tables], _sweeps(reports)
    runs = sections.find_runs(reports)  # by their own files, whatever the folder's name
    tables = tables_of(reports) if tables is None else tables  # build_report reads them once for both pages

    out = _claims_section(tables) + _comparison_section(tables) + _decomposition_section(tables)
    for k, d in made:
        if k.place == kinds.WITH_FIGURES:
            out += k.section(reports, d, tables.get(d.name, []) if k.tables else [], columns.view("summary"))
            out += sections.pareto_plot(reports, d.name) if k.tables else []
    for d in runs:  # study run: one scene each, not among the tables the claims are checked on
        out += sections.run_section(reports, d, results_table(d / "table.csv"), columns.view("summary"))
    for d in sweeps:
        out += sections.sweep_section(d, tables[d.name]) + sections.pareto_plot(reports, d.name)
    for k, d in made:
        if k.place == kinds.AFTER_SWEEPS:
            out += k.section(reports, d, tables.get(d.name, []) if k.tables else [], columns.view("summary"))
    out += sections.paper_section(reports)
    others = sections.shown(p for p in reports.glob("*.md") if p.name != "index.md")
    others += sections.shown(
        p for p in reports.glob("*/*.md") if p.parent.name not in {d.name for d in figs + sweeps}
    )
    if others:
        out += [
            ("h", 2, "Other reports"),
            ("list", [link(p.relative_to(reports), p.relative_to(reports).as_posix()) for p in others]),
        ]
    if not out:  # nothing found: no page of empty sections (build_report writes none)
        return []
    head = [
        ("h", 1, TITLE),
        (
            "p",
            f"Generated by {code('study report')} from the tables under {code(_named(reports))} (nothing here is "
            "computed by hand); the same report with image viewers: [index.html](index.html). The tables are "
            "committed; the pictures made beside them (viewer images, EXRs, the sweeps' plots, Pareto charts, the "
            "animation) are not: where one is absent, `bash scripts/reproduce.sh` makes it (or the command its "
            "section names). Whether each table was made by the code of its commit: *Versions and commands*.",
        ),
        *summary.headline_blocks(tables),  # the headline first
        ("p", INTRO),
    ]
    return head + out + sections.versions_section(figs + sweeps)


def _named(reports: Path) -> str:
    """The reports folder as the reader names it: relative to the working directory where it lies below it."""
    try:
        rel = reports.resolve().relative_to(Path.cwd().resolve())
    except ValueError:
        return reports.as_posix().rstrip("/") + "/"
    return (rel.as_posix() if str(rel) != "." else ".") + "/"


def _md_cell(v):
    return v if isinstance(v, Md) or not isinstance(v, str) else md_esc(v)


def markdown_text(blocks_: list[tuple], reports: Path) -> str:
    """The blocks as Markdown (``index.md``): table cells and image names from data escaped (:mod:`.markup`)."""
    from study.tables import markdown

    lines = []
    for b in blocks_:
        kind = b[0]
        if kind == "h":
            lines += ["#" * b[1] + " " + b[2], ""]
        elif kind == "p":
            lines += [b[1], ""]
        elif kind == "list":
            lines += [f"- {t}" for t in b[1]] + [""]
        elif kind == "table":
            rows = [{md_esc(k): _md_cell(v) for k, v in r.items()} for r in b[1]]
            lines += [markdown(rows, [md_esc(c) for c in b[2]], digits=3), ""]
        elif kind == "img":
            lines += ["!" + link(b[2], b[1]), ""]
        elif kind == "media":
            lines += [f"- {link(b[1], b[1])}", ""]
        elif kind == "viewer":
            lines += [html.viewer_note(reports, b[1]), ""]
    return "\n".join(lines)


def build_report(reports: str | Path = "reports") -> Path | None:
    """Write ``<reports>/index.md`` and ``<reports>/index.html`` (the directory locked meanwhile,
    :func:`study.io.locked`); returns the Markdown's path, or None where ``reports`` holds no results (nothing is
    written then: the command line says so)."""
    reports = Path(reports)
    if not reports.is_dir():
        raise StudyError("no such directory (expected the reports: figures and sweeps)", file=str(reports))
    if sections.is_run(reports):
        raise StudyError(
            "is the folder of one `study run` (the report would replace its page); give the folder above it",
            file=str(reports),
        )
    with locked(reports), pg.task("report", None):  # stage lines (study.progress)
        with pg.stage("sections"):  # the tables read, the claims checked, the viewers' images listed
            tables = tables_of(reports)
            bl = blocks(reports, tables)
        if not bl:
            return None
        with pg.stage("pages"):
            files = {
                "index.md": markdown_text(bl, reports),
                "index.html": html.page(bl, reports, title=TITLE),
                "claims.md": register_markdown(
                    tables,
                    motion_sentences(reports),
                    bench_sentence(reports / "performance" / "bench-gpu.csv"),
                ),
            }
            return write_set(reports, files, lock=False, swap=False)[0]  # others write beside it
