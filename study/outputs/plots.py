"""Curves from a results table (matplotlib): error vs each method's accuracy knob (its declared ``Method.knob``,
e.g. the iterations of ``localized``), vs displacement, vs cube resolution.

Each plot is a PNG with the numbers it shows in a CSV of the same name beside it. A curve varies one column and
holds every other axis of the sweep at one value (stated in the plot's title): cube resolution at its largest, the
other axes at their first value, unless the curve varies them.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from study import columns
from study.io import atomic_savefig
from study.tables import REFERENCE_ROWS, write_csv

#: metric → (axis label, floor of the log axis: values at or below it are marked at the bottom, not hidden): the
#: declared columns of view "plots" (study/columns.py)
METRICS = {c.name: (c.axis, c.log_floor) for c in columns.in_view("plots")}
#: 20 distinct colours (tab10, then a darker or stronger one of each hue and a few more); beyond them evenly spaced
#: hues at alternating lightness: every series of a plot its own colour.
_COLOURS = [
    "#1f77b4",
    "#ff7f0e",
    "#2ca02c",
    "#d62728",
    "#9467bd",
    "#8c564b",
    "#e377c2",
    "#7f7f7f",
    "#bcbd22",
    "#17becf",
    "#0b3d91",
    "#a65628",
    "#00a087",
    "#6a3d9a",
    "#f0b400",
    "#e7298a",
    "#000000",
    "#66a61e",
    "#4dbbd5",
    "#b15928",
]
_MARKERS = ["o", "s", "^", "D", "P", "X", "*"]
_LINES = ["-", "--", ":", "-."]


def colour(i: int) -> str:
    """The colour of series ``i``: distinct for every ``i`` (the 20 of :data:`_COLOURS`, then golden-angle hues)."""
    if i < len(_COLOURS):
        return _COLOURS[i]
    import colorsys

    h = (0.618033988749895 * i) % 1.0
    r, g, b = colorsys.hls_to_rgb(h, 0.35 if i % 2 else 0.55, 0.75 + 0.2 * ((i // 2) % 2))
    return "#{:02x}{:02x}{:02x}".format(*(round(255 * x) for x in (r, g, b)))


def style(i: int) -> dict:
    """Colour, marker and line style of series ``i``: every series its own colour, and marker and line style
    vary too (for print in grey)."""
    return {"color": colour(i), "marker": _MARKERS[i % 7], "linestyle": _LINES[(i // 10) % 4]}


def pareto_indices(points: list[tuple[float, float]]) -> list[int]:
    """Indices of the (cost, error) points no other point beats in both (lower is better), by rising cost."""
    order = sorted(range(len(points)), key=lambda i: (points[i][0], points[i][1]))
    front, best = [], np.inf
    for i in order:
        if points[i][1] < best:
            front.append(i)
            best = points[i][1]
    return front


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


def _plot(
    path: Path,
    series: dict[str, list[tuple[float, float]]],
    *,
    xlabel: str,
    metric: str,
    title: str,
    logx: bool = False,
) -> int:
    """Curves on a log y axis; points at or below the metric's floor are drawn as open ▽ on the axis's bottom.
    Returns how many points were drawn that way."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ylabel, floor = METRICS[metric]
    fig, ax = plt.subplots(figsize=(7.2, 4.6))
    n_low = 0
    for i, (name, pts) in enumerate(series.items()):
        pts = sorted(p for p in pts if np.isfinite(p[1]))
        st = style(i)
        xs, ys = [p[0] for p in pts], [max(p[1], floor) for p in pts]
        ax.plot(xs, ys, ms=4, lw=1.2, label=name, **st)
        low = [(x, floor) for x, y in pts if y <= floor]
        if low:
            n_low += len(low)
            ax.plot(*zip(*low), ls="none", marker="v", ms=8, mfc="none", mec=st["color"])
    ax.set_yscale("log")
    ax.set_ylim(bottom=floor * 0.6)
    if logx:
        ax.set_xscale("log", base=2)
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title(
        title + (f"\n▽ on the bottom edge: value ≤ {floor:g} (0 included)" if n_low else ""), fontsize=8
    )
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=6, ncol=2, loc="best")
    fig.tight_layout()
    atomic_savefig(fig, path, dpi=110)
    return n_low


