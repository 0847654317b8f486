"""``reports/index.md`` from results only: figures, metrics tables, the paper's claims, versions and commands.

Nothing is computed here but summaries of the tables under ``reports/``: every figure directory with a
``metrics.csv`` (``reports/fig*/``), every sweep with a ``results.csv`` (``reports/sweep-*/``), and any Markdown
report another command wrote (e.g. ``reports/performance.md``). A malformed table is one error naming it (exit 2),
and ``index.md`` is replaced only when it is complete (:func:`study.io.output_set`, the reports directory locked).
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from study.errors import StudyError
from study.io import locked, write_set
from study.outputs import claims as claim_registry
from study.outputs.check import read_table
from study.tables import REFERENCE_ROWS, markdown

#: Outcome classes first (study.evaluate.outcomes): the angle alone is blind to a wrong depth on the same ray.
OUTCOMES = ["wrong_fraction", "wrong_fraction_visible", "wrong_fraction_hidden", "dist_p95"]
SUMMARY = [*OUTCOMES, "angle_median_deg", "angle_p95_deg", "rmse_oracle", "rmse_truth_debiased",
           "rmse_mitsuba_debiased", "flip_truth", "occluded_fraction", "lookups_per_ray"]
#: The error decomposition (study.evaluate.truth): the parts add up in quadrature to dec_total.
DECOMPOSITION = ["dec_total", "dec_localization", "dec_representation", "dec_noise", "dec_ratio",
                 "rmse_truth", "rmse_truth_debiased", "truth_noise_rmse", "rmse_mitsuba", "rmse_mitsuba_debiased",
                 "mitsuba_noise_rmse"]


def table(rows: list[dict], cols: list[str]) -> str:
    return markdown(rows, cols, digits=3)


def _meta(d: Path) -> dict:
    try:
        meta = json.loads((d / "metadata.json").read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return {}
    return meta if isinstance(meta, dict) else {}


def _shown(paths) -> list[Path]:
    """The files a report links, sorted: never a hidden or temporary one (what a killed writer may leave)."""
    return sorted(p for p in paths if not p.name.startswith(".") and ".tmp" not in p.name)


def _claims_section(tables: dict[str, list[dict]]) -> list[str]:
    lines = ["## The paper's claims", "",
             "Each claim is checked on every table it applies to (study/claims.py).", "",
             "| claim | paper | table | holds | evidence |", "|---|---|---|---|---|"]
    seen = set()
    for name, rows in tables.items():
        for cl, v in claim_registry.evaluate(rows):
            seen.add(cl.id)
            lines.append(f"| {cl.text} | {cl.source} | {name} | {'✓' if v.ok else '✗'} | {v.number} |")
    figs = [n for n in tables if n.startswith("fig")]
    if len(figs) > 1:                      # claims that contrast figures (e.g. occluded vs free cases)
        name = " + ".join(figs)
        for cl, v in claim_registry.evaluate([r for n in figs for r in tables[n]]):
            if cl.id not in seen:
                lines.append(f"| {cl.text} | {cl.source} | {name} | {'✓' if v.ok else '✗'} | {v.number} |")
    return lines + [""]


COMPARISON = [*OUTCOMES, "angle_p95_deg", "rmse_oracle", "rmse_truth_debiased", "rmse_mitsuba_debiased",
              "flip_truth", "valid_fraction", "lookups_per_ray"]


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


def _decomposition_section(tables: dict[str, list[dict]]) -> list[str]:
    rows = [r for r in _medians(tables, DECOMPOSITION) if np.isfinite(r["dec_total"])]
    if not rows:
        return []
    return ["## Where the image error comes from", "",
            "Per table and method, medians over the cases, over the object's pixels whose exact hits the reference "
            "point sees (study/evaluate/truth.py). dec_total = RMSE against *truth_at_hit* (Mitsuba's radiance "
            "along each exact secondary ray, the impostor's bounce budget, no object shadow in either, the methods' "
            "own sub-pixel rays); dec_localization = against *oracle_map* (the exact hit's radiance from the "
            "impostor); dec_representation = oracle_map vs truth_at_hit, noise-debiased (what the map cannot hold); "
            "dec_noise = truth_at_hit's own noise (two seeds). dec_ratio = √(loc² + rep² + noise²) / total (1 when "
            "the parts add up in quadrature). *_debiased = √max(0, RMSE² − σ²) with σ the reference's noise; "
            "rmse_mitsuba is against Mitsuba's own camera render with the object (two seeds), which differs from "
            "what the methods are asked by the object's shadow and one bounce on the reflected path.", "",
            table(rows, ["table", "method", "cases", *DECOMPOSITION]), ""]


def _comparison_section(tables: dict[str, list[dict]]) -> list[str]:
    """One row per table × method: the median over the table's cases of each metric, and the cost."""
    rows = _medians(tables, COMPARISON)
    return ["## Method comparison", "",
            "Per table and method, the median over the table's cases of each metric. *wrong* = the fraction of "
            "rays whose shown point is farther than ε = max(1 cm, one cube-map texel at the hit) from the exact hit "
            "(wrong depth on the same ray, another surface, or no hit), over all rays, the rays whose exact hit is "
            "visible from the reference point and those whose hit is hidden from it (– where there are none); "
            "dist_p95 = 95th percentile of |shown − exact| (m). The cost is cube-map lookups per ray (the oracle's "
            "single lookup is the radiance read at the exact hit).", "",
            table(rows, ["table", "method", "cases", *COMPARISON]), ""]


