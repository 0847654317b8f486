"""Content-addressed cache of arrays (impostors, Mitsuba renders), validated when loaded.

An entry is ``<root>/<kind>/<key>.npy`` (the float32 array as NumPy writes it: exact, and fast to write and read;
a lossless EXR took 0.6 s per entry of a 512² cube map, a third of a case's time on a GPU) and ``<key>.json``
holding its full key, the array's shape and SHA-256. The key is the caller's content key folded with the hash
of the code
that produces the array (:func:`study.codehash.code_hash` of ``code``) and, off the CPU, the render device's
Mitsuba variant (:func:`study.runtime.current_variant`), so an entry made by other code or on another device is
never found. Both files are written atomically (temporary file + rename), the JSON last; an entry whose JSON names
another key (a file copied or renamed), or whose array file is missing, unreadable, of another shape or another
checksum is recomputed, never trusted. Entries of the format used before (``<key>.exr``, float32 EXR through Mitsuba's
Bitmap) are still read, with the same checks. :meth:`Cache.info` and :meth:`Cache.clear` serve ``study cache``.

Several commands may share one cache (``--cache``), ``study cache clear`` among them. Two writers of one key write
the same bytes, each atomically; a reader sees a whole entry or none. ``clear`` removes a kind's directory when it
empties it, so a writer may find its directory gone between making it and writing into it, or (Python's
``mkdir(exist_ok=True)``) told that it exists when it no longer does: :meth:`Cache.store` makes it again and
writes again (:data:`WRITE_ATTEMPTS`). ``info`` and ``clear`` skip a file or directory that vanished while they
listed it (another ``clear``, a writer's temporary file renamed).
"""

from __future__ import annotations

import contextlib
import hashlib
import io
import json
import os
import threading
import time
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

from study import runtime
from study.codehash import code_hash
from study.errors import StudyError
from study.io import atomic_write, read_exr


def content_key(*parts) -> str:
    """A short stable hash of JSON-serialisable parts."""
    return hashlib.sha256(json.dumps(parts, sort_keys=True, default=str).encode()).hexdigest()[:20]


def _variant_part() -> tuple:
    """The render device's Mitsuba variant as a key part, left out for the default (``llvm_ad_rgb``) so entries
    made on the CPU keep their keys: a render or exact hit made on CUDA (OptiX) is never taken for a CPU one."""
    v = runtime.current_variant()
    return () if v == runtime.VARIANTS["cpu"] else (v,)


def _digest(a: np.ndarray) -> str:
    return hashlib.sha256(np.ascontiguousarray(a, np.float32).tobytes()).hexdigest()


def _npy_bytes(a: np.ndarray) -> bytes:
    buf = io.BytesIO()
    np.save(buf, a, allow_pickle=False)
    return buf.getvalue()


