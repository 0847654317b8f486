"""Figure kinds, registered by name: what ``study figure`` makes from a config and what the report shows of it.

A config names its kind (``kind = "caustics"``; a config without one is a ``grid``), and each kind is one module
of this package declaring a :class:`FigureKind`: that name, its runner, the files its runs write into their
folder (the report knows a folder under ``reports/`` as the kind's by them, whatever the folder's name) and the
report section for such a folder. Every module of the package is imported here, so adding a kind means adding a
file and nothing else; from outside the package, the same :func:`register_kind` call in a module loaded with
``study --plugin MODULE`` (``tests/report/test_figure_kinds.py`` does that). The built-in kinds: ``grid`` (image grids
and metrics, :mod:`.grid`), ``glossy`` (a grid and its error split, :mod:`.glossy_split`), ``caustics``
(Figure 8, :mod:`.caustics`) and ``animation`` (motion, :mod:`.animation`).
"""

from __future__ import annotations

import importlib
import pkgutil
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from study.errors import StudyError
from study.io import read_toml

#: The kind of a config that names none.
DEFAULT_KIND = "grid"
#: Where a kind's sections stand in the report: among the figures (sorted by folder), or after the sweeps.
WITH_FIGURES, AFTER_SWEEPS = 0, 1


@dataclass(frozen=True)
class FigureKind:
    """One kind of figure.

    ``name``: what a config writes in ``kind = "…"``. ``run(config, out, *, name, backend, cache, quality)``
    makes the figure from the config file into the folder ``out`` and returns its rows. ``files``: what every run
    writes into ``out`` (paths relative to it); a folder directly under the reports holding all of them is this
    kind's (the kind with the most files that match wins). ``section(reports, folder, table, cols)`` returns the
    report's blocks for such a folder (:mod:`study.report.report`: headings, paragraphs, tables, images);
    ``table`` is the folder's ``metrics.csv`` as the report read it where ``tables`` is true (it then joins the
    tables the claims and the method comparison are judged on), else empty; ``cols``: the report's summary
    columns. ``place``: :data:`WITH_FIGURES` or :data:`AFTER_SWEEPS` (then ``rank`` orders the kinds there).
    ``lines(rows)``: what ``study figure`` prints of the rows (None: the rows as a table)."""

    name: str
    run: Callable[..., list[dict]]
    files: tuple[str, ...]
    section: Callable[[Path, Path, list[dict], list[str]], list[tuple]]
    tables: bool = False
    place: int = WITH_FIGURES
    rank: int = 0
    lines: Callable[[list[dict]], list[str]] | None = None


#: name → kind, every kind registered so far.
KINDS: dict[str, FigureKind] = {}


def register_kind(kind: FigureKind) -> FigureKind:
    """Add ``kind`` under its name; a name taken by another kind is an error."""
    if not isinstance(kind, FigureKind) or not kind.files:
        raise StudyError(f"{kind!r} is no FigureKind with files", key="kind")
    old = KINDS.get(kind.name)
    if old is not None and old != kind:
        raise StudyError(f"figure kind {kind.name!r} is registered twice", key="kind")
    KINDS[kind.name] = kind
    return kind


def kind_named(name: object, *, source: str = "") -> FigureKind:
    """The kind called ``name``; an unknown one is one line naming the allowed ones."""
    if not isinstance(name, str) or name not in KINDS:
        raise StudyError(
            f"unknown figure kind {name!r}; allowed: {', '.join(sorted(KINDS))}", file=source, key="kind"
        )
    return KINDS[name]


def config_kind(config: str | Path) -> FigureKind:
    """The kind a config file names in ``kind = "…"`` (:data:`DEFAULT_KIND` where it names none)."""
    return kind_named(read_toml(config).get("kind", DEFAULT_KIND), source=str(config))


def folder_kind(d: Path) -> FigureKind | None:
    """The kind whose files folder ``d`` holds (of several, the one with the most files), or None."""
    fits = [k for k in KINDS.values() if all((d / f).is_file() for f in k.files)]
    return max(fits, key=lambda k: len(k.files), default=None)


def found(reports: Path) -> list[tuple[FigureKind, Path]]:
    """The folders directly under ``reports`` (hidden ones aside) that a kind's run wrote, with their kinds, in
    the report's order: by place, then rank among the kinds after the sweeps, then folder."""
    out = []
    for d in sorted(reports.iterdir()) if reports.is_dir() else []:
        if d.is_dir() and not d.name.startswith(".") and ".tmp" not in d.name and (k := folder_kind(d)):
            out.append((k, d))
    return sorted(out, key=lambda kd: (kd[0].place, kd[0].rank if kd[0].place else 0, kd[1].name))


for _m in pkgutil.iter_modules(__path__):
    importlib.import_module(f"{__name__}.{_m.name}")
