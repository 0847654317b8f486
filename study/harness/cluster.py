"""Cases on a Dask distributed cluster (``--dask``): a scheduler's address, ``local`` (a LocalCluster of ``jobs``
single-threaded worker processes) or ``local-gpus`` (``jobs`` worker processes per visible GPU, each pinned to its
GPU with ``CUDA_VISIBLE_DEVICES``). The cache directory must be shared by the workers."""

from __future__ import annotations

import os
import subprocess
import threading

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


def run_dask(batches, task, jobs: int, address: str, finish, warm: tuple | None = None) -> None:
    """Run ``task(case)`` = (function, *args) for each case of each batch (a batch after the one before it) on
    a Dask cluster at ``address`` (or ``local`` / ``local-gpus``); ``finish(case, rows)`` as each one ends.
    ``warm`` = (function, *args): run once on every worker first, not waited for (imports, GPU context), so that
    workers left idle by a first small batch get ready meanwhile."""
    try:
        from distributed import Client, KilledWorker, LocalCluster, as_completed  # optional (study[cluster])
    except ImportError:
        raise StudyError("needs dask[distributed] (pip install 'dask[distributed]')", key="--dask") from None
    address = check_address(address)
    cluster = None
    if address == "local":
        cluster = LocalCluster(
            n_workers=max(jobs, 1), threads_per_worker=1, processes=True, dashboard_address=None
        )
        client = Client(cluster)
    elif address == "local-gpus":
        cluster = gpu_cluster(per_gpu=jobs)
        client = Client(cluster)
    else:
        client = _connect(Client, address)
    try:
        try:
            client.wait_for_workers(1, timeout=_timeout(WORKER_TIMEOUT))
        except TimeoutError:
            raise EnvironmentProblem(
                f"no Dask worker joined the scheduler at {address} within {_timeout(WORKER_TIMEOUT):g} s "
                "(start workers with `dask worker ADDRESS`)",
                key="--dask",
            ) from None
        if warm is not None:
            for w in client.scheduler_info().get("workers", {}):
                client.submit(*warm, workers=[w], allow_other_workers=False, pure=False, priority=10)
        for batch in batches:
            futs = {
                client.submit(*_flat(task(c)), key=f"study-{c.key}-{c.index}", pure=False): c for c in batch
            }
            for f in as_completed(list(futs)):
                try:
                    result = f.result()
                except KilledWorker as err:
                    raise EnvironmentProblem(
                        f"Dask workers died running case {futs[f].key} ({err}); too little memory per worker?",
                        key="--dask",
                    ) from None
                finish(futs[f], result)
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


def _flat(t: tuple) -> tuple:
    fn, args = t
    return (fn, *args)
