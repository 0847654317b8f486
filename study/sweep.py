"""Declarative sweeps: a base scene, axes that override scene keys, the methods to compare → one tidy table.

A sweep file (TOML)::

    scene = "../scenes/room.toml"            # or an inline [scene] table
    seed = 0                                 # → render.seed (default: the scene's)
    zip = [["object.center", "columns"]]     # axes that move together (default: Cartesian product of all)

    [overrides]                              # dotted scene keys applied to the base scene first
    "render.spp" = 16

    [axes]
    "render.cube_res" = [64, 128, 256]                                   # a list of values
    "object.center" = { line = { from = [0, 1.5, 0], to = [1.5, 0.6, 1], steps = 4 } }   # points along a line
    "columns" = { named = { none = [], small = [ {center = [1, 1], footprint = [0.3, 0.3], height = 2} ] } }

    [[methods]]                              # as in figure configs; list parameters expand
    name = "localized"
    iterations = [0, 1, 3, 10]

Each case (one combination of axis values) is run by :func:`study.case.run_case` with every method; its rows get
one column per axis holding the value's label. Cases are identified by a content key (scene, methods, backend,
code version): a finished case is stored under ``<out>/cases/<key>.json`` (atomically) and never recomputed, so a
killed sweep resumes where it stopped. After each case the table ``<out>/results.csv`` is rewritten atomically from
the finished cases, in case order; ``<out>/metadata.json`` records versions, config hash, seed, git commit, backend.
One sweep at a time may write to an output directory (a lock file; a second one stops with a clear message).
"""
from __future__ import annotations

import fcntl
import hashlib
import itertools
import json
import os
import platform
import subprocess
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

from pydantic import BaseModel, ConfigDict, Field

from study.capture import _atomic_write
from study.config import base_scene, expand_methods, validate
from study.errors import StudyError
from study.methods import Method
from study.results import write_csv
from study.scene import Scene

#: Bump when a change of code changes results, so cached cases are not reused across it.
CODE_VERSION = 1


class Line(BaseModel):
    model_config = ConfigDict(extra="forbid", populate_by_name=True)
    start: tuple[float, float, float] = Field(alias="from")
    end: tuple[float, float, float] = Field(alias="to")
    steps: int = Field(ge=1, le=1000)


class Axis(BaseModel):
    model_config = ConfigDict(extra="forbid")
    values: list[Any] | None = None
    named: dict[str, Any] | None = None
    line: Line | None = None


class SweepConfig(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)
    scene: str | dict[str, Any]
    seed: int | None = Field(default=None, ge=0)
    overrides: dict[str, Any] = {}
    axes: dict[str, list[Any] | Axis] = {}
    zip: list[list[str]] = []
    methods: list[dict[str, Any]] = Field(min_length=1)


@dataclass
class Case:
    index: int
    id: str                  # c0000, c0001, … in sweep order
    scene: Scene
    labels: dict[str, str]   # axis key → value label
    key: str = ""            # content key (scene, methods, backend, code version)


@dataclass
class Sweep:
    path: Path
    config: SweepConfig
    methods: list[Method]
    cases: list[Case]
    config_hash: str


def _label(v) -> str:
    if isinstance(v, float):
        return f"{v:g}"
    if isinstance(v, (list, tuple)) and all(isinstance(x, (int, float)) for x in v):
        return "(" + ", ".join(f"{x:g}" for x in v) + ")"
    return json.dumps(v, sort_keys=True) if not isinstance(v, str) else v


def _axis_values(key: str, spec, source: str) -> list[tuple[str, Any]]:
    if isinstance(spec, list):
        vals = [(_label(v), v) for v in spec]
    elif spec.line is not None:
        a, b, n = spec.line.start, spec.line.end, spec.line.steps
        pts = [[a[i] + (b[i] - a[i]) * (k / (n - 1) if n > 1 else 0.0) for i in range(3)] for k in range(n)]
        vals = [(_label(p), p) for p in pts]
    elif spec.named is not None:
        vals = list(spec.named.items())
    elif spec.values is not None:
        vals = [(_label(v), v) for v in spec.values]
    else:
        raise StudyError("an axis needs a list, or one of values, named, line", file=source, key=f"axes.{key}")
    if not vals:
        raise StudyError("an axis needs at least one value", file=source, key=f"axes.{key}")
    return vals


