"""Where a command's wall time goes on every thread: a sampling profiler over ``sys._current_frames()``.

cProfile sees only the thread it was started on; study's columns run on a thread pool (study/measure/workers.py)
and a figure's cases one behind, so the case's thread alone does not say what the wall clock waits for. This runs
a module in this process, samples every thread's stack every ``--interval`` seconds and writes, per thread group
(the main thread, the columns' pool, …), the functions by inclusive and by self share of that group's samples,
with the share of samples where the group was idle (waiting on a lock, a queue or a future).

    PYTHONPATH=. .venv/bin/python scripts/wall_profile.py OUT.txt [--interval 0.005] [--top 40] \\
        -m study.cli figure fig4 --backend llvm --out /tmp/o

Samples are taken under the GIL, so a thread inside C code that holds it (numpy, Dr.Jit's tracing) is seen where
it called in; one that released it (a kernel, I/O) is seen there too, since its Python frame stays on the stack.
Each sample counts the wall time since the sampler's previous one, not ``--interval``: a sampler that waits for the
GIL, or for a core on a loaded machine, samples less often than asked (0.6 s of a thread's wait read as 0.2 s, and a
50 s run's main thread as 37 s, when samples were counted at the interval), and each thread's seconds add up to the
time it was seen alive.
"""

from __future__ import annotations

import argparse
import collections
import os
import runpy
import sys
import threading
import time

IDLE = {  # a thread whose innermost frame is one of these is waiting, not working
    ("threading.py", "wait"),
    ("threading.py", "_wait_for_tstate_lock"),
    ("queue.py", "get"),
    ("thread.py", "_worker"),
    ("_base.py", "result"),
    ("_base.py", "wait"),
    ("selectors.py", "select"),
}


def _group(name: str) -> str:
    """'ThreadPoolExecutor-0_7' → 'ThreadPoolExecutor-0': one row per pool, not per worker."""
    return name.rsplit("_", 1)[0] if "_" in name and name.rsplit("_", 1)[1].isdigit() else name


def _key(code) -> tuple[str, str]:
    f = code.co_filename
    parts = f.replace("\\", "/").split("/")
    short = "/".join(parts[-2:]) if "study" not in parts else "/".join(parts[parts.index("study") :])
    return short, f"{code.co_name}:{code.co_firstlineno}"


class Sampler(threading.Thread):
    def __init__(self, interval: float):
        super().__init__(name="wall-profile", daemon=True)
        self.interval, self.stop = interval, threading.Event()
        self.samples = collections.Counter()  # group → samples
        self.seconds = collections.Counter()  # group → wall seconds its samples stand for
        self.idle = collections.Counter()  # group → seconds idle
        self.incl: dict[str, collections.Counter] = collections.defaultdict(collections.Counter)
        self.self_: dict[str, collections.Counter] = collections.defaultdict(collections.Counter)

    def run(self):
        me, last = threading.get_ident(), time.perf_counter()
        while not self.stop.wait(self.interval):
            now = time.perf_counter()
            dt, last = now - last, now  # the wall time this sample stands for
            names = {t.ident: t.name for t in threading.enumerate()}
            for ident, frame in sys._current_frames().items():
                if ident == me:
                    continue
                g = _group(names.get(ident, f"thread-{ident}"))
                top = frame.f_code
                file = os.path.basename(top.co_filename)
                self.samples[g] += 1
                self.seconds[g] += dt
                if (file, top.co_name) in IDLE:
                    self.idle[g] += dt
                    continue
                self.self_[g][_key(top)] += dt
                seen = set()
                while frame is not None:
                    k = _key(frame.f_code)
                    if k not in seen:
                        seen.add(k)
                        self.incl[g][k] += dt
                    frame = frame.f_back


def report(s: Sampler, wall: float, interval: float, top: int) -> str:
    asked = (
        f"a sample each {interval * 1e3:g} ms per thread asked, each weighing the time since the one before"
    )
    lines = [f"wall {wall:.1f} s, {asked}"]
    for g, sec in s.seconds.most_common():
        busy = sec - s.idle[g]
        lines.append(
            f"\n## {g}: {s.samples[g]} samples, {sec:.1f} s, busy {busy:.1f} s ({busy / max(sec, 1e-9):.0%}), "
            f"idle {s.idle[g]:.1f} s"
        )
        if busy <= 0:
            continue
        for title, table in (("inclusive", s.incl[g]), ("self", s.self_[g])):
            lines.append(f"### {title} (seconds, share of busy)")
            for (f, fn), c in table.most_common(top):
                lines.append(f"{c:8.2f} {c / busy:6.1%}  {f} {fn}")
    return "\n".join(lines) + "\n"


def main(argv=None):
    argv = list(sys.argv[1:] if argv is None else argv)
    if "-m" not in argv:
        raise SystemExit("wall_profile: usage: OUT.txt [--interval S] [--top N] -m MODULE [ARGS...]")
    i = argv.index("-m")
    p = argparse.ArgumentParser(prog="wall_profile")
    p.add_argument("out")
    p.add_argument("--interval", type=float, default=0.005)
    p.add_argument("--top", type=int, default=60)
    a = p.parse_args(argv[:i])
    module, rest = argv[i + 1], argv[i + 2 :]
    sampler = Sampler(a.interval)
    sampler.start()
    t0, code = time.perf_counter(), 0
    sys.argv = [module, *rest]
    try:
        runpy.run_module(module, run_name="__main__", alter_sys=True)
    except SystemExit as e:
        code = e.code if isinstance(e.code, int) else (0 if e.code is None else 1)
    finally:
        sampler.stop.set()
        sampler.join()
        with open(a.out, "w") as f:
            f.write(
                f"# {module} {' '.join(rest)}\n"
                + report(sampler, time.perf_counter() - t0, a.interval, a.top)
            )
    return code


if __name__ == "__main__":
    sys.exit(main())
