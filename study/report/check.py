"""CI regression on error metrics: run a small fixed sweep, compare every metric with a committed baseline that
knows each metric's seed-to-seed noise (docs/check.md).

The check file (``configs/check.toml``) names the sweep, the baseline directory, the paper's claims that must hold
(:mod:`study.report.claims`), the baseline's ``seeds`` (at least 3), ``k`` and a floor per compared metric.
``update=True`` (``study check --update``) runs the sweep once per seed and writes the baseline as one output set:
``results.csv`` (the first seed's table: what the report shows and what a check at that seed replays),
``spread.csv`` (per (case, label) and metric the mean over the seeds, ``<metric>``, and their sample standard
deviation, ``<metric>_sd``) and ``metadata.json`` (the seeds, the backend).

A check runs the sweep once (its own seed, or ``seed``). At the baseline's first seed (the sweep's own, so what CI
runs) the references' Monte Carlo noise is replayed: every metric is compared with that seed's own value in
``results.csv`` within its floor alone, ``|new − value| ≤ abs + rel · |value|``, so a 3 % radiance change in one
method shows (issue 53; ``radiance_bias_truth``, signed, tells its sign and size). At any other seed a metric passes
when

    |new − mean| ≤ k · sd + abs + rel · |mean|          (NaN equals NaN)

with sd the row's own, or the metric's pooled sd where that is larger (:func:`pooled_relative_sd`: relative to
the mean, or absolute for a signed metric; a few seeds of a heavy-tailed image metric can underestimate one
row's). The floor (``abs``, ``rel``) is for what the seed does not move (the geometric metrics: Embree's hits and
the methods' searches are exactly deterministic, sd = 0): it covers the rounding a platform may change, bounded by
the difference between the numpy and Dr.Jit LLVM backends (both float32, their operations in another order) on the
same sweep (configs/check.toml states the measured numbers). On another backend than the baseline's, a
backend-sensitive column (:data:`study.columns.BACKEND_SENSITIVE`) gets at least its stated floor
(:func:`backend_floor`). Rows are matched by (case, label); a row missing on either side is a failure.

The baseline is checked as a whole before the sweep runs (:func:`read_baseline_set`, :func:`check_baseline`): a
malformed one is bad input (a StudyError naming the file and its first offending cell, exit 2: not UTF-8, a NUL
byte, a column or a (case, label) twice, an infinite compared metric, a negative value of a metric ≥ 0, a
negative, infinite or impossible spread — more than its seeds could give, or far beyond its metric's other
rows), never a regression (exit 1) nor a pass.
"""

from __future__ import annotations

import csv
import difflib
import io
import json
import math
import re
import statistics
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

from pydantic import BaseModel, ConfigDict, Field

from study import columns
from study.codehash import code_hash
from study.errors import StudyError, os_problem
from study.harness.runner import prepare_sweep, run_sweep
from study.harness.sweep import case_key
from study.io import write_set
from study.measure.case import run_case
from study.report import claims as claim_registry
from study.scene.schema import MAX_SEED, Float
from study.tables import read_csv, to_csv, without_timing, write_csv
from study.validation import validate_file

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


