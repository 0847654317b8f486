"""Progress by stage: what a long command is doing, how long each stage took, and when the whole will be done.

The pipeline marks its work and never prints: a command's loop over its units is a :func:`task` (the cases of a
figure or sweep, the frames of an animation) whose units finish with :func:`advance`; one unit is an
:func:`item` (a case), and inside it each phase is a :func:`stage` — for a case, in this order, :data:`STAGES`:
load (the environment and the object's rays), placement (automatic placement of the keys a scene leaves out),
capture (impostor and camera renders), probes (the other views methods search: layers, probes, the camera's
buffer), references (Mitsuba with the object, Embree's exact hits, the oracle), methods (every method traced)
and metrics (the rows). A long stage may say how far it is with :func:`note` (``"probe 2/6"``). The command
line decides where that goes by installing a :class:`Reporter` (:func:`reporting`; :mod:`study.cli.progress`
prints lines on stderr — when a stage starts, when it ends, and every few seconds while it runs — with a live bar
on a terminal). Without one every call here is a no-op: the Python API, tests and worker processes stay silent.

The elapsed time and the ETA (the mean time per unit finished in this run × the units left) are computed here,
so every reporter shows the same numbers.

Work stops here too: under a :func:`deadline` (the command's ``--max-minutes``), :func:`checkpoint` raises the
deadline's error once it has passed. Every stage boundary, unit and item is a checkpoint, and long loops inside a
stage call it themselves (a method's samples), so a run its estimate got wrong stops soon after its time is up.
"""

from __future__ import annotations

import contextlib
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field

#: The stages of one case, in the order they run.
STAGES = ("load", "placement", "capture", "probes", "references", "methods", "metrics")


@dataclass
class Task:
    """A command's loop over its units: ``total`` units, ``done`` of them finished (``start`` of those before
    this run began: resumed work does not count towards the ETA)."""

    name: str
    total: int | None
    done: int = 0
    start: int = 0
    t0: float = field(default_factory=time.perf_counter)
    item: str = ""  # the unit now running
    open: list = field(default_factory=list)  # the stages running, outermost first: (name, start)
    detail: str = ""  # how far the stage is (:func:`note`: "probe 2/6"), "" until it says
    expected: float | None = None  # seconds the whole task was estimated to take (:func:`expect`)

    @property
    def stage(self) -> str:
        """The innermost stage now running ("" between stages)."""
        return self.open[-1][0] if self.open else ""

    @property
    def stage_t0(self) -> float:
        return self.open[-1][1] if self.open else self.t0

    @property
    def elapsed(self) -> float:
        return time.perf_counter() - self.t0

    @property
    def eta(self) -> float | None:
        """Seconds left: mean seconds per unit finished in this run × units left; before the first unit, the
        estimate (:func:`expect`) less the time spent (None without one)."""
        ran = self.done - self.start
        if not self.total or ran <= 0:
            return None if self.expected is None else max(self.expected - self.elapsed, 0.0)
        return self.elapsed / ran * max(self.total - self.done, 0)

    @property
    def where(self) -> str:
        """``name i/n item``: the task, the unit now running (counted from 1) and its label."""
        n = f" {min(self.done + 1, self.total)}/{self.total}" if self.total else ""
        return f"{self.name}{n}" + (f" {self.item}" if self.item else "")


class Reporter:
    """Where progress goes (the command line's; the default reports nothing). Every method gets the task."""

    def started(self, task: Task) -> None:
        """A task began (its ``done`` may be > 0: units finished by an earlier run)."""

    def stage(self, task: Task, name: str, seconds: float) -> None:
        """Stage ``name`` of the unit now running finished after ``seconds``."""

    def entered(self, task: Task, name: str) -> None:
        """Stage ``name`` began."""

    def noted(self, task: Task, text: str) -> None:
        """The stage now running said how far it is (``task.detail``)."""

    def expected(self, task: Task, text: str) -> None:
        """The task's estimate, told before its work starts (:func:`expect`): ``text`` says it in one line."""

    def advanced(self, task: Task, what: str) -> None:
        """Unit ``what`` finished (``task.done`` counts it)."""

    def finished(self, task: Task) -> None:
        """The task ended with all its work done."""

    def failed(self, task: Task) -> None:
        """The task ended on an error (the error says why; nothing more to print)."""