def load_sweep(path: str | Path, *, backend: str = "numpy") -> Sweep:
    """Read, validate and expand a sweep file: every case's scene is validated before anything runs."""
    path = Path(path)
    cfg = validate(SweepConfig, path)
    scene = base_scene(cfg.scene, config_path=path)
    if cfg.overrides:
        scene = scene.with_updates(cfg.overrides, source=f"{path} [overrides]")
    if cfg.seed is not None:
        scene = scene.with_updates({"render.seed": cfg.seed}, source=str(path))
    methods = expand_methods(cfg.methods, source=str(path))
    if len({m.label for m in methods}) != len(methods):
        raise StudyError("two methods have the same name and parameters", file=str(path), key="methods")

    # ------------------------------------------------------------------ axes → groups (zipped or single)
    axes = {k: _axis_values(k, v, str(path)) for k, v in cfg.axes.items()}
    zipped = set()
    groups: list[list[str]] = []
    for i, z in enumerate(cfg.zip):
        for k in z:
            if k not in axes:
                raise StudyError(f"{k!r} is not an axis; axes: {', '.join(axes)}", file=str(path), key=f"zip[{i}]")
            if k in zipped:
                raise StudyError(f"{k!r} is in two zip groups", file=str(path), key=f"zip[{i}]")
        if len({len(axes[k]) for k in z}) > 1:
            raise StudyError("zipped axes need the same number of values: "
                             + ", ".join(f"{k} has {len(axes[k])}" for k in z), file=str(path), key=f"zip[{i}]")
        zipped |= set(z)
        groups.append(list(z))
    groups += [[k] for k in axes if k not in zipped]

    # ------------------------------------------------------------------ cases: product over the groups
    cases = []
    per_group = [[{k: axes[k][i] for k in g} for i in range(len(axes[g[0]]))] for g in groups]
    for idx, combo in enumerate(itertools.product(*per_group) if groups else [()]):
        chosen = {k: lv for part in combo for k, lv in part.items()}
        try:
            sc = scene.with_updates({k: v for k, (_, v) in chosen.items()}, source=f"{path} [axes]")
        except StudyError as err:
            labels = ", ".join(f"{k}={lab}" for k, (lab, _) in chosen.items())
            raise StudyError(f"{err.detail} (case {labels})", file=str(path), key=f"axes.{err.key}") from None
        cases.append(Case(idx, f"c{idx:04d}", sc, {k: lab for k, (lab, _) in chosen.items()}))
    for c in cases:
        c.key = case_key(c.scene, methods, backend)
    return Sweep(path, cfg, methods, cases, hashlib.sha256(path.read_bytes()).hexdigest()[:16])


def case_key(scene: Scene, methods: list[Method], backend: str) -> str:
    blob = json.dumps({"scene": scene.model_dump(mode="json"), "methods": [m.label for m in methods],
                       "backend": backend, "v": CODE_VERSION}, sort_keys=True)
    return hashlib.sha256(blob.encode()).hexdigest()[:20]


