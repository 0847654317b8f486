"""The baseline of `study check` (:mod:`study.report.check`): its tables, its pooled seed-to-seed spread and the
checks it passes as a whole before any sweep runs (docs/check.md).

A baseline directory holds ``results.csv`` (the first seed's table), ``spread.csv`` (per (case, label) and compared
metric the mean over the seeds and their sample sd, ``<metric>_sd``) and ``metadata.json`` (the seeds, the backend).
:func:`read_baseline_set` reads and checks all three; a table that is not what its seeds could have given is bad
input (a StudyError naming the file, the row and the column: exit 2), never a pass nor a crash after the sweep.
"""

from __future__ import annotations

import csv
import io
import json
import math
import re
import statistics
from pathlib import Path
from typing import Literal

from pydantic import BaseModel, ConfigDict, Field

from study import columns
from study.errors import StudyError, os_problem
from study.scene.schema import MAX_SEED, Float
from study.tables import read_csv, unique_cases

#: The baseline's table of seed-to-seed spread (beside its results.csv).
SPREAD = "spread.csv"


class Tolerance(BaseModel):
    """The floor of a metric's tolerance: abs + rel·|mean|, added to k × its seed-to-seed sd."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)
    abs: Float = Field(ge=0)
    rel: Float = Field(ge=0)
    #: how the metric's rows share their seed-to-seed sd (:func:`pooled_relative_sd`): "relative" (sd / |mean|, a
    #: metric ≥ 0 whose noise grows with it), "absolute" (the sd itself: a signed metric near 0, a bias)
    pool: Literal["relative", "absolute"] = "relative"


def spread_of(row: dict, metric: str) -> float:
    """The baseline's seed-to-seed sd of ``metric`` in ``row`` (``<metric>_sd``); 0 where it has none."""
    sd = row.get(f"{metric}_sd")
    return sd if isinstance(sd, float) and math.isfinite(sd) else 0.0


#: How far one row's seed-to-seed spread (relative to its mean, or absolute: :attr:`Tolerance.pool`) may lie above
#: the median of its metric's rows in a baseline, and the most the pooled spread may be. A few seeds of a row
#: scatter its sd: with the 3 seeds a baseline needs at least, the largest of 68 rows' sample sds comes out about
#: 4 × their median when all share one σ (χ² with 2 degrees of freedom), and the rows of the committed baseline
#: differ by up to 6.2 × (rmse_oracle, 5 seeds). A row beyond 25 × is no spread the seeds gave: a forged or broken
#: baseline (one row's sd of 1e6 would widen every row's tolerance through the pooled sd).
SPREAD_RATIO_MAX = 25.0
#: The most the pooled spread (:func:`pooled_relative_sd`) may be over the median of its rows: their root mean
#: square, heavy-tailed, is at most 2.3 × their median in the committed baseline (rmse_oracle; 1.0–1.4 × in the
#: others), and one row of 25 × the median would lift it to 5.7 ×, a 10× regression within k = 5 of it.
POOLED_RATIO_MAX = 5.0


def _scaled_spreads(base: list[dict], metric: str, pool: str = "relative") -> list[tuple[int, float]]:
    """(row index, the row's spread as :func:`pooled_relative_sd` pools it) for the rows that have one."""
    out = []
    for i, r in enumerate(base):
        mean = r.get(metric)
        if not isinstance(mean, float) or not math.isfinite(mean):
            continue
        if pool == "relative":
            if mean == 0:
                continue
            out.append((i, spread_of(r, metric) / abs(mean)))
        else:
            out.append((i, spread_of(r, metric)))
    return out


def pooled_relative_sd(base: list[dict], metric: str, pool: str = "relative") -> float:
    """The metric's seed-to-seed sd relative to its mean, pooled over the baseline's rows (root mean square of
    sd / |mean| over the rows with both, a nonzero mean): a floor under each row's own sd, which a few seeds of
    a heavy-tailed metric underestimate (one seed in eight can move an image metric of the check's ~90 object
    pixels by 10 of its row's sd, and the rows of a metric share that tail). 0 where no row has a spread. Robust:
    at most :data:`POOLED_RATIO_MAX` × the rows' median, so that one row cannot widen every row's tolerance. With
    ``pool="absolute"`` the same over the sds themselves (a signed metric near 0)."""
    rel = [v for _, v in _scaled_spreads(base, metric, pool) if math.isfinite(v)]
    if not rel:
        return 0.0
    top = max(rel)
    rms = top * math.sqrt(statistics.fmean([(v / top) ** 2 for v in rel])) if top > 0 else 0.0
    return min(rms, POOLED_RATIO_MAX * statistics.median(rel))


