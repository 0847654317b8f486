"""The equal-cost front (``study pareto``): per results table (a figure or a sweep, one scene each), every method's
error against its measured time per 1080p frame on a named device, the Pareto front, and which method to use at a
few budgets.

Inputs, all committed: the tables (``reports/fig*/metrics.csv``, ``reports/sweep-*/results.csv``) and the bench's
main tables (``reports/performance/bench-<tag>.csv``; the device is read from the machine line of
``bench-<tag>.md``, the commit that holds the numbers from git).

**Time.** A method's ``ms_per_frame`` in the bench (Dr.Jit's frozen path: ``cuda`` in a GPU bench, ``llvm`` in a
CPU one) on one batch (:data:`BATCHES`; by default ``close-up``, a full 1024² frame of coherent secondary rays),
scaled to a 1080p frame by the ray count, one secondary ray per pixel: × 1920·1080 / 1024² = 1.978 (on a full
frame the time grows with the rays; ``scaling-<tag>.csv`` measures it). A method that is the exact query itself
(``traced``: its class names its ``bench_query``) takes that query's time on the same batch and device, from its
own bench row where the bench has one, else from the exact query's row (the same number); one that makes K queries
a ray (``traced_glossy(samples=K)``, the glossy tables' exact row: ``queries``) K times that. A bench that prices
``traced`` with the shading a renderer does at the hit (path ``shaded``: the full ``ray_intersect``, the material
towards the point light, the shadow ray) gives that price, the bare query stated beside it; an older bench's bare
query is used and the page says so. The clock is the device's time in the kernels by default (:data:`CLOCKS`):
what a renderer pays inside a frame, where its work is fused into few launches; a 1080p frame's host share
(launching, about 0.05 ms per call on the H200) does not grow with the rays, so the wall clock (``--clock wall``)
scaled by the ray count overstates the cheapest GPU methods. The page states the launch share apart. The bench times the
methods at its cube resolution (256²) on the fig4 room, whatever the table's scene: a time is the method's, not the
scene's. Table labels the bench did not time (other parameters) are listed, not placed.

**Error.** The median over the table's cases of ``metric`` (``wrong_fraction`` by default: the share of rays whose
shown point is not the exact hit) with its interval over the cases (:func:`study.stats.case_interval`: the
95 % bootstrap from 10 cases on, else the range). A sweep that varies the cube resolution is read at the bench's
(its cases at 256²) where it has it, else over all its cases; the page says which.

**Front and budgets.** A point is on the front when no other point is at most as slow and at most as wrong, and
better in one (:func:`pareto_front`, on the medians). At a budget of B ms the answer is the front's point with the
lowest error among those within B (the last front point not dearer than B); "none" below the cheapest.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from study import columns
from study import methods as registry
from study.errors import StudyError
from study.io import png_bytes, write_set
from study.outputs.plots import pareto_indices, style
from study.report.bench_times import (
    CLOCK_WORDS,
    CLOCKS,
    RAYS_1080P,
    RAYS_BENCH,
    DeviceTimes,
    device_times,
    exact_priced,
)
from study.report.check import read_table
from study.stats import case_interval
from study.tables import REFERENCE_ROWS, check_rows, markdown

#: Budgets (ms per 1080p frame) the page answers, per bench tag; others get :data:`DEFAULT_BUDGETS`.
BUDGETS = {"gpu": (0.15, 0.3, 0.6, 1.5), "cpu": (40.0, 80.0, 200.0, 1000.0)}
DEFAULT_BUDGETS = (1.0, 10.0, 100.0)
#: Error columns the front can be drawn for → axis label: the declared columns of view "pareto" (study/columns.py;
#: the log axis's floor is the column's ``log_floor``, else :data:`AXIS_FLOOR`).
ERRORS = {c.name: f"{c.axis} (median over cases)" for c in columns.in_view("pareto")}
AXIS_FLOOR = 1e-4
#: At or below this an error column counts as exact (no front to draw): an image RMSE this small is the noise's.
EXACT_AT = {"rmse_truth_debiased": 1e-4}


def table_points(rows: list[dict], metric: str, *, cube_res: float = 256) -> tuple[list[dict], str]:
    """Per method label of a results table: the median of ``metric`` over its cases, the interval over them
    (``<metric>_lo``/``_hi``, ``n``, ``interval``: ci or range), and which cases: (points, note)."""
    rows = [r for r in rows if r.get("method") not in REFERENCE_ROWS]
    if rows and metric not in rows[0]:
        raise StudyError(f"the table has no column {metric!r}", key="--metric")
    res = sorted({float(r["cube_res"]) for r in rows if "cube_res" in r})
    if len(res) > 1 and cube_res in res:
        rows = [r for r in rows if float(r["cube_res"]) == cube_res]
        note = f"the cases at cube resolution {cube_res:g}² (the bench's)"
    else:
        note = f"every case (cube resolution {', '.join(f'{r:g}²' for r in res)})" if res else "every case"
    out = []
    for label in dict.fromkeys(r["label"] for r in rows):
        sel = [r for r in rows if r["label"] == label]
        med, lo, hi, n, kind = case_interval([r[metric] for r in sel])
        out.append({"label": label, "method": sel[0]["method"], "family": sel[0].get("family", label),
                    metric: med, f"{metric}_lo": lo, f"{metric}_hi": hi, "n": n, "interval": kind})  # fmt: skip
    return out, note


def pareto_front(rows: list[dict], cost: str, err: str) -> list[dict]:
    """The rows no other row beats on both ``cost`` and ``err`` (lower is better; finite values only), cheapest
    first (:func:`study.outputs.plots.pareto_indices`)."""
    ok = [r for r in rows if np.isfinite(r.get(cost, np.nan)) and np.isfinite(r.get(err, np.nan))]
    return [ok[i] for i in pareto_indices([(r[cost], r[err]) for r in ok])]


def _exact_times(d: DeviceTimes) -> dict[str, float]:
    """Label → ms of the methods that are one exact query a ray (``traced``; not ``hit_cache``, which makes the
    same query and shades from its cache, nor ``traced_glossy``'s K queries, placed as points), on device ``d``."""
    own = {registry.make(n).label for n in registry.names() if "bench_query" in vars(registry.REGISTRY[n])}
    return {lab: d.ms[lab] for lab, (_, k) in exact_priced().items() if k == 1 and lab in d.ms and lab in own}


def at_budget(front: list[dict], budget: float, cost: str) -> dict | None:
    """The front's point with the lowest error within ``budget`` (the dearest one not over it); None if none."""
    within = [r for r in front if r[cost] <= budget]
    return within[-1] if within else None


# ---------------------------------------------------------------------------------------------- the page
def _fmt(v: float) -> str:
    if not math.isfinite(v):
        return "–"
    return f"{v:.3g}" if v >= 1e-3 or v == 0 else f"{v:.2g}"


def _err_text(p: dict, metric: str) -> str:
    lo, hi = p[f"{metric}_lo"], p[f"{metric}_hi"]
    pct = metric.startswith("wrong_fraction")
    f = (lambda v: f"{100 * v:.3g} %") if pct else _fmt
    if p["n"] <= 1 or not math.isfinite(lo):
        return f(p[metric])
    return f"{f(p[metric])} [{f(lo)}, {f(hi)}]" + (" (range)" if p["interval"] == "range" else "")


def scene_section(name: str, points: list[dict], devices: list[DeviceTimes], metric: str, note: str) -> str:
    """The Markdown of one table: every method's error and times, the fronts, the budget answers."""
    rows, fronts = [], {}
    for d in devices:
        placed = [{**p, "ms": d.ms[p["label"]]} for p in points if p["label"] in d.ms]
        fronts[d.tag] = pareto_front(placed, "ms", metric)
    for p in points:
        row = {"method": p["label"], metric: _err_text(p, metric)}
        for d in devices:
            on = any(f["label"] == p["label"] for f in fronts[d.tag])
            row[f"ms {d.tag}"] = (
                f"{_fmt(d.ms[p['label']])}{' ◆' if on else ''}" if p["label"] in d.ms else "–"
            )
        rows.append(row)
    n = points[0]["n"] if points else 0
    lines = [f"## {name}", "", f"![{name}]({name}.png)", "",
             f"Error over {note}; n = {n} cases. ◆: on the front of that device.", "",
             markdown(rows, list(rows[0]) if rows else []), ""]  # fmt: skip
    for d in devices:
        answers = []
        for b in BUDGETS.get(d.tag, DEFAULT_BUDGETS):
            r = at_budget(fronts[d.tag], b, "ms")
            answers.append(f"{b:g} ms → `{r['label']}` ({_err_text(r, metric)} at {_fmt(r['ms'])} ms)" if r
                           else f"{b:g} ms → none fits")  # fmt: skip
        lines += [f"- **{d.tag}** ({d.device}): at " + "; ".join(answers) + "."]
        for label, t in _exact_times(d).items():
            dearer = [f"`{f['label']}`" for f in fronts[d.tag] if f["ms"] > t and f["label"] != label]
            tail = f"dearer on the front: {', '.join(dearer)}." if dearer else "no front method is dearer."
            how = (
                "the bare query, its shading not measured in this bench"
                if label in d.unshaded
                else f"the query and the shading of its hit; the bare query {_fmt(d.bare.get(label, math.nan))} ms"
            )
            lines += [f"  Tracing the rays (`{label}`, exact hits) costs {_fmt(t)} ms here ({how}); {tail}"]
    missing = [p["label"] for p in points if not any(p["label"] in d.ms for d in devices)]
    if missing:
        lines += [
            "",
            "Not benched (other parameters than the bench's): " + ", ".join(f"`{m}`" for m in missing) + ".",
        ]
    return "\n".join(lines) + "\n"


#: The families drawn as the exact query (black stars): the mirror rays' and the glossy lobe's.
EXACT_FAMILIES = ("traced", "traced_glossy")


def scene_plot(name: str, points: list[dict], devices: list[DeviceTimes], metric: str) -> bytes:
    """One panel per device: every placed method (families coloured, ladders joined), its interval over the cases,
    the front (grey steps, ringed points, labelled), the budgets (dotted). Zero errors sit on the floor as ▽."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    floor = getattr(columns.declared(metric), "log_floor", None) or AXIS_FLOOR
    families = list(dict.fromkeys(p["family"] for p in points))
    fig, axes = plt.subplots(1, len(devices), figsize=(6.4 * len(devices), 5.2), squeeze=False)
    for ax, d in zip(axes[0], devices):
        placed = [{**p, "ms": d.ms[p["label"]]} for p in points if p["label"] in d.ms]
        for i, fam in enumerate(families):
            pts = sorted((p for p in placed if p["family"] == fam), key=lambda p: p["ms"])
            if not pts:
                continue
            st = (
                style(i) if fam not in EXACT_FAMILIES else {"color": "black", "marker": "*", "linestyle": "-"}
            )
            xs = [p["ms"] for p in pts]
            ys = [max(p[metric], floor) for p in pts]
            lo = [max(min(p[metric], p[f"{metric}_lo"]), floor) for p in pts]
            hi = [max(p[f"{metric}_hi"], p[metric], floor) for p in pts]
            ax.errorbar(xs, ys, yerr=[np.subtract(ys, lo), np.subtract(hi, ys)], color=st["color"], lw=0.8,
                        ls=st["linestyle"], marker="none", capsize=2, alpha=0.7)  # fmt: skip
            for x, y, p in zip(xs, ys, pts):
                zero = p[metric] <= floor
                ax.plot([x], [y], ls="none", marker="v" if zero else st["marker"], ms=7 if fam in EXACT_FAMILIES else 5,
                        color=st["color"], mfc="none" if zero else st["color"],
                        label=fam if p is pts[0] else None, zorder=3)  # fmt: skip
        front = pareto_front(placed, "ms", metric)
        fx = [p["ms"] for p in front]
        fy = [max(p[metric], floor) for p in front]
        ax.step(fx, fy, where="post", color="0.45", lw=1.3, ls="--", zorder=1, label="Pareto front")
        ax.plot(fx, fy, ls="none", marker="o", ms=12, mfc="none", mec="0.2", zorder=2)
        for k, (p, x, y) in enumerate(zip(front, fx, fy)):
            ax.annotate(p["label"], (x, y), xytext=(7, 6 if k % 2 == 0 else -11), textcoords="offset points",
                        fontsize=6.5)  # fmt: skip
        for b in BUDGETS.get(d.tag, DEFAULT_BUDGETS):
            ax.axvline(b, color="0.7", lw=0.8, ls=":", zorder=0)
            ax.annotate(f"{b:g} ms", (b, 0), xycoords=("data", "axes fraction"), xytext=(2, 4),
                        textcoords="offset points", fontsize=6, color="0.4")  # fmt: skip
        for t in sorted(set(_exact_times(d).values())):  # what tracing the rays costs, in the table or not
            ax.axvline(t, color="black", lw=1.0, ls="-.", zorder=0)  # (traced and hit_cache share one query)
            ax.annotate(f"traced (exact query, shaded): {_fmt(t)} ms", (t, 0.5), xycoords=("data", "axes fraction"),
                        xytext=(-4, 0), textcoords="offset points", fontsize=6.5, rotation=90, ha="right",
                        va="center")  # fmt: skip
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_ylim(bottom=floor * 0.6)
        ax.set_xlabel(f"ms per 1080p frame, {d.backend} on {d.device}")
        ax.set_ylabel(ERRORS.get(metric, metric))
        ax.set_title(f"{d.tag}: bench {Path(d.source).name} ({d.commit}), batch {d.batch}", fontsize=7.5)
        ax.grid(True, which="both", alpha=0.25)
    axes[0][0].legend(fontsize=6.5, loc="best")
    fig.suptitle(f"{name}: error against measured time; ▽ on the bottom edge: {metric} ≤ {floor:g} (0 included)",
                 fontsize=9)  # fmt: skip
    fig.tight_layout()
    return png_bytes(fig, dpi=110)


def _results_table(path: Path) -> list[dict]:
    """A figure's or sweep's table, well formed (:func:`~study.report.check.read_table`) and every number possible
    (:func:`study.tables.check_rows`), else one StudyError naming the file, line and column."""
    return check_rows(read_table(path, numeric=["cube_res", *ERRORS]), path)


def find_tables(reports: Path) -> dict[str, Path]:
    """Name → results table of every figure and sweep under ``reports`` (as ``study report`` finds them)."""
    figs = sorted(d for d in reports.glob("fig*") if (d / "metrics.csv").is_file())
    sweeps = sorted(d for d in reports.glob("sweep-*") if (d / "results.csv").is_file())
    return {**{d.name: d / "metrics.csv" for d in figs}, **{d.name: d / "results.csv" for d in sweeps}}


def _launch_line(d: DeviceTimes) -> str:
    """One line of the page: what the host's launch share (wall − kernel) adds per frame on device ``d``."""
    share = sorted(max(d.wall[k] - d.ms[k], 0.0) for k in d.ms if k in d.wall and k not in d.on_wall)
    if d.clock != "kernel" or not share:
        return ""
    med = share[len(share) // 2]
    names = ", ".join(f"`{k}`" for k in d.on_wall)
    wall = f"; on the wall clock ({names})" if d.on_wall else ""
    return (f"  Launch share left out (wall − kernel per call where the wall is longer, scaled to the frame): "
            f"median {_fmt(med)} ms, {_fmt(share[0])}–{_fmt(share[-1])} ms over the rows{wall}.")  # fmt: skip


def write_pareto(reports: Path, out: Path, benches: list[Path], *, metric: str = "wrong_fraction",
                 batch: str = "close-up", clock: str = "kernel", lock: bool = True) -> list[Path]:  # fmt: skip
    """``out``/<table>.png per figure and sweep with benched methods, and ``out``/pareto.md; the paths."""
    if metric not in ERRORS:
        raise StudyError(f"unknown metric {metric!r}; allowed: {', '.join(ERRORS)}", key="--metric")
    devices = [device_times(b, batch=batch, clock=clock) for b in benches]
    tables = find_tables(Path(reports))
    if not tables:
        raise StudyError("no figure or sweep tables here (reports/fig*/metrics.csv, reports/sweep-*/results.csv)",
                         file=str(reports))  # fmt: skip
    files, sections, skipped, exact = {}, [], [], []
    for name, path in tables.items():
        points, note = table_points(_results_table(path), metric)  # forged numbers: one line, exit 2
        if not any(p["label"] in d.ms for p in points for d in devices):
            skipped.append(name)
            continue
        if all(
            not p[metric] > EXACT_AT.get(metric, 0.0) for p in points
        ):  # every method exact: no front to draw
            exact.append(name)
            continue
        sections.append(scene_section(name, points, devices, metric, note))
        files[f"{name}.png"] = scene_plot(name, points, devices, metric)
    head = [
        "# The equal-cost front: which method at which budget",
        "",
        "Written by `study pareto` from the committed tables and the bench's; do not edit. Error: "
        f"`{metric}`, the median over each table's cases with its interval over them (95 % bootstrap from 10 "
        f"cases, else the range). Time: the bench's measured ms per 1024² frame (`{CLOCKS[clock]}`: "
        f"{CLOCK_WORDS[clock]}"
        f") of the methods' Dr.Jit kernels (frozen path) on the `{batch}` batch, × 1920·1080/1024² = "
        f"{RAYS_1080P / RAYS_BENCH:.3f} for a 1080p "
        "frame (one secondary ray per pixel); every row is priced with everything it reads: `traced` at the exact "
        "query and the shading a renderer does at its hit (the full `ray_intersect`, the material towards the point "
        "light and the shadow ray, on the same rays and device: OptiX on CUDA, Embree inside Mitsuba on the CPU; "
        "the bare query is stated beside it), `traced_glossy(samples=K)` at K of them (the lobe's rays), "
        "`hit_cache` at the query and its cache read. The bench times at cube resolution 256² on the fig4 room; a "
        "method's time is taken as the same in every scene. At budget B: the front's point with the lowest error "
        "within B.",
        "",
        *(
            f"- **{d.tag}**: {d.device}, backend {d.backend}; `{d.source}` (commit {d.commit}, bench code {d.code}), "
            f"batch `{d.batch}`" + (f"\n{_launch_line(d)}" if _launch_line(d) else "")
            for d in devices
        ),  # fmt: skip
        "",
    ]
    if skipped:
        head += [f"No benched method in: {', '.join(skipped)} (the bench times mirror methods; glossy tables place "
                 "only `traced_glossy`, priced from the exact query).", ""]  # fmt: skip
    if exact:
        head += [f"Every method at `{metric}` = 0 (nothing to trade): {', '.join(exact)}.", ""]
    files["pareto.md"] = "\n".join(head) + "\n" + "\n".join(sections)
    return write_set(out, files, lock=lock)
