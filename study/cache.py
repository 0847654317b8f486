"""Content-addressed cache of arrays (impostors, Mitsuba renders), validated when loaded.

An entry is ``<root>/<kind>/<key>.exr`` (float32 EXR through Mitsuba's Bitmap) and ``<key>.json`` holding the
array's shape and SHA-256. Both are written atomically (temporary file + rename), the JSON last; an entry whose
EXR is missing, unreadable, of another shape or another checksum is recomputed, never trusted.
"""
from __future__ import annotations

import hashlib
import json
from pathlib import Path
from typing import Callable

import numpy as np

from study.errors import StudyError
from study.io import atomic_write, read_exr, write_exr


def content_key(*parts) -> str:
    """A short stable hash of JSON-serialisable parts."""
    return hashlib.sha256(json.dumps(parts, sort_keys=True, default=str).encode()).hexdigest()[:20]


def _digest(a: np.ndarray) -> str:
    return hashlib.sha256(np.ascontiguousarray(a, np.float32).tobytes()).hexdigest()


def _as_image(a: np.ndarray) -> np.ndarray:
    """Any array as an (H, W, C) image for EXR: trailing channel axis kept when it has 3 or 4 entries."""
    if a.ndim >= 3 and a.shape[-1] in (3, 4):
        return a.reshape(-1, a.shape[-2], a.shape[-1])
    return a.reshape(-1, a.shape[-1] if a.ndim > 1 else 1, 1)


class Cache:
    def __init__(self, root: str | Path | None):
        self.root = Path(root) if root else None
        self.hits = self.misses = 0

    def load(self, kind: str, key: str) -> np.ndarray | None:
        if self.root is None:
            return None
        exr, meta = self.root / kind / f"{key}.exr", self.root / kind / f"{key}.json"
        try:
            info = json.loads(meta.read_text())
            a = read_exr(exr)
            a = a.reshape(info["shape"])
            if _digest(a) != info["sha256"]:
                return None
        except (OSError, ValueError, KeyError, TypeError, StudyError):
            return None
        return a

    def store(self, kind: str, key: str, a: np.ndarray) -> None:
        if self.root is None:
            return
        a = np.ascontiguousarray(a, np.float32)
        d = self.root / kind
        try:
            d.mkdir(parents=True, exist_ok=True)
            write_exr(d / f"{key}.exr", _as_image(a))
            atomic_write(d / f"{key}.json", json.dumps({"shape": list(a.shape), "sha256": _digest(a)}).encode())
        except OSError as err:
            raise StudyError(f"cannot write the cache ({err.strerror})", file=str(d)) from None

    def get(self, kind: str, key: str, make: Callable[[], np.ndarray]) -> np.ndarray:
        """The cached array, or ``make()`` stored under (kind, key)."""
        a = self.load(kind, key)
        if a is not None:
            self.hits += 1
            return a
        self.misses += 1
        a = np.asarray(make(), np.float32)
        self.store(kind, key, a)
        return a