# ---------------------------------------------------------------------------------------------- running
def _limit_threads(jobs: int) -> None:
    """Give each of ``jobs`` worker processes its share of the cores (Dr.Jit's and Mitsuba's thread pools).

    Never fewer than 2 threads: with a pool of 1 thread, Mitsuba's ``Bitmap.write`` of an EXR deadlocks
    (Mitsuba 3.9.1 / Dr.Jit 1.5.0, seen here)."""
    n = max(2, (os.cpu_count() or 1) // max(jobs, 1))
    try:
        import drjit as dr
        dr.set_thread_count(n)
    except Exception:  # pragma: no cover - Dr.Jit without a thread pool
        pass


def _run_one(scene_json: dict, method_specs: list[tuple[str, dict]], backend: str, cache: str | None,
             case_id: str, jobs: int) -> list[dict]:
    """Worker: one case → rows (module-level so worker processes can import it)."""
    from study import methods as registry
    from study.cache import Cache
    from study.case import run_case
    from study.scene import scene_from_dict
    _limit_threads(jobs)
    scene = scene_from_dict(scene_json)
    ms = [registry.make(n, **p) for n, p in method_specs]
    return run_case(scene, ms, backend=backend, cache=Cache(cache), case_id=case_id, keep_images=False).rows


def _lock(out: Path):
    f = open(out / ".lock", "a+")
    try:
        fcntl.flock(f, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        f.close()
        raise StudyError("another sweep is writing to this directory; wait for it or choose another --out",
                         file=str(out)) from None
    return f


def _git_commit() -> str:
    try:
        return subprocess.run(["git", "rev-parse", "HEAD"], capture_output=True, text=True, check=True,
                              cwd=Path(__file__).parent).stdout.strip()
    except Exception:
        return "unknown"


def metadata(config: str | Path, *, backend: str, seed: int, methods: list[str], cases: int, **extra) -> dict:
    """What a results table was made with: versions, config hash, seed, git commit, backend, command."""
    import sys
    from importlib.metadata import PackageNotFoundError, version
    vers = {}
    for p in ("study", "mitsuba", "drjit", "embreex", "numpy", "scikit-image", "flip-evaluator"):
        try:
            vers[p] = version(p)
        except PackageNotFoundError:
            vers[p] = None
    config = Path(config)
    return {"config": str(config), "config_sha256": hashlib.sha256(config.read_bytes()).hexdigest()[:16],
            "seed": seed, "git_commit": _git_commit(), "backend": backend, "versions": vers,
            "python": platform.python_version(), "machine": platform.machine(), "cpus": os.cpu_count(),
            "command": "study " + " ".join(sys.argv[1:]) if Path(sys.argv[0]).name in ("study", "cli.py") else None,
            "cases": cases, "methods": methods, "code_version": CODE_VERSION, **extra}


def _case_file(out: Path, case: Case) -> Path:
    return out / "cases" / f"{case.key}.json"


def _load_case(out: Path, case: Case) -> list[dict] | None:
    try:
        data = json.loads(_case_file(out, case).read_text())
        if data.get("key") != case.key or not isinstance(data.get("rows"), list):
            return None
        return data["rows"]
    except (OSError, ValueError):
        return None


def run_sweep(path: str | Path, out: str | Path, *, backend: str = "numpy", cache: str | Path | None = ".cache",
              jobs: int = 1, dask: str | None = None,
              progress: Callable[[int, int, str], None] | None = None) -> tuple[list[dict], dict]:
    """Run (or resume) a sweep; returns (rows, stats) with stats = {cases, cached, computed, seconds}.

    Cases run in this process (``jobs=1``), in ``jobs`` local processes, or on a Dask distributed cluster
    (``dask`` = a scheduler address, or ``"local"`` for a LocalCluster of ``jobs`` single-threaded worker
    processes). The table is the same either way: rows are ordered by case, not by completion."""
    t0 = time.perf_counter()
    sweep = load_sweep(path, backend=backend)
    out = Path(out)
    try:
        (out / "cases").mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise StudyError(f"cannot create the output directory ({err.strerror})", file=str(out)) from None
    if not os.access(out, os.W_OK):
        raise StudyError("the output directory is not writable", file=str(out))
    lock = _lock(out)
    try:
        meta = metadata(sweep.path, backend=backend, seed=sweep.cases[0].scene.render.seed, jobs=jobs,
                        methods=[m.label for m in sweep.methods], cases=len(sweep.cases))
        _atomic_write(out / "metadata.json", json.dumps(meta, indent=2).encode())
        done: dict[int, list[dict]] = {}
        for c in sweep.cases:
            rows = _load_case(out, c)
            if rows is not None:
                done[c.index] = rows
        cached = len(done)
        todo = [c for c in sweep.cases if c.index not in done]
        specs = [(m.name, m.params.model_dump(exclude_unset=True)) for m in sweep.methods]
        cache_s = str(cache) if cache else None

        def finish(c: Case, rows: list[dict]):
            for r in rows:
                r.update({f"axis:{k}": v for k, v in c.labels.items()})
                r["case"] = c.id
            _atomic_write(_case_file(out, c), json.dumps({"key": c.key, "rows": rows}, default=float).encode())
            done[c.index] = rows
            _write_table(sweep, done, out)
            if progress:
                progress(len(done), len(sweep.cases), c.id)

        if progress:
            progress(len(done), len(sweep.cases), "")
        if dask:
            _run_dask(todo, specs, backend, cache_s, jobs, dask, finish)
        elif jobs <= 1 or len(todo) <= 1:
            for c in todo:
                finish(c, _run_one(c.scene.model_dump(mode="json"), specs, backend, cache_s, c.id, 1))
        else:
            _run_parallel(todo, specs, backend, cache_s, jobs, finish)
        _write_table(sweep, done, out)
        rows = [r for i in sorted(done) for r in done[i]]
        return rows, {"cases": len(sweep.cases), "cached": cached, "computed": len(todo),
                      "seconds": time.perf_counter() - t0}
    finally:
        lock.close()


def _run_parallel(todo: list[Case], specs, backend, cache_s, jobs, finish) -> None:
    """Cases on ``jobs`` processes. Cases that share an impostor are spread so that the first case of each
    impostor runs before its siblings (they then find it cached)."""
    import multiprocessing as mp
    from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait

    first, rest = _first_of_each_impostor(todo)
    with ProcessPoolExecutor(max_workers=jobs, mp_context=mp.get_context("spawn")) as pool:
        for batch in (first, rest):
            futs = {pool.submit(_run_one, c.scene.model_dump(mode="json"), specs, backend, cache_s, c.id, jobs): c
                    for c in batch}
            while futs:
                fin, _ = wait(futs, return_when=FIRST_COMPLETED)
                for f in fin:
                    finish(futs.pop(f), f.result())


def _first_of_each_impostor(todo: list[Case]) -> tuple[list[Case], list[Case]]:
    """Split cases into the first case of each impostor and the rest (which then find it cached)."""
    from study.capture import impostor_key
    first, rest, seen = [], [], set()
    for c in todo:
        k = impostor_key(c.scene)
        (rest if k in seen else first).append(c)
        seen.add(k)
    return first, rest


def _run_dask(todo: list[Case], specs, backend, cache_s, jobs, address: str, finish) -> None:
    """Cases as tasks on a Dask distributed cluster; the cache directory must be shared by the workers."""
    try:
        from distributed import Client, LocalCluster, as_completed
    except ImportError:
        raise StudyError("needs dask[distributed] (pip install 'dask[distributed]')", key="--dask") from None
    cluster = None
    if address == "local":
        cluster = LocalCluster(n_workers=max(jobs, 1), threads_per_worker=1, processes=True, dashboard_address=None)
        client = Client(cluster)
    else:
        try:
            client = Client(address, timeout="20s")
        except OSError as err:
            raise StudyError(f"cannot reach the Dask scheduler ({err})", key="--dask") from None
    try:
        for batch in _first_of_each_impostor(todo):
            futs = {client.submit(_run_one, c.scene.model_dump(mode="json"), specs, backend, cache_s, c.id,
                                  max(jobs, 1), key=f"study-{c.key}", pure=False): c for c in batch}
            for f in as_completed(list(futs)):
                finish(futs[f], f.result())
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


def _write_table(sweep: Sweep, done: dict[int, list[dict]], out: Path) -> None:
    rows = [r for i in sorted(done) for r in done[i]]
    if rows:
        write_csv(rows, out / "results.csv")
