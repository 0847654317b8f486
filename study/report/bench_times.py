"""The bench's times as ``study pareto`` reads them (:func:`device_times`): one bench table's rows per method
label, on a clock (:data:`CLOCKS`), scaled to a 1080p frame, the exact rows priced with everything they read (the
module docstring of :mod:`study.report.pareto` says how), every time the page uses checked (:func:`_time`)."""

from __future__ import annotations

import math
import re
import subprocess
from dataclasses import dataclass, field
from pathlib import Path

from study import methods as registry
from study.errors import StudyError
from study.report.check import read_table

#: Rays of a 1080p frame (one secondary ray per pixel) and of the bench's frame.
RAYS_1080P, RAYS_BENCH = 1920 * 1080, 1024 * 1024
#: The bench's batches by short name → a test of the batch's name.
BATCHES = {
    "close-up": lambda b: "close-up" in b,
    "fig4": lambda b: b.startswith("fig4") and "close-up" not in b,
    "synthetic": lambda b: b.startswith("synthetic") and "sorted" not in b,
    "sorted": lambda b: b.startswith("synthetic") and "sorted" in b,
}

#: Which time of a bench row: the wall clock per call (what a frame pays, host share included), or the device's
#: time in the kernels alone (Dr.Jit's kernel history: on a fast GPU a short kernel's call is the host's).
CLOCKS = {"wall": "ms_per_frame", "kernel": "kernel_ms_per_frame"}
CLOCK_WORDS = {
    "wall": "the wall clock per call, host launch share included",
    "kernel": "the device time in the kernels alone, what a renderer pays inside a frame; the host launch share "
    "is stated apart per device",
}


@dataclass
class DeviceTimes:
    """One bench's times per method label, scaled to a 1080p frame, and where they come from."""

    tag: str  # the bench's tag (gpu, cpu, …)
    device: str  # words: the machine line of bench-<tag>.md
    backend: str  # the method rows read: cuda or llvm
    batch: str  # the bench batch's full name
    source: str  # the CSV
    commit: str  # the git commit that holds the CSV ('uncommitted' where none)
    code: str  # study.codehash of the bench's code (bench-<tag>.md), 'not stated' where missing
    ms: dict[str, float] = field(default_factory=dict)  # label → ms per 1080p frame (on the clock asked for)
    clock: str = "kernel"  # the clock of ``ms`` (CLOCKS)
    wall: dict[str, float] = field(
        default_factory=dict
    )  # label → the wall clock's ms (launch share included)
    on_wall: list[str] = field(default_factory=list)  # labels the kernel clock had no time for: on the wall's
    bare: dict[str, float] = field(default_factory=dict)  # exact rows → their bare query's ms (no shading)
    unshaded: list[str] = field(default_factory=list)  # exact rows priced without shading (an older bench)


def _commit_of(path: Path) -> str:
    try:
        out = subprocess.run(["git", "log", "-1", "--format=%h %cs", "--", path.name], capture_output=True,
                             text=True, check=True, cwd=path.parent).stdout.strip()  # fmt: skip
    except (OSError, subprocess.CalledProcessError):
        out = ""
    return out or "uncommitted"


def _header(md: Path) -> tuple[str, str]:
    """(device, code hash) from bench-<tag>.md's machine and code lines."""
    text = md.read_text(encoding="utf-8", errors="replace") if md.is_file() else ""
    mach = re.search(r"^machine: (.*)$", text, re.M)
    code = re.search(r"^code: (\S+)", text, re.M)  # older benches do not state it
    device = "unknown machine"
    if mach:
        cpu, _, gpu = mach.group(1).partition("; GPU: ")
        device = cpu if gpu.strip() in ("", "none") else f"{gpu.split(',')[0]} (host {cpu.split(',')[0]})"
    return device, code.group(1) if code else "not stated"


def exact_priced() -> dict[str, tuple[str, int]]:
    """Label → (bench query, queries per ray) of every registered method that is the exact query itself
    (``bench_query``), at its defaults and at each rung of its knob's ladder: ``traced`` makes one query a ray,
    ``traced_glossy(samples=K)`` K (``queries``), priced at K times the query's time."""
    out = {}
    for name in registry.names():
        q = getattr(registry.REGISTRY[name], "bench_query", None)
        if q:
            m = registry.make(name)
            for v in [m, *m.ladder()]:
                out[v.label] = (q, int(getattr(v, "queries", 1)))
    return out


def _ms(row: dict, col: str) -> float:
    try:
        return float(row.get(col, math.nan))
    except (TypeError, ValueError):
        return math.nan


