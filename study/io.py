"""Files written and read the one way study does it: atomically, with one clear error per problem.

* :func:`atomic_write` / :func:`atomic_savefig` / :func:`write_exr`: a temporary file beside the target, renamed
  over it at the end, so a reader (or a killed run) never sees half a file, and no temporary file is left behind.
* :func:`read_toml`: a TOML file, or a :class:`~study.errors.StudyError` naming the file.
* :func:`write_exr` / :func:`read_exr`: float32 EXR through Mitsuba's ``Bitmap`` (:func:`study.runtime.mitsuba`).
"""
from __future__ import annotations

import contextlib
import os
import tempfile
import tomllib
from pathlib import Path

import numpy as np

from study import runtime
from study.errors import StudyError


@contextlib.contextmanager
def _temp_beside(path: Path, suffix: str):
    """A temporary file name beside ``path``; renamed over ``path`` if the block succeeds, removed otherwise."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.stem}.", suffix=suffix)
    os.close(fd)
    try:
        yield tmp
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)


def atomic_write(path: str | Path, data: bytes | str) -> None:
    """Write ``data`` to ``path`` atomically (temporary file + rename)."""
    path = Path(path)
    with _temp_beside(path, ".tmp") as tmp:
        Path(tmp).write_bytes(data.encode() if isinstance(data, str) else data)


def atomic_savefig(fig, path: str | Path, *, dpi: int = 110) -> None:
    """Save a matplotlib figure as PNG atomically, then close it."""
    import matplotlib.pyplot as plt
    path = Path(path)
    try:
        with _temp_beside(path, ".png") as tmp:
            fig.savefig(tmp, dpi=dpi, format="png")
    finally:
        plt.close(fig)


def read_toml(path: str | Path, *, what: str = "config file") -> dict:
    """The TOML file at ``path`` as a dict; a missing, unreadable or invalid file is one StudyError that calls
    the file ``what``."""
    path = Path(path)
    try:
        return tomllib.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise StudyError(f"{what} not found", file=str(path)) from None
    except IsADirectoryError:
        raise StudyError(f"is a directory, expected a {what} (TOML)", file=str(path)) from None
    except UnicodeDecodeError:
        raise StudyError(f"not UTF-8 text, expected a {what} (TOML)", file=str(path)) from None
    except tomllib.TOMLDecodeError as err:
        raise StudyError(f"not valid TOML ({err})", file=str(path)) from None


def write_exr(path: str | Path, array: np.ndarray) -> None:
    """Write an (H, W, C) float32 array as EXR through Mitsuba's Bitmap, atomically."""
    mi = runtime.mitsuba()
    with _temp_beside(Path(path), ".exr") as tmp:
        mi.Bitmap(np.ascontiguousarray(array, np.float32)).write(tmp)


def read_exr(path: str | Path) -> np.ndarray:
    """Read an EXR as an (H, W, C) float32 array; a missing or damaged file is a StudyError."""
    mi = runtime.mitsuba()
    if not Path(path).is_file():
        raise StudyError("EXR file not found", file=str(path))
    try:
        a = np.array(mi.Bitmap(str(path)), dtype=np.float32)
    except Exception as err:
        raise StudyError(f"unreadable EXR ({str(err).splitlines()[0][:120]})", file=str(path)) from None
    return a if a.ndim == 3 else a[..., None]