class Cache:
    def __init__(self, root: str | Path | None):
        self.root = Path(root) if root else None
        self.hits = self.misses = 0

    def load(self, kind: str, key: str) -> np.ndarray | None:
        if self.root is None:
            return None
        with _LOCK:
            being = _WRITES.get((str(self.root), kind, key))
        if being is not None:  # handed to the writer, not yet on disk
            return being.copy()
        arr, meta = self.root / kind / f"{key}.npy", self.root / kind / f"{key}.json"
        try:
            info = json.loads(meta.read_text())
            if info["key"] != key:
                return None
            if arr.exists() or not arr.with_suffix(".exr").exists():
                a = np.load(arr, allow_pickle=False)
            else:  # an entry of the older format (EXR)
                a = read_exr(arr.with_suffix(".exr"))
            if a.dtype != np.float32:
                return None
            a = a.reshape(info["shape"])
            if _digest(a) != info["sha256"]:
                return None
        except (OSError, EOFError, ValueError, KeyError, TypeError, StudyError):
            return None
        return a

    def store(self, kind: str, key: str, a: np.ndarray) -> None:
        if self.root is None:
            return
        a = np.ascontiguousarray(a, np.float32)
        d = self.root / kind
        meta = json.dumps({"key": key, "shape": list(a.shape), "sha256": _digest(a)}).encode()
        data = _npy_bytes(a)
        for attempt in range(WRITE_ATTEMPTS):  # `study cache clear` meanwhile may remove the directory
            try:
                d.mkdir(parents=True, exist_ok=True)
                atomic_write(d / f"{key}.npy", data)
                atomic_write(d / f"{key}.json", meta)
                return
            except (FileNotFoundError, FileExistsError):  # gone, or "exists" as rmdir removed it: again
                if attempt == WRITE_ATTEMPTS - 1:
                    raise StudyError(
                        "cannot write the cache (its directory keeps vanishing)", file=str(d)
                    ) from None
                time.sleep(0.001 * 2**attempt)
            except OSError as err:
                raise StudyError(f"cannot write the cache ({err.strerror})", file=str(d)) from None

    def get(self, kind: str, key: str, make: Callable[[], np.ndarray], *, code) -> np.ndarray:
        """The cached array, or ``make()`` stored under (kind, key + the hash of ``code``).

        ``code`` is the function that produces the array (or a tuple of functions, classes, modules): its
        module's source and that of every study module it imports are part of the key."""
        _raise_failed(str(self.root))
        key = content_key(
            key, code_hash(*(code if isinstance(code, (tuple, list)) else (code,))), *_variant_part()
        )
        a = self.load(kind, key)
        if a is not None:
            self.hits += 1
            return a
        self.misses += 1
        a = np.asarray(make(), np.float32)
        self.store_later(kind, key, a)
        return a

    def holds(self, kind: str, key: str) -> bool:
        """Whether the entry (kind, key) is on disk or being written (its JSON, unchecked)."""
        if self.root is None:
            return False
        with _LOCK:
            if (str(self.root), kind, key) in _WRITES:
                return True
        return (self.root / kind / f"{key}.json").is_file()

    def store_later(self, kind: str, key: str, a: np.ndarray) -> None:
        """:meth:`store` on the cache's writer thread, of a private copy of ``a`` (the caller may go on changing
        ``a``); a failed write is raised by the next :meth:`get` and by :func:`flush`."""
        if self.root is None:
            return
        slot = (str(self.root), kind, key)
        mine = np.array(a, np.float32, order="C", copy=True)
        with _LOCK:
            _WRITES[slot] = mine
        _writer().submit(_write, self, slot, mine)

    # ------------------------------------------------------------------ study cache info / clear
    def _kinds(self) -> dict[str, list[Path]]:
        """Kind → the cache's files in ``<root>/<kind>/`` (a directory holding at least one entry): entries (JSON +
        array) and, where the directory holds nothing else, arrays without JSON and temporary files left by
        interrupted writes (and EXRs of the format used before). Files the cache never writes are never listed, so
        never removed."""
        if self.root is None or not self.root.exists():
            return {}
        if not self.root.is_dir():
            raise StudyError("the cache is not a directory", file=str(self.root))
        out = {}
        try:
            for d in sorted(p for p in self.root.iterdir() if p.is_dir()):
                try:
                    files = sorted(p for p in d.iterdir() if p.is_file())
                except FileNotFoundError:  # removed meanwhile (another clear)
                    continue
                entries = [
                    p for p in files if p.suffix == ".json" and not p.name.startswith(".") and _is_entry(p)
                ]
                if not entries:
                    continue
                mine = {
                    p
                    for e in entries
                    for p in (e, e.with_suffix(".npy"), e.with_suffix(".exr"))
                    if p.exists()
                }
                strays = [p for p in files if p not in mine and not _in_flight(p)]
                if all(
                    p.suffix in _OURS or p.name.startswith(".") and p.suffix in (".tmp", *_OURS)
                    for p in strays
                ):
                    mine.update(strays)
                out[d.name] = sorted(mine)
        except OSError as err:
            raise StudyError(f"cannot read the cache ({err.strerror})", file=str(self.root)) from None
        return out

    def info(self) -> dict[str, tuple[int, int]]:
        """Kind → (entries, bytes on disk) of everything the cache holds (this process's writes done first)."""
        flush()
        return {
            k: (sum(p.suffix == ".json" and not p.name.startswith(".") for p in fs), sum(map(_size, fs)))
            for k, fs in self._kinds().items()
        }

    def clear(self, kind: str | None = None) -> dict[str, tuple[int, int]]:
        """Remove every entry (of ``kind`` only, if given); returns kind → (entries, bytes) removed (this process's
        writes done first)."""
        flush()
        kinds = self._kinds()
        if kind is not None:
            if kind not in kinds:
                raise StudyError(
                    f"no entries of kind {kind!r}; kinds here: {', '.join(kinds) or 'none'}",
                    file=str(self.root),
                    key="--kind",
                )
            kinds = {kind: kinds[kind]}
        gone = {}
        for k, fs in kinds.items():
            n = sum(p.suffix == ".json" and not p.name.startswith(".") for p in fs)
            size = 0
            for p in fs:
                try:
                    size += _size(p)
                    p.unlink()
                except FileNotFoundError:  # removed meanwhile (another clear)
                    pass
                except OSError as err:
                    raise StudyError(f"cannot remove a cache file ({err.strerror})", file=str(p)) from None
            try:
                (self.root / k).rmdir()  # only if nothing else is left in it
            except OSError:
                pass
            gone[k] = (n, size)
        return gone


