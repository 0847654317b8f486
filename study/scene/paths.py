"""One rule for every path a scene file names (glTF buffers and images, OBJ ``mtllib``, MTL maps, Mitsuba XML
``filename``\\ s and includes): it must stay inside the folder of the scene file the user named (its *root*).

:func:`named_file` decides before any byte is read. The name is percent-decoded where the format says it is a URI
(glTF), made relative to the naming file's folder and normalised *lexically* (``a/../b`` → ``b``); an absolute
path, a URI with a scheme (``file:``, ``http:``) or a name that climbs out of the folder (``..``) is refused in one
line naming the file and the element. The root is the folder of the file the user named, not of each file in
between: an MTL in ``materials/`` may name ``../textures/wall.png`` when both lie under the OBJ's folder, as asset
packs are laid out; nothing above that folder is read. Symlinks are not followed for the check: a symlink the
user placed inside the folder may point anywhere (the user put it there). The file is then resolved strictly, so a
symlink loop is one line too.

A scene TOML is held to the same rule (:func:`scene_file_names`): every file it names (``environment.file``,
``environment.sky``, ``object.file``, a ``filename`` anywhere in it) must lie in or below the TOML's folder. What
the user names on the command line or through the API (``--set environment.sky=/data/sky.exr``, an override, a
scene dict) may lie anywhere: the user typed it.
"""

from __future__ import annotations

import errno
import os
import re
from pathlib import Path
from typing import Any
from urllib.parse import unquote

from pydantic import ValidationInfo
from pydantic_core import PydanticCustomError

from study.errors import StudyError

_SCHEME = re.compile(r"^[A-Za-z][A-Za-z0-9+.-]*:")


def named_file(
    folder: Path, name: str, *, what: str, src: str, uri: bool = False, root: Path | None = None
) -> Path:
    """The file ``name`` (as written in a scene file of ``folder``) names, as an absolute path inside ``folder``.

    Parameters
    ----------
    folder : the folder of the file that names ``name``
    name : the name as the file writes it
    what : the element that names it, for the message (``"buffer 0"``, ``"line 3: mtllib"``)
    src : the key the message is about (``"environment.file"``)
    uri : ``name`` is a URI reference (glTF): percent-decoded; a scheme (``file:``, ``http:``) is refused
    root : the folder ``name`` must stay in (default: ``folder``)

    Raises
    ------
    StudyError
        the name leaves ``folder`` or is absolute (nothing is read), names no file, or is a symlink loop.
    """
    raw = name
    what = f"{what}: " if what else ""
    if uri:
        if _SCHEME.match(name) and not re.match(r"^[A-Za-z]:[\\/]", name):
            raise StudyError(f"{what}{raw!r} is a URI with a scheme; study reads files beside the scene only",
                             key=src)  # fmt: skip
        name = unquote(name)
    if "\0" in name:
        raise StudyError(f"{what}{raw!r} is not a file name (NUL byte)", key=src)
    base = Path(os.path.abspath(root if root is not None else folder))
    if Path(name).is_absolute() or re.match(r"^[A-Za-z]:[\\/]", name) or name.startswith("\\"):
        raise StudyError(f"{what}{raw!r} is an absolute path; files a scene names must lie in its folder "
                         f"({base})", key=src)  # fmt: skip
    p = Path(os.path.normpath(Path(os.path.abspath(folder)) / name.replace("\\", "/")))
    if p != base and base not in p.parents:
        raise StudyError(f"{what}{raw!r} leaves the scene's folder ({base}); files a scene names must lie in "
                         "it", key=src)  # fmt: skip
    if strict_resolve(p) == "a symlink loop":
        raise StudyError(f"{what}{raw!r} is a symlink loop", key=src)
    return p  # missing: the caller says what that means for its format


def strict_resolve(p: Path) -> Path | str:
    """``p`` resolved (symlinks followed), or why it cannot be: "a symlink loop" or "no such file"."""
    try:
        return p.resolve(strict=True)
    except RuntimeError:  # Python < 3.13: a symlink loop
        return "a symlink loop"
    except OSError as err:
        return "a symlink loop" if err.errno == errno.ELOOP else "no such file"


def inside(folder: Path, name: str, *, uri: bool = False, root: Path | None = None) -> Path | None:
    """:func:`named_file` as a question: the path, or None where the rule refuses it (content keys skip what the
    loader will refuse, so that nothing outside is read for them either)."""
    try:
        return named_file(folder, name, what="", src="", uri=uri, root=root)
    except StudyError:
        return None


#: Keys whose string values in a scene TOML name files, at any depth (``environment.file``, ``environment.sky``,
#: ``object.file``, a Mitsuba scene dict's ``filename``); a sky's ``"#rrggbb"`` is a colour, not a file.
FILE_KEYS = ("file", "filename", "sky")


def scene_file_names(data: Any, toml: Path, *, key: str = "") -> None:
    """Hold every file the scene TOML ``toml`` names in ``data`` (its tables) to :func:`named_file`'s rule, with the
    TOML's folder as the root: nothing outside it is read for a scene file. ``~`` counts as absolute.

    Parameters
    ----------
    data : the TOML's tables (or a part of them, at ``key``)
    toml : the scene file
    key : the dotted key of ``data`` (for the message)

    Raises
    ------
    StudyError
        naming ``toml`` and the dotted key, with the name and the folder, for a path that is absolute or leaves it.
    """
    items = data.items() if isinstance(data, dict) else enumerate(data) if isinstance(data, list) else ()
    for k, v in items:
        where = f"{key}[{k}]" if isinstance(k, int) else f"{key}.{k}" if key else str(k)
        if (
            isinstance(k, str)
            and k in FILE_KEYS
            and isinstance(v, str)
            and not (k == "sky" and v.startswith("#"))
        ):
            try:
                named_file(toml.parent, os.path.expanduser(v), what="", src=where)
            except StudyError as err:
                raise StudyError(
                    f"{err.detail} (a file elsewhere may be named on the command line: --set {where}=PATH)",
                    file=str(toml),
                    key=where,
                ) from None
        else:
            scene_file_names(v, toml, key=where)


def resolve(v: Any, info: ValidationInfo) -> Any:
    """A ``file`` field: absolute, resolved against the scene file's directory; it must exist."""
    if v is None or not isinstance(v, (str, Path)):
        return v
    p = Path(v).expanduser()
    if not p.is_absolute():
        base = (info.context or {}).get("base") if info.context else None
        p = Path(base or ".") / p
    found = strict_resolve(p)
    if isinstance(found, str):  # a symlink loop, or missing
        raise PydanticCustomError("file", "{why}: {path}", {"why": found, "path": str(p)})
    p = found
    if not p.is_file():
        raise PydanticCustomError("file", "no such file: {path}", {"path": str(p)})
    return str(p)
