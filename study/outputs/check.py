"""CI regression on error metrics: run a small fixed sweep, compare every metric with a committed baseline.

The check file (``configs/check.toml``) names the sweep, the baseline directory, the paper's claims that must hold
(:mod:`study.outputs.claims`) and a tolerance per metric: a metric passes when |new − baseline| ≤ abs + rel·|baseline|
(NaN equals NaN) or, where the baseline row carries the metric's 95 % interval (``<metric>_lo``, ``<metric>_hi``:
:mod:`study.measure.stats`) and the tolerance has ``interval = true`` (the default), when the new value lies
within that interval widened by the same tolerance: a move smaller than the sampling uncertainty of the baseline's
own rays or pixels is not a regression. Rows are matched by (case, label); a row missing on either side is a
failure. ``update=True`` rewrites the baseline (results.csv + metadata.json, one output set: both or neither)
instead of comparing. A malformed baseline is bad input (a StudyError naming the file and its first offending
cell, exit 2: not UTF-8, a NUL byte, a column or a (case, label) twice, an infinite compared metric, whose
tolerance would be infinite too), never a regression (exit 1).
"""

from __future__ import annotations

import csv
import difflib
import io
import json
import math
import re
import tempfile
from dataclasses import dataclass
from pathlib import Path

from pydantic import BaseModel, ConfigDict, Field

from study import columns
from study.errors import StudyError, os_problem
from study.harness.runner import run_sweep
from study.io import write_set
from study.outputs import claims as claim_registry
from study.scene.schema import Float
from study.tables import read_csv, to_csv, without_timing, write_csv
from study.validation import validate_file


class Tolerance(BaseModel):
    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)
    abs: Float = Field(ge=0)
    rel: Float = Field(ge=0)
    interval: bool = True  # also accept values within the baseline's own interval (module docstring)


class CheckConfig(BaseModel):
    model_config = ConfigDict(extra="forbid")
    sweep: str
    baseline: str
    claims: list[str] = []
    tolerance: dict[str, Tolerance] = Field(min_length=1)


@dataclass
class Failure:
    message: str


def load_check(path: str | Path) -> tuple[CheckConfig, Path, Path]:
    path = Path(path)
    cfg = validate_file(CheckConfig, path)
    known = [c.id for c in claim_registry.CLAIMS]
    for i, c in enumerate(cfg.claims):
        if c not in known:
            raise StudyError(
                f"unknown claim {c!r}; allowed: {', '.join(known)}", file=str(path), key=f"claims[{i}]"
            )
    for (
        metric
    ) in cfg.tolerance:  # a tolerance names a declared column (study.columns), or it compares nothing
        if columns.declared(metric) is None:
            near = difflib.get_close_matches(metric, columns.column_names(), n=3)
            raise StudyError(
                f"{metric!r} is not a declared column"
                + (f" (did you mean {', '.join(near)}?)" if near else "")
                + "; the columns are listed in study/columns.py",
                file=str(path),
                key=f"tolerance.{metric}",
            )
    return cfg, path.parent / cfg.sweep, path.parent / cfg.baseline


def compare(new: list[dict], base: list[dict], tolerance: dict[str, Tolerance]) -> list[Failure]:
    fails = []
    index = {(r["case"], r["label"]): r for r in base}
    seen = set()
    for r in new:
        k = (r["case"], r["label"])
        b = index.get(k)
        if b is None:
            fails.append(Failure(f"{k[1]} in {k[0]}: not in the baseline (run `study check --update`?)"))
            continue
        seen.add(k)
        for metric, tol in tolerance.items():
            if metric not in r or metric not in b:
                fails.append(
                    Failure(f"{metric}: missing from the {'results' if metric not in r else 'baseline'}")
                )
                continue
            x, y = float(r[metric]), float(b[metric])
            if math.isnan(x) and math.isnan(y) or x == y:
                continue
            if math.isinf(y):  # its tolerance would be infinite: only the same value passes
                fails.append(Failure(f"{metric} of {k[1]} in {k[0]} moved from {y:g} to {x:.6g}"))
                continue
            allowed = tol.abs + tol.rel * abs(y)
            if abs(x - y) <= allowed:
                continue
            band = _interval(b, metric) if tol.interval else None
            if band is not None and band[0] - allowed <= x <= band[1] + allowed:
                continue
            within = f"; baseline interval [{band[0]:.4g}, {band[1]:.4g}]" if band else ""
            fails.append(
                Failure(
                    f"{metric} of {k[1]} in {k[0]} moved from {y:.6g} to {x:.6g} "
                    f"(by {x - y:+.3g}; tolerance ±{allowed:.3g} = {tol.abs:g} + {tol.rel:g}·|baseline|"
                    f"{within})"
                )
            )
    for k in index.keys() - seen:
        fails.append(Failure(f"{k[1]} in {k[0]}: in the baseline but not in the results"))
    return fails


