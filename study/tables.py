"""Tables: the tidy results table (one row per case × method) as CSV and Parquet, written atomically, and Markdown
tables.

Every CSV study writes goes through :func:`write_csv` (fixed column order, NaN as an empty cell) and is read back
by :func:`read_csv`; a results table (``metrics.csv``, ``results.csv``) also goes out as Parquet beside it
(:func:`table_files` / :func:`write_table`: the same columns, ``pd.read_parquet(path)`` in one line); every
Markdown table through :func:`markdown`."""

from __future__ import annotations

import csv
import io
import math
from pathlib import Path

from study import columns
from study.columns import LEAD
from study.errors import StudyError
from study.io import atomic_write

#: Column order of every results table (:data:`study.columns.LEAD`); extra keys follow in the order first seen.
COLUMNS = LEAD


#: Rows that are references, not methods: the exact hit with the impostor's radiance and with Mitsuba's.
REFERENCE_ROWS = ("oracle_map", "truth_at_hit")

#: Wall-clock columns: measured, not computed, so never part of a regression baseline.
TIMING_COLUMNS = ("seconds", "case_seconds")


def without_timing(rows: list[dict]) -> list[dict]:
    """The rows without their wall-clock columns (:data:`TIMING_COLUMNS`)."""
    return [{k: v for k, v in r.items() if k not in TIMING_COLUMNS} for r in rows]


def _fmt(v):
    if isinstance(v, float):
        if math.isnan(v):
            return ""
        return (
            repr(float(v)) if math.isfinite(v) else ("inf" if v > 0 else "-inf")
        )  # np.float64's repr names it
    return v


def columns_of(rows: list[dict]) -> list[str]:
    extra = [k for r in rows for k in r if k not in COLUMNS]
    return [c for c in COLUMNS if any(c in r for r in rows)] + list(dict.fromkeys(extra))


def to_csv(rows: list[dict]) -> str:
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=columns_of(rows), lineterminator="\n")
    w.writeheader()
    for r in rows:
        w.writerow({k: _fmt(v) for k, v in r.items()})
    return buf.getvalue()


def write_csv(rows: list[dict], path: str | Path) -> None:
    atomic_write(Path(path), to_csv(rows).encode())


def to_parquet(rows: list[dict]) -> bytes:
    """The rows as a Parquet file's bytes (pyarrow): the columns of :func:`to_csv` in its order; a column of numbers
    is float64 (int64 when every row has an integer), missing or NaN cells NaN, as :func:`read_csv` reads the CSV;
    any other column is text (missing cells null; a cell that is not text written as the CSV writes it)."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    arrays = {}
    for c in columns_of(rows):
        vals = [r.get(c) for r in rows]
        real = [v for v in vals if v is not None and not (isinstance(v, float) and math.isnan(v))]
        if all(isinstance(v, int) and not isinstance(v, bool) for v in vals) and vals:
            arrays[c] = pa.array(vals, pa.int64())
        elif all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in real):
            arrays[c] = pa.array([math.nan if v is None else float(v) for v in vals], pa.float64())
        else:
            arrays[c] = pa.array(
                [None if v is None else v if isinstance(v, str) else str(_fmt(v)) for v in vals], pa.string()
            )
    buf = pa.BufferOutputStream()
    pq.write_table(pa.table(arrays), buf)
    return buf.getvalue().to_pybytes()


def table_files(rows: list[dict], stem: str) -> dict[str, bytes]:
    """A results table's files for an output set: ``<stem>.csv`` and ``<stem>.parquet`` (the same rows)."""
    return {f"{stem}.csv": to_csv(rows).encode(), f"{stem}.parquet": to_parquet(rows)}


def write_table(rows: list[dict], path: str | Path) -> None:
    """A results table at ``path`` (``….csv``) and beside it as Parquet (``….parquet``), each atomically."""
    path = Path(path)
    for name, data in table_files(rows, path.stem).items():
        atomic_write(path.with_name(name), data)


