"""The time estimate's seconds per unit (:mod:`study.harness.estimate`) fitted to real runs: every figure's and
sweep's last run under a reports folder, one table per backend.

A figure's ``reports/NAME/metadata.json`` and a sweep's ``reports/sweep-STEM/metadata.json`` hold the run's
``backend``, ``cpus``, ``seconds`` and ``time_split`` (seconds per stage of :data:`study.progress.CASE_PARTS`,
summed over the cases it ran; a sweep's over the cases it ``computed``, core seconds). Each run's units are
recomputed over those cases with :func:`study.harness.estimate.units`, as the estimate counts them (its config
must be unchanged: its ``config_sha256``), and each stage's rate is

    seconds per unit = Σ seconds / Σ units  over the backend's runs

the least-squares fit of ``seconds = rate × units`` with each run's variance proportional to its units (a ratio
estimator): a total, so the long runs, which make most of a reproduce's time, weigh most, and a stage's rate
times all the units gives back all the seconds measured. By stage:

- inputs, exact, traces: every run.
- renders, probes: the runs that rendered (seconds per unit at least ``estimate.RENDERED`` of the median run's
  of the backend; a run that found its impostors in the cache read them in a small fraction of that and says
  nothing of the cost of rendering, since the units are counted as if nothing were cached; the median, not the
  highest: one scene whose renders the units undercount, fig_glossy's rough truth at 10× the others' seconds
  per unit, would otherwise leave only itself).
- columns: figures (with their pixel intervals), two rates, one per pixel × method (``columns``) and one per
  method row (``columns_method``): their least-squares fit to the figures' columns seconds, both ≥ 0 (one alone,
  the ratio above, where the other comes out negative or one figure is all there is; measured: a figure's columns
  follow its method rows more than its pixels, an upper bound). ``sweep_share`` from the sweeps' columns seconds
  over their columns units at those rates, or, where the sweeps' metadata holds no time split (written before it
  did), from their case files' ``case_seconds`` less the other stages at the fitted rates.
- case (fixed seconds per case): the figures' seconds and outputs beyond their stages, per case.

A stage no run measured keeps the base table's rate (numpy's where the backend has none) and is listed as kept.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from study.harness import estimate, provenance
from study.progress import CASE_PARTS

_FIT = "sum of seconds / sum of units per stage over the runs (least squares, variance ∝ units)"


def _summed(scenes, methods, *, intervals: bool) -> dict[str, float]:
    """Units of the cases in order, each impostor rendered by its first case (nothing cached before)."""
    from study.impostor.capture import impostor_key

    total: dict[str, float] = {}
    seen: set[str] = set()
    for sc in scenes:
        k = impostor_key(sc)
        n = estimate.units(sc, methods, rendered=k not in seen, intervals=intervals)
        seen.add(k)
        for stage, v in n.items():
            total[stage] = total.get(stage, 0.0) + v
    return total


def _device(meta: dict) -> str:
    """``GPU, N cores`` or ``CPU, N cores`` of a run's metadata."""
    dev = meta.get("device") if isinstance(meta.get("device"), dict) else {}
    return f"{dev.get('gpu') or dev.get('cpu') or meta.get('machine', '?')}, {meta.get('cpus', '?')} cores"


def run_of(meta_path: Path, repo: Path = estimate.REPO) -> dict | None:
    """One run: {command, kind, backend, cpus, commit, cases, seconds, split, units}; None where its metadata
    holds no time split, names no config of ``repo`` or a config since changed."""
    from study.harness.config import load_figure_config, quality_overrides
    from study.harness.sweep import load_sweep

    meta = estimate.read_meta(meta_path)
    if not meta or not isinstance(meta.get("time_split"), dict) or "config" not in meta:
        return None
    config = repo / str(meta["config"])
    if not config.is_file() or meta.get("config_sha256") != provenance.config_sha(config):
        return None
    backend = str(meta.get("backend", "numpy"))
    if "figure" in meta:
        cfg, scene, methods = load_figure_config(config)
        preset = quality_overrides(str(meta.get("quality", "preview")))
        scenes = [scene.with_updates({**over, **preset}) for _, _, over in cfg.case_list()]
        units, kind = _summed(scenes, methods, intervals=True), "figure"
    elif "computed_cases" in meta:
        sw = load_sweep(config, backend=backend)
        ran = set(meta["computed_cases"])
        scenes = [c.scene for c in sw.cases if c.id in ran]
        units, kind = _summed(scenes, sw.methods, intervals=False), "sweep"
    else:
        return None
    return {
        "command": str(meta.get("command", meta_path.parent.name)),
        "kind": kind,
        "backend": backend,
        "cpus": meta.get("cpus"),
        "device": _device(meta),
        "commit": str(meta.get("git_commit") or "?")[:7],
        "cases": len(scenes),
        "seconds": float(meta.get("seconds", 0.0)),
        "split": {k: float(v) for k, v in meta["time_split"].items()},
        "units": units,
    }


