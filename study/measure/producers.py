"""Column producers: the functions that write a case's columns from one trace's rays (:class:`RayContext`), each
declaring the columns it writes, so that two writers of one name are an error when the second registers.

A plug-in adds a per-ray column with one declaration (:func:`study.columns.declare`) and one producer
(:func:`producer`, also reachable as ``study.measure.case.producer``); :func:`study.measure.case.run_case` calls
every registered producer for every trace of every case and adds its columns to the trace's row. The built-in
column groups (the trace's identity, geometry, outcome classes, ray intervals, off-screen hits, image errors,
the references' own, the method's flags, the search's cost: :mod:`study.measure.groups`) are producers over the
same context, registered with :func:`group` and declared the same way; a row is theirs in that order, the
plug-ins' after the references' own.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from study import columns
from study import columns as columns_table  # where `columns` names a producer's argument
from study.errors import StudyError


@dataclass(frozen=True)
class RayContext:
    """What a column producer sees of one trace in one case: per ray (K) and per pixel (H, W)."""

    x: np.ndarray  # (K, 3) shading points
    R: np.ndarray  # (K, 3) secondary ray directions
    shown: np.ndarray  # (K, 3) the trace's shown points
    exact: np.ndarray  # (K, 3) the exact hits (escaping rays at FAR)
    occluded: np.ndarray  # (K,) the exact hit is hidden from the reference point
    classes: np.ndarray  # (K,) outcome classes (study.measure.outcomes)
    angle: np.ndarray  # (K,) angular error, degrees
    image: np.ndarray  # (H, W, 3) the trace's image
    truth: np.ndarray  # (H, W, 3) truth_at_hit
    mask: np.ndarray  # (H, W) pixels fully on the object
    label: str  # the method's label (or the reference's name)
    # the case around the trace, once per case (the built-in groups read them; a plug-in may)
    trace: Any = (
        None  # study.measure.case.Traced: what the trace answered (validity, ratio, cost, knobs, flags)
    )
    rays: Any = None  # study.optics.shading's object rays (pixels, sub-pixel sources)
    hits: Any = None  # study.measure.case.ExactHits (tolerances, off-screen hits)
    pixels: np.ndarray | None = None  # (K,) each ray's pixel (study.stats.spatial.ray_pixels)
    held: np.ndarray | None = None  # (K,) the exact hit is held by o's views (study.measure.split.held)
    image_columns: dict | None = None  # the trace's image errors, measured with the case's other traces
    case_columns: dict | None = None  # the case's own columns, the same in each of its rows


#: column producers beyond the built-in ones (:func:`producer`), called for every trace of every case
PRODUCERS: list = []
#: column → the producer that writes it (``module.name``): what each registered producer declared it writes
WRITERS: dict[str, str] = {}
#: who writes the built-in columns (:data:`study.columns.BUILTIN`), as errors name it
BUILTIN_WRITER = "study's built-in columns (study.measure.case)"


def _writer(fn) -> str:
    return f"{fn.__module__}.{fn.__qualname__}"


def _written_by(name: str) -> str | None:
    """Who already writes the column ``name`` (an interval's ``_lo``/``_hi`` through its column), or None."""
    if name in WRITERS:
        return WRITERS[name]
    return BUILTIN_WRITER if name in columns.BUILTIN else None


#: the built-in column groups (:func:`group`), in the order a row holds them; ``AFTER``: those after the plug-ins'
GROUPS: list = []
AFTER: list = []


def group(*, columns: tuple[str, ...] = (), after_plugins: bool = False):
    """Register a built-in column group ``fn(ctx: RayContext) -> {column: value}`` that writes ``columns`` (each
    declared in :mod:`study.column_rows`; a group whose names depend on the trace, as the flags', declares none):
    the plug-ins' producers may write none of them (:func:`producer` names the group)."""

    def register(f):
        name = f"the built-in group {_writer(f)}"
        for c in columns:
            if columns_table.declared(c) is None:
                raise ValueError(f"{name} writes the column {c!r}, which study.column_rows does not declare")
            if WRITERS.get(c, name) != name:
                raise ValueError(f"{name} writes the column {c!r}, which {WRITERS[c]} already writes")
        WRITERS.update(dict.fromkeys(columns, name))
        f.columns = tuple(columns)
        (AFTER if after_plugins else GROUPS).append(f)
        return f

    return register


def producer(fn=None, *, columns: tuple[str, ...] | list[str] = ()):
    """Register ``fn(ctx: RayContext) -> {column: value}``: its columns join every row of every case, and so every
    table, API result and report, once each is declared (:func:`study.columns.declare`). A column that is not
    declared is an error naming the producer.

    ``@producer(columns=("my_col", …))`` declares what ``fn`` writes: a name that a built-in column or another
    producer already writes is an error here, at registration (one line naming both), rather than a value silently
    replaced in every row. The bare ``@producer`` still registers; its columns are checked the same way when it
    first writes them."""

    def register(f):
        name = _writer(f)
        for c in columns:
            who = _written_by(c)
            if who is not None and who != name:
                raise StudyError(
                    f"{name} writes the column {c!r}, which {who} already writes; give it a name of its own",
                    key="columns",
                )
        for stale in [k for k, w in WRITERS.items() if w == name]:  # the same one again: a module reloaded
            del WRITERS[stale]
        PRODUCERS[:] = [p for p in PRODUCERS if _writer(p) != name]
        WRITERS.update(dict.fromkeys(columns, name))
        PRODUCERS.append(f)
        return f

    return register if fn is None else register(fn)


def _produced(ctx: RayContext, taken=()) -> dict:
    """Every registered producer's columns of one trace; ``taken``: the names the row already has from elsewhere
    (a method's flags), which no producer may write."""
    out, by = {}, {}
    for fn in PRODUCERS:
        cols = fn(ctx)
        name = _writer(fn)
        for k in cols:
            if columns.declared(k) is None:
                raise StudyError(
                    f"{name} writes the column {k!r}, which is not declared; declare it "
                    "with study.columns.declare(TableColumn(...))",
                    key="columns",
                )
            who = by.get(k) or _written_by(k) or ("the method's flags" if k in taken else None)
            if who is not None and who != name:
                raise StudyError(
                    f"{name} writes the column {k!r}, which {who} already writes; give it a name of its own",
                    key="columns",
                )
            by[k] = name
        out.update(cols)
    return out
