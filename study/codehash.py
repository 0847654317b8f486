"""Hashes of code: the source files behind functions, classes and modules, with every study module they import.

:func:`code_hash` is what makes cache and resume keys follow the code: a result computed by a function is keyed
by the source of the function's module and of every ``study`` module that module imports, transitively (imports
anywhere in a file count, also those inside functions; ``from study.x import y`` counts ``study.x`` and, where
``y`` is a module, ``study.x.y``; a package's ``__init__`` counts whenever one of its modules does). Imports made
by name at run time (``importlib.import_module``) are not seen: pass such modules' objects explicitly (the sweep
passes every method class, since ``study.methods`` imports its method modules that way). A module outside
``study`` (a plugin's method module) counts by its own file only. Study's own modules are read once per process;
files outside study are read on every call, so an edited plugin module changes the hash at once.
"""

from __future__ import annotations

import ast
import hashlib
import sys
import types
from functools import cache
from pathlib import Path

PACKAGE = __name__.partition(".")[0]  # "study"
PACKAGE_DIR = Path(__file__).resolve().parent  # the study package directory


def code_hash(*objs) -> str:
    """A short hash (16 hex digits) of the code behind ``objs`` (functions, classes, methods or modules)."""
    return _combine(_parts(objs))


def code_record(*objs) -> dict:
    """What a table's metadata says of the code that made it: ``code_hash`` (:func:`code_hash` of ``objs``),
    ``code_files`` (the study source files it covers, relative to the repository root, sorted) and
    ``code_outside`` (modules outside study it covers, by name: plug-ins, whose files no commit holds).

    With ``code_files`` the hash can be recomputed from any commit's files (:func:`hash_of_sources`), so whether
    a committed table was made by the code of its commit is checked, not asserted."""
    parts = _parts(objs)
    inside = sorted(k for k in parts if k == PACKAGE or k.startswith(PACKAGE + "."))
    return {
        "code_hash": _combine(parts),
        "code_files": sorted(module_file(m) for m in inside),
        "code_outside": sorted(k for k in parts if k not in inside),
    }


def module_file(name: str) -> str:
    """The source file of study module ``name``, relative to the repository root (``study/x/__init__.py`` for a
    package, ``study/x/y.py`` for a module)."""
    p = _path(name)
    if p is None:
        raise ValueError(f"code_hash: no source file for module {name}")
    return p.relative_to(PACKAGE_DIR.parent).as_posix()


def file_module(path: str) -> str:
    """The module name of a study source file relative to the repository root (the inverse of
    :func:`module_file`)."""
    parts = path.removesuffix(".py").split("/")
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def hash_of_sources(sources: dict[str, bytes]) -> str:
    """:func:`code_hash` from source files' bytes (``{path relative to the repository root: bytes}``), e.g. as
    a commit holds them: equal to the hash the same files gave when the table was made."""
    return _combine({file_module(p): hashlib.sha256(b).hexdigest() for p, b in sources.items()})


def _parts(objs) -> dict[str, str]:
    parts = {}
    for obj in objs:
        name = _module_of(obj)
        if name == PACKAGE or name.startswith(PACKAGE + "."):
            parts.update(_study_closure(name))
        else:
            parts[name] = _outside_digest(name)
    return parts


def _combine(parts: dict[str, str]) -> str:
    blob = "\n".join(f"{k} {v}" for k, v in sorted(parts.items()))
    return hashlib.sha256(blob.encode()).hexdigest()[:16]


def _module_of(obj) -> str:
    if isinstance(obj, types.ModuleType):
        return obj.__name__
    obj = getattr(obj, "__func__", obj)  # bound methods
    name = getattr(obj, "__module__", None)
    if not isinstance(name, str):
        raise TypeError(f"code_hash: cannot tell which module defines {obj!r}")
    return name


def _outside_digest(name: str) -> str:
    """A module outside study: the SHA-256 of its own source file (read now), or of its name without one."""
    mod = sys.modules.get(name)
    path = getattr(mod, "__file__", None) if mod is not None else None
    if path is None:
        import importlib.util

        try:
            spec = importlib.util.find_spec(name)
        except (ImportError, ValueError):
            spec = None
        path = spec.origin if spec is not None and spec.has_location else None
    try:
        return hashlib.sha256(Path(path).read_bytes()).hexdigest() if path else f"no-file:{name}"
    except OSError:
        return f"unreadable:{name}"


def _path(name: str) -> Path | None:
    """The source file of study module ``name`` (a module file or a package's ``__init__``), None if none."""
    rel = name.split(".")[1:]
    base = PACKAGE_DIR.joinpath(*rel) if rel else PACKAGE_DIR
    if (base / "__init__.py").is_file():
        return base / "__init__.py"
    f = base.with_suffix(".py") if rel else None
    return f if f is not None and f.is_file() else None


def _is_package(name: str) -> bool:
    p = _path(name)
    return p is not None and p.name == "__init__.py"


@cache
def _source(name: str) -> bytes:
    p = _path(name)
    return p.read_bytes() if p is not None else b""


@cache
def _imports(name: str) -> frozenset[str]:
    """The study modules that module ``name`` imports directly (parent packages included)."""
    src = _source(name)
    try:
        tree = ast.parse(src)
    except SyntaxError:
        return frozenset()
    pkg = name if _is_package(name) else name.rpartition(".")[0]
    found: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:  # relative: from the module's own package upwards
                up = pkg.split(".")
                up = up[: len(up) - (node.level - 1)] if node.level > 1 else up
                base = ".".join(up + ([node.module] if node.module else []))
            else:
                base = node.module or ""
            found.add(base)
            found.update(f"{base}.{a.name}" for a in node.names if a.name != "*")
    out: set[str] = set()
    for mod in found:
        if not (mod == PACKAGE or mod.startswith(PACKAGE + ".")):
            continue
        parts = mod.split(".")
        for i in range(1, len(parts) + 1):  # the module and every package above it
            m = ".".join(parts[:i])
            if _path(m) is not None:
                out.add(m)
    return frozenset(out)


@cache
def _study_closure(name: str) -> dict[str, str]:
    """Module name → SHA-256 of its source, for ``name``, its packages and every study module it imports."""
    parts = name.split(".")
    todo = [".".join(parts[:i]) for i in range(1, len(parts) + 1)]
    seen: set[str] = set()
    while todo:
        m = todo.pop()
        if m in seen or _path(m) is None:
            continue
        seen.add(m)
        todo.extend(_imports(m) - seen)
    return {m: hashlib.sha256(_source(m)).hexdigest() for m in seen}
