"""Progress on stderr for every long command (no command of its own): each stage of each case when it starts and
when it ends, with its time, a line every few seconds while a long one runs (with how far it is, where the stage
says: ``probe 2/6``), and each finished unit with the ETA (:mod:`study.progress`), as plain timestamped lines —
what a log or CI keeps, also when stderr is a file — and, on a terminal, a live bar under them. Installed by
:func:`study.cli.app.guarded`; ``study --quiet`` turns it off. Tables and results go to stdout, untouched.

A log of ``study figure fig4`` reads::

    [    0.3 s] fig4 1/4 fig4-p0: load …
    [    1.4 s] fig4 1/4 fig4-p0: load 1.1 s
    [    1.4 s] fig4 1/4 fig4-p0: capture …
    [    6.4 s] fig4 1/4 fig4-p0: capture running for 5.0 s
    …
    [  320.2 s] fig4 1/4 fig4-p0: capture 5 min 19 s
    …
    [  …     s] fig4: 1/4 done (fig4-p0), ETA …
"""

from __future__ import annotations

import os
import threading
import time

from rich.console import Console
from rich.markup import escape

from study.progress import Reporter, Task


def duration(seconds: float | None) -> str:
    """``42.0 s``, ``3 min 12 s``, ``1 h 02 min``; ``?`` for None."""
    if seconds is None:
        return "?"
    if seconds < 60:
        return f"{seconds:.1f} s"
    m, s = divmod(round(seconds), 60)
    if m < 60:
        return f"{m} min {s} s"
    h, m = divmod(m, 60)
    return f"{h} h {m:02d} min"


def _every() -> float:
    """Seconds between the lines that say a long stage still runs: ``$STUDY_PROGRESS_EVERY`` (0: none), else 5."""
    try:
        return max(0.0, float(os.environ.get("STUDY_PROGRESS_EVERY", "5")))
    except ValueError:
        return 5.0


#: Seconds between the lines that say a long stage is still running (when nothing else was printed meanwhile).
EVERY = _every()


class Lines(Reporter):
    """One line when a stage starts and when it ends, one per finished unit, and while a stage runs one every
    ``every`` seconds that nothing else was printed (a thread: Mitsuba and Dr.Jit let it run while they render);
    each stamped with the seconds since the command began."""

    def __init__(self, console: Console, every: float | None = None):
        self.console = console
        self.t0 = self.last = time.perf_counter()
        self.every = EVERY if every is None else every
        self.tasks: list[Task] = []
        self.lock = threading.RLock()
        self.stop = threading.Event()
        self.beat: threading.Thread | None = None

    def line(self, text: str) -> None:
        with self.lock:
            self.last = time.perf_counter()
            stamp = f"[{self.last - self.t0:7.1f} s] "
            self.console.print(stamp + text, highlight=False, markup=False, soft_wrap=True)

    def started(self, task: Task) -> None:
        self.tasks.append(task)
        if self.beat is None and self.every > 0:
            self.stop.clear()
            self.beat = threading.Thread(target=self._beat, name="study-progress", daemon=True)
            self.beat.start()

    def _beat(self) -> None:
        while not self.stop.wait(min(self.every / 4, 1.0)):
            t = self.tasks[-1] if self.tasks else None
            now = time.perf_counter()
            if t is None or not t.stage or now - max(self.last, t.stage_t0) < self.every:
                continue
            how = f" ({t.detail})" if t.detail else ""
            left = t.eta
            eta = "" if left is None else f", ETA {duration(left)}"
            self.line(f"{t.where}: {t.stage} running for {duration(now - t.stage_t0)}{how}{eta}")

    def _ended(self, task: Task) -> None:
        if task in self.tasks:
            self.tasks.remove(task)
        if not self.tasks and self.beat is not None:
            self.stop.set()
            self.beat.join()
            self.beat = None

    def failed(self, task: Task) -> None:
        self._ended(task)

    def expected(self, task: Task, text: str) -> None:
        self.line(text)

    def entered(self, task: Task, name: str) -> None:
        self.line(f"{task.where}: {name} …")

    def stage(self, task: Task, name: str, seconds: float) -> None:
        self.line(f"{task.where}: {name} {duration(seconds)}")

    def advanced(self, task: Task, what: str) -> None:
        of = f"/{task.total}" if task.total else ""
        left = task.eta
        eta = "" if left is None else (", ETA " + duration(left) if task.done < (task.total or 0) else "")
        earlier = f", {task.start} of them by an earlier run" if task.start else ""
        self.line(f"{task.name}: {task.done}{of} done" + (f" ({what})" if what else "") + earlier + eta)

    def finished(self, task: Task) -> None:
        self._ended(task)
        self.line(f"{task.name}: finished in {duration(task.elapsed)}")


class Bar(Lines):
    """:class:`Lines` printed above a live bar (units done, elapsed, ETA, the stage now running): a terminal's."""

    def __init__(self, console: Console):
        from rich.progress import (
            BarColumn,
            MofNCompleteColumn,
            Progress,
            TextColumn,
            TimeElapsedColumn,
            TimeRemainingColumn,
        )

        super().__init__(console, every=0)  # the bar shows the stage and its time, live
        self.bar = Progress(
            TextColumn("{task.description}"),
            BarColumn(),
            MofNCompleteColumn(),
            TimeElapsedColumn(),
            TextColumn("ETA"),
            TimeRemainingColumn(),
            console=console,
            transient=True,
        )
        self.ids: dict[int, int] = {}

    def line(self, text: str) -> None:
        stamp = f"[{time.perf_counter() - self.t0:7.1f} s] "
        self.bar.console.print(stamp + text, highlight=False, markup=False, soft_wrap=True)

    def started(self, task: Task) -> None:
        if not self.ids:
            self.bar.start()
        self.ids[id(task)] = self.bar.add_task(escape(task.name), total=task.total, completed=task.done)

    def entered(self, task: Task, name: str) -> None:
        super().entered(task, name)
        if id(task) in self.ids:
            self.bar.update(self.ids[id(task)], total=task.total, description=escape(f"{task.where}: {name}"))

    def noted(self, task: Task, text: str) -> None:
        if id(task) in self.ids:
            where = f"{task.where}: {task.stage} ({text})"
            self.bar.update(self.ids[id(task)], total=task.total, description=escape(where))

    def advanced(self, task: Task, what: str) -> None:
        if id(task) in self.ids:
            self.bar.update(self.ids[id(task)], total=task.total, completed=task.done)
        super().advanced(task, what)

    def failed(self, task: Task) -> None:
        tid = self.ids.pop(id(task), None)
        if tid is not None:
            self.bar.remove_task(tid)
        if not self.ids:
            self.bar.stop()

    def finished(self, task: Task) -> None:
        self.failed(task)  # the bar goes either way
        super().finished(task)


def reporter(console: Console) -> Lines:
    """The reporter for ``console`` (stderr): a live bar on a terminal, plain lines elsewhere."""
    return Bar(console) if console.is_terminal else Lines(console)
