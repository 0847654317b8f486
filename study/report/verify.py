"""Reproduction checked: freshly made tables against the committed ones, row by row (``study verify``).

Each table under the fresh folder (a figure's ``metrics.csv``, a sweep's ``results.csv``, found by
:func:`study.report.report.tables_of`'s rules) is paired with the table of the same folder name under the
committed reports; rows are paired by ``(case, label)``. A column with an interval (``<col>_lo``, ``<col>_hi``
beside it) agrees where the fresh value lies within the committed interval (at a relative tolerance of
:data:`REL_TOL`, for the float32 round trip of the CSV). A column without one is deterministic for a given config,
seed and backend: it is compared within :data:`DET_RTOL` where both tables come from the same backend, and counted
but not judged where they do not (each backend's float32 arithmetic differs). Timing columns are never compared.

The result is one table a screen high (tables, rows, columns, values compared, how many outside), with the worst
values outside listed under it, as Markdown (printed, and written to ``--out``).
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path

from study.errors import StudyError
from study.outputs.markup import md_esc
from study.tables import TIMING_COLUMNS, markdown

#: Relative slack on an interval's ends (the CSV keeps floats to their repr; intervals computed in float32).
REL_TOL = 1e-6
#: Deterministic columns on the same backend: agreement within this relative (and absolute 1e-9) tolerance.
DET_RTOL = 1e-5
ROW_KEYS = ("case", "label")
#: Columns that are identity or bookkeeping, not results.
SKIP = {*ROW_KEYS, *TIMING_COLUMNS, "method", "seed", "table"}


@dataclass
class TableAgreement:
    """One table's comparison: rows paired, values compared, and those outside."""

    table: str
    backends: tuple[str, str]
    rows: int = 0
    rows_unpaired: int = 0
    interval_cols: int = 0
    interval_names: list[str] = field(default_factory=list)
    interval_values: int = 0
    outside: int = 0
    det_cols: int = 0
    det_values: int = 0
    det_differ: int = 0
    det_judged: bool = True
    worst: list[tuple] = field(default_factory=list)  # (excess, case, label, column, fresh, lo, hi)


def _tables(d: Path) -> dict[str, Path]:
    """Folder name → results table under ``d`` (figures' metrics.csv, sweeps' results.csv), or ``d``'s own."""
    out = {}
    for name in ("metrics.csv", "results.csv"):
        if (d / name).is_file():
            out[d.name] = d / name
        out.update({p.parent.name: p for p in sorted(d.glob(f"*/{name}"))})
    return out


def _backend(table: Path) -> str:
    try:
        return str(json.loads((table.parent / "metadata.json").read_text()).get("backend", "?"))
    except (OSError, ValueError, AttributeError):
        return "?"


def _num(v) -> float | None:
    return float(v) if isinstance(v, (int, float)) and not isinstance(v, bool) else None


def compare_table(name: str, fresh: Path, committed: Path) -> TableAgreement:
    """The agreement of one fresh table with its committed one (see the module's docstring)."""
    from study.report.check import read_table

    a, b = read_table(fresh), read_table(committed)
    res = TableAgreement(name, (_backend(fresh), _backend(committed)))
    res.det_judged = res.backends[0] == res.backends[1]
    by_key = {tuple(r.get(k) for k in ROW_KEYS): r for r in b}
    cols_b = set().union(*(r.keys() for r in b)) if b else set()
    cols = [c for c in dict.fromkeys(k for r in a for k in r) if c in cols_b and c not in SKIP]
    bounded = {c for c in cols if f"{c}_lo" in cols_b and f"{c}_hi" in cols_b}
    bounds = {f"{c}_{e}" for c in bounded for e in ("lo", "hi")}
    det = [c for c in cols if c not in bounded and c not in bounds]
    res.interval_cols = len(bounded)
    res.interval_names = sorted(bounded)
    used_det = set()
    for ra in a:
        rb = by_key.get(tuple(ra.get(k) for k in ROW_KEYS))
        if rb is None:
            res.rows_unpaired += 1
            continue
        res.rows += 1
        for c in bounded:
            v, lo, hi = _num(ra.get(c)), _num(rb.get(f"{c}_lo")), _num(rb.get(f"{c}_hi"))
            if v is None or lo is None or hi is None or not all(map(math.isfinite, (v, lo, hi))):
                continue
            res.interval_values += 1
            tol = REL_TOL * max(abs(lo), abs(hi), 1e-12)
            if v < lo - tol or v > hi + tol:
                res.outside += 1
                width = max(hi - lo, 1e-12)
                res.worst.append((max(lo - v, v - hi) / width, ra["case"], ra["label"], c, v, lo, hi))
        for c in det:
            v, w = _num(ra.get(c)), _num(rb.get(c))
            if v is None or w is None:
                continue
            if (math.isnan(v) and math.isnan(w)) or v == w:  # equal, infinities included
                res.det_values += 1
                used_det.add(c)
                continue
            used_det.add(c)
            res.det_values += 1
            if not (
                math.isfinite(v) and math.isfinite(w) and abs(v - w) <= DET_RTOL * max(abs(v), abs(w)) + 1e-9
            ):
                res.det_differ += 1
    keys_a = {tuple(r.get(k) for k in ROW_KEYS) for r in a}
    res.rows_unpaired += sum(1 for key in by_key if key not in keys_a)  # committed rows no fresh row has
    res.det_cols = len(used_det)
    res.worst.sort(reverse=True)
    return res