def read_csv(path: str | Path) -> list[dict]:
    """Rows with numbers parsed back to float (empty → NaN)."""
    out = []
    with open(path, newline="") as f:
        for r in csv.DictReader(f):
            row = {}
            for k, v in r.items():
                try:
                    row[k] = float(v) if v != "" else math.nan
                except ValueError:
                    row[k] = v
            out.append(row)
    return out


def _allowed(lo: float, hi: float) -> str:
    def end(v):
        return "∞" if v == math.inf else "-∞" if v == -math.inf else f"{v:g}"

    if hi == columns.FINITE:
        return f"a finite number ≥ {end(lo)}"
    if hi == math.inf:
        return f"a number ≥ {end(lo)} (∞ allowed)"
    return f"a number in [{end(lo)}, {end(hi)}]"


def unique_cases(rows: list[dict], path: str | Path, *, kind: str = "results table") -> None:
    """Each (case, label) of ``rows`` once (rows without both are not counted), else one StudyError naming the
    file and the two lines (a line is the row's index + 2: the header is line 1)."""
    first: dict[tuple, int] = {}
    for i, r in enumerate(rows):
        if "case" in r and "label" in r:
            k = (r["case"], r["label"])
            if k in first:
                raise StudyError(
                    f"malformed {kind}: line {i + 2} repeats case {str(k[0])[:40]!r}, label {str(k[1])[:40]!r} "
                    f"of line {first[k]}; each (case, label) once",
                    file=str(path),
                )
            first[k] = i + 2


def check_rows(rows: list[dict], path: str | Path, *, kind: str = "results table") -> list[dict]:
    """``rows`` of the results table at ``path`` (as :func:`read_csv` reads it) checked against the declared
    columns (:func:`study.columns.domain`): every number of a declared column within its domain (fractions in
    [0, 1], counts, lookups, times and RMSEs finite and ≥ 0, …; an empty cell, NaN, is allowed; an interval's
    ``_hi`` may be +∞), and each (case, label) once. A forged or impossible number is one StudyError naming the
    file, the line and the column (bad input, exit 2) before any verdict is drawn from it.

    Parameters
    ----------
    rows : list of dict
        The table's rows, line 2 of the file first.
    path : str or Path
        The file (named in the error).
    kind : str
        What the table is, in the error.

    Returns
    -------
    list of dict
        ``rows``, unchanged.
    """
    doms: dict[str, tuple[float, float] | None] = {}
    unique_cases(rows, path, kind=kind)
    for i, r in enumerate(rows):
        line = i + 2
        for c, v in r.items():
            if not isinstance(v, float) or math.isnan(v):
                continue
            if c not in doms:
                doms[c] = columns.domain(c)
            dom = doms[c]
            if dom is None:
                continue
            lo, hi = dom
            if lo <= v <= hi or (c.endswith("_hi") and v == math.inf and columns.declared(c) is not None):
                continue
            who = (
                f" (case {str(r.get('case'))[:40]!r}, label {str(r.get('label'))[:40]!r})"
                if "label" in r
                else ""
            )
            raise StudyError(
                f"impossible {kind}: line {line}, column {c!r}{who} holds {v:g}; allowed: {_allowed(lo, hi)} "
                "or empty",
                file=str(path),
            )
    return rows


def fmt_number(v, digits: int = 3) -> str:
    """A table cell: floats to ``digits`` significant digits (tiny ones in e-notation), NaN as '–'."""
    if isinstance(v, float):
        if math.isnan(v):
            return "–"
        if v == 0:
            return "0"
        return f"{v:.{digits}g}" if abs(v) >= 1e-3 else f"{v:.1e}"
    return str(v)


def markdown(rows: list[dict], cols: list[str], *, digits: int = 3) -> str:
    """A Markdown table of ``rows`` with the columns ``cols`` that some row has."""
    cols = [c for c in cols if any(c in r for r in rows)]
    out = ["| " + " | ".join(cols) + " |", "|" + "---|" * len(cols)]
    for r in rows:
        out.append("| " + " | ".join(fmt_number(r.get(c, ""), digits) for c in cols) + " |")
    return "\n".join(out)
