"""``reports/index.md`` from results only: figures, metrics tables, the paper's claims, versions and commands.

Nothing is computed here but summaries of the tables under ``reports/``: every figure directory with a
``metrics.csv`` (``reports/fig*/``), every sweep with a ``results.csv`` (``reports/sweep-*/``), and any Markdown
report another command wrote (e.g. ``reports/performance.md``).
"""
from __future__ import annotations

import json
from pathlib import Path

from study.io import atomic_write
from study.outputs import claims as claim_registry
from study.tables import markdown, read_csv

SUMMARY = ["angle_median_deg", "angle_p95_deg", "rmse_oracle", "rmse_mitsuba", "ssim_mitsuba", "flip_mitsuba",
           "occluded_fraction", "lookups_per_ray"]


def table(rows: list[dict], cols: list[str]) -> str:
    return markdown(rows, cols, digits=3)


def _meta(d: Path) -> dict:
    try:
        return json.loads((d / "metadata.json").read_text())
    except (OSError, ValueError):
        return {}


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


COMPARISON = ["angle_median_deg", "angle_p95_deg", "rmse_oracle", "rmse_mitsuba", "flip_mitsuba", "valid_fraction",
              "lookups_per_ray"]


def _comparison_section(tables: dict[str, list[dict]]) -> list[str]:
    """One row per table × method: the median over the table's cases of each metric, and the cost."""
    import numpy as np
    rows = []
    for name, tab in tables.items():
        labels = list(dict.fromkeys(r["label"] for r in tab))
        for lab in labels:
            sel = [r for r in tab if r["label"] == lab]
            row = {"table": name, "method": lab, "cases": len(sel)}
            for m in COMPARISON:
                vals = np.array([r.get(m, np.nan) for r in sel], float)
                row[m] = float(np.nanmedian(vals)) if np.isfinite(vals).any() else float("nan")
            rows.append(row)
    return ["## Method comparison", "",
            "Per table and method, the median over the table's cases of each metric; the cost is cube-map lookups "
            "per ray (the oracle's single lookup is the radiance read at the exact hit).", "",
            table(rows, ["table", "method", "cases", *COMPARISON]), ""]


def _sweep_section(d: Path, rows: list[dict]) -> list[str]:
    meta = _meta(d)
    rel = d.name
    lines = [f"## Sweep `{meta.get('config', d.name)}`", "",
             f"{meta.get('cases', '?')} cases × {len(meta.get('methods', []))} methods "
             f"({', '.join(meta.get('methods', []))}); table: [{rel}/results.csv]({rel}/results.csv).", ""]
    for png in sorted((d / "plots").glob("*.png")):
        lines.append(f"![{png.stem}]({rel}/plots/{png.name})")
    lines.append("")
    # one compact table: per axis combination at the largest cube resolution, median angular error per method
    axes = [k for k in rows[0] if k.startswith("axis:")] if rows else []
    top = max((r["cube_res"] for r in rows), default=None)
    sel = [r for r in rows if r["cube_res"] == top and r["method"] != "oracle"]
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
    rows = read_csv(d / "sweep" / "results.csv")
    lines = ["## fig8: caustics", "",
             "Glass sphere (n = 1.3) focusing the point light; caustic map from the light, photon hits localized in "
             "the distance impostor, splatted into light maps (study/caustics.py, study/lightmap.py). "
             "lm_* = light-map error against exact photon tracing (a), W/m²; img_* = caustic-only image against "
             "Mitsuba ptracer (b); mitsuba_noise_rmse = Mitsuba's own noise (two seeds). "
             "Table: [fig8/sweep/results.csv](fig8/sweep/results.csv).", ""]
    lines += [f"![fig8](fig8/{p.name})" for p in sorted(d.glob("*.png"))]
    return lines + ["", table(rows, CAUSTIC_COLS), ""]


def build_report(reports: str | Path = "reports") -> Path:
    """Write ``<reports>/index.md``; returns its path."""
    reports = Path(reports)
    figs = sorted(d for d in reports.glob("fig*") if (d / "metrics.csv").is_file())
    sweeps = sorted(d for d in reports.glob("sweep-*") if (d / "results.csv").is_file())
    tables = {d.name: read_csv(d / "metrics.csv") for d in figs}
    tables.update({d.name: read_csv(d / "results.csv") for d in sweeps})

    lines = ["# study: how close do ray-tracing effects without tracing rays come to ray tracing?", "",
             "Generated by `study report` from the tables under `reports/` (nothing here is computed by hand).",
             "Angular error: at the shading point, between the direction to the shown point and the direction to "
             "the exact (Embree) hit. Image errors over the object's pixels: RMSE on linear radiance; PSNR, SSIM "
             "(scikit-image) and FLIP (flip-evaluator, LDR mode) on images clipped at 1 and sRGB-encoded. "
             "*oracle* = exact hit, radiance read from the impostor (a perfect localization); *mitsuba* = "
             "path-traced ground truth.", ""]
    lines += _claims_section(tables)
    lines += _comparison_section(tables)
    for d in figs:
        rows = tables[d.name]
        meta = _meta(d)
        lines += [f"## {d.name}", "", f"Config `{meta.get('config', '?')}`, backend {meta.get('backend', '?')}; "
                  f"table: [{d.name}/metrics.csv]({d.name}/metrics.csv).", ""]
        for png in sorted(d.glob("*.png")):
            lines.append(f"![{d.name}]({d.name}/{png.name})")
        lines += ["", table(rows, ["case", "label", *SUMMARY]), ""]
    for d in sweeps:
        lines += _sweep_section(d, tables[d.name])
    lines += _caustics_section(reports)
    others = sorted(p for p in reports.glob("*.md") if p.name != "index.md")
    others += sorted(p for p in reports.glob("*/*.md") if p.parent.name not in {d.name for d in figs + sweeps})
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
    path = reports / "index.md"
    atomic_write(path, "\n".join(lines).encode())
    return path
