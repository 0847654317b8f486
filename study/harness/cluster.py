"""Cases on a Dask distributed cluster (``--dask``): a scheduler's address, ``local`` (a LocalCluster of ``jobs``
single-threaded worker processes) or ``local-gpus`` (``jobs`` worker processes per visible GPU, each pinned to its
GPU with ``CUDA_VISIBLE_DEVICES``). The cache directory must be shared by the workers."""

from __future__ import annotations

import os
import subprocess
import threading
import time

from study import runtime
from study.errors import EnvironmentProblem, StudyError


def visible_gpus() -> list[str]:
    """The GPUs this process may use: ``CUDA_VISIBLE_DEVICES`` if set, else those ``nvidia-smi -L`` lists."""
    env = os.environ.get("CUDA_VISIBLE_DEVICES")
    if env is not None:
        return [g.strip() for g in env.split(",") if g.strip() and g.strip() != "-1"]
    try:
        out = subprocess.run(["nvidia-smi", "-L"], capture_output=True, text=True, timeout=20).stdout
    except (OSError, subprocess.SubprocessError):
        return []
    return [str(i) for i, line in enumerate(out.splitlines()) if line.startswith("GPU ")]


def gpu_cluster(gpus: list[str] | None = None, per_gpu: int = 1):
    """A local Dask cluster (``distributed.SpecCluster``) of ``per_gpu`` single-threaded worker processes per GPU in
    ``gpus`` (default: :func:`visible_gpus`); each worker's nanny sets ``CUDA_VISIBLE_DEVICES`` to its GPU and
    passes the render device on (:func:`study.runtime.render_device`) before the worker process starts."""
    from distributed import Nanny, Scheduler, SpecCluster

    gpus = visible_gpus() if gpus is None else gpus
    if not gpus:
        raise EnvironmentProblem(
            "no GPU visible (CUDA_VISIBLE_DEVICES, nvidia-smi): 'local-gpus' needs at least one", key="--dask"
        )
    share = str(
        max(2, (os.cpu_count() or 1) // (len(gpus) * max(per_gpu, 1)))
    )  # threads each (Dr.Jit, Embree,
    # OpenMP in FLIP): the cores over every worker (study.harness.runner._limit_threads)
    workers = {
        f"gpu{g}-{i}": {
            "cls": Nanny,
            "options": {
                "nthreads": 1,
                "env": {
                    "CUDA_VISIBLE_DEVICES": g,
                    "STUDY_RENDER_DEVICE": runtime.render_device(),
                    "OMP_NUM_THREADS": os.environ.get("OMP_NUM_THREADS", share),
                    "STUDY_WORKER_THREADS": share,
                },
            },
        }
        for g in gpus
        for i in range(max(per_gpu, 1))
    }
    return SpecCluster(scheduler={"cls": Scheduler, "options": {"dashboard_address": None}}, workers=workers)


#: Seconds to wait for a scheduler to answer and for its first worker ($STUDY_DASK_TIMEOUT overrides both).
CONNECT_TIMEOUT, WORKER_TIMEOUT = 30.0, 120.0
_SCHEMES = ("tcp://", "tls://", "ucx://", "ws://", "wss://", "inproc://")


def check_address(address: str | None) -> str | None:
    """``--dask``'s value: None (no cluster), ``local``, ``local-gpus`` or a scheduler address with its scheme
    (``tcp://host:8786``); anything else, the empty string included, is one line naming the allowed values."""
    if address is None:
        return None
    a = address.strip()
    if a in ("local", "local-gpus") or (a.startswith(_SCHEMES) and len(a.split("://", 1)[1]) > 0):
        return a
    raise StudyError(
        f"{address!r} is not a Dask cluster (allowed: 'local', 'local-gpus' or a scheduler address such as "
        "'tcp://host:8786')",
        key="--dask",
    )


def _timeout(default: float) -> float:
    try:
        return float(os.environ.get("STUDY_DASK_TIMEOUT", default))
    except ValueError:
        return default


def _connect(Client, address: str):
    """``Client(address)`` within :data:`CONNECT_TIMEOUT` seconds, also where the peer accepts the connection and
    then stays silent (an HTTP server, a stuck port), which Dask's own timeout does not bound: the attempt runs in
    a daemon thread, abandoned when it does not come back in time."""
    seconds = _timeout(CONNECT_TIMEOUT)
    box: dict = {}

    def attempt():
        try:
            box["client"] = Client(address, timeout=f"{seconds}s")
        except BaseException as err:  # handed to the caller
            box["error"] = err

    t = threading.Thread(target=attempt, name="study-dask-connect", daemon=True)
    t.start()
    t.join(seconds + 5)
    if "client" in box:
        return box["client"]
    err = box.get("error")
    why = f"{type(err).__name__}: {err}" if err is not None else f"no answer within {seconds:g} s"
    raise EnvironmentProblem(
        f"cannot reach the Dask scheduler at {address} ({' '.join(why.split())[:200]})", key="--dask"
    )


_WARM = {"runs": 0, "seconds": 0.0, "cases": 0}  # this worker process: warm-ups run, their seconds, cases run


def warm_worker(backend: str) -> None:
    """Ready a worker before its first case: study's modules imported, the render device's Mitsuba variant and,
    on CUDA, the GPU context made (a few seconds each worker would otherwise spend in its first case)."""
    from study.measure import case  # noqa: F401 - the imports a case needs

    with runtime.using_render_device("cuda" if backend == "cuda" else None):
        runtime.mitsuba()
        if backend == "cuda":
            from study import backend as backends

            backends.get("cuda")


def _warm_once(warm: tuple | None) -> dict:
    """Worker: run ``warm`` = (function, *args) unless this process already has; its record (runs, seconds)."""
    if warm is not None and _WARM["runs"] == 0:
        t0 = time.perf_counter()
        warm[0](*warm[1:])
        _WARM["runs"] += 1
        _WARM["seconds"] = time.perf_counter() - t0
    return dict(_WARM)


def _case_on_worker(warm: tuple | None, after: list, fn, *args):
    """Worker: one case, the worker warmed first if it is not yet (a worker that joined late, or whose warm-up
    task has not run); ``after`` (the results of the cases this one waits for, e.g. its impostor's first case) is
    not used. Returns (rows, the worker's address)."""
    from distributed import get_worker

    _warm_once(warm)
    rows = fn(*args)
    _WARM["cases"] += 1
    return rows, get_worker().address


def _worker_record() -> dict:
    return dict(_WARM)


def _start(address: str, jobs: int):
    """(client, cluster or None, how many workers to wait for) for ``--dask``'s value."""
    from distributed import Client, LocalCluster

    if address == "local":
        cluster = LocalCluster(
            n_workers=max(jobs, 1), threads_per_worker=1, processes=True, dashboard_address=None
        )
    elif address == "local-gpus":
        cluster = gpu_cluster(per_gpu=jobs)
    else:
        return _connect(Client, address), None, 1
    return Client(cluster), cluster, len(cluster.workers)


def run_dask(batches, task, jobs: int, address: str, finish, warm: tuple | None = None, group=None) -> dict:
    """Run ``task(case)`` = (function, *args) for each case of each batch on a Dask cluster at ``address`` (or
    ``local`` / ``local-gpus``); ``finish(case, rows)`` as each one ends. Returns the run's timing
    (:func:`throughput`).

    Phases: the cluster starts (a local cluster: until all its workers joined; a scheduler's address: until one
    has); ``warm`` = (function, *args) runs once in every worker process (imports, GPU context), first on every
    worker as a task of high priority, and again before any case on a worker that has not run it (it runs once per
    process either way). Every case is submitted at once: a case of a later batch waits, on the scheduler, only for
    the cases of earlier batches with the same ``group(case)`` (its impostor's first case), or for the whole
    previous batch when ``group`` is None, so no worker idles behind a barrier while another compiles."""
    try:
        from distributed import KilledWorker, as_completed  # optional (study[cluster])
    except ImportError:
        raise StudyError("needs dask[distributed] (pip install 'dask[distributed]')", key="--dask") from None
    address = check_address(address)
    t_enter = time.perf_counter()
    startup = _process_age()
    client, cluster, expect = _start(address, jobs)
    marks = {"startup": startup, "enter": t_enter}
    try:
        try:
            client.wait_for_workers(expect, timeout=_timeout(WORKER_TIMEOUT))
        except TimeoutError:
            raise EnvironmentProblem(
                f"no Dask worker joined the scheduler at {address} within {_timeout(WORKER_TIMEOUT):g} s "
                "(start workers with `dask worker ADDRESS`)",
                key="--dask",
            ) from None
        marks["ready"] = time.perf_counter()
        workers = list(client.scheduler_info().get("workers", {}))
        warming = [  # held, so that the scheduler does not forget them before they run
            client.submit(_warm_once, warm, workers=[w], allow_other_workers=False, pure=False, priority=10)
            for w in workers
        ]
        futs, earlier = {}, {}
        for batch in batches:
            made = {}
            for c in batch:
                g = group(c) if group else None
                after = earlier.get(g, []) if group else list(earlier.get(None, []))
                fn, args = task(c)
                f = client.submit(
                    _case_on_worker, warm, after, fn, *args, key=f"study-{c.key}-{c.index}", pure=False
                )
                futs[f] = c
                made.setdefault(g, []).append(f)
            earlier = (
                made if not group else {g: earlier.get(g, []) + made.get(g, []) for g in {*earlier, *made}}
            )
        done_at, first_at = [], {}
        for f in as_completed(list(futs)):
            try:
                rows, worker = f.result()
            except KilledWorker as err:
                raise EnvironmentProblem(
                    f"Dask workers died running case {futs[f].key} ({err}); too little memory per worker?",
                    key="--dask",
                ) from None
            finish(futs[f], rows)
            done_at.append(time.perf_counter())
            first_at.setdefault(worker, done_at[-1])
        marks["last"] = time.perf_counter()
        records = client.run(_worker_record) if futs else {}
        del warming
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
    marks["closed"] = time.perf_counter()
    return throughput(marks, done_at, first_at, records)


def throughput(marks: dict, done_at: list[float], first_at: dict, records: dict) -> dict:
    """A Dask run's fixed cost apart from its steady throughput (seconds; ``perf_counter`` marks):

    - ``startup_s``: the process's start to the cluster's request (imports, the sweep's validation, case files);
    - ``cluster_s``: the cluster's start until its workers joined;
    - ``warmup_s``: from then until every worker that ran a case has finished its first one (imports, GPU context,
      kernels compiled, the first case of each impostor);
    - ``shutdown_s``: the last case to the cluster's close; ``fixed_s`` = cluster + warm-up + shutdown;
    - ``steady_cases`` finished after the warm-up, over ``steady_s`` (the warm-up's end to the last case):
      ``steady_cases_per_s``; ``workers``: each worker's warm-up runs and seconds and its cases."""
    ready, last = marks.get("ready", marks["enter"]), marks.get("last", marks["closed"])
    warm_end = max(first_at.values(), default=ready)
    steady = sum(t > warm_end for t in done_at)
    span = last - warm_end
    out = {
        "startup_s": marks["startup"],
        "cluster_s": ready - marks["enter"],
        "warmup_s": warm_end - ready,
        "shutdown_s": marks["closed"] - last,
        "steady_cases": steady,
        "steady_s": span,
        "steady_cases_per_s": steady / span if steady and span > 0 else None,
        "cases": len(done_at),
        "workers": {w: records[w] for w in sorted(records)},
    }
    out["fixed_s"] = out["cluster_s"] + out["warmup_s"] + out["shutdown_s"]
    return {k: round(v, 3) if isinstance(v, float) else v for k, v in out.items()}


def timing_line(t: dict) -> str:
    """The printed line of a Dask run's timing (:func:`throughput`)."""
    rate = t["steady_cases_per_s"]
    return (
        f"dask: {len(t['workers'])} workers; fixed cost {t['fixed_s']:.1f} s (cluster start {t['cluster_s']:.1f}, "
        f"warm-up {t['warmup_s']:.1f}, shutdown {t['shutdown_s']:.1f}; process start before it "
        f"{t['startup_s']:.1f} s); steady "
        + (
            f"{rate:.2f} cases/s ({t['steady_cases']} cases in {t['steady_s']:.1f} s)"
            if rate
            else "not reached"
        )
    )


def _process_age() -> float:
    """Seconds since this process started (psutil, which distributed needs)."""
    import psutil

    return time.time() - psutil.Process().create_time()