def case_totals(sweep_dir: Path, repo: Path = estimate.REPO) -> list[dict]:
    """A sweep's case files that match its config today (their key): one {backend, seconds (the case's wall
    time in its worker), units} per case, units counted in the sweep's order (the first case of an impostor
    renders it)."""
    from study.harness.sweep import load_sweep
    from study.impostor.capture import impostor_key

    meta = estimate.read_meta(sweep_dir / "metadata.json")
    config = repo / str((meta or {}).get("config", ""))
    if not meta or not config.is_file():
        return []
    found: dict[str, dict[str, float]] = {}  # backend → key → seconds
    for f in sorted((sweep_dir / "cases").glob("*.json")):
        data = estimate.read_meta(f)
        rows = (data or {}).get("rows") or []
        if rows and isinstance(rows[0], dict) and "case_seconds" in rows[0]:
            b = str(rows[0].get("backend", "numpy"))
            found.setdefault(b, {})[str(data.get("key"))] = float(rows[0]["case_seconds"])
    out = []
    for b, keys in found.items():
        sw = load_sweep(config, backend=b)
        cases = [c for c in sw.cases if c.key in keys]
        seen: set[str] = set()
        for c in cases:
            k = impostor_key(c.scene)
            n = estimate.units(c.scene, sw.methods, rendered=k not in seen, intervals=False)
            seen.add(k)
            out.append({"backend": b, "seconds": keys[c.key], "units": n, "command": sweep_dir.name})
    return out


def collect(reports: Path, repo: Path = estimate.REPO) -> tuple[list[dict], list[dict]]:
    """(runs with a time split, sweep cases without one) under ``reports``: ``*/metadata.json`` (figures) and
    ``sweep-*/metadata.json`` (sweeps); a sweep whose metadata has no time split gives its case files."""
    runs, totals = [], []
    for meta in sorted(Path(reports).glob("*/metadata.json")):
        run = run_of(meta, repo)
        if run:
            runs.append(run)
        elif meta.parent.name.startswith("sweep-"):
            totals += case_totals(meta.parent, repo)
    return runs, totals


def _columns(figs: list[tuple[float, float, float]]) -> tuple[float, float]:
    """(per pixel × method, per method row) seconds: the least-squares fit to (pixel units, row units, seconds)
    per figure, both ≥ 0 (a negative one set to 0 and the other the ratio of the sums)."""
    p, m, s = (np.array(v, float) for v in zip(*figs, strict=True))
    if len(figs) >= 2:
        (a, b), *_ = np.linalg.lstsq(np.stack([p, m], axis=1), s, rcond=None)
        if a >= 0 and b >= 0:
            return float(a), float(b)
        if a < 0 and m.sum() > 0:
            return 0.0, float(s.sum() / m.sum())
    return float(s.sum() / max(p.sum(), 1e-300)), 0.0