def spread_table(runs: list[list[dict]], metrics: list[str], seeds: list[int], source: str) -> list[dict]:
    """Per (case, label) of the first run: each metric's mean over the runs and its sample sd (``<metric>_sd``).
    A metric that is NaN at some seeds but not at others has no stable baseline: a StudyError naming it."""
    index = [{(r["case"], r["label"]): r for r in run} for run in runs]
    out = []
    for r in runs[0]:
        key = (r["case"], r["label"])
        row = {"case": key[0], "label": key[1], "seeds": len(runs)}
        for m in metrics:
            vals = [
                float(ix[key][m]) if isinstance(ix.get(key, {}).get(m), float) else math.nan for ix in index
            ]
            nan = [math.isnan(v) for v in vals]
            if any(nan) and not all(nan):
                raise StudyError(
                    f"{m} of {key[1]} in {key[0]} is NaN at seed {seeds[nan.index(True)]} but "
                    f"{vals[nan.index(False)]:.4g} at seed {seeds[nan.index(False)]}: no stable baseline; "
                    "leave it out of [tolerance]",
                    file=source,
                    key=f"tolerance.{m}",
                )
            row[m] = math.nan if all(nan) else statistics.fmean(vals)
            row[f"{m}_sd"] = math.nan if all(nan) else statistics.stdev(vals)
        out.append(row)
    return out