# ---------------------------------------------------------------------- the writes, off the caller's thread
#: One thread writes every entry that :meth:`Cache.get` made (its SHA-256, its .npy bytes, two atomic writes: about
#: 2.5 s of a paper-quality fig4 on the case's thread before), from a private copy, in the order they were made:
#: the entries being written, (root, kind, key) → array, which :meth:`Cache.load` returns meanwhile; the first
#: failed write's error, raised (once) by the next :meth:`Cache.get` of that cache and by :func:`flush`. The CLI's
#: commands (:func:`study.cli.app.guarded`), the API's ``evaluate``, a sweep's worker and an output set
#: (:func:`study.io.output_set`) flush before they finish, so a write that fails is still the command's error.
_WRITES: dict[tuple[str, str, str], np.ndarray] = {}
_FAILED: list[tuple[str, BaseException]] = []  # (the cache's root, the error)
_LOCK = threading.Lock()
_EXECUTOR: list[ThreadPoolExecutor] = []


def _writer() -> ThreadPoolExecutor:
    with _LOCK:
        if not _EXECUTOR:
            _EXECUTOR.append(ThreadPoolExecutor(1, thread_name_prefix="study-cache"))
        return _EXECUTOR[0]


def _write(cache: Cache, slot: tuple[str, str, str], a: np.ndarray) -> None:
    try:
        cache.store(slot[1], slot[2], a)
    except BaseException as err:  # kept for the caller's thread: raised there
        with _LOCK:
            _FAILED.append((slot[0], err))
    finally:
        with _LOCK:
            if _WRITES.get(slot) is a:
                del _WRITES[slot]


def _raise_failed(root: str | None = None) -> None:
    """Raise the first failed write (of cache ``root``, or of any) once the writes queued before it are done, and
    forget that cache's other failures: the writes queued with it fail alike, and the error ends the command
    once, not the next command of the same process as well."""
    with _LOCK:
        if not any(root in (None, r) for r, _ in _FAILED):
            return
    _drain()
    with _LOCK:
        err = next(e for r, e in _FAILED if root in (None, r))
        _FAILED[:] = [(r, e) for r, e in _FAILED if root not in (None, r)]
    raise err


def _drain() -> None:
    """Wait until every write queued so far is done (one thread, first in first out)."""
    with _LOCK:
        ex = _EXECUTOR[0] if _EXECUTOR else None
    if ex is not None:
        ex.submit(lambda: None).result()


def flush() -> None:
    """Wait until every entry handed to the writer is on disk; raise the first failed write's error (once)."""
    _drain()
    _raise_failed()


def _forked() -> None:
    """In a forked child: the writer thread did not come along (its executor would take work and never run it)."""
    global _LOCK
    _LOCK = threading.Lock()
    _EXECUTOR.clear()
    _WRITES.clear()
    _FAILED.clear()


os.register_at_fork(after_in_child=_forked)

_OURS = (".npy", ".exr")  # array files the cache writes (.exr: the older format)
#: Writes of one entry before :meth:`Cache.store` gives up on a directory that keeps vanishing (backing off 1, 2,
#: 4, … ms between them).
WRITE_ATTEMPTS = 8


def _size(p: Path) -> int:
    """``p``'s size in bytes; 0 for a file that vanished since it was listed."""
    with contextlib.suppress(FileNotFoundError):
        return p.stat().st_size
    return 0


#: A temporary file younger than this may belong to a write in progress (a running sweep's): clear leaves it.
IN_FLIGHT_S = 600.0


def _in_flight(p: Path) -> bool:
    try:
        return p.name.startswith(".") and time.time() - p.stat().st_mtime < IN_FLIGHT_S
    except OSError:
        return False


def _is_entry(p: Path) -> bool:
    try:
        info = json.loads(p.read_text())
    except (OSError, ValueError):
        return False
    return isinstance(info, dict) and "sha256" in info and "shape" in info
