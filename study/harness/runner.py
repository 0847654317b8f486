"""Running a sweep: cases in this process, in local processes or on a Dask cluster; resume; the results table.

A finished case is stored under ``<out>/cases/<key>.json`` (atomically) and never recomputed, so a killed sweep
resumes where it stopped. After each case the table ``<out>/results.csv`` is rewritten atomically from the finished
cases, in case order; ``<out>/metadata.json`` records versions, config hash, seed, git commit, backend. One sweep at
a time may write to an output directory (a lock file; a second one stops with a clear message).
"""
from __future__ import annotations

import fcntl
import hashlib
import json
import os
import platform
import subprocess
import sys
import time
from pathlib import Path
from typing import Callable

from study import methods as registry
from study.cache import Cache
from study.errors import StudyError
from study.evaluate.case import run_case
from study.harness.sweep import CODE_VERSION, Case, load_sweep
from study.impostor.capture import impostor_key
from study.io import atomic_write
from study.scene import scene_from_dict
from study.tables import write_csv


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
    registry.load_plugins()                          # methods registered outside study ($STUDY_PLUGINS)
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


#: A case's work, as something a worker process can run: (module-level function, its arguments).
Task = tuple[Callable[..., list[dict]], tuple]


def run_sweep(path: str | Path, out: str | Path, *, backend: str = "numpy", cache: str | Path | None = ".cache",
              jobs: int = 1, dask: str | None = None,
              progress: Callable[[int, int, str], None] | None = None) -> tuple[list[dict], dict]:
    """Run (or resume) a sweep; returns (rows, stats) with stats = {cases, cached, computed, seconds}.

    Cases run in this process (``jobs=1``), in ``jobs`` local processes, or on a Dask distributed cluster
    (``dask`` = a scheduler address, or ``"local"`` for a LocalCluster of ``jobs`` single-threaded worker
    processes). The table is the same either way: rows are ordered by case, not by completion."""
    sweep = load_sweep(path, backend=backend)
    specs = [(m.name, m.params.model_dump(exclude_unset=True)) for m in sweep.methods]
    cache_s = str(cache) if cache else None
    meta = metadata(sweep.path, backend=backend, seed=sweep.cases[0].scene.render.seed, jobs=jobs,
                    methods=[m.label for m in sweep.methods], cases=len(sweep.cases))

    def task(c: Case) -> Task:
        return _run_one, (c.scene.model_dump(mode="json"), specs, backend, cache_s, c.id, jobs)
    return run_cases(sweep.cases, out, meta, task, jobs=jobs, dask=dask, progress=progress,
                     batches=_first_of_each_impostor)


def run_cases(cases: list[Case], out: str | Path, meta: dict, task: Callable[[Case], Task], *, jobs: int = 1,
              dask: str | None = None, progress: Callable[[int, int, str], None] | None = None,
              batches: Callable[[list[Case]], tuple[list[Case], ...]] = lambda todo: (todo,)
              ) -> tuple[list[dict], dict]:
    """Run the cases not yet finished under ``out`` and write ``<out>/results.csv`` (+ ``metadata.json``).

    ``task(case)`` gives the function and arguments that compute a case's rows (run here, in ``jobs`` processes or
    on Dask); each row gets the case id and one ``axis:<key>`` column per label of the case. ``batches`` splits
    the cases to run into groups run one after the other (e.g. the first case of each impostor first). The
    output directory is locked for the run. Returns (rows, stats = {cases, cached, computed, seconds})."""
    t0 = time.perf_counter()
    out = Path(out)
    try:
        (out / "cases").mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise StudyError(f"cannot create the output directory ({err.strerror})", file=str(out)) from None
    if not os.access(out, os.W_OK):
        raise StudyError("the output directory is not writable", file=str(out))
    lock = _lock(out)
    try:
        atomic_write(out / "metadata.json", json.dumps(meta, indent=2).encode())
        done: dict[int, list[dict]] = {}
        for c in cases:
            rows = _load_case(out, c)
            if rows is not None:
                done[c.index] = rows
        cached = len(done)
        todo = [c for c in cases if c.index not in done]

        def finish(c: Case, rows: list[dict]):
            for r in rows:
                r.update({f"axis:{k}": v for k, v in c.labels.items()})
                r["case"] = c.id
            atomic_write(_case_file(out, c), json.dumps({"key": c.key, "rows": rows}, default=float).encode())
            done[c.index] = rows
            _write_table(done, out)
            if progress:
                progress(len(done), len(cases), c.id)

        if progress:
            progress(len(done), len(cases), "")
        if dask:
            _run_dask(batches(todo), task, jobs, dask, finish)
        elif jobs <= 1 or len(todo) <= 1:
            for c in todo:
                fn, args = task(c)
                finish(c, fn(*args))
        else:
            _run_parallel(batches(todo), task, jobs, finish)
        _write_table(done, out)
        rows = [r for i in sorted(done) for r in done[i]]
        return rows, {"cases": len(cases), "cached": cached, "computed": len(todo),
                      "seconds": time.perf_counter() - t0}
    finally:
        lock.close()


def _run_parallel(batches, task, jobs, finish) -> None:
    """Cases on ``jobs`` processes, batch after batch."""
    import multiprocessing as mp
    from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait

    with ProcessPoolExecutor(max_workers=jobs, mp_context=mp.get_context("spawn")) as pool:
        for batch in batches:
            futs = {pool.submit(*_flat(task(c))): c for c in batch}
            while futs:
                fin, _ = wait(futs, return_when=FIRST_COMPLETED)
                for f in fin:
                    finish(futs.pop(f), f.result())


def _flat(t: Task) -> tuple:
    return (t[0], *t[1])


def _first_of_each_impostor(todo: list[Case]) -> tuple[list[Case], list[Case]]:
    """Split cases into the first case of each impostor and the rest (which then find it cached)."""
    first, rest, seen = [], [], set()
    for c in todo:
        k = impostor_key(c.scene)
        (rest if k in seen else first).append(c)
        seen.add(k)
    return first, rest


def _run_dask(batches, task, jobs, address: str, finish) -> None:
    """Cases as tasks on a Dask distributed cluster; the cache directory must be shared by the workers."""
    try:
        from distributed import Client, LocalCluster, as_completed  # optional dependency (study[cluster])
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
        for batch in batches:
            futs = {client.submit(*_flat(task(c)), key=f"study-{c.key}", pure=False): c for c in batch}
            for f in as_completed(list(futs)):
                finish(futs[f], f.result())
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


def _write_table(done: dict[int, list[dict]], out: Path) -> None:
    rows = [r for i in sorted(done) for r in done[i]]
    if rows:
        write_csv(rows, out / "results.csv")