def device_times(path: str | Path, *, batch: str = "close-up", clock: str = "kernel") -> DeviceTimes:
    """The times of one bench CSV (module docstring) on ``clock`` (:data:`CLOCKS`); a StudyError names the file
    where it has no such batch. On the kernel clock a row without a kernel time (numpy's) takes its wall time and
    is listed in ``on_wall``; ``wall`` keeps every row's wall time (the launch share is their difference). The
    exact rows (``exact_priced``) take their own bench row (``traced``'s: the query and its shading, path
    ``shaded``; ``bare``: the query alone); without one, a method that shades its hits is priced at the bare query
    (listed in ``unshaded``) and one whose reads at the hit the bench prices (``hit_cache``) is not placed."""
    path = Path(path)
    if clock not in CLOCKS:
        raise StudyError(f"unknown clock {clock!r}; allowed: {', '.join(CLOCKS)}", key="--clock")
    col = CLOCKS[clock]
    if batch not in BATCHES:
        raise StudyError(f"unknown batch {batch!r}; allowed: {', '.join(BATCHES)}", key="--batch")
    if not path.is_file():
        raise StudyError("no such bench table (study bench writes it)", file=str(path))
    # UTF-8 CSV with these columns and numbers in the clock's (random bytes, UTF-16: one line naming the file)
    rows = read_table(
        path,
        required=("batch", "backend", "path", "label", "ms_per_frame", col),
        numeric=list(dict.fromkeys(["ms_per_frame", col])),
        kind="bench table",
    )
    backend = "cuda" if any(r["backend"] == "cuda" for r in rows) else "llvm"
    names = [b for b in dict.fromkeys(r["batch"] for r in rows) if BATCHES[batch](b)]
    if not names:
        raise StudyError(f"no batch {batch!r} in it (batches: {', '.join(dict.fromkeys(r['batch'] for r in rows))})",
                         file=str(path), key="--batch")  # fmt: skip
    sel = [r for r in rows if r["batch"] == names[0]]
    scale = RAYS_1080P / RAYS_BENCH
    line = {id(r): i + 2 for i, r in enumerate(rows)}
    variant = "cuda_ad_rgb" if backend == "cuda" else "llvm_ad_rgb"
    wall, ms, bare, unshaded = {}, {}, {}, []

    def put(label: str, r: dict, k: int = 1) -> None:  # an impossible time: one line (_time), never a verdict
        wall[label] = _time(path, r, "ms_per_frame", line[id(r)]) * scale * k
        v = r.get(col)  # the kernel clock: a row without one (numpy's) takes the wall's (on_wall)
        known = col == "ms_per_frame" or (isinstance(v, float) and v == v)
        ms[label] = _time(path, r, col, line[id(r)]) * scale * k if known else math.nan

    for r in sel:
        if r["backend"] == backend and r["path"] == "frozen":
            put(r["label"], r)
    for label, (query, k) in exact_priced().items():
        own = [r for r in sel if r["label"] == label and r["backend"] == backend]
        exact = [r for r in sel if r["label"] == f"exact: Mitsuba {variant}" and r["path"] == query]
        for r in (
            own
        ):  # its own bench row already holds its k queries and shading (study.bench.run.exact_query_row)
            put(label, r)
            bare[label] = _ms(r, "query_ms_per_frame") * scale
        cls = registry.REGISTRY[label.split("(")[0]]
        shaded = [
            r for r in sel if r["backend"] == backend and r.get("path") == "shaded" and r["label"] == "traced"
        ]
        for r in exact if not own and getattr(cls, "shades_hit", True) else []:
            bare[label] = _ms(r, "ms_per_frame") * scale * k
            if shaded:  # K shaded exact rays: K times traced's query and shading
                put(label, shaded[0], k)
            else:
                put(label, r, k)
                unshaded.append(label)
    on_wall = [k for k, v in ms.items() if not math.isfinite(v) and math.isfinite(wall[k])]
    ms.update({k: wall[k] for k in on_wall})
    tag = path.stem.removeprefix("bench-")
    device, code = _header(path.with_suffix(".md"))
    ms = {k: v for k, v in ms.items() if math.isfinite(v)}
    return DeviceTimes(tag, device, backend, names[0], str(path), _commit_of(path), code, ms, clock,
                       {k: v for k, v in wall.items() if math.isfinite(v)}, on_wall,
                       {k: v for k, v in bare.items() if math.isfinite(v)}, unshaded)  # fmt: skip


def _time(path: Path, r: dict, col: str, line: int) -> float:
    """A bench row's time that the page places: a finite number > 0 ms, else (−5, 0, NaN, ∞) one StudyError
    naming the file, line and column (exit 2), never a front or a budget answer."""
    v = r[col]
    if isinstance(v, float) and math.isfinite(v) and v > 0:
        return v
    raise StudyError(
        f"impossible bench table: line {line}, column {col!r} (label {str(r.get('label'))[:40]!r}, backend "
        f"{str(r.get('backend'))[:20]!r}) holds {'nothing' if v != v else f'{v:g}'}; a time per frame is a "
        "finite number > 0 ms",
        file=str(path),
    )