def cost_plot(rows: list[dict], path: Path, *, metric: str, title: str) -> list[dict]:
    """Error (median over the rows of each method) against cube-map lookups per ray, one point per method, the
    Pareto front (no method cheaper and better) drawn as a line. Returns the table behind it."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ylabel, floor = METRICS[metric]
    labels = list(dict.fromkeys(r["label"] for r in rows))
    table = []
    for lab in labels:
        sel = [r for r in rows if r["label"] == lab]
        table.append(
            {
                "method": lab,
                "lookups_per_ray": float(np.nanmedian([r["lookups_per_ray"] for r in sel])),
                metric: float(np.nanmedian([r[metric] for r in sel])),
            }
        )
    pts = [(t["lookups_per_ray"], t[metric]) for t in table]
    front = pareto_indices(pts)
    for i, t in enumerate(table):
        t["pareto"] = i in front
    fig, ax = plt.subplots(figsize=(7.2, 4.6))
    fx = [pts[i][0] for i in front]
    fy = [max(pts[i][1], floor) for i in front]
    ax.step(fx, fy, where="post", color="0.6", lw=1, zorder=1, label="Pareto front")
    for i, (t, (x, y)) in enumerate(zip(table, pts)):
        st = style(i)
        ax.plot(
            [x],
            [max(y, floor)],
            ls="none",
            ms=8 if i in front else 6,
            marker="v" if y <= floor else st["marker"],
            color=st["color"],
            mfc=st["color"] if y > floor else "none",
            label=t["method"],
            zorder=2,
        )
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_ylim(bottom=floor * 0.6)
    ax.set_xlabel("cube-map lookups per ray (cost)")
    ax.set_ylabel(ylabel)
    ax.set_title(f"{title}\nmedian over the cases; ▽: value ≤ {floor:g}", fontsize=8)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=6, ncol=2, loc="best")
    fig.tight_layout()
    atomic_savefig(fig, path, dpi=110)
    return table


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
        for metric in [m for m in METRICS if m in k_rows[0]]:
            series, table = {}, []
            for r in sel:
                name = r["family"] + (f" @ {r[pos_axis]}" if pos_axis else "")
                series.setdefault(name, []).append((r["knob_value"], r[metric]))
                table.append({"series": name, knob: r["knob_value"], metric: r[metric]})
            p = out / f"{metric}_vs_{knob}.png"
            _plot(p, series, xlabel=knob, metric=metric, title=_held_title(held))
            write_csv(table, p.with_suffix(".csv"))
            made.append(p)

    # ------------------------------------------------------------------ error vs displacement, cube resolution
    for x, vary, xlabel, logx in (
        (
            "displacement",
            {pos_axis} if pos_axis else set(),
            "|object centre − reference point| / room diagonal",
            False,
        ),
        ("cube_res", {"cube_res", "axis:render.cube_res"}, "cube resolution (texels per face side)", True),
    ):
        if len({r[x] for r in rows}) < 2:
            continue
        sel, held = _hold(rows, vary)
        for metric in [m for m in METRICS if m in rows[0]]:
            series, table = {}, []
            for r in sel:
                series.setdefault(r["label"], []).append((r[x], r[metric]))
                table.append({"series": r["label"], x: r[x], metric: r[metric]})
            p = out / f"{metric}_vs_{x}.png"
            _plot(p, series, xlabel=xlabel, metric=metric, title=_held_title(held), logx=logx)
            write_csv(table, p.with_suffix(".csv"))
            made.append(p)

    # ------------------------------------------------------------------ error against cost, Pareto front
    for metric in ("wrong_fraction", "angle_p95_deg"):
        if rows and metric in rows[0]:
            p = out / f"{metric}_vs_lookups.png"
            write_csv(
                cost_plot(rows, p, metric=metric, title="every case of the sweep"), p.with_suffix(".csv")
            )
            made.append(p)
    return made


def plot_tolerance_curve(rows: list[dict], path, title: str = "") -> None:
    """Wrong fraction (median over cases; the band up to the worst case) against the fixed tolerance, one line
    per method, log tolerance axis; written to ``path`` (PNG)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 4))
    for lab in dict.fromkeys(r["label"] for r in rows):
        sel = sorted((r for r in rows if r["label"] == lab), key=lambda r: r["tolerance_m"])
        t = [r["tolerance_m"] for r in sel]
        (line,) = ax.plot(t, [r["wrong"] for r in sel], marker="o", ms=3, label=lab)
        ax.fill_between(
            t, [r["wrong"] for r in sel], [r["wrong_max"] for r in sel], alpha=0.1, color=line.get_color()
        )
    ax.set_xscale("log")
    ax.set_xlabel("tolerance |shown − exact| (m)")
    ax.set_ylabel("wrong fraction (median over cases; band to the worst)")
    ax.set_title(title)
    ax.legend(fontsize=6)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