def _interval(row: dict, metric: str) -> tuple[float, float] | None:
    """The baseline's interval of ``metric`` (``<metric>_lo``, ``<metric>_hi``) where it has a finite one."""
    try:
        lo, hi = float(row[f"{metric}_lo"]), float(row[f"{metric}_hi"])
    except (KeyError, TypeError, ValueError):
        return None
    return (lo, hi) if math.isfinite(lo) and math.isfinite(hi) else None


def run_check(
    path: str | Path = "configs/check.toml",
    *,
    update: bool = False,
    cache: str | Path | None = ".cache",
    backend: str = "numpy",
) -> tuple[list[Failure], list[str]]:
    """Returns (failures, report lines). With ``update`` the baseline is rewritten and failures are empty."""
    cfg, sweep_path, base_dir = load_check(path)
    if not update:  # a missing or malformed baseline stops before the sweep runs
        if not (base_dir / "results.csv").is_file():
            raise StudyError(
                "no baseline yet; create it with `study check --update`", file=str(base_dir / "results.csv")
            )
        base = read_table(base_dir / "results.csv", numeric=list(cfg.tolerance))
        check_baseline(base, list(cfg.tolerance), base_dir / "results.csv")
    with tempfile.TemporaryDirectory(prefix="study-check-") as tmp:
        rows, stats = run_sweep(sweep_path, Path(tmp) / "run", backend=backend, cache=cache)
        meta = json.loads((Path(tmp) / "run" / "metadata.json").read_text())
    lines = [f"check: {stats['cases']} cases × {len(meta['methods'])} methods in {stats['seconds']:.1f} s"]
    if update:  # never a baseline that the next check would refuse
        for r in read_csv_rows(rows):
            bad = next((m for m in cfg.tolerance if isinstance(r.get(m), float) and math.isinf(r[m])), None)
            if bad:
                raise StudyError(
                    f"the check sweep's {bad} of {r['label']} in {r['case']} is {r[bad]}, which no baseline "
                    "can hold (its tolerance would be infinite); baseline not written",
                    file=str(path),
                    key=f"tolerance.{bad}",
                )
        write_set(
            base_dir,
            {
                "results.csv": to_csv(without_timing(rows)),  # timing is not a regression
                "metadata.json": json.dumps(meta, indent=2),
            },
        )
        lines.append(f"baseline written: {base_dir / 'results.csv'} ({len(rows)} rows)")
        return [], lines
    parsed = read_csv_rows(rows)
    fails = compare(parsed, base, cfg.tolerance)
    verdicts = {c.id: (c, v) for c, v in claim_registry.judge_claims(parsed)}
    for cid in cfg.claims:
        if cid not in verdicts:
            fails.append(Failure(f"claim {cid}: the check sweep has no rows it applies to"))
            continue
        c, v = verdicts[cid]
        lines.append(f"claim {cid}: {'✓' if v.ok else '✗'} {v.number}")
        if not v.ok:
            fails.append(Failure(f"claim {cid} ({c.text}) does not hold: {v.number}"))
    lines.append(
        f"{len(parsed)} rows × {len(cfg.tolerance)} metrics compared with {base_dir / 'results.csv'}"
    )
    return fails, lines


