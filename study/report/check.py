"""CI regression on error metrics: run a small fixed sweep, compare every metric with a committed baseline that
knows each metric's seed-to-seed noise (docs/check.md).

The check file (``configs/check.toml``) names the sweep, the baseline directory, the paper's claims that must hold
(:mod:`study.report.claims`), the baseline's ``seeds`` (at least 3), ``k`` and a floor per compared metric.
``update=True`` (``study check --update``) runs the sweep once per seed and writes the baseline as one output set:
``results.csv`` (the first seed's table: what the report shows and what a check at that seed replays),
``spread.csv`` (per (case, label) and metric the mean over the seeds, ``<metric>``, and their sample standard
deviation, ``<metric>_sd``) and ``metadata.json`` (the seeds, the backend).

A check runs the sweep once (its own seed, or ``seed``). At the baseline's first seed (the sweep's own, so what CI
runs) on the baseline's backend the references' Monte Carlo noise is replayed: every metric is compared with that
seed's own value in ``results.csv`` within its floor alone, ``|new − value| ≤ abs + rel · |value|``, so a 3 %
radiance change in one method shows (``radiance_bias_truth``, signed, tells its sign and size). At any other seed,
or on another backend (whose floats can pick another probe or hit for a few pixels), a metric passes when

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

import difflib
import json
import math
import tempfile
from dataclasses import dataclass
from pathlib import Path

from pydantic import BaseModel, ConfigDict, Field

from study import columns
from study.errors import StudyError
from study.harness.runner import prepare_sweep, run_sweep
from study.harness.sweep import case_code, case_key
from study.io import write_set
from study.report import claims as claim_registry
from study.report.baseline import (  # re-exported: the check's API keeps its names
    POOLED_RATIO_MAX,
    SPREAD,
    SPREAD_RATIO_MAX,
    Tolerance,
    check_baseline,
    pooled_relative_sd,
    read_baseline,
    read_baseline_set,
    read_table,
    spread_csv,
    spread_of,
    spread_table,
)
from study.report.verdicts import verdict_mark
from study.scene.schema import MAX_SEED, Float
from study.tables import read_csv, to_csv, without_timing, write_csv
from study.validation import validate_file

__all__ = [
    "POOLED_RATIO_MAX",
    "SPREAD",
    "SPREAD_RATIO_MAX",
    "CheckConfig",
    "Failure",
    "Tolerance",
    "backend_floor",
    "check_claims",
    "check_baseline",
    "compare",
    "load_check",
    "pooled_relative_sd",
    "read_baseline",
    "read_baseline_set",
    "read_table",
    "run_check",
    "spread_csv",
    "spread_of",
    "spread_table",
]


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


#: The stated floor of a backend-sensitive column when the check runs on another backend than its
#: baseline's: angles BACKEND_FLOOR_TEXELS of the cube texel's angle at a face's centre (2 / cube_res rad), distances
#: the same share of a texel's width 1 m from o, lookups per ray BACKEND_FLOOR_LOOKUPS. Two float32 backends differ
#: in these statistics by far less than a texel (up to 12 % of near-zero percentiles between CUDA and the
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


def _run_at(sweep_path: Path, seed: int | None, *, backend: str, cache) -> tuple[list[dict], dict, dict]:
    """The check's sweep run once (in a temporary directory), at ``seed`` (None: the sweep's own)."""
    sweep = prepare_sweep(sweep_path, backend=backend)
    if seed is not None:  # every case at this seed: a new scene, so a new content key
        code = case_code(sweep.methods)
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
    base, replay, meta0 = read_baseline_set(
        base_dir, cfg.tolerance, cfg.k
    )  # a missing or malformed one: before the sweep
    rows, stats, meta = _run_at(sweep_path, seed, backend=backend, cache=cache)
    lines = [
        f"check: {stats['cases']} cases × {len(meta['methods'])} methods at seed {meta['seed']} "
        f"in {stats['seconds']:.1f} s"
    ]
    parsed = read_csv_rows(rows)
    other = meta0.get("backend") != backend
    if meta["seed"] == meta0["seeds"][0] and not other:  # the baseline's own seed and floats: the floor alone
        fails = compare(parsed, replay, cfg.tolerance, cfg.k, what=" (the baseline's)")
        lines.append(
            f"{len(parsed)} rows × {len(metrics)} metrics replayed against the baseline's seed {meta['seed']} "
            f"({base_dir / 'results.csv'}: within each metric's floor)"
        )
    else:  # a new seed, or another backend's floats (a probe or hit picked apart): the seed-to-seed spread
        fails = compare(parsed, base, cfg.tolerance, cfg.k, other_backend=other)
        why = "a new seed" if not other else f"{backend}, not the baseline's {meta0.get('backend')}"
        lines.append(
            f"{len(parsed)} rows × {len(metrics)} metrics compared with {base_dir / SPREAD} "
            f"({why}: within {cfg.k:g} sd over {int(base[0].get('seeds', 0))} seeds + floor"
            + ("; backend-sensitive columns at least their stated floor)" if other else ")")
        )
    claim_fails, claim_lines = check_claims(parsed, cfg.claims)
    return fails + claim_fails, lines + claim_lines


def check_claims(rows: list[dict], ids: list[str]) -> tuple[list[Failure], list[str]]:
    """The check's claims ``ids`` judged on ``rows``: a failure only where the evidence contradicts a claim
    (``ok`` False) or no row applies; an undecided claim (the evidence decides neither way at this sample size)
    or a measured one (no threshold) is reported with its mark, never a regression."""
    fails, lines = [], []
    verdicts = {c.id: (c, v) for c, v in claim_registry.judge_claims(rows)}
    for cid in ids:
        if cid not in verdicts:
            fails.append(Failure(f"claim {cid}: the check sweep has no rows it applies to"))
            continue
        c, v = verdicts[cid]
        lines.append(f"claim {cid}: {verdict_mark(v)} {v.number}")
        if v.ok is False:
            fails.append(Failure(f"claim {cid} ({c.text}) does not hold: {v.number}"))
    return fails, lines


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


def read_csv_rows(rows: list[dict]) -> list[dict]:
    """Rows as they read back from CSV (so in-memory and baseline values compare alike)."""
    with tempfile.TemporaryDirectory() as tmp:
        write_csv(rows, Path(tmp) / "r.csv")
        return read_csv(Path(tmp) / "r.csv")