class CheckConfig(BaseModel):
    model_config = ConfigDict(extra="forbid")
    sweep: str
    baseline: str
    claims: list[str] = []
    seeds: list[int] = Field([0, 1, 2, 3, 4], min_length=3)  # the baseline's: mean and sd over them
    k: Float = Field(5.0, gt=0)  # a value passes within k sd of the baseline's mean (+ its floor)
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
    for i, s in enumerate(cfg.seeds):
        if not 0 <= s <= MAX_SEED or s in cfg.seeds[:i]:
            raise StudyError(
                f"{s} is {'a seed twice' if s in cfg.seeds[:i] else 'out of range'}; "
                f"seeds are distinct integers in 0..{MAX_SEED}",
                file=str(path),
                key=f"seeds[{i}]",
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


def compare(
    new: list[dict],
    base: list[dict],
    tolerance: dict[str, Tolerance],
    k: float = 5.0,
    *,
    other_backend: bool = False,
    what: str = "",
) -> list[Failure]:
    """Failures of ``new`` against the baseline's ``base`` rows: per metric its mean (``<metric>``) and its
    spread (the row's seed-to-seed sd, ``<metric>_sd``, or the metric's pooled sd, :func:`pooled_relative_sd`,
    whichever is larger; none: 0, the floor alone: a replayed seed's own values). ``other_backend``: ``new`` was
    made on another backend than the baseline, so a backend-sensitive column (:data:`study.columns.TABLE`) gets at
    least its stated floor (:func:`backend_floor`). ``what`` names the baseline in the messages."""
    fails = []
    index = {(r["case"], r["label"]): r for r in base}
    pooled = {m: pooled_relative_sd(base, m, tol.pool) for m, tol in tolerance.items()}
    seen = set()
    for r in new:
        key = (r["case"], r["label"])
        b = index.get(key)
        if b is None:
            fails.append(Failure(f"{key[1]} in {key[0]}: not in the baseline (run `study check --update`?)"))
            continue
        seen.add(key)
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
                fails.append(Failure(f"{metric} of {key[1]} in {key[0]} moved from {y:g} to {x:.6g}"))
                continue
            sd = max(spread_of(b, metric), pooled[metric] * (abs(y) if tol.pool == "relative" else 1.0))
            floor = tol.abs + tol.rel * abs(y)
            if other_backend:
                floor = max(floor, backend_floor(metric, r))
            if abs(x - y) <= k * sd + floor:
                continue
            fails.append(
                Failure(
                    f"{metric} of {key[1]} in {key[0]} moved from {y:.6g}{what} to {x:.6g} (by {x - y:+.3g}"
                    + (f" = {(x - y) / sd:+.1f} sd" if sd > 0 else "")
                    + (
                        f"; tolerance ±{k * sd + floor:.3g} = {k:g} × sd {sd:.3g} + floor {floor:.3g})"
                        if sd > 0
                        else f"; tolerance ±{floor:.3g}, its floor)"
                    )
                )
            )
    for key in index.keys() - seen:
        fails.append(Failure(f"{key[1]} in {key[0]}: in the baseline but not in the results"))
    return fails


#: The stated floor of a backend-sensitive column (issue 55) when the check runs on another backend than its
#: baseline's: angles BACKEND_FLOOR_TEXELS of the cube texel's angle at a face's centre (2 / cube_res rad), distances
#: the same share of a texel's width 1 m from o, lookups per ray BACKEND_FLOOR_LOOKUPS. Two float32 backends differ
#: in these statistics by far less than a texel (issue 55: up to 12 % of near-zero percentiles between CUDA and the
#: CPU with the same captures), while what the plants move (one search iteration, a shown point one texel off)
#: moves them by a good share of one.
BACKEND_FLOOR_TEXELS = 0.02
BACKEND_FLOOR_LOOKUPS = 0.05


def backend_floor(metric: str, row: dict) -> float:
    """The stated floor of ``metric`` in a results ``row`` made on another backend than the baseline's
    (:data:`BACKEND_FLOOR_TEXELS`, :data:`BACKEND_FLOOR_LOOKUPS`); 0 for a column that is not backend-sensitive.

    Parameters
    ----------
    metric : str
        A declared column (:mod:`study.columns`).
    row : dict
        The new results row (its ``cube_res`` sets the texel).

    Returns
    -------
    float
        The floor in the column's unit (deg, m or lookups).
    """
    col = columns.declared(metric)
    if col is None or not col.backend_sensitive:
        return 0.0
    if col.unit == "lookups":
        return BACKEND_FLOOR_LOOKUPS
    res = row.get("cube_res")
    if not isinstance(res, (int, float)) or not math.isfinite(res) or res <= 0:
        return 0.0
    texel = 2.0 / float(res)  # radians at a face's centre; metres at 1 m from o
    return BACKEND_FLOOR_TEXELS * (math.degrees(texel) if col.unit == "deg" else texel)


def spread_of(row: dict, metric: str) -> float:
    """The baseline's seed-to-seed sd of ``metric`` in ``row`` (``<metric>_sd``); 0 where it has none."""
    sd = row.get(f"{metric}_sd")
    return sd if isinstance(sd, float) and math.isfinite(sd) else 0.0


#: How far one row's seed-to-seed spread (relative to its mean, or absolute: :attr:`Tolerance.pool`) may lie above
#: the median of its metric's rows in a baseline, and the most the pooled spread may be. A few seeds of a row
#: scatter its sd: with the 3 seeds a baseline needs at least, the largest of 68 rows' sample sds comes out about
#: 4 × their median when all share one σ (χ² with 2 degrees of freedom), and the rows of the committed baseline
#: differ by up to 6.2 × (rmse_oracle, 5 seeds). A row beyond 25 × is no spread the seeds gave: a forged or broken
#: baseline (issue 51: one row's sd of 1e6 widened every row's tolerance through the pooled sd).
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


def _run_at(sweep_path: Path, seed: int | None, *, backend: str, cache) -> tuple[list[dict], dict, dict]:
    """The check's sweep run once (in a temporary directory), at ``seed`` (None: the sweep's own)."""
    sweep = prepare_sweep(sweep_path, backend=backend)
    if seed is not None:  # every case at this seed: a new scene, so a new content key
        code = code_hash(run_case, *[type(m) for m in sweep.methods])
        for c in sweep.cases:
            c.scene = c.scene.with_updates({"render.seed": seed}, source="study check --seed")
            c.key = case_key(c.scene, sweep.methods, backend, code=code)
    with tempfile.TemporaryDirectory(prefix="study-check-") as tmp:
        rows, stats = run_sweep(sweep_path, Path(tmp) / "run", backend=backend, cache=cache, prepared=sweep)
        meta = json.loads((Path(tmp) / "run" / "metadata.json").read_text())
    return rows, stats, meta


def run_check(
    path: str | Path = "configs/check.toml",
    *,
    update: bool = False,
    cache: str | Path | None = ".cache",
    backend: str = "numpy",
    seed: int | None = None,
) -> tuple[list[Failure], list[str]]:
    """Returns (failures, report lines). With ``update`` the baseline is rewritten from the check file's seeds
    and failures are empty; else the sweep runs once, at ``seed`` (None: the sweep's own)."""
    cfg, sweep_path, base_dir = load_check(path)
    metrics = list(cfg.tolerance)
    if update and seed is not None:
        raise StudyError(
            f"--seed {seed} with --update: the baseline is written at the check file's seeds "
            f"({', '.join(map(str, cfg.seeds))})",
            file=str(path),
            key="seeds",
        )
    if update:
        return [], _update(cfg, Path(path), sweep_path, base_dir, backend=backend, cache=cache)
    base, replay, meta0 = read_baseline_set(base_dir, cfg)  # a missing or malformed one: before the sweep
    rows, stats, meta = _run_at(sweep_path, seed, backend=backend, cache=cache)
    lines = [
        f"check: {stats['cases']} cases × {len(meta['methods'])} methods at seed {meta['seed']} "
        f"in {stats['seconds']:.1f} s"
    ]
    parsed = read_csv_rows(rows)
    other = meta0.get("backend") != backend
    if meta["seed"] == meta0["seeds"][0]:  # the baseline's own seed: its noise replayed, so the floor alone
        fails = compare(parsed, replay, cfg.tolerance, cfg.k, other_backend=other, what=" (the baseline's)")
        lines.append(
            f"{len(parsed)} rows × {len(metrics)} metrics replayed against the baseline's seed {meta['seed']} "
            f"({base_dir / 'results.csv'}: within each metric's floor"
            + (
                f"; backend-sensitive columns within their stated floor, {meta0.get('backend')} → {backend})"
                if other
                else ")"
            )
        )
    else:
        fails = compare(parsed, base, cfg.tolerance, cfg.k, other_backend=other)
        lines.append(
            f"{len(parsed)} rows × {len(metrics)} metrics compared with {base_dir / SPREAD} "
            f"(a new seed: within {cfg.k:g} sd over {int(base[0].get('seeds', 0))} seeds + floor)"
        )
    verdicts = {c.id: (c, v) for c, v in claim_registry.judge_claims(parsed)}
    for cid in cfg.claims:
        if cid not in verdicts:
            fails.append(Failure(f"claim {cid}: the check sweep has no rows it applies to"))
            continue
        c, v = verdicts[cid]
        lines.append(f"claim {cid}: {'✓' if v.ok else '✗'} {v.number}")
        if not v.ok:
            fails.append(Failure(f"claim {cid} ({c.text}) does not hold: {v.number}"))
    return fails, lines


def read_baseline_set(base_dir: Path, cfg: CheckConfig) -> tuple[list[dict], list[dict], dict]:
    """The baseline as a whole, checked before anything runs: its spread table (:func:`read_baseline`), the first
    seed's results table that a check at that seed replays (the same checks, without spreads) and its metadata
    (the seeds it was made at, the backend). Each problem is one StudyError naming the file (bad input, exit 2)."""
    metrics = list(cfg.tolerance)
    base = read_baseline(base_dir / SPREAD, metrics, tolerance=cfg.tolerance, k=cfg.k)
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


def _update(cfg: CheckConfig, path: Path, sweep_path: Path, base_dir: Path, *, backend, cache) -> list[str]:
    """The baseline rewritten: the sweep at each of the check file's seeds → results.csv, spread.csv, metadata."""
    runs, lines, first = [], [], None
    for s in cfg.seeds:
        rows, stats, meta = _run_at(sweep_path, s, backend=backend, cache=cache)
        first = first or (rows, meta)
        runs.append(read_csv_rows(rows))
        lines.append(
            f"seed {s}: {stats['cases']} cases × {len(meta['methods'])} methods in {stats['seconds']:.1f} s"
        )
    for run in runs:  # never a baseline that the next check would refuse
        for r in run:
            bad = next((m for m in cfg.tolerance if isinstance(r.get(m), float) and math.isinf(r[m])), None)
            if bad:
                raise StudyError(
                    f"the check sweep's {bad} of {r['label']} in {r['case']} is {r[bad]}, which no baseline "
                    "can hold (its tolerance would be infinite); baseline not written",
                    file=str(path),
                    key=f"tolerance.{bad}",
                )
    spread = spread_table(runs, list(cfg.tolerance), cfg.seeds, str(path))
    check_baseline(spread, list(cfg.tolerance), base_dir / SPREAD, tolerance=cfg.tolerance, k=cfg.k)
    meta = {**first[1], "seeds": cfg.seeds, "k": cfg.k}
    write_set(
        base_dir,
        {
            "results.csv": to_csv(without_timing(first[0])),  # timing is not a regression
            SPREAD: spread_csv(spread, list(cfg.tolerance)),
            "metadata.json": json.dumps(meta, indent=2),
        },
    )
    lines.append(f"baseline written: {base_dir / SPREAD} ({len(spread)} rows, {len(cfg.seeds)} seeds)")
    return lines


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
    first = {}

    def refuse(i: int, col: str, what: str) -> StudyError:
        r = rows[i]
        return StudyError(
            f"malformed baseline: line {i + 2}, column {col!r} (case {r['case']!r}, label {r['label']!r}) {what}",
            file=str(path),
        )

    for i, r in enumerate(rows):
        key = (r["case"], r["label"])
        if key in first:
            raise StudyError(
                f"malformed baseline: line {i + 2} repeats case {key[0]!r}, label {key[1]!r} of line "
                f"{first[key]}; each (case, label) once",
                file=str(path),
            )
        first[key] = i + 2
        bad = next((m for m in metrics if isinstance(r.get(m), float) and math.isinf(r[m])), None)
        if bad:
            raise refuse(i, bad, f"holds {r[bad]}; a compared metric is a finite number or empty")
        neg = next((m for m in metrics if _nonnegative(m) and isinstance(r.get(m), float) and r[m] < 0), None)
        if neg:
            raise refuse(i, neg, f"holds {r[neg]:g}; {neg} ({columns.declared(neg).unit}) is never negative")
        sd = next((f"{m}_sd" for m in metrics if _bad_spread(r.get(f"{m}_sd"))), None)
        if sd:
            raise refuse(i, sd, f"holds {r[sd]}; a seed-to-seed sd is a finite number ≥ 0 or empty")
        spreads = [m for m in metrics if isinstance(r.get(f"{m}_sd"), float) and not math.isnan(r[f"{m}_sd"])]
        if not spreads:
            continue
        n = r.get("seeds")
        if not isinstance(n, (int, float)) or not float(n).is_integer() or not 2 <= n <= 10**6:
            raise refuse(i, "seeds", f"holds {n!r}; the number of seeds the spreads are over, an integer ≥ 2")
        for m in spreads:
            mean, s = r.get(m), r[f"{m}_sd"]
            if _nonnegative(m) and isinstance(mean, float) and s > abs(mean) * math.sqrt(n) * (1 + 1e-9):
                raise refuse(
                    i,
                    f"{m}_sd",
                    f"holds {s:.4g}, more than {int(n)} seeds of a metric ≥ 0 with mean {mean:.4g} can spread "
                    f"(at most mean × √{int(n)} = {abs(mean) * math.sqrt(n):.4g})",
                )
    for m in metrics:
        pool = tolerance[m].pool if m in tolerance else "relative"
        scaled = _scaled_spreads(rows, m, pool)
        typical = statistics.median([v for _, v in scaled]) if scaled else 0.0
        over = next(((i, v) for i, v in scaled if typical > 0 and v > SPREAD_RATIO_MAX * typical), None)
        if over:
            i, v = over
            unit = "sd / |mean|" if pool == "relative" else "sd"
            raise refuse(
                i,
                f"{m}_sd",
                f"holds {rows[i][f'{m}_sd']:.4g}, whose {unit} {v:.4g} is {v / typical:.3g} × the median of "
                f"{m}'s {len(scaled)} rows ({typical:.4g}); seeds scatter a row's sd by far less: at most "
                f"{SPREAD_RATIO_MAX:g} ×",
            )
        if m not in tolerance:
            continue
        pooled = pooled_relative_sd(rows, m, pool)
        for i, r in enumerate(rows):
            y = r.get(m)
            if not isinstance(y, float) or math.isnan(y):
                continue
            sd = max(spread_of(r, m), pooled * (abs(y) if pool == "relative" else 1.0))
            if not math.isfinite(k * sd + tolerance[m].abs + tolerance[m].rel * abs(y)):
                raise refuse(i, m, f"holds {y:.4g}, whose tolerance (k × sd + floor) is not a finite number")


def _nonnegative(metric: str) -> bool:
    col = columns.declared(metric)
    return col is not None and col.unit in NONNEGATIVE_UNITS and not metric.endswith(("_lo", "_hi"))


def _bad_spread(v) -> bool:
    return isinstance(v, float) and (math.isinf(v) or v < 0)


def read_csv_rows(rows: list[dict]) -> list[dict]:
    """Rows as they read back from CSV (so in-memory and baseline values compare alike)."""
    with tempfile.TemporaryDirectory() as tmp:
        write_csv(rows, Path(tmp) / "r.csv")
        return read_csv(Path(tmp) / "r.csv")