def read_table(
    path: str | Path, *, required: tuple[str, ...] = ("case", "label"), numeric: list[str] = ()
) -> list[dict]:
    """A results table (:func:`study.tables.read_csv`) that must be well formed: UTF-8 CSV with a header of
    distinct names without control characters, no NUL byte in any cell, every row as long as the header, the
    ``required`` columns, and numbers (or empty cells) in the ``numeric`` columns it has. Anything else is one
    StudyError naming the file and the first offending cell (bad input, exit 2)."""
    path = Path(path)
    try:
        data = path.read_bytes()
        text = data.decode("utf-8")
        raw = list(csv.reader(io.StringIO(text, newline="")))
    except UnicodeDecodeError as err:
        line = data[: err.start].count(b"\n") + 1
        raise StudyError(
            f"not UTF-8 text, expected a results table (CSV): line {line} holds byte 0x{data[err.start]:02x}",
            file=str(path),
        ) from None
    except IsADirectoryError:
        raise StudyError("is a directory, expected a results table (CSV)", file=str(path)) from None
    except csv.Error as err:
        raise StudyError(f"malformed CSV ({err})", file=str(path)) from None
    except OSError as err:
        raise os_problem(err, "cannot read the results table", path) from None
    header = raw[0] if raw else []
    for j, name in enumerate(header):
        if _CONTROL.search(name) or not name:
            raise StudyError(
                f"malformed results table: line 1, column {j + 1} of the header is {name[:40]!r}, "
                "not a column name (empty, or with a NUL or control character)",
                file=str(path),
            )
        if name in header[:j]:
            raise StudyError(
                f"malformed results table: line 1, column {j + 1}: {name!r} is already column "
                f"{header.index(name) + 1}",
                file=str(path),
            )
    missing = [c for c in required if c not in header]
    if missing:
        raise StudyError(
            f"malformed results table: no column {missing[0]!r} (header: {','.join(header)[:60] or 'empty'})",
            file=str(path),
        )
    for i, cells in enumerate(raw[1:]):
        if cells and len(cells) != len(header):
            raise StudyError(
                f"malformed results table: line {i + 2} has {len(cells)} cells, the header {len(header)}",
                file=str(path),
            )
        nul = next((j for j, c in enumerate(cells) if "\0" in c), None)
        if nul is not None:
            raise StudyError(
                f"malformed results table: line {i + 2}, column {header[nul]!r} holds a NUL byte",
                file=str(path),
            )
    rows = read_csv(path)
    for i, r in enumerate(rows):
        bad = next((c for c in numeric if c in r and not isinstance(r[c], float)), None)
        if bad:
            raise StudyError(
                f"malformed results table: line {i + 2}, column {bad!r} holds {str(r[bad])[:20]!r}, "
                "not a number",
                file=str(path),
            )
    if not rows:
        raise StudyError("malformed results table: no rows", file=str(path))
    return rows


#: Characters no column name holds: NUL and the other C0 controls, DEL.
_CONTROL = re.compile(r"[\x00-\x1f\x7f]")


def check_baseline(rows: list[dict], metrics: list[str], path: str | Path) -> None:
    """A baseline's rows as :func:`compare` needs them: one row per (case, label), and every compared metric a
    finite number or empty (NaN): an infinite baseline would make its tolerance infinite too. Else one
    StudyError naming the first offending cell (bad input, exit 2)."""
    first = {}
    for i, r in enumerate(rows):
        k = (r["case"], r["label"])
        if k in first:
            raise StudyError(
                f"malformed baseline: line {i + 2} repeats case {k[0]!r}, label {k[1]!r} of line {first[k]}; "
                "each (case, label) once",
                file=str(path),
            )
        first[k] = i + 2
        bad = next((m for m in metrics if isinstance(r.get(m), float) and math.isinf(r[m])), None)
        if bad:
            raise StudyError(
                f"malformed baseline: line {i + 2}, column {bad!r} (case {k[0]!r}, label {k[1]!r}) holds "
                f"{r[bad]}; a compared metric is a finite number or empty",
                file=str(path),
            )


def read_csv_rows(rows: list[dict]) -> list[dict]:
    """Rows as they read back from CSV (so in-memory and baseline values compare alike)."""
    with tempfile.TemporaryDirectory() as tmp:
        write_csv(rows, Path(tmp) / "r.csv")
        return read_csv(Path(tmp) / "r.csv")
