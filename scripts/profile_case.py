"""Where a case of a sweep, or a whole figure, spends its time, under cProfile in this process (no progress display,
so no thread of study's own blurs the profile):

    python scripts/profile_case.py configs/sweep.toml [BACKEND] [CASE] [CACHE]   # case number CASE (default: last)
    python scripts/profile_case.py configs/fig4.toml [BACKEND] [NAME] [CACHE]    # the figure (NAME: its name)

Each runs twice, on an empty cache and then on the cache the first run filled, and prints the costliest calls of
each run, by cumulative and by own time. Used on the GPU machine by ``scripts/device_run.sh profile``."""

import cProfile
import pstats
import shutil
import sys
import tempfile
import time
from pathlib import Path

from study import runtime
from study.cache import Cache

path, backend = sys.argv[1], (sys.argv[2] if len(sys.argv) > 2 else "numpy")
which = sys.argv[3] if len(sys.argv) > 3 else None
cache_dir = sys.argv[4] if len(sys.argv) > 4 else tempfile.mkdtemp(prefix="study-profile-")
runtime.set_render_device("cuda" if backend == "cuda" else "cpu")
shutil.rmtree(cache_dir, ignore_errors=True)
if "\n[axes" in "\n" + Path(path).read_text():  # a sweep (its cases come from axes)
    from study.harness.runner import prepare_sweep
    from study.measure.case import run_case

    sweep = prepare_sweep(path, backend=backend)
    case = sweep.cases[int(which) if which else -1]
    name = case.id

    def job():
        run_case(case.scene, sweep.methods, backend=backend, cache=Cache(cache_dir), case_id=case.id)
else:
    from study.outputs.figures import figure_positions

    name = which or Path(path).stem
    out = Path(tempfile.mkdtemp(prefix="study-profile-out-"))

    def job():
        shutil.rmtree(out / name, ignore_errors=True)
        figure_positions(path, out / name, name=name, backend=backend, cache=cache_dir)


for run in ("cold", "warm"):
    prof = cProfile.Profile()
    t0 = time.perf_counter()
    prof.runcall(job)
    print(f"== {name} {run}: {time.perf_counter() - t0:.1f} s", flush=True)
    st = pstats.Stats(prof)
    st.sort_stats("cumulative").print_stats(45)
    st.sort_stats("tottime").print_stats(25)
