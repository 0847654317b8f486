"""Running a sweep: cases in this process, in local processes or on a Dask cluster; resume; the results table.

A finished case is stored under ``<out>/cases/<key>.json`` (atomically) and not recomputed, so a killed sweep
resumes where it stopped. A case file is used only if it names the case's key and holds a non-empty list of rows
that the caller's check accepts (for a sweep: run_case's reference rows, then one row per method, labelled as
configured); anything else is recomputed. The rows' case id and ``axis:*`` columns always come from the config as
expanded now, never from the file. Worker processes (``jobs`` > 1) exit when the sweep's process dies.

Before anything runs the backend and every case are checked (:mod:`study.harness.budget`: in view, memory, time).
The table ``<out>/results.csv`` (in case order), ``<out>/metadata.json`` (versions, config hash, code hash, seed,
git commit, backend) and the caller's extras (the sweep's ``plots/``) are one output set
(:func:`study.io.output_set`): written when every case is done and swapped in together, so a failed or killed
sweep leaves the previous table, metadata and plots as they were. One command at a time may write to an output
directory (a lock file; a second one stops with a clear message).
"""

from __future__ import annotations

import contextlib
import json
import os
import platform
import sys
import time
from collections.abc import Callable
from pathlib import Path

from study import methods as registry
from study import progress as pg
from study import runtime
from study.cache import Cache
from study.cache import flush as cache_flush
from study.codehash import code_record
from study.errors import StudyError, os_problem
from study.harness import budget, estimate, provenance
from study.harness.cluster import run_dask, warm_worker
from study.harness.sweep import Case, load_sweep
from study.impostor.capture import impostor_key
from study.io import atomic_write, json_text, locked, output_set
from study.measure.case import run_case
from study.scene import scene_from_dict
from study.tables import write_table