def fit(runs: list[dict], totals: list[dict], backend: str, base: dict[str, float]) -> dict:
    """The table of ``backend`` from its ``runs`` and sweep ``totals`` (:func:`collect`) over ``base``
    (seconds per unit, the module docstring's fit); its ``seconds_per_unit``, ``kept`` (stages no run measured),
    and the seconds and units summed."""
    runs = [r for r in runs if r["backend"] == backend]
    totals = [t for t in totals if t["backend"] == backend]
    sec = dict.fromkeys([*CASE_PARTS, "sweep_columns", "case"], 0.0)
    units = dict.fromkeys(sec, 0.0)
    mid = {k: float(np.median([r["split"].get(k, 0.0) / r["units"][k] for r in runs if r["units"][k] > 0] or [0]))
           for k in ("renders", "probes")}  # fmt: skip
    for r in runs:
        s, n = r["split"], r["units"]
        for stage in ("inputs", "exact", "traces"):
            sec[stage] += s.get(stage, 0.0)
            units[stage] += n[stage]
        for stage in ("renders", "probes"):
            if n[stage] > 0 and s.get(stage, 0.0) >= estimate.RENDERED * n[stage] * mid[stage]:
                sec[stage] += s.get(stage, 0.0)
                units[stage] += n[stage]
        if r["kind"] == "figure":
            sec["columns"] += s.get("columns", 0.0)
            units["columns"] += n["columns"]
            sec["case"] += r["seconds"] + s.get("outputs", 0.0) - sum(s.get(k, 0.0) for k in CASE_PARTS)
            units["case"] += r["cases"]
        else:
            sec["sweep_columns"] += s.get("columns", 0.0)
    rate, kept = dict(base), []
    for stage in (*CASE_PARTS, "case"):
        if units[stage] > 0:
            rate[stage] = max(sec[stage], 0.0) / units[stage]
        else:
            kept.append(stage)
    figs = [(r["units"]["columns"], r["units"]["columns_method"], r["split"].get("columns", 0.0))
            for r in runs if r["kind"] == "figure"]  # fmt: skip
    if figs:
        rate["columns"], rate["columns_method"] = _columns(figs)

    def cols(n: dict) -> float:  # a case's columns seconds at the fitted rates, before the sweep's share
        return n["columns"] * rate["columns"] + n["columns_method"] * rate["columns_method"]

    sweeps = [r for r in runs if r["kind"] == "sweep"]
    units["sweep_columns"] = sum(cols(r["units"]) for r in sweeps)  # in seconds at the figures' rates
    if units["sweep_columns"] > 0:
        rate["sweep_share"] = sec["sweep_columns"] / units["sweep_columns"]
    elif totals:  # the cases' wall times less their other stages at the fitted rates
        rest = sum(t["seconds"] - rate["case"] - sum(t["units"][k] * rate[k] for k in CASE_PARTS[:-1])
                   for t in totals)  # fmt: skip
        units["sweep_columns"], sec["sweep_columns"] = sum(cols(t["units"]) for t in totals), max(rest, 0.0)
        if units["sweep_columns"] > 0:
            rate["sweep_share"] = sec["sweep_columns"] / units["sweep_columns"]
    else:
        kept.append("sweep_share")
    return {
        "seconds_per_unit": {k: float(f"{v:.4g}") for k, v in rate.items()},
        "kept": kept,
        "measured_seconds": {k: round(v, 3) for k, v in sec.items()},
        "units": units,
    }


def fitted_table(reports: Path, backend: str, *, made_by: str = "", repo: Path = estimate.REPO,
                 collected: tuple[list[dict], list[dict]] | None = None) -> dict | None:  # fmt: skip
    """The ``backend`` table fitted to the runs under ``reports`` (:func:`fit` over the backend's table today,
    numpy's where it has none), with the machine, the commit and the runs it came from; None where no run of
    ``backend`` is there. ``collected``: what :func:`collect` gave for ``reports`` (not read again)."""
    import platform
    import subprocess

    runs, totals = collected or collect(reports, repo)
    mine = [r for r in runs if r["backend"] == backend]
    theirs = [t for t in totals if t["backend"] == backend]
    if not mine and not theirs:
        return None
    got = fit(runs, totals, backend, estimate.table_for(backend)[0])
    machines = sorted({r["device"] for r in mine}) or [f"{platform.machine()}: sweeps' case files"]
    try:
        commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True,
                                cwd=repo, check=True).stdout.strip()  # fmt: skip
    except (OSError, subprocess.CalledProcessError):
        commit = "unknown"
    return {
        "made_by": made_by,
        "machine": "; ".join(machines),
        "backend": backend,
        "commit": commit,
        "fit": _FIT,
        "runs": [{k: r[k] for k in ("command", "commit", "cpus", "cases", "seconds")} for r in mine]
        + [
            {"command": f"{n} (case files: case_seconds)", "cases": sum(t["command"] == n for t in theirs)}
            for n in sorted({t["command"] for t in theirs})
        ],  # fmt: skip
        **got,
    }


def write(path: Path, backend: str, tab: dict) -> None:
    """Put ``tab`` as ``backend``'s table into ``path`` (``{"backends": {...}}``; an older single table is kept
    as its backend's)."""
    tables = estimate.tables_in(path)
    tables[backend] = tab
    Path(path).write_text(json.dumps({"backends": dict(sorted(tables.items()))}, indent=2) + "\n")