_reporter: Reporter | None = None
_tasks: list[Task] = []


@contextlib.contextmanager
def reporting(reporter: Reporter | None) -> Iterator[Reporter | None]:
    """Send progress to ``reporter`` for the duration of the block (``None``: nowhere)."""
    global _reporter
    before, _reporter = _reporter, reporter
    try:
        yield reporter
    finally:
        _reporter = before


def _current() -> Task:
    return _tasks[-1] if _tasks else Task("study", None)


def current() -> Task | None:
    """The innermost task running, None outside every task (what a reporter's heartbeat reads)."""
    return _tasks[-1] if _tasks else None


def note(text: str) -> None:
    """How far the stage now running is (``"probe 2/6"``), for long stages: kept on the task, and the reporter
    told; a no-op without a reporter."""
    if _reporter is None:
        return
    t = _current()
    t.detail = text
    _reporter.noted(t, text)


def expect(seconds: float, text: str) -> None:
    """The current task is estimated to take ``seconds`` (:mod:`study.harness.estimate`), ``text`` the line that
    says so: kept on the task (its ETA starts from it) and told to the reporter; a no-op without a reporter."""
    if _reporter is None:
        return
    t = _current()
    t.expected = float(seconds)
    _reporter.expected(t, text)


def _enter(t: Task, name: str) -> None:
    t.open.append((name, time.perf_counter()))
    t.detail = ""
    _reporter.entered(t, name)


def _close(t: Task, name: str) -> None:
    for i in range(len(t.open) - 1, -1, -1):
        if t.open[i][0] == name:
            del t.open[i:]
            break
    t.detail = ""


def _leave(t: Task, name: str, seconds: float) -> None:
    _close(t, name)
    _reporter.stage(t, name, seconds)


@contextlib.contextmanager
def task(name: str, total: int | None, done: int = 0) -> Iterator[Task]:
    """A loop over ``total`` units, ``done`` of them finished already (resumed); ``finished`` is reported only when
    the block ends without an error."""
    t = Task(name, total, done=done, start=done)
    _tasks.append(t)
    reporter = _reporter
    try:
        if reporter:
            reporter.started(t)
        yield t
    except BaseException:
        if reporter:
            reporter.failed(t)
        raise
    else:
        if reporter:
            reporter.finished(t)
    finally:
        _tasks.remove(t)


def advance(what: str = "") -> None:
    """One unit of the current task finished (then a :func:`checkpoint`)."""
    t = _current()
    t.done += 1
    if _reporter:
        _reporter.advanced(t, what)
    checkpoint()


@contextlib.contextmanager
def item(label: str) -> Iterator[None]:
    """One unit (a case) running: the stages inside are reported under its label."""
    checkpoint()
    t = _current()
    before, t.item, stages = t.item, label, list(t.open)
    try:
        yield
    finally:
        t.item, t.open[:], t.detail = before, stages, ""  # a stage that failed inside is not running any more


@contextlib.contextmanager
def stage(name: str) -> Iterator[None]:
    """A stage of the unit now running (:data:`STAGES` for a case); reported when it begins and with its time
    when it ends (not when it fails: the error says why). Its start is a :func:`checkpoint`."""
    checkpoint()
    if _reporter is None:
        yield
        return
    t = _current()
    _enter(t, name)
    t0 = time.perf_counter()
    try:
        yield
    except BaseException:
        _close(t, name)
        raise
    _leave(t, name, time.perf_counter() - t0)


