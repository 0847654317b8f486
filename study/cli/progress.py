"""Progress on stderr for every long command (no command of its own): the stages of each case with their times
and each finished unit with the ETA (:mod:`study.progress`), as plain timestamped lines — what a log or CI keeps —
and, on a terminal, a live bar under them. Installed by :func:`study.cli.app.guarded`; ``study --quiet`` turns it
off. Tables and results go to stdout, untouched.

A log of ``study figure fig4`` reads::

    [    1.4 s] fig4 1/4 fig4-p0: load 1.1 s
    [  320.2 s] fig4 1/4 fig4-p0: capture 5 min 19 s
    …
    [  …     s] fig4: 1/4 done (fig4-p0), ETA …
"""

from __future__ import annotations

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


class Lines(Reporter):
    """One line per finished stage and per finished unit, stamped with the seconds since the command began."""

    def __init__(self, console: Console):
        self.console = console
        self.t0 = time.perf_counter()

    def line(self, text: str) -> None:
        stamp = f"[{time.perf_counter() - self.t0:7.1f} s] "
        self.console.print(stamp + text, highlight=False, markup=False, soft_wrap=True)

    def stage(self, task: Task, name: str, seconds: float) -> None:
        self.line(f"{task.where}: {name} {duration(seconds)}")

    def advanced(self, task: Task, what: str) -> None:
        of = f"/{task.total}" if task.total else ""
        left = task.eta
        eta = "" if left is None else (", ETA " + duration(left) if task.done < (task.total or 0) else "")
        earlier = f", {task.start} of them by an earlier run" if task.start else ""
        self.line(f"{task.name}: {task.done}{of} done" + (f" ({what})" if what else "") + earlier + eta)

    def finished(self, task: Task) -> None:
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

        super().__init__(console)
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
        if id(task) in self.ids:
            self.bar.update(self.ids[id(task)], total=task.total, description=escape(f"{task.where}: {name}"))

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
