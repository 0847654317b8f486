"""The bench's files: ``bench-<tag>.csv`` / ``.md`` (the main table) and ``scaling-<tag>.csv`` / ``.png``.

Columns of the main table: lookups_mean and bytes_per_ray (what a ray reads, :mod:`study.bench.carry`), ms_per_call,
mrays_per_s, ms_per_frame (a 1024² frame = 1 048 576 rays at the measured rate), x_vs_embree / x_vs_mitsuba (the
exact tracer's time for the same rays over the method's; > 1: the method is faster). The Markdown file starts with
the machine and the package versions; on a GPU without RT cores it has a projection to GPUs with them
(``projection-<tag>.csv``).

The main table (CSV + Markdown) and the scaling study (CSV + plot) are two output sets (:func:`study.io.output_set`),
each replaced whole or not at all: the main table is kept when the scaling studies fail after it.
"""

from __future__ import annotations

from pathlib import Path

from study import columns
from study import methods as registry
from study.bench.carry import PROJECTION_COLS, projection_rows, projection_title, shaded_parts
from study.io import atomic_savefig, png_bytes, write_set
from study.tables import markdown, to_csv

BENCH_COLS = columns.table_columns("bench")  # the declared tables: study/column_tables.py
HEADLINE_COLS = columns.table_columns("bench", "headline")
FLOOR_COLS = columns.table_columns("bench_floors")


def header(info: dict) -> str:
    gpu = info.get("gpu") or "none"
    return (
        f"machine: {info['cpu']}, {info['cores']} cores; GPU: {gpu}\n\n"
        f"versions: Python {info['python']}, numpy {info['numpy']}, drjit {info['drjit']}, "
        f"mitsuba {info['mitsuba']}, embreex {info['embreex']}; libLLVM {info['libllvm'] or '-'}\n\n"
        f"code: {info.get('code', '-')} (study.codehash of the bench and of every method timed)\n\n"
        f"{info.get('rt_cores', '')}"
    )


def bench_headline(rows: list[dict]) -> list[dict]:
    """The headline rows: each method's frozen (Dr.Jit) row on the full-frame batches (close-up, synthetic)
    that has a floor, with its floor, its ratio to the floor and to the exact queries."""
    return [
        r
        for r in rows
        if r.get("path") == "frozen"
        and r.get("x_floor") not in ("", None)
        and ("close-up" in r["batch"] or r["batch"].startswith("synthetic"))
    ]


def bench_table(rows: list[dict]) -> str:
    """The main table as Markdown (4 significant digits)."""
    return markdown(rows, BENCH_COLS, digits=4)


def projection_section(proj: list[dict]) -> str:
    """The Markdown section of the RT-core projection (:mod:`study.bench.carry`); '' without rows."""
    if not proj:
        return ""
    return (
        f"## Cost that carries: a projection to GPUs with RT cores\n\n{projection_title()}\n\n"
        f"{markdown(proj, PROJECTION_COLS, digits=3)}\n\n"
    )


def write_bench_files(rows, info, out: Path, *, lock: bool = True) -> list[Path]:
    """Replace the main table (``bench-<tag>.csv`` and ``.md``) in ``out``; the paths."""
    tag = info["tag"]
    fl = info.get("floors") or []
    proj = (
        projection_rows(bench_headline(rows), shading=shaded_parts(rows))
        if "no RT cores" in info.get("rt_cores", "")
        else []
    )
    md = (
        f"# study bench ({tag})\n\n{header(info)}\n\n## Headline: ms per 1024² frame, floor, ratios\n\n"
        f"x_floor = time / floor (1 = at the floor); kernel_* = the device's time in the kernels alone (Dr.Jit's "
        f"kernel history), without the host's share of a call; x_vs_* = the exact query's time / the method's "
        f"(> 1: the method is faster)\n\n{markdown(bench_headline(rows), HEADLINE_COLS, digits=3)}\n\n"
        f"## Measured floors\n\n{markdown(fl, FLOOR_COLS, digits=4) if fl else '(none measured)'}\n\n"
        f"{projection_section(proj)}"
        f"## Every row\n\n{bench_table(rows)}\n"
    )
    files = {f"bench-{tag}.csv": to_csv(rows), f"bench-{tag}.md": md}
    if proj:
        files[f"projection-{tag}.csv"] = to_csv(proj)
    if fl:
        files[f"floors-{tag}.csv"] = to_csv(fl)
    return write_set(out, files, lock=lock)


def write_scaling(scaling, info, out: Path, *, lock: bool = True) -> list[Path]:
    """Replace the scaling study (``scaling-<tag>.csv`` and ``.png``) in ``out``; the paths."""
    tag = info["tag"]
    png = plot_scaling(scaling, None, title=f"study bench scaling ({tag}: {info.get('gpu') or info['cpu']})")
    return write_set(out, {f"scaling-{tag}.csv": to_csv(scaling), f"scaling-{tag}.png": png}, lock=lock)


def write_outputs(rows, scaling, info, out: Path, *, lock: bool = True) -> list[Path]:
    """Write the main table (CSV, Markdown) and, if there are scaling rows, their CSV and plot; the paths."""
    files = write_bench_files(rows, info, out, lock=lock)
    return files + (write_scaling(scaling, info, out, lock=lock) if scaling else [])


def _method_of(rows: list[dict]) -> str:
    """The label of the method a study timed (its first row that is not an exact tracer)."""
    return next((r["label"] for r in rows if not r["label"].startswith("exact")), "")


def _knob_axis(rows: list[dict]) -> str:
    name = _method_of(rows).split("(")[0]
    cls = registry.REGISTRY.get(name)
    return f"{cls.knob.param} of {name}" if cls is not None and cls.knob is not None else "knob value"


def plot_scaling(rows: list[dict], path: Path | None, *, title: str) -> bytes | None:
    """Four log-scale panels (rays, knob, cube resolution, triangles), one line per backend × method;
    exact tracers dashed. With ``path`` None: the PNG's bytes."""
    import matplotlib  # heavy: only when a plot is made

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    sub = {s: [r for r in rows if r["study"] == s] for s in ("rays", "knob", "cube_res", "triangles")}
    studies = [
        ("rays", "rays per call", "ms per call", True),
        ("knob", _knob_axis(sub["knob"]), "ms per 1024² frame", False),
        ("cube_res", f"cube resolution ({_method_of(sub['cube_res'])})", "ms per 1024² frame", True),
        ("triangles", "triangles in the room (+ displaced heightfield)", "ms per 1024² frame", True),
    ]
    fig, axes = plt.subplots(2, 2, figsize=(13, 9))
    for ax, (study, xlabel, ylabel, logx) in zip(axes.ravel(), studies):

        def key(r, study=study):
            lab = r["label"].split("(")[0] if study == "knob" else r["label"]
            return f"{lab} [{r['backend']}]"

        for k in dict.fromkeys(key(r) for r in sub[study]):
            pts = sorted(
                (float(r["value"]), float(r["ms_per_call"] if study == "rays" else r["ms_per_frame"]))
                for r in sub[study]
                if key(r) == k
            )
            ax.plot(*zip(*pts), "--" if k.startswith("exact") else "-", marker="o", ms=3, label=k)
        ax.set_xscale("log" if logx else "linear")
        ax.set_yscale("log")
        ax.set_xlabel(xlabel)
        ax.set_ylabel(ylabel)
        ax.grid(True, which="both", alpha=0.3)
        if sub[study]:
            ax.legend(fontsize=7)
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    if path is None:
        return png_bytes(fig, dpi=100)
    atomic_savefig(fig, path, dpi=100)
    return None