def compare_tables(fresh: str | Path, committed: str | Path) -> list[TableAgreement]:
    """Every table under ``fresh`` against the same-named table under ``committed``. A folder without tables,
    or a fresh table with no committed counterpart, is one StudyError (bad input, exit 2)."""
    fresh, committed = Path(fresh), Path(committed)
    for d, what in ((fresh, "fresh tables"), (committed, "committed reports")):
        if not d.is_dir():
            raise StudyError(f"no such directory (expected the {what})", file=str(d))
    ours, theirs = _tables(fresh), _tables(committed)
    if not ours:
        raise StudyError(
            "holds no results table (a figure's metrics.csv or a sweep's results.csv)", file=str(fresh)
        )
    missing = [n for n in ours if n not in theirs]
    if missing:
        raise StudyError(
            f"no committed table to compare {missing[0]} with (allowed: {', '.join(sorted(theirs)) or 'none'})",
            file=str(committed),
        )
    return [compare_table(n, p, theirs[n]) for n, p in ours.items()]


def _summary_rows(results: list[TableAgreement]) -> list[dict]:
    """One row per table, and the totals."""
    rows = [
        {
            "table": r.table,
            "backends": f"{r.backends[0]} vs {r.backends[1]}",
            "rows": r.rows,
            "unpaired": r.rows_unpaired,
            "interval columns": r.interval_cols,
            "values": r.interval_values,
            "outside": r.outside,
            "deterministic columns": r.det_cols,
            "differ": r.det_differ if r.det_judged else f"{r.det_differ} (not judged: backends differ)",
        }
        for r in results
    ]
    total = {
        "table": "all",
        **{k: sum(row[k] for row in rows) for k in ("rows", "unpaired", "values", "outside")},
    }
    return [*rows, {**total, "differ": sum(r.det_differ for r in results if r.det_judged)}]


def _outside_blocks(results: list[TableAgreement], worst: int) -> list[str]:
    """Which columns agree, which do not (counts, magnitudes: near-zero statistics amplify float32), and the worst
    values outside, as Markdown lines."""
    every = [w for r in results for w in r.worst]
    names = sorted({c for r in results for c in r.interval_names})
    clean = [c for c in names if not any(w[3] == c for w in every)]
    text = [
        f"Columns with every value inside its interval: {len(clean)} of {len(names)} ({', '.join(clean)}).",
        "",
    ]
    if not every:
        return [*text, "Every value with an interval lies within its committed interval.", ""]
    by_col: dict[str, list] = {}
    for w in every:
        by_col.setdefault(w[3], []).append(w)
    cols = ["column", "outside", "largest fresh (abs)", "largest committed end (abs)"]
    magnitudes = [
        dict(zip(cols, (c, len(ws), max(abs(w[4]) for w in ws), max(max(abs(w[5]), abs(w[6])) for w in ws))))
        for c, ws in sorted(by_col.items(), key=lambda kv: -len(kv[1]))
    ]
    cols_w = ["case", "label", "column", "fresh", "committed lo", "committed hi", "excess"]
    bad = [
        dict(zip(cols_w, (c, lab, col, v, lo, hi, e)))
        for e, c, lab, col, v, lo, hi in sorted(every)[::-1][:worst]
    ]
    return [
        *text,
        "Outside, by column (the largest magnitudes among them: near-zero statistics amplify float32):",
        "",
        markdown(magnitudes, cols, digits=3),
        "",
        "Outside their committed intervals (worst first; excess in interval widths):",
        "",
        markdown(bad, cols_w, digits=4),
        "",
    ]


def agreement_markdown(results: list[TableAgreement], *, fresh: str, committed: str, seconds: float | None = None,
                       worst: int = 8, note: str = "") -> str:  # fmt: skip
    """The one-screen agreement table, which columns agree, and the worst values outside their intervals."""
    rows = _summary_rows(results)
    head = [
        f"# Reproduction: {fresh} against {committed}",
        "",
        *([md_esc(note), ""] if note else []),
        f"Written by `study verify {fresh} --against {committed}` (study/report/verify.py)"
        + (f" in {seconds:.0f} s" if seconds is not None else "")
        + ". A value with an interval agrees where the fresh value lies within the committed interval "
        f"(`<col>_lo` … `<col>_hi`, relative slack {REL_TOL:g}); a column without one is compared within a "
        f"relative {DET_RTOL:g} where both tables come from the same backend, else counted, not judged.",
        "",
        markdown(rows, list(rows[0]), digits=4),
        "",
    ]
    return "\n".join(head + _outside_blocks(results, worst))