def _limit_threads(jobs: int) -> None:
    """Give each of ``jobs`` worker processes its share of the cores (Dr.Jit's and Mitsuba's thread pools,
    Embree's through ``$STUDY_THREADS``, and OpenMP's through ``$OMP_NUM_THREADS`` unless the user set it: FLIP
    (flip-evaluator) runs on OpenMP, and 8 workers × every core each, spinning, made a sweep's cases 4× slower on
    a 16-core GPU machine than one worker alone; the variable is read when FLIP is first imported, later). A Dask
    worker of ``--dask local-gpus`` gets its share from ``$STUDY_WORKER_THREADS`` (set by the cluster: the cores
    over all its workers, not over ``jobs``, which counts the workers of one GPU).

    Never fewer than 2 threads: with a pool of 1 thread, Mitsuba's ``Bitmap.write`` of an EXR deadlocks
    (Mitsuba 3.9.1 / Dr.Jit 1.5.0, seen here)."""
    n = int(os.environ.get("STUDY_WORKER_THREADS") or 0) or max(2, (os.cpu_count() or 1) // max(jobs, 1))
    os.environ["STUDY_THREADS"] = str(n)  # Embree's chunks (study.reference.embree.Tracer)
    if jobs > 1:
        os.environ.setdefault("OMP_NUM_THREADS", str(n))
    try:
        import drjit as dr

        dr.set_thread_count(n)
    except Exception:  # pragma: no cover - Dr.Jit without a thread pool
        pass


def _run_one(
    scene_json: dict,
    method_specs: list[tuple[str, dict]],
    backend: str,
    cache: str | None,
    case_id: str,
    jobs: int,
    images: tuple | None = None,
) -> list[dict]:
    """Worker: one case → rows (module-level so worker processes can import it); ``images`` = (writer, *args):
    ``writer(case, case_id, out, labels, *args)`` writes its images (``study.outputs.case_images``)."""
    registry.load_plugins()  # methods registered outside study ($STUDY_PLUGINS)
    _limit_threads(jobs)
    scene = scene_from_dict(scene_json)
    ms = [registry.make(n, **p) for n, p in method_specs]
    prof_dir = os.environ.get(
        "STUDY_PROFILE"
    )  # a developer's switch: a cProfile of every case, <dir>/<case>.prof
    prof = None
    if prof_dir:
        import cProfile

        prof = cProfile.Profile()
        prof.enable()
    t0 = time.perf_counter()
    try:  # a remote worker: renders and exact hits on its GPU too
        with runtime.using_render_device("cuda" if backend == "cuda" else None):
            case = run_case(scene, ms, backend=backend, cache=Cache(cache), case_id=case_id,
                            keep_images=bool(images), intervals=False)  # fmt: skip
            cache_flush()  # its entries on disk before the worker reports the case (a failed write: its error)
            if images:
                images[0](case, case_id, images[1], [m.label for m in ms], *images[2:])
        for r in case.rows:
            r["case_seconds"] = time.perf_counter() - t0  # the case's wall time in its worker
        for r in case.rows[:1]:  # its stage times, for the metadata (run_cases takes them off the row)
            r[estimate.TIMES] = dict(case.times)
        return case.rows
    except StudyError as err:  # which case refused, for the sweep's one line
        raise type(err)(f"{err.detail} (case {case_id})", file=err.file, key=err.key, code=err.code) from None
    finally:
        if prof is not None:
            prof.disable()
            Path(prof_dir).mkdir(parents=True, exist_ok=True)
            prof.dump_stats(str(Path(prof_dir) / f"{case_id}.prof"))


def metadata(
    config: str | Path, *, backend: str, seed: int, methods: list[str], cases: int, code: tuple = (), **extra
) -> dict:
    """What a results table was made with, written by code (:mod:`study.harness.provenance`): config hash, seed,
    git commit and whether the tree was dirty (from ``git``, or the stamp a copy without ``.git`` carries), the
    backend, the device (CPU model and cores, the GPU's name on cuda), versions (study's own included), the
    command line, and the code that made it: ``code_hash`` with the files it covers (of ``code``: functions,
    classes or modules, e.g. the case runner and the method classes; the caller's module where none given)."""
    config = Path(config)
    if not code:
        code = (sys.modules[sys._getframe(1).f_globals["__name__"]],)
    git = provenance.git_state()
    return {
        "config": str(config),
        "config_sha256": provenance.config_sha(config),
        "seed": seed,
        "git_commit": git["commit"],
        "git_dirty": git["dirty"],
        "git_diff_sha256": git["diff_sha256"],
        "git_from": git["from"],
        "backend": backend,
        "device": provenance.device(backend),
        "versions": provenance.versions(),
        "python": platform.python_version(),
        "machine": platform.machine(),
        "cpus": os.cpu_count(),
        "command": provenance.command(),
        "cases": cases,
        "methods": methods,
        **code_record(*code),
        **extra,
    }


def _case_file(out: Path, case: Case) -> Path:
    return out / "cases" / f"{case.key}.json"


#: A case's work, as something a worker process can run: (module-level function, its arguments).
Task = tuple[Callable[..., list[dict]], tuple]
#: Whether rows (from a case file, or just computed) are what ``case`` produces under today's config.
Check = Callable[[Case, list[dict]], bool]


def sweep_check(methods: list) -> Check:
    """The rows of a sweep case: first :func:`run_case`'s reference rows (at least one; rows of no configured
    method, e.g. the oracle's, each label once), then exactly one row per method, its label as configured, in
    order. Which references a case has is fixed by the code, whose hash is part of the case's key."""
    names, labels = {m.name for m in methods}, [m.label for m in methods]

    def check(case: Case, rows: list[dict]) -> bool:
        n = len(rows) - len(labels)
        refs, own = rows[:n], rows[n:]
        return (
            n >= 1
            and [r.get("label") for r in own] == labels
            and all(r.get("method") in names for r in own)
            and all(r.get("method") not in names for r in refs)
            and len({r.get("label") for r in refs}) == n
        )

    return check


def _identify(case: Case, rows: list[dict]) -> list[dict]:
    """The rows with their identity from ``case``: its id and one ``axis:<key>`` column per label (others go)."""
    for r in rows:
        for k in [k for k in r if k.startswith("axis:")]:
            del r[k]
        r.update({f"axis:{k}": v for k, v in case.labels.items()})
        r["case"] = case.id
    return rows


_NONFINITE = ("NaN", "Infinity", "-Infinity")  # how a case file holds NaN and ±inf (strict JSON)


def _load_case(out: Path, case: Case, check: Check | None = None) -> list[dict] | None:
    """The rows of ``case``'s file, relabelled from ``case``; None (recompute) unless the file names the case's
    key and holds a non-empty list of rows that ``check`` accepts."""
    try:
        data = json.loads(_case_file(out, case).read_text())
    except (OSError, ValueError):
        return None
    if not isinstance(data, dict) or data.get("key") != case.key:
        return None
    rows = data.get("rows")
    if not isinstance(rows, list) or not rows or not all(isinstance(r, dict) for r in rows):
        return None
    rows = [
        {k: float(v) if v in _NONFINITE else v for k, v in r.items()} for r in rows
    ]  # strict JSON: as text
    if check is not None and not check(case, rows):
        return None
    return _identify(case, rows)


def prepare_sweep(path: str | Path, *, backend: str = "numpy", jobs: int = 1):
    """The sweep, validated, with the backend and every case checked (:mod:`study.harness.budget`)."""
    sweep = load_sweep(path, backend=backend)
    budget.check_backend(backend)
    budget.check_cases(
        [(c.id, c.scene) for c in sweep.cases], sweep.methods, source=str(sweep.path), jobs=jobs
    )
    return sweep


def run_sweep(
    path: str | Path,
    out: str | Path,
    *,
    backend: str = "numpy",
    cache: str | Path | None = ".cache",
    jobs: int = 1,
    dask: str | None = None,
    progress: Callable[[int, int, str], None] | None = None,
    extra: Callable[[list[dict], Path], None] | None = None,
    prepared=None,
    images: tuple | None = None,
) -> tuple[list[dict], dict]:
    """Run (or resume) a sweep; returns (rows, stats) with stats = {cases, cached, computed, seconds}; ``images``:
    (writer, *args), what writes the images of the cases computed (:func:`_run_one`).
    ``prepared``: the sweep as :func:`prepare_sweep` gave it for the same path, backend and jobs (not redone).
    ``extra(rows, dir)`` writes more outputs (the curves, under ``dir/plots``) into the sweep's output set.

    Cases run in this process (``jobs=1``), in ``jobs`` local processes, or on a Dask distributed cluster
    (``dask`` = a scheduler address, or ``"local"`` for a LocalCluster of ``jobs`` single-threaded worker
    processes). The table is the same either way: rows are ordered by case, not by completion."""
    sweep = prepared or prepare_sweep(path, backend=backend, jobs=jobs)
    specs = [(m.name, m.params.model_dump(exclude_unset=True)) for m in sweep.methods]
    cache_s = str(cache) if cache else None
    labels = [m.label for m in sweep.methods]
    meta = metadata(
        sweep.path,
        backend=backend,
        seed=sweep.cases[0].scene.render.seed,
        jobs=jobs,
        methods=labels,
        cases=len(sweep.cases),
        code=(run_case, *[type(m) for m in sweep.methods]),
    )

    def task(c: Case) -> Task:
        return _run_one, (c.scene.model_dump(mode="json"), specs, backend, cache_s, c.id, jobs, images)

    try:
        return run_cases(
            sweep.cases,
            out,
            meta,
            task,
            jobs=jobs,
            dask=dask,
            progress=progress,
            batches=_first_of_each_impostor,
            check=sweep_check(sweep.methods),
            extra=extra,
            warm=(warm_worker, backend),
            group=lambda c: impostor_key(c.scene),
            name=f"sweep {Path(path).stem}",
            expect=estimate.teller(
                sweep.methods, Cache(cache_s), jobs=jobs, intervals=False, backend=backend
            ),
        )
    except StudyError as err:  # a case's refusal names the sweep file
        if err.file:
            raise
        raise type(err)(err.detail, file=str(sweep.path), key=err.key, code=err.code) from None


#: What a sweep's output set holds besides its cases (:func:`study.io.output_set`).
OWNS = ("results.csv", "results.parquet", "metadata.json", "plots")


def run_cases(
    cases: list[Case],
    out: str | Path,
    meta: dict,
    task: Callable[[Case], Task],
    *,
    jobs: int = 1,
    dask: str | None = None,
    progress: Callable[[int, int, str], None] | None = None,
    batches: Callable[[list[Case]], tuple[list[Case], ...]] = lambda todo: (todo,),
    check: Check | None = None,
    extra: Callable[[list[dict], Path], None] | None = None,
    into: Path | None = None,
    warm: tuple | None = None,
    group: Callable[[Case], str] | None = None,
    name: str = "cases",
    expect: Callable[[list[Case]], None] | None = None,
) -> tuple[list[dict], dict]:
    """Run the cases not yet finished under ``out`` and write ``<out>/results.csv`` (+ ``metadata.json``, and
    what ``extra(rows, dir)`` writes) as one output set, swapped in at the end (:func:`study.io.output_set`); with
    ``into`` they go to that directory instead, part of the caller's output set (the case files stay in ``out``).

    ``task(case)`` gives the function and arguments that compute a case's rows (run here, in ``jobs`` processes or
    on Dask); each row gets the case id and one ``axis:<key>`` column per label of the case. A case file is reused
    only if ``check(case, rows)`` accepts its rows (e.g. :func:`sweep_check`); computed rows must pass it too.
    ``batches`` splits the cases to run into groups run one after the other (e.g. the first case of each impostor
    first); on Dask a case waits only for earlier batches' cases of its ``group(case)``. ``warm`` = (function,
    *args) readies each Dask worker once (:func:`~study.harness.cluster.warm_worker`). The output directory is
    locked for the run; ``name`` names the run in progress lines (:mod:`study.progress`). Returns (rows, stats =
    {cases, cached, computed, seconds}, and on Dask ``dask``: its fixed cost and steady throughput,
    :func:`~study.harness.cluster.throughput`, also in the metadata)."""
    t0, out = time.perf_counter(), Path(out)
    task = budget.bounded(task)  # workers stop at the command's --max-minutes too
    with locked(out) if into is None else _locked_into(out, into):
        done = {c.index: rows for c in cases if (rows := _load_case(out, c, check)) is not None}
        cached, todo = len(done), [c for c in cases if c.index not in done]
        times: list = []  # the stage times each computed case's first row brought (estimate.TIMES)

        def finish(c: Case, rows: list[dict]):
            times.append(rows[0].pop(estimate.TIMES, None) if rows and isinstance(rows[0], dict) else None)
            if not rows or (check and not check(c, rows)):
                raise RuntimeError(
                    f"case {c.id}: its computed rows ({[r.get('label') for r in rows]}) are not "
                    "what the runner's check expects"
                )
            _identify(c, rows)
            atomic_write(
                _case_file(out, c),
                json_text({"key": c.key, "rows": rows}, nonfinite="text", default=float).encode(),
            )
            done[c.index] = rows
            pg.advance(c.id)
            if progress:
                progress(len(done), len(cases), c.id)

        if progress:
            progress(len(done), len(cases), "")
        timing = None
        with pg.task(name, len(cases), done=len(done)):  # stage lines in this process, the ETA everywhere
            expect(todo) if expect and todo else None  # the cases left's estimate first (estimate.teller)
            if dask and todo:
                timing = run_dask(batches(todo), task, jobs, dask, finish, warm=warm, group=group)
                meta = {**meta, "dask": timing}
            elif jobs <= 1 or len(todo) <= 1:
                for c in todo:
                    fn, args = task(c)
                    with pg.item(c.id):
                        rows = fn(*args)
                    finish(c, rows)
            else:
                _run_parallel(batches(todo), task, jobs, finish)
        rows = [r for i in sorted(done) for r in done[i]]
        if into is None:  # its own output set: what this run took (study.harness.estimate_fit reads it)
            meta = {**meta, **estimate.run_record(time.perf_counter() - t0, [c.id for c in todo], times)}
        outputs = (
            output_set(out, OWNS, keeps=("cases",), lock=False)
            if into is None  # when every case is done
            else contextlib.nullcontext(into)
        )
        with outputs as dest:
            if rows:  # metadata only with the table it describes
                write_table(rows, dest / "results.csv")  # and results.parquet beside it
                atomic_write(dest / "metadata.json", json_text(meta, indent=2).encode())
            if extra:
                extra(rows, dest)
    return rows, {
        "cases": len(cases),
        "cached": cached,
        "computed": len(todo),
        "seconds": time.perf_counter() - t0,
        **({"dask": timing} if timing else {}),
    }


@contextlib.contextmanager
def _locked_into(out: Path, dest: Path):
    """``out`` created and locked for the case files; the outputs go to ``dest`` (a caller's output set)."""
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise os_problem(err, "cannot create the output directory", out) from None
    with locked(out):
        dest.mkdir(parents=True, exist_ok=True)
        yield dest


def _run_parallel(batches, task, jobs, finish) -> None:
    """Cases on ``jobs`` processes, batch after batch."""
    import multiprocessing as mp
    from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait

    with ProcessPoolExecutor(
        max_workers=jobs,
        mp_context=mp.get_context("spawn"),
        initializer=_die_with_parent,
        initargs=(os.getpid(),),
    ) as pool:
        for batch in batches:
            futs = {pool.submit(*_flat(task(c))): c for c in batch}
            while futs:
                fin, _ = wait(futs, return_when=FIRST_COMPLETED)
                for f in fin:
                    finish(futs.pop(f), f.result())


def _die_with_parent(parent: int, poll: float = 0.5) -> None:
    """Worker initializer: exit as soon as the process ``parent`` (the sweep) is gone, never blocking forever on
    a queue nobody writes to. Linux: the kernel kills the worker (PR_SET_PDEATHSIG); everywhere: a daemon thread
    sees the worker re-parented (``os.getppid()`` no longer ``parent``) and exits."""
    import threading

    if sys.platform.startswith("linux"):
        try:
            import ctypes
            import signal

            ctypes.CDLL("libc.so.6", use_errno=True).prctl(
                1, int(signal.SIGKILL), 0, 0, 0
            )  # PR_SET_PDEATHSIG
        except (OSError, AttributeError):  # pragma: no cover - no libc.so.6: the watchdog alone
            pass

    def watch():
        while os.getppid() == parent:
            time.sleep(poll)
        os._exit(3)

    if os.getppid() != parent:  # the parent died while this worker was starting
        os._exit(3)
    threading.Thread(target=watch, name="die-with-parent", daemon=True).start()


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


def _is_study_cli(argv0: str) -> bool:
    """Whether this process is the ``study`` command: its script, ``python -m study`` or ``python -m study.cli``
    (also under ``python -m cProfile -m study.cli``)."""
    return provenance.command([argv0]) == "study"