def _sweep_section(d: Path, rows: list[dict]) -> list[str]:
    meta = _meta(d)
    rel = d.name
    lines = [f"## Sweep `{meta.get('config', d.name)}`", "",
             f"{meta.get('cases', '?')} cases × {len(meta.get('methods', []))} methods "
             f"({', '.join(meta.get('methods', []))}); table: [{rel}/results.csv]({rel}/results.csv).", ""]
    for png in _shown((d / "plots").glob("*.png")):
        lines.append(f"![{png.stem}]({rel}/plots/{png.name})")
    lines.append("")
    # one compact table: per axis combination at the largest cube resolution, median angular error per method
    axes = [k for k in rows[0] if k.startswith("axis:")] if rows else []
    top = max((r["cube_res"] for r in rows), default=None)
    sel = [r for r in rows if r["cube_res"] == top and r["method"] not in REFERENCE_ROWS]
    labels = list(dict.fromkeys(r["label"] for r in sel))
    groups: dict[tuple, dict] = {}
    for r in sel:
        key = tuple(r[a] for a in axes if a != "axis:render.cube_res")
        g = groups.setdefault(key, {a.removeprefix("axis:"): r[a] for a in axes if a != "axis:render.cube_res"})
        g[r["label"]] = r["angle_median_deg"]
        g["occluded"] = r["occluded_fraction"]
    if groups:
        lines += [f"Median angular error (degrees) at cube resolution {top:g}:", "",
                  table(list(groups.values()), [a.removeprefix("axis:") for a in axes
                                                if a != "axis:render.cube_res"] + ["occluded"] + labels), ""]
    return lines


CAUSTIC_COLS = ["caustic_res", "label", "photons", "lm_rmse", "lm_relmse", "img_rmse_mitsuba", "img_sum_ratio_mitsuba",
                "mitsuba_noise_rmse", "photon_angle_p95_deg", "seconds_per_map"]


def _caustics_section(reports: Path) -> list[str]:
    """Figure 8 (``study caustics-sweep`` → reports/fig8/): light-map error against exact photon tracing (a),
    image error against Mitsuba's ptracer (b), time per caustic map."""
    d = reports / "fig8"
    if not (d / "sweep" / "results.csv").is_file():
        return []
    rows = read_table(d / "sweep" / "results.csv", required=("label",), numeric=["caustic_res"])
    lines = ["## fig8: caustics", "",
             "Glass sphere (n = 1.3) focusing the point light; caustic map from the light, photon hits localized in "
             "the distance impostor, splatted into light maps (study/caustics.py, study/lightmap.py). "
             "lm_* = light-map error against exact photon tracing (a), W/m²; img_* = caustic-only image against "
             "Mitsuba ptracer (b); mitsuba_noise_rmse = Mitsuba's own noise (two seeds). "
             "Table: [fig8/sweep/results.csv](fig8/sweep/results.csv).", ""]
    lines += [f"![fig8](fig8/{p.name})" for p in _shown(d.glob("*.png"))]
    return lines + ["", table(rows, CAUSTIC_COLS), ""]


