"""Curves from a results table (matplotlib): error vs each method's accuracy knob (its declared ``Method.knob``,
e.g. the iterations of ``localized``), vs displacement, vs cube resolution.

Each plot is a PNG with the numbers it shows in a CSV of the same name beside it. A curve varies one column and
holds every other axis of the sweep at one value (stated in the plot's title): cube resolution at its largest, the
other axes at their first value, unless the curve varies them.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from study.io import atomic_savefig
from study.tables import REFERENCE_ROWS, write_csv

METRICS = ("angle_median_deg", "angle_p95_deg")


def _axes_of(rows: list[dict]) -> list[str]:
    return [k for k in rows[0] if k.startswith("axis:")] if rows else []


def _hold(rows: list[dict], vary: set[str]) -> tuple[list[dict], dict]:
    """Rows with every sweep axis not in ``vary`` held at one value; returns (rows, held values)."""
    held = {}
    for ax in _axes_of(rows):
        if ax in vary:
            continue
        vals = list(dict.fromkeys(r[ax] for r in rows))
        if ax == "axis:render.cube_res":
            vals = sorted(vals, key=float)[-1:]
        held[ax] = vals[0]
    if "cube_res" not in vary and not any(a == "axis:render.cube_res" for a in held):
        res = max(r["cube_res"] for r in rows)
        held["cube_res"] = res
    return [r for r in rows if all(r.get(k) == v for k, v in held.items())], held


def _plot(path: Path, series: dict[str, list[tuple[float, float]]], *, xlabel: str, ylabel: str, title: str,
          logx: bool = False) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(6.4, 4.2))
    for name, pts in series.items():
        pts = sorted(pts)
        ax.plot([p[0] for p in pts], [max(p[1], 1e-6) for p in pts], marker="o", ms=3, label=name)
    ax.set_yscale("log")
    if logx:
        ax.set_xscale("log", base=2)
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title(title, fontsize=8)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=6, ncol=2)
    fig.tight_layout()
    atomic_savefig(fig, path, dpi=110)


def _held_title(held: dict) -> str:
    return "; ".join(f"{k.removeprefix('axis:')}={v}" for k, v in held.items()) or "all rows"


def sweep_plots(rows: list[dict], out: str | Path) -> list[Path]:
    """Write the curves a sweep's table supports into ``out``; returns the PNG paths."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    rows = [r for r in rows if r["method"] not in REFERENCE_ROWS]
    made = []
    pos_axis = "axis:object.center" if rows and "axis:object.center" in rows[0] else None

    # ------------------------------------------------------------------ error vs each method's accuracy knob
    knobbed = [r for r in rows if r.get("knob") and np.isfinite(r.get("knob_value", np.nan))]
    for knob in dict.fromkeys(r["knob"] for r in knobbed):
        k_rows = [r for r in knobbed if r["knob"] == knob]
        if len({r["knob_value"] for r in k_rows}) < 2:
            continue
        sel, held = _hold(k_rows, {pos_axis} if pos_axis else set())
        for metric in METRICS:
            series, table = {}, []
            for r in sel:
                name = r["family"] + (f" @ {r[pos_axis]}" if pos_axis else "")
                series.setdefault(name, []).append((r["knob_value"], r[metric]))
                table.append({"series": name, knob: r["knob_value"], metric: r[metric]})
            p = out / f"{metric}_vs_{knob}.png"
            _plot(p, series, xlabel=knob, ylabel=f"{metric} (deg)", title=_held_title(held))
            write_csv(table, p.with_suffix(".csv"))
            made.append(p)

    # ------------------------------------------------------------------ error vs displacement, cube resolution
    for x, vary, xlabel, logx in (
            ("displacement", {pos_axis} if pos_axis else set(), "|object centre − reference point| / room diagonal",
             False),
            ("cube_res", {"cube_res", "axis:render.cube_res"}, "cube resolution (texels per face side)", True)):
        if len({r[x] for r in rows}) < 2:
            continue
        sel, held = _hold(rows, vary)
        for metric in METRICS:
            series, table = {}, []
            for r in sel:
                series.setdefault(r["label"], []).append((r[x], r[metric]))
                table.append({"series": r["label"], x: r[x], metric: r[metric]})
            p = out / f"{metric}_vs_{x}.png"
            _plot(p, series, xlabel=xlabel, ylabel=f"{metric} (deg)", title=_held_title(held), logx=logx)
            write_csv(table, p.with_suffix(".csv"))
            made.append(p)
    return made
