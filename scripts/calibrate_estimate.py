"""Calibrate the time estimate (study/harness/estimate.py) on this machine, one table per backend in
study/harness/stage_costs.json, with the machine, the backend and the commit.

    PYTHONPATH=. .venv/bin/python scripts/calibrate_estimate.py --from-reports reports [--backend llvm ...]

fits each backend's seconds per unit to the figures' and sweeps' last runs under that folder (reports/*/metadata.json,
reports/sweep-*/metadata.json: their time split over the units of their cases, study.harness.estimate_fit: per
stage Σ seconds / Σ units over the backend's runs, a least-squares fit with variance ∝ units); every backend found, or
those named. The folder is only read.

    PYTHONPATH=. .venv/bin/python scripts/calibrate_estimate.py [SCENE] [--backend numpy] [--set KEY=VALUE ...]

runs one case of SCENE with every method instead, cold (an empty cache: every render and probe) and then warm (the
cache it filled), each stage's measured time divided by its units (estimate.units). The default is scenes/room.toml
at a third of its sizes (camera 128², cube 128², 16 samples), a few minutes on 2 cores; the estimate then scales
each stage's rate by its units to the command's own sizes. One small case under-weighs what long runs spend (the
traces of many methods over large frames): prefer --from-reports after a reproduce."""

from __future__ import annotations

import argparse
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

SMALL = {"camera.width": 128, "camera.height": 128, "render.cube_res": 128, "render.cube_spp": 16,
         "render.spp": 16}  # fmt: skip


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scene", nargs="?", default=str(ROOT / "scenes" / "room.toml"))
    ap.add_argument(
        "--backend", action="append", default=None, help="numpy (default) | llvm | cuda; repeatable"
    )
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE")
    ap.add_argument("--out", type=Path, default=None)
    ap.add_argument(
        "--from-reports", type=Path, default=None, metavar="DIR", help="fit to the runs under DIR"
    )
    args = ap.parse_args(argv)
    made_by = "PYTHONPATH=. .venv/bin/python scripts/calibrate_estimate.py " + " ".join(argv or sys.argv[1:])
    if args.from_reports is not None:
        return from_reports(args.from_reports, args.backend, args.out, made_by)
    args.backend = (args.backend or ["numpy"])[-1]
    from study import runtime
    from study.api import load_scene, method_list
    from study.cache import Cache
    from study.cli.run import parse_sets
    from study.harness import estimate, estimate_fit
    from study.harness.config import surface_methods
    from study.measure.case import run_case

    runtime.set_render_device("cuda" if args.backend == "cuda" else "cpu")
    scene = load_scene(Path(args.scene), {**SMALL, **parse_sets(args.set)})
    methods, _ = surface_methods(scene, method_list("all"), chosen=False, allow_mismatch=False)  # `study run`
    cache = Cache(tempfile.mkdtemp(prefix="study-calibrate-"))
    seconds, measured = {}, {}
    for run in ("cold", "warm"):
        t0 = time.perf_counter()
        case = run_case(scene, methods, backend=args.backend, cache=cache, intervals=True)
        measured[run] = {**case.times, "wall": round(time.perf_counter() - t0, 3)}
        print(f"{run}: {measured[run]}", flush=True)
    cold, warm = measured["cold"], measured["warm"]
    n = estimate.units(scene, methods, rendered=True, intervals=True)
    sweep = run_case(scene, methods, backend=args.backend, cache=cache, intervals=False, keep_images=False)
    measured["sweep"] = dict(sweep.times)
    # twice the camera's width and height (the impostor and probes cached): the columns' cost per pixel and row
    big = scene.with_updates(
        {"camera.width": 2 * scene.camera.width, "camera.height": 2 * scene.camera.height}
    )
    measured["large"] = dict(run_case(big, methods, backend=args.backend, cache=cache, intervals=True).times)
    print(f"sweep: {measured['sweep']}\nlarge: {measured['large']}", flush=True)
    n2 = estimate.units(big, methods, rendered=True, intervals=True)
    for stage in ("inputs", "exact", "traces"):  # the same work cold and warm: the faster (a shared machine)
        seconds[stage] = min(cold[stage], warm[stage]) / max(n[stage], 1.0)
    small_cols = min(cold["columns"], warm["columns"])
    per_px = (measured["large"]["columns"] - small_cols) / max(n2["columns"] - n["columns"], 1.0)
    if per_px > 0:  # a cost per pixel and a fixed one per method row
        seconds["columns"] = per_px
        seconds["columns_method"] = max(small_cols - per_px * n["columns"], 0.0) / len(methods)
    else:  # the larger frame was not slower (a busy machine): all of its cost per pixel, an upper bound
        seconds["columns"] = measured["large"]["columns"] / max(n2["columns"], 1.0)
        seconds["columns_method"] = 0.0
    seconds["sweep_share"] = min(1.0, sweep.times["columns"] / max(small_cols, 1e-9))
    for stage in ("renders", "probes"):  # what the cold run rendered beyond the warm run's reads
        seconds[stage] = max(cold[stage] - warm[stage], 0.0) / max(n[stage], 1.0)
    seconds["case"] = max(warm["wall"] - sum(warm[k] for k in estimate.CASE_PARTS), 0.0)
    try:
        commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True,
                                cwd=ROOT, check=True).stdout.strip()  # fmt: skip
    except Exception:
        commit = "unknown"
    table = {
        "made_by": made_by,
        "machine": f"{platform.machine()}, {os.cpu_count()} CPU cores, load average {os.getloadavg()[0]:.1f}",
        "backend": args.backend,
        "commit": commit,
        "scene": str(Path(args.scene).resolve().relative_to(ROOT))
        if ROOT in Path(args.scene).resolve().parents
        else args.scene,
        "units": n,
        "measured_seconds": measured,
        "seconds_per_unit": {k: float(f"{v:.4g}") for k, v in seconds.items()},
    }
    out = args.out or estimate.COSTS
    estimate_fit.write(out, args.backend, table)
    print(f"wrote {out} ({args.backend})")


def from_reports(reports: Path, backends: list[str] | None, out: Path | None, made_by: str) -> None:
    """Each backend's table fitted to the runs under ``reports`` (every backend they ran on, or ``backends``)."""
    from study.harness import estimate, estimate_fit

    out = out or estimate.COSTS
    collected = runs, totals = estimate_fit.collect(reports)
    for b in backends or sorted({r["backend"] for r in runs} | {t["backend"] for t in totals}):
        tab = estimate_fit.fitted_table(reports, b, made_by=made_by, collected=collected)
        if tab is None:
            print(f"{b}: no run under {reports}")
            continue
        estimate_fit.write(out, b, tab)
        print(f"{b}: {len(tab['runs'])} runs, kept {tab['kept'] or 'none'}: {tab['seconds_per_unit']}")
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