def build_report(reports: str | Path = "reports") -> Path:
    """Write ``<reports>/index.md`` (the directory locked meanwhile, :func:`study.io.locked`); returns its path."""
    reports = Path(reports)
    if not reports.is_dir():
        raise StudyError("no such directory (expected the reports: figures and sweeps)", file=str(reports))
    with locked(reports):
        text = _index(reports)
        return write_set(reports, {"index.md": text}, lock=False, swap=False)[0]   # others write beside it


def _index(reports: Path) -> str:
    """The text of ``index.md``."""
    figs = sorted(d for d in reports.glob("fig*") if (d / "metrics.csv").is_file())
    sweeps = sorted(d for d in reports.glob("sweep-*") if (d / "results.csv").is_file())
    numeric = ["cube_res", *SUMMARY]
    tables = {d.name: read_table(d / "metrics.csv", numeric=numeric) for d in figs}
    tables.update({d.name: read_table(d / "results.csv", numeric=numeric) for d in sweeps})

    lines = ["# study: how close do ray-tracing effects without tracing rays come to ray tracing?", "",
             "Generated by `study report` from the tables under `reports/` (nothing here is computed by hand).",
             "Outcome per ray (study/evaluate/outcomes.py): *correct* when the shown point is within ε = max(1 cm, "
             "one cube-map texel at the hit) of the exact (Embree) hit, else *wrong depth* (on the same ray), *wrong "
             "surface* or *no hit*; wrong_fraction = 1 − correct. "
             "Angular error: at the shading point, between the direction to the shown point and the direction to "
             "the exact (Embree) hit (blind to a wrong depth on the same ray). Image errors over the object's pixels: RMSE on linear radiance; PSNR, SSIM "
             "(scikit-image) and FLIP (flip-evaluator, LDR mode) on images clipped at 1 and sRGB-encoded. "
             "*oracle_map* = exact hit, radiance read from the impostor (a perfect localization); *truth_at_hit* = "
             "exact hit, Mitsuba's radiance along the same ray (the truth the methods are measured against); "
             "*mitsuba* = Mitsuba's camera render with the object.", ""]
    lines += _claims_section(tables)
    lines += _comparison_section(tables)
    lines += _decomposition_section(tables)
    for d in figs:
        rows = tables[d.name]
        meta = _meta(d)
        lines += [f"## {d.name}", "", f"Config `{meta.get('config', '?')}`, backend {meta.get('backend', '?')}; "
                  f"table: [{d.name}/metrics.csv]({d.name}/metrics.csv).", ""]
        for png in _shown(d.glob("*.png")):
            lines.append(f"![{d.name}]({d.name}/{png.name})")
        lines += ["", table(rows, ["case", "label", *SUMMARY]), ""]
    for d in sweeps:
        lines += _sweep_section(d, tables[d.name])
    lines += _caustics_section(reports)
    others = _shown(p for p in reports.glob("*.md") if p.name != "index.md")
    others += _shown(p for p in reports.glob("*/*.md") if p.parent.name not in {d.name for d in figs + sweeps})
    if others:
        lines += ["## Other reports", ""] + [f"- [{p.relative_to(reports)}]({p.relative_to(reports)})"
                                             for p in others] + [""]
    lines += ["## Versions and commands", "", "| table | command | config sha256 | seed | backend | git commit | "
              "versions |", "|---|---|---|---|---|---|---|"]
    for d in figs + sweeps:
        m = _meta(d)
        vers = ", ".join(f"{k} {v}" for k, v in m.get("versions", {}).items() if v)
        lines.append(f"| {d.name} | `{m.get('command') or '?'}` | {m.get('config_sha256', '?')} | {m.get('seed', '?')} "
                     f"| {m.get('backend', '?')} | {str(m.get('git_commit', '?'))[:10]} | {vers} |")
    lines += ["", "Regenerate everything: `bash scripts/reproduce.sh` (figures, the main sweep, this report).", ""]
    return "\n".join(lines)
