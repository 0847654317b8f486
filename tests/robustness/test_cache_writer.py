"""The cache's entries written off the caller's thread (study.cache: one writer thread, issue 52): the same files as
a write on the caller's thread, an entry being written read back without being made again, the caller free to change
the array it got, a failed write raised once (by the next get and by flush, so a command still ends on it with one
line), and a forked child that writes without the parent's thread."""

import json
import multiprocessing as mp
import threading

import numpy as np
import pytest

from study import cache as cache_mod
from study.cache import Cache
from study.errors import StudyError


def value() -> np.ndarray:
    return np.arange(4 * 5 * 3, dtype=np.float32).reshape(4, 5, 3) / 7


def _key(k: str) -> str:
    return cache_mod.content_key(k, cache_mod.code_hash(value), *cache_mod._variant_part())


def test_a_background_write_leaves_the_files_a_direct_store_leaves(tmp_path):
    a, b = Cache(tmp_path / "a"), Cache(tmp_path / "b")
    got = a.get("kind", "k", value, code=value)
    cache_mod.flush()
    b.store("kind", _key("k"), value())
    for suffix in (".npy", ".json"):
        pa, pb = (c.root / "kind" / f"{_key('k')}{suffix}" for c in (a, b))
        assert pa.read_bytes() == pb.read_bytes(), suffix
    np.testing.assert_array_equal(got, value())
    assert json.loads((a.root / "kind" / f"{_key('k')}.json").read_text())["key"] == _key("k")


def test_an_entry_being_written_is_read_back_not_made_again(tmp_path):
    c, made, gate = Cache(tmp_path / "c"), [], threading.Event()
    cache_mod._writer().submit(gate.wait, 10)  # the writer busy: the entry stays in flight

    def make():
        made.append(1)
        return value()

    try:
        first = c.get("kind", "k", make, code=value)
        assert not (c.root / "kind").exists()  # not on disk yet
        again = c.get("kind", "k", make, code=value)
    finally:
        gate.set()
    cache_mod.flush()
    assert made == [1]
    np.testing.assert_array_equal(again, first)
    assert (c.root / "kind" / f"{_key('k')}.npy").exists()


def test_the_caller_may_change_its_array_while_it_is_written(tmp_path):
    c, gate = Cache(tmp_path / "c"), threading.Event()
    cache_mod._writer().submit(gate.wait, 10)
    try:
        got = c.get("kind", "k", value, code=value)
        got[:] = -1  # the caller's own array, changed before the writer reads it
    finally:
        gate.set()
    cache_mod.flush()
    np.testing.assert_array_equal(Cache(tmp_path / "c").load("kind", _key("k")), value())


def test_a_failed_write_is_raised_once_by_flush_and_by_the_next_get(tmp_path):
    (tmp_path / "file").write_text("not a directory")
    c = Cache(tmp_path / "file" / "cache")  # its directory cannot be made
    c.get("kind", "k", value, code=value)  # returns the array; the write fails on the writer's thread
    with pytest.raises(StudyError, match="cannot write the cache"):
        cache_mod.flush()
    cache_mod.flush()  # raised once
    c.get("kind", "k1", value, code=value)
    cache_mod._writer().submit(lambda: None).result()  # the failed write done, not yet raised
    with pytest.raises(StudyError, match="cannot write the cache"):
        c.get("kind", "k2", value, code=value)
    cache_mod.flush()


def _child(root: str, q) -> None:
    c = Cache(root)
    c.get("kind", "child", value, code=value)
    cache_mod.flush()
    q.put(sorted(p.name for p in (c.root / "kind").iterdir()))


def test_a_forked_child_writes_without_the_parents_thread(tmp_path):
    c, gate = Cache(tmp_path / "c"), threading.Event()
    cache_mod._writer().submit(gate.wait, 10)  # the parent's writer alive and busy as it forks
    try:
        c.get("kind", "parent", value, code=value)
        ctx = mp.get_context("fork")
        q = ctx.Queue()
        p = ctx.Process(target=_child, args=(str(tmp_path / "c"), q))
        p.start()
        names = q.get(timeout=60)  # the child's flush returned: its own writer wrote its entry
        p.join(timeout=60)
    finally:
        gate.set()
    cache_mod.flush()
    assert names == [f"{_key('child')}.json", f"{_key('child')}.npy"], names
    assert (c.root / "kind" / f"{_key('parent')}.npy").exists()


def test_a_failed_burst_ends_one_command_and_leaves_the_next_alone(tmp_path):
    """Several writes to a cache that cannot be written, queued together: the first get after them raises once,
    the others of that burst are forgotten with it, and the next command (another cache, then flush) sees none.
    Before: the burst's later failures stayed queued and ended the next in-process command (two CLI tests in one
    pytest worker)."""
    (tmp_path / "file").write_text("not a directory")
    bad, gate = Cache(tmp_path / "file" / "cache"), threading.Event()
    cache_mod._writer().submit(gate.wait, 10)  # the burst queued behind it, not yet failed
    for k in ("k1", "k2", "k3"):
        bad.get("kind", k, value, code=value)
    gate.set()
    cache_mod._writer().submit(lambda: None).result()  # the burst failed, not yet raised
    with pytest.raises(StudyError, match="cannot write the cache"):
        bad.get("kind", "k4", value, code=value)
    good = Cache(tmp_path / "good")
    np.testing.assert_array_equal(good.get("kind", "k", value, code=value), value())
    cache_mod.flush()  # nothing left of the burst