class Stages:
    """Consecutive stages of one unit without nesting the code: ``mark = Stages()``, then ``mark("load")``,
    ``mark("capture")``, … — each call ends the stage before it — and ``mark.end()`` after the last.

    Each stage's wall time is kept in ``seconds`` (reporter or not), and the part of it spent in Mitsuba's renders
    (:func:`rendering`) in ``rendered``: what a case's time split is made of (:func:`study.measure.case.time_split`)."""

    def __init__(self) -> None:
        self._name: str | None = None
        self._t0 = 0.0
        self._told = False  # the reporter was told the stage began
        self.seconds: dict[str, float] = {}
        self.rendered: dict[str, float] = {}

    def __call__(self, name: str) -> None:
        global _clock
        self.end()
        checkpoint()
        self._name, self._t0, self._told, _clock = name, time.perf_counter(), _reporter is not None, self
        if self._told:
            _enter(_current(), name)

    def end(self) -> None:
        global _clock
        if self._name is not None:
            dt = time.perf_counter() - self._t0
            self.seconds[self._name] = self.seconds.get(self._name, 0.0) + dt
            if self._told and _reporter is not None:
                _leave(_current(), self._name, dt)
        if _clock is self:
            _clock = None
        self._name = None

    def split(self) -> dict[str, float]:
        """Seconds per :data:`CASE_PARTS` from a case's stages (:data:`STAGES`): ``inputs`` the rays and the
        impostor's distances (load, placement, capture), ``renders`` Mitsuba's renders outside the probes (the
        impostor's faces, the camera views, the truth along the exact rays, the oracle's second captures:
        :func:`rendering`), ``probes`` the views methods search (probes' and layers' path tracing, distance
        fields, caches), ``exact`` Embree's exact hits and the oracle, ``traces`` the methods, ``columns`` the
        rows. A cached render costs its read."""
        sec, ren = self.seconds, self.rendered
        own = {k: sec.get(k, 0.0) - (ren.get(k, 0.0) if k != "probes" else 0.0) for k in sec}
        out = {
            "inputs": own.get("load", 0.0) + own.get("placement", 0.0) + own.get("capture", 0.0),
            "renders": sum(v for k, v in ren.items() if k != "probes"),
            "probes": own.get("probes", 0.0),
            "exact": own.get("references", 0.0),
            "traces": own.get("methods", 0.0),
            "columns": own.get("metrics", 0.0),
        }
        return {k: round(max(v, 0.0), 3) for k, v in out.items()}


#: The parts of a case's wall time (:meth:`Stages.split`), in pipeline order; a figure adds ``outputs``.
CASE_PARTS = ("inputs", "renders", "probes", "exact", "traces", "columns")


def split_line(times: dict[str, float]) -> str:
    """One line of a time split: ``inputs 1.2 s, renders 30.1 s, …`` and what is left without the renders and
    the probes (the part a faster renderer does not shorten)."""
    parts = ", ".join(f"{k} {v:.1f} s" for k, v in times.items())
    rest = sum(v for k, v in times.items() if k not in ("renders", "probes"))
    return f"{parts}; without renders and probes {rest:.1f} s"


#: the :class:`Stages` whose stage is running now (where :func:`rendering` books its time)
_clock: Stages | None = None
_rendering = 0  # depth of nested :func:`rendering` calls (the outermost one books)


def rendering(fn: Callable) -> Callable:
    """Decorate a function that renders with Mitsuba (a camera view, cube faces, radiance along rays): its wall
    time is booked to the stage running (:attr:`Stages.rendered`), once where such calls nest."""
    import functools

    @functools.wraps(fn)
    def timed(*args, **kwargs):
        global _rendering
        clock, t0 = _clock, time.perf_counter()
        _rendering += 1
        try:
            return fn(*args, **kwargs)
        finally:
            _rendering -= 1
            if _rendering == 0 and clock is not None and clock._name is not None:
                clock.rendered[clock._name] = clock.rendered.get(clock._name, 0.0) + time.perf_counter() - t0

    return timed


# ---------------------------------------------------------------------------------------------- the time limit
_deadlines: list[tuple[float, Callable[[], BaseException]]] = []


@contextlib.contextmanager
def deadline(at: float, error: Callable[[], BaseException]) -> Iterator[None]:
    """Until the block ends, :func:`checkpoint` raises ``error()`` once the wall clock (``time.time()``, so that
    worker processes share it) has passed ``at``."""
    entry = (at, error)
    _deadlines.append(entry)
    try:
        yield
    finally:
        _deadlines.remove(entry)


def checkpoint() -> None:
    """A point where work may stop: raises the error of the earliest :func:`deadline` passed (a no-op without
    one, or before it)."""
    if _deadlines:
        at, error = min(_deadlines, key=lambda d: d[0])
        if time.time() > at:
            raise error()
