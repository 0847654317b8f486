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
    if uri:
        if _SCHEME.match(name) and not re.match(r"^[A-Za-z]:[\\/]", name):
            raise StudyError(f"{what}: {raw!r} is a URI with a scheme; study reads files beside the scene only",
                             key=src)  # fmt: skip
        name = unquote(name)
    if "\0" in name:
        raise StudyError(f"{what}: {raw!r} is not a file name (NUL byte)", key=src)
    base = Path(os.path.abspath(root if root is not None else folder))
    if Path(name).is_absolute() or re.match(r"^[A-Za-z]:[\\/]", name) or name.startswith("\\"):
        raise StudyError(f"{what}: {raw!r} is an absolute path; files a scene names must lie in its folder "
                         f"({base})", key=src)  # fmt: skip
    p = Path(os.path.normpath(Path(os.path.abspath(folder)) / name.replace("\\", "/")))
    if p != base and base not in p.parents:
        raise StudyError(f"{what}: {raw!r} leaves the scene's folder ({base}); files a scene names must lie in "
                         "it", key=src)  # fmt: skip
    if strict_resolve(p) == "a symlink loop":
        raise StudyError(f"{what}: {raw!r} is a symlink loop", key=src)
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
