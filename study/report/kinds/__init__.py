"""Figure kinds, registered by name: what ``study figure`` makes from a config and what the report shows of it.

A config names its kind (``kind = "caustics"``; a config without one is a ``grid``), and each kind is one module
of this package declaring a :class:`FigureKind`: that name, its runner, the files its runs write into their
folder (the report knows a folder under ``reports/`` as the kind's by them, whatever the folder's name) and the
report section for such a folder. Every module of the package is imported here, so adding a kind means adding a
file and nothing else; from outside the package, the same :func:`register_kind` call in a module loaded with
``study --plugin MODULE`` (``tests/report/test_figure_kinds.py`` does that). The built-in kinds: ``grid`` (image grids
and metrics, :mod:`.grid`), ``glossy`` (a grid and its error split, :mod:`.glossy_split`), ``caustics``
(Figure 8, :mod:`.caustics`) and ``animation`` (motion, :mod:`.animation`).

``study figure`` runs a kind through :meth:`FigureKind.make`, which holds a plug-in kind to its contract as
:meth:`study.methods.Method._guarded` holds a method and :func:`study.scene.sources.base.source_call` a source: a
``run`` that raises, calls ``sys.exit`` (even ``sys.exit(0)``) or returns anything but a list of rows (dicts) is one
StudyError line naming the kind and what it did (exit 2); so is a ``lines`` that fails. :func:`register_kind` says
in a sentence what is wrong with a kind it refuses.
"""

from __future__ import annotations

import importlib
import inspect
import pkgutil
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from study.errors import StudyError, plugin_guard
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

    @property
    def plugin(self) -> bool:
        """Whether the kind's runner comes from outside study (a plug-in's module)."""
        return not str(getattr(self.run, "__module__", "") or "").startswith("study.")

    def _who(self) -> str:
        mod = getattr(self.run, "__module__", None)
        return f"figure kind {self.name!r}" + (f" (plug-in {mod})" if self.plugin else "")

    def _guarded(self, what: str, call):
        who = self._who()
        return plugin_guard(
            call,
            plugin=self.plugin,
            exited=lambda code: f"{who}: {what} called sys.exit({code!r}); a kind returns its rows",
            failed=f"{who}: {what} failed",
        )

    def make(self, config: str | Path, out: Path, **options) -> list[dict]:
        """``run(config, out, **options)`` held to the contract (module docstring): its rows, or one StudyError
        line naming the kind. ``options`` the runner does not take (``images``: the grid's) are left out.

        Parameters
        ----------
        config : the figure's config file
        out : the folder it writes
        **options : ``name``, ``backend``, ``cache``, ``quality`` and, for runners that take them, ``images``

        Returns
        -------
        list of dict
            the rows, one per case and method (what ``study figure`` prints).
        """
        try:
            takes = "images" in inspect.signature(self.run).parameters  # the grid's per-case images
        except (TypeError, ValueError):  # a callable without a signature
            takes = False
        if not takes:
            options.pop("images", None)
        rows = self._guarded("run()", lambda: self.run(config, out, **options))
        if not isinstance(rows, list) or not all(isinstance(r, dict) for r in rows):
            bad = next((r for r in rows if not isinstance(r, dict)), None) if isinstance(rows, list) else rows
            got = _what(rows) if not isinstance(rows, list) else f"a list holding {_what(bad)}"
            raise StudyError(
                f"{self._who()}: run() returned {got}; a kind's run returns a list of rows (dicts)"
            )
        return rows

    def printed(self, rows: list[dict]) -> list[str] | None:
        """What ``study figure`` prints of ``rows``: the kind's ``lines`` (checked: a list of text lines), or None
        for the rows as a table."""
        if self.lines is None:
            return None
        out = self._guarded("lines()", lambda: self.lines(rows))
        if not isinstance(out, (list, tuple)) or not all(isinstance(x, str) for x in out):
            raise StudyError(f"{self._who()}: lines() returned {_what(out)}; it returns a list of text lines")
        return list(out)


def _what(v) -> str:
    """A value in a few words for a message (never its whole repr)."""
    if v is None:
        return "None"
    text, name = repr(v), type(v).__name__
    return f"{'an' if name[0] in 'aeiou' else 'a'} {name}" + (f" ({text})" if len(text) <= 40 else "")


def kind_problem(kind) -> str | None:
    """What keeps ``kind`` from being registered, as a sentence (None: nothing)."""
    if not isinstance(kind, FigureKind):
        return f"register_kind takes a study.report.kinds.FigureKind, not {_what(kind)}"
    if not isinstance(kind.name, str) or not kind.name.strip():
        return f'a figure kind\'s name is the word a config writes in kind = "…", not {_what(kind.name)}'
    if not callable(kind.run) or not callable(kind.section):
        return f"figure kind {kind.name!r}: run and section must be functions (see study.report.kinds.FigureKind)"
    files = kind.files
    if isinstance(files, str) or not isinstance(files, (tuple, list)) or not files:
        return (f"figure kind {kind.name!r} declares no files: files names what every run writes into its folder "
                "(e.g. files=(\"metrics.csv\",)), by which the report finds the folder as this kind's")  # fmt: skip
    if not all(
        isinstance(f, str) and f and not Path(f).is_absolute() and ".." not in Path(f).parts for f in files
    ):
        return f"figure kind {kind.name!r}: files are paths relative to the run's folder, not {list(files)!r}"
    return None


#: name → kind, every kind registered so far.
KINDS: dict[str, FigureKind] = {}


def register_kind(kind: FigureKind) -> FigureKind:
    """Add ``kind`` under its name; a name taken by another kind, or a kind :func:`kind_problem` finds wrong, is an
    error (one sentence)."""
    problem = kind_problem(kind)
    if problem:
        raise StudyError(problem, key="kind")
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
