"""Cases on a Dask distributed cluster (``--dask``): a scheduler's address, ``local`` (a LocalCluster of ``jobs``
single-threaded worker processes) or ``local-gpus`` (``jobs`` worker processes per visible GPU, each pinned to its
GPU with ``CUDA_VISIBLE_DEVICES``). The cache directory must be shared by the workers."""

from __future__ import annotations

import os
import subprocess

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


def run_dask(batches, task, jobs: int, address: str, finish, warm: tuple | None = None) -> None:
    """Run ``task(case)`` = (function, *args) for each case of each batch (a batch after the one before it) on
    a Dask cluster at ``address`` (or ``local`` / ``local-gpus``); ``finish(case, rows)`` as each one ends.
    ``warm`` = (function, *args): run once on every worker first, not waited for (imports, GPU context), so that
    workers left idle by a first small batch get ready meanwhile."""
    try:
        from distributed import Client, LocalCluster, as_completed  # optional dependency (study[cluster])
    except ImportError:
        raise StudyError("needs dask[distributed] (pip install 'dask[distributed]')", key="--dask") from None
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
        try:
            client = Client(address, timeout="20s")
        except OSError as err:
            raise StudyError(f"cannot reach the Dask scheduler ({err})", key="--dask") from None
    try:
        if warm is not None:
            for w in client.scheduler_info().get("workers", {}):
                client.submit(*warm, workers=[w], allow_other_workers=False, pure=False, priority=10)
        for batch in batches:
            futs = {
                client.submit(*_flat(task(c)), key=f"study-{c.key}-{c.index}", pure=False): c for c in batch
            }
            for f in as_completed(list(futs)):
                finish(futs[f], f.result())
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


def _flat(t: tuple) -> tuple:
    fn, args = t
    return (fn, *args)
