"""`study cache clear` while a sweep writes into the cache: the writer's entry still lands (its directory made
again, its temporary file left alone by clear), and no error reaches the sweep."""

import numpy as np

from study import io
from study.cache import Cache


def test_clear_between_mkdir_and_write_does_not_break_store(tmp_path, monkeypatch):
    c = Cache(tmp_path / "cache")
    c.store("k", "seed", np.zeros(3, np.float32))  # the kind directory exists, with one entry
    real = io.os.replace
    cleared = []

    def replace(src, dst):  # another process clears the cache at the worst moment: before the rename
        if not cleared:
            cleared.append(Cache(tmp_path / "cache").clear())
        return real(src, dst)

    monkeypatch.setattr(io.os, "replace", replace)
    a = np.arange(6, dtype=np.float32).reshape(2, 3)
    c.store("k", "entry", a)
    monkeypatch.undo()
    assert cleared and cleared[0]["k"][0] == 1  # the earlier entry went, the write in flight survived
    np.testing.assert_array_equal(c.load("k", "entry"), a)


def test_clear_removes_old_temporaries_only(tmp_path):
    c = Cache(tmp_path / "cache")
    c.store("k", "e", np.zeros(2, np.float32))
    d = tmp_path / "cache" / "k"
    young, old = d / ".e.abc.tmp", d / ".e.def.tmp"
    young.write_bytes(b"x")
    old.write_bytes(b"x")
    t = old.stat().st_mtime - 3600
    import os

    os.utime(old, (t, t))
    c.clear()
    assert young.exists() and not old.exists() and not (d / "e.json").exists()