def read_baseline_set(
    base_dir: Path, tolerance: dict[str, Tolerance], k: float
) -> tuple[list[dict], list[dict], dict]:
    """The baseline as a whole, checked before anything runs: its spread table (:func:`read_baseline`), the first
    seed's results table that a check at that seed replays (the same checks, without spreads) and its metadata
    (the seeds it was made at, the backend). Each problem is one StudyError naming the file (bad input, exit 2)."""
    metrics = list(tolerance)
    base = read_baseline(base_dir / SPREAD, metrics, tolerance=tolerance, k=k)
    meta_path = base_dir / "metadata.json"
    try:
        meta = json.loads(meta_path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise StudyError(
            "missing; re-create the baseline with `study check --update`", file=str(meta_path)
        ) from None
    except (UnicodeDecodeError, json.JSONDecodeError, RecursionError) as err:
        raise StudyError(f"not JSON ({str(err)[:60]}); re-create the baseline with `study check --update`",
                         file=str(meta_path)) from None  # fmt: skip
    except OSError as err:
        raise os_problem(err, "cannot read the baseline's metadata", meta_path) from None
    seeds = meta.get("seeds") if isinstance(meta, dict) else None
    if not (isinstance(seeds, list) and seeds and all(type(x) is int and 0 <= x <= MAX_SEED for x in seeds)):
        raise StudyError(
            f"'seeds' is {str(seeds)[:40]}, expected the list of seeds the baseline was made at "
            "(re-create it with `study check --update`)",
            file=str(meta_path),
        )
    results = base_dir / "results.csv"
    if not results.is_file():
        raise StudyError(
            "no replay table; re-create the baseline with `study check --update`", file=str(results)
        )
    replay = read_table(results, numeric=metrics, kind="results table")
    check_baseline(replay, metrics, results)
    return base, replay, meta


def spread_csv(rows: list[dict], metrics: list[str]) -> str:
    """The spread table as CSV: case, label, seeds, then each metric's mean and sd side by side (NaN empty)."""
    header = ["case", "label", "seeds", *(c for m in metrics for c in (m, f"{m}_sd"))]
    buf = io.StringIO()
    out = csv.writer(buf, lineterminator="\n")
    out.writerow(header)
    for r in rows:
        out.writerow([_cell(r[c]) for c in header])
    return buf.getvalue()


def _cell(v) -> str:
    if isinstance(v, float):
        return "" if math.isnan(v) else repr(v)
    return str(v)


def read_baseline(
    path: Path, metrics: list[str], *, tolerance: dict[str, Tolerance] | None = None, k: float = 5.0
) -> list[dict]:
    """The baseline's spread table, well formed (:func:`read_table`, :func:`check_baseline`), or a StudyError."""
    if not path.is_file():
        raise StudyError("no baseline yet; create it with `study check --update`", file=str(path))
    numeric = ["seeds", *(c for m in metrics for c in (m, f"{m}_sd"))]
    rows = read_table(path, numeric=numeric, kind="spread table")
    check_baseline(rows, metrics, path, tolerance=tolerance, k=k)
    return rows


def read_table(
    path: str | Path,
    *,
    required: tuple[str, ...] = ("case", "label"),
    numeric: list[str] = (),
    kind: str = "results table",
) -> list[dict]:
    """A results table (:func:`study.tables.read_csv`) that must be well formed: UTF-8 CSV with a header of
    distinct names without control characters, no NUL byte in any cell, every row as long as the header, the
    ``required`` columns, and numbers (or empty cells) in the ``numeric`` columns it has. Anything else is one
    StudyError naming the file and the first offending cell (bad input, exit 2); ``kind`` names the table in it."""
    path = Path(path)
    try:
        data = path.read_bytes()
        text = data.decode("utf-8")
        raw = list(csv.reader(io.StringIO(text, newline="")))
    except UnicodeDecodeError as err:
        line = data[: err.start].count(b"\n") + 1
        raise StudyError(
            f"not UTF-8 text, expected a {kind} (CSV): line {line} holds byte 0x{data[err.start]:02x}",
            file=str(path),
        ) from None
    except IsADirectoryError:
        raise StudyError(f"is a directory, expected a {kind} (CSV)", file=str(path)) from None
    except csv.Error as err:
        raise StudyError(f"malformed CSV ({err})", file=str(path)) from None
    except OSError as err:
        raise os_problem(err, f"cannot read the {kind}", path) from None
    header = raw[0] if raw else []
    for j, name in enumerate(header):
        if _CONTROL.search(name) or not name:
            raise StudyError(
                f"malformed {kind}: line 1, column {j + 1} of the header is {name[:40]!r}, "
                "not a column name (empty, or with a NUL or control character)",
                file=str(path),
            )
        if name in header[:j]:
            raise StudyError(
                f"malformed {kind}: line 1, column {j + 1}: {name!r} is already column "
                f"{header.index(name) + 1}",
                file=str(path),
            )
    missing = [c for c in required if c not in header]
    if missing:
        raise StudyError(
            f"malformed {kind}: no column {missing[0]!r} (header: {','.join(header)[:60] or 'empty'})",
            file=str(path),
        )
    for i, cells in enumerate(raw[1:]):
        if cells and len(cells) != len(header):
            raise StudyError(
                f"malformed {kind}: line {i + 2} has {len(cells)} cells, the header {len(header)}",
                file=str(path),
            )
        nul = next((j for j, c in enumerate(cells) if "\0" in c), None)
        if nul is not None:
            raise StudyError(
                f"malformed {kind}: line {i + 2}, column {header[nul]!r} holds a NUL byte",
                file=str(path),
            )
    rows = read_csv(path)
    for i, r in enumerate(rows):
        bad = next((c for c in numeric if c in r and not isinstance(r[c], float)), None)
        if bad:
            raise StudyError(
                f"malformed {kind}: line {i + 2}, column {bad!r} holds {str(r[bad])[:20]!r}, not a number",
                file=str(path),
            )
    if not rows:
        raise StudyError(f"malformed {kind}: no rows", file=str(path))
    return rows


#: Characters no column name holds: NUL and the other C0 controls, DEL.
_CONTROL = re.compile(r"[\x00-\x1f\x7f]")


#: Units of declared columns that are never negative (an error, a distance, a count): their baseline means are ≥ 0,
#: and the sample sd of n values ≥ 0 with mean m is at most m·√n (all of them in one seed).
NONNEGATIVE_UNITS = {"fraction", "deg", "m", "linear RGB", "count", "lookups", "px", "s", "texels"}


def check_baseline(
    rows: list[dict],
    metrics: list[str],
    path: str | Path,
    *,
    tolerance: dict[str, Tolerance] | None = None,
    k: float = 5.0,
) -> None:
    """A baseline's rows as :func:`compare` needs them, checked as a whole before anything runs: one row per
    (case, label); every compared metric a finite number or empty (NaN; an infinite baseline would make its
    tolerance infinite too), ≥ 0 where its unit is (:data:`NONNEGATIVE_UNITS`); its spread (``<metric>_sd``, where
    present) a finite number ≥ 0 that its own seeds could give: at most mean × √seeds for a metric ≥ 0, and at
    most :data:`SPREAD_RATIO_MAX` × the median of the metric's rows (relative to the mean, or absolute: the
    metric's :attr:`Tolerance.pool`); the ``seeds`` column an integer ≥ 2 where spreads are given; and, with
    ``tolerance``, every row's tolerance (k × sd + floor) finite. Else one StudyError naming the first offending
    cell (bad input, exit 2).

    Parameters
    ----------
    rows : list of dict
        The spread table's rows (or a replayed seed's results table: no spreads).
    metrics : list of str
        The compared metrics (the check file's ``[tolerance]``).
    path : str or Path
        The table's file, named in the error.
    tolerance : dict, optional
        The check file's tolerances (their ``pool`` and floors); default: relative pooling, no floor.
    k : float
        The check file's ``k``.
    """
    tolerance = tolerance or {}
    unique_cases(rows, path, kind="baseline")
    for i in range(len(rows)):
        _check_row(rows, i, metrics, path)
    for m in metrics:
        _check_metric(rows, m, tolerance.get(m), k, path)


def _refuse(rows: list[dict], i: int, col: str, what: str, path) -> StudyError:
    r = rows[i]
    return StudyError(
        f"malformed baseline: line {i + 2}, column {col!r} (case {r['case']!r}, label {r['label']!r}) {what}",
        file=str(path),
    )


def _check_row(rows: list[dict], i: int, metrics: list[str], path) -> None:
    """One row's values and spreads (:func:`check_baseline`)."""
    r = rows[i]
    bad = next((m for m in metrics if isinstance(r.get(m), float) and math.isinf(r[m])), None)
    if bad:
        raise _refuse(rows, i, bad, f"holds {r[bad]}; a compared metric is a finite number or empty", path)
    neg = next((m for m in metrics if _nonnegative(m) and isinstance(r.get(m), float) and r[m] < 0), None)
    if neg:
        unit = columns.declared(neg).unit
        raise _refuse(rows, i, neg, f"holds {r[neg]:g}; {neg} ({unit}) is never negative", path)
    sd = next((f"{m}_sd" for m in metrics if _bad_spread(r.get(f"{m}_sd"))), None)
    if sd:
        raise _refuse(rows, i, sd, f"holds {r[sd]}; a seed-to-seed sd is a finite number ≥ 0 or empty", path)
    spreads = [m for m in metrics if isinstance(r.get(f"{m}_sd"), float) and not math.isnan(r[f"{m}_sd"])]
    if not spreads:
        return
    n = r.get("seeds")
    if not isinstance(n, (int, float)) or not float(n).is_integer() or not 2 <= n <= 10**6:
        what = f"holds {n!r}; the number of seeds the spreads are over, an integer ≥ 2"
        raise _refuse(rows, i, "seeds", what, path)
    for m in spreads:
        mean, s = r.get(m), r[f"{m}_sd"]
        if _nonnegative(m) and isinstance(mean, float) and s > abs(mean) * math.sqrt(n) * (1 + 1e-9):
            what = (
                f"holds {s:.4g}, more than {int(n)} seeds of a metric ≥ 0 with mean {mean:.4g} can spread "
                f"(at most mean × √{int(n)} = {abs(mean) * math.sqrt(n):.4g})"
            )
            raise _refuse(rows, i, f"{m}_sd", what, path)


def _check_metric(rows: list[dict], m: str, tol: Tolerance | None, k: float, path) -> None:
    """One metric's spreads against its other rows', and its tolerances finite (:func:`check_baseline`)."""
    pool = tol.pool if tol is not None else "relative"
    scaled = _scaled_spreads(rows, m, pool)
    typical = statistics.median([v for _, v in scaled]) if scaled else 0.0
    over = next(((i, v) for i, v in scaled if typical > 0 and v > SPREAD_RATIO_MAX * typical), None)
    if over:
        i, v = over
        unit = "sd / |mean|" if pool == "relative" else "sd"
        what = (
            f"holds {rows[i][f'{m}_sd']:.4g}, whose {unit} {v:.4g} is {v / typical:.3g} × the median of "
            f"{m}'s {len(scaled)} rows ({typical:.4g}); seeds scatter a row's sd by far less: at most "
            f"{SPREAD_RATIO_MAX:g} ×"
        )
        raise _refuse(rows, i, f"{m}_sd", what, path)
    if tol is None:
        return
    pooled = pooled_relative_sd(rows, m, pool)
    for i, r in enumerate(rows):
        y = r.get(m)
        if not isinstance(y, float) or math.isnan(y):
            continue
        sd = max(spread_of(r, m), pooled * (abs(y) if pool == "relative" else 1.0))
        if not math.isfinite(k * sd + tol.abs + tol.rel * abs(y)):
            what = f"holds {y:.4g}, whose tolerance (k × sd + floor) is not a finite number"
            raise _refuse(rows, i, m, what, path)


def _nonnegative(metric: str) -> bool:
    col = columns.declared(metric)
    return col is not None and col.unit in NONNEGATIVE_UNITS and not metric.endswith(("_lo", "_hi"))


def _bad_spread(v) -> bool:
    return isinstance(v, float) and (math.isinf(v) or v < 0)
