"""Which per-case images a command writes (``--images none|viewer|all``), and the background writer of a sweep's.

``all``: each case's multi-layer EXR and its viewer images (:func:`study.outputs.viewer.case_files`); ``viewer``:
the viewer images only (the viewer then says the EXR is not in this copy); ``none``: neither. ``study figure``
writes ``all`` by default (its files are one output set, :mod:`study.outputs.figures`); ``study sweep`` writes
``none`` by default, as before. A sweep's images are made where its case ran, for the cases computed in that run
(a resumed case keeps the files it has): ``<out>/exr/<case>.exr``, ``<out>/viewer/<case>.js`` and the case's
manifest entry ``<out>/viewer/<case>.json``, each written atomically; at its end the command gathers the entries
into ``<out>/viewer/index.json``. In the sweep's own process (``--jobs 1``) they are encoded and written by one
background thread, which the next case does not wait for; the command waits for it at its end
(:func:`finish`). In worker processes the worker writes them before it takes its next case.
"""

from __future__ import annotations

import json
from concurrent.futures import Future, ThreadPoolExecutor
from pathlib import Path

from study.errors import StudyError
from study.io import atomic_write, file_stem

#: The choices of ``--images``.
IMAGE_CHOICES = ("none", "viewer", "all")

_writer: ThreadPoolExecutor | None = None
_pending: list[Future] = []


def image_choice(value: str) -> str:
    """``value`` if it is one of :data:`IMAGE_CHOICES`, else one line naming the allowed values."""
    if value not in IMAGE_CHOICES:
        raise StudyError(f"unknown --images {value!r}; allowed: {', '.join(IMAGE_CHOICES)}", key="images")
    return value


def write_case(case, case_id: str, out: str, labels: list[str], what: str, background: bool) -> None:
    """A sweep case's images (:func:`study.outputs.viewer.case_files`, ``what`` = ``viewer`` or ``all``) under
    ``out``, in the background writer with ``background``, else here; a sweep hands this function to its runner."""
    global _writer
    if not background:
        return _write(case, case_id, Path(out), labels, what)
    if _writer is None:
        _writer = ThreadPoolExecutor(1, thread_name_prefix="case-images")
    _pending.append(_writer.submit(_write, case, case_id, Path(out), labels, what))


def _write(case, case_id: str, out: Path, labels: list[str], what: str) -> None:
    from study.outputs import viewer

    stem = file_stem(case_id)
    files, entry = viewer.case_files(out.name, stem, case, labels, case_id=case_id, exr=what == "all")
    for rel, data in files.items():
        atomic_write(out / rel, data)
    atomic_write(out / "viewer" / f"{stem}.json", json.dumps(entry))


def finish(out: str | Path, name: str) -> int:
    """Wait for the background writer, then write ``<out>/viewer/index.json`` from the cases' entries (none: no
    manifest). Returns the number of cases in it."""
    from study.outputs import viewer

    while _pending:
        _pending.pop(0).result()  # a failed write fails the command
    entries = []
    for f in sorted((Path(out) / "viewer").glob("*.json")):
        if f.name != Path(viewer.MANIFEST).name:
            entries.append(json.loads(f.read_text(encoding="utf-8")))
    if entries:
        atomic_write(Path(out) / viewer.MANIFEST, viewer.manifest_text(name, entries))
    return len(entries)
