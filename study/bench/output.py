"""The bench's files: ``bench-<tag>.csv`` / ``.md`` (the main table) and ``scaling-<tag>.csv`` / ``.png``.

Columns of the main table: ms_per_call, mrays_per_s, ms_per_frame (a 1024² frame = 1 048 576 rays at the measured
rate), x_vs_embree / x_vs_mitsuba (the exact tracer's time for the same rays over the method's; > 1: the method is
faster). The Markdown file starts with the machine and the package versions.
"""
from __future__ import annotations

from pathlib import Path

from study import methods as registry
from study.io import atomic_savefig, atomic_write
from study.tables import markdown, to_csv

BENCH_COLS = ["batch", "backend", "path", "label", "rays", "ms_per_call", "mrays_per_s", "ms_per_frame",
              "x_vs_embree", "x_vs_mitsuba"]


def header(info: dict) -> str:
    gpu = info.get("gpu") or "none"
    return (f"machine: {info['cpu']}, {info['cores']} cores; GPU: {gpu}\n\n"
            f"versions: Python {info['python']}, numpy {info['numpy']}, drjit {info['drjit']}, "
            f"mitsuba {info['mitsuba']}, embreex {info['embreex']}; libLLVM {info['libllvm'] or '-'}")


def bench_table(rows: list[dict]) -> str:
    """The main table as Markdown (4 significant digits)."""
    return markdown(rows, BENCH_COLS, digits=4)


def write_outputs(rows, scaling, info, out: Path) -> list[Path]:
    """Write the main table (CSV, Markdown) and, if there are scaling rows, their CSV and plot; the paths."""
    out = Path(out)
    tag = info["tag"]
    files = [out / f"bench-{tag}.csv", out / f"bench-{tag}.md"]
    atomic_write(files[0], to_csv(rows))
    atomic_write(files[1], f"# study bench ({tag})\n\n{header(info)}\n\n{bench_table(rows)}\n")
    if scaling:
        files.append(out / f"scaling-{tag}.csv")
        atomic_write(files[-1], to_csv(scaling))
        files.append(out / f"scaling-{tag}.png")
        plot_scaling(scaling, files[-1], title=f"study bench scaling ({tag}: {info.get('gpu') or info['cpu']})")
    return files


def _method_of(rows: list[dict]) -> str:
    """The label of the method a study timed (its first row that is not an exact tracer)."""
    return next((r["label"] for r in rows if not r["label"].startswith("exact")), "")


def _knob_axis(rows: list[dict]) -> str:
    name = _method_of(rows).split("(")[0]
    cls = registry.REGISTRY.get(name)
    return f"{cls.knob.param} of {name}" if cls is not None and cls.knob is not None else "knob value"


def plot_scaling(rows: list[dict], path: Path, *, title: str) -> None:
    """Four log-scale panels (rays, knob, cube resolution, triangles), one line per backend × method;
    exact tracers dashed."""
    import matplotlib  # heavy: only when a plot is made
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    sub = {s: [r for r in rows if r["study"] == s] for s in ("rays", "knob", "cube_res", "triangles")}
    studies = [("rays", "rays per call", "ms per call", True),
               ("knob", _knob_axis(sub["knob"]), "ms per 1024² frame", False),
               ("cube_res", f"cube resolution ({_method_of(sub['cube_res'])})", "ms per 1024² frame", True),
               ("triangles", "triangles in the room (+ displaced heightfield)", "ms per 1024² frame", True)]
    fig, axes = plt.subplots(2, 2, figsize=(13, 9))
    for ax, (study, xlabel, ylabel, logx) in zip(axes.ravel(), studies):
        def key(r):
            lab = r["label"].split("(")[0] if study == "knob" else r["label"]
            return f"{lab} [{r['backend']}]"
        for k in dict.fromkeys(key(r) for r in sub[study]):
            pts = sorted((float(r["value"]), float(r["ms_per_call"] if study == "rays" else r["ms_per_frame"]))
                         for r in sub[study] if key(r) == k)
            ax.plot(*zip(*pts), "--" if k.startswith("exact") else "-", marker="o", ms=3, label=k)
        ax.set_xscale("log" if logx else "linear")
        ax.set_yscale("log")
        ax.set_xlabel(xlabel); ax.set_ylabel(ylabel); ax.grid(True, which="both", alpha=0.3)
        if sub[study]:
            ax.legend(fontsize=7)
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    atomic_savefig(fig, path, dpi=100)
