"""Which files of an output folder are study's: the list of the files it wrote there (:data:`OUTPUTS`), the rule
that an empty output path is no folder (:func:`out_dir`), what an output set may replace (:func:`in_the_way`) and
the entries it carries over untouched (:func:`carry`). :func:`study.io.output_set` removes or replaces only the
files on the list or of the names it writes: a file of the user's in an output folder is never removed."""

from __future__ import annotations

import json
import os
import shutil
from pathlib import Path

from study.errors import StudyError

#: In every output folder: the files study wrote there (relative paths, JSON), the only ones a later command may
#: remove (an earlier run's output that this run does not write again); anything else in the folder stays.
OUTPUTS = ".study-outputs.json"


def out_dir(value: str | Path, *, key: str = "--out") -> Path:
    """``value`` as an output folder: an empty path (``--out ""``, a shell variable left unset) is one StudyError
    naming ``key``, never the current directory.

    Parameters
    ----------
    value : str or Path
        The path as given (a ``Path("")`` is already ``"."``: check the text before it becomes a Path).
    key : str
        What the error names (``--out``, ``--reports``, ``out``).

    Returns
    -------
    Path
    """
    if not str(value).strip():
        raise StudyError("empty path; name a folder (e.g. reports/mine, or . for this one)", key=key)
    return Path(value)


def written_here(out: str | Path) -> set[str]:
    """The files study wrote in the output folder ``out`` (relative POSIX paths, from its :data:`OUTPUTS`);
    empty where it has none (a folder study did not make, or one written before study kept the list) or an
    unreadable one."""
    try:
        files = json.loads((Path(out) / OUTPUTS).read_text(encoding="utf-8")).get("files")
    except (OSError, ValueError, AttributeError, RecursionError):
        return set()
    return {f for f in files if isinstance(f, str)} if isinstance(files, list) else set()


def owned(rel: str, owns: set[str]) -> bool:
    """Whether the relative path ``rel`` is one of ``owns`` or lies under one."""
    return any(rel == o or rel.startswith(o + "/") for o in owns)


def _holds_owned(rel: str, owns: set[str]) -> bool:
    return any(o.startswith(rel + "/") for o in owns)


def carry(src: Path, dst: Path, rel: str, owns: set[str], keeps: set[str]) -> bool:
    """Hard-link (or copy) the entries of ``src`` that the command does not own into ``dst``; False if one is a
    directory neither owned in part nor named in ``keeps`` (then the swap is not used)."""
    for e in sorted(os.scandir(src), key=lambda e: e.name):
        r = f"{rel}{e.name}"
        if owned(r, owns):
            continue
        target = dst / e.name
        if e.is_dir(follow_symlinks=False):
            if r in keeps:
                shutil.copytree(e.path, target, symlinks=True, copy_function=_link, dirs_exist_ok=True)
            elif _holds_owned(r, owns):
                made = not target.exists()
                target.mkdir(exist_ok=True)
                if not carry(Path(e.path), target, r + "/", owns, keeps):
                    return False
                if made and not any(target.iterdir()):  # every file in it was an earlier output: it goes
                    target.rmdir()
            else:
                return False
        elif not target.exists():
            if e.is_symlink():
                os.symlink(os.readlink(e.path), target)
            else:
                _link(e.path, target)
    return True


def _link(src, dst) -> None:
    try:
        os.link(src, dst)
    except OSError:
        shutil.copy2(src, dst)


def in_the_way(out: Path, new: set[str], listed: set[str]) -> None:
    """Refuse (one StudyError, nothing changed yet) where an output would replace something study did not write: a
    folder where it writes a file, or a file of the user's where it needs a folder."""
    for rel in sorted(new):
        p = out / rel
        if p.is_dir() and not p.is_symlink():
            raise StudyError(
                f"{rel} is a folder that study did not write, where it writes a file; move it or choose another "
                "--out",
                file=str(out),
            )
        for parent in Path(rel).parents:
            q = out / parent
            if parent.name and (q.is_symlink() or q.exists()) and not q.is_dir():
                if parent.as_posix() in listed:
                    continue  # an earlier output of study's: replaced by the folder
                raise StudyError(
                    f"{parent.as_posix()} is a file that study did not write, where it writes the folder of "
                    f"{rel}; move it or choose another --out",
                    file=str(out),
                )
