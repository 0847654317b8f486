"""Commands sharing one ``--cache`` (issue 51, item 9): writers of the same keys in several processes and threads,
``study cache clear`` and ``study cache info`` running meanwhile. Before: ``Path.mkdir(exist_ok=True)`` raced
clear's ``rmdir`` ("cannot write the cache (File exists)", ending the command), and ``info`` / ``clear`` stopped at
a file that vanished while they listed it (FileNotFoundError). Now every writer's entry lands and reads back whole,
and the listing skips what vanished."""

import multiprocessing as mp
import os
import threading
import time

import numpy as np

from study import cache as cache_mod
from study.cache import Cache


def value(key: str) -> np.ndarray:
    """The array every writer of ``key`` computes (the same bytes, as a content key promises)."""
    return np.full((16, 16, 3), int(key[1:]), np.float32)


def test_clear_removing_the_directory_as_mkdir_finds_it_does_not_end_the_write(tmp_path, monkeypatch):
    """The interleaving the stress test below finds, planted: ``os.mkdir`` of the kind's directory fails with
    EEXIST, and a clear removes the directory before ``mkdir(exist_ok=True)`` checks that it is one."""
    c = Cache(tmp_path / "cache")
    c.store("k", "k1", value("k1"))
    d = tmp_path / "cache" / "k"
    real = os.mkdir
    planted = []

    def mkdir(path, *a, **k):
        if os.fspath(path) == os.fspath(d) and not planted:
            planted.append(Cache(tmp_path / "cache").clear())  # the directory existed; now it is gone
            raise FileExistsError(17, "File exists", os.fspath(path))
        return real(path, *a, **k)

    monkeypatch.setattr(os, "mkdir", mkdir)
    c.store("k", "k2", value("k2"))
    monkeypatch.undo()
    assert planted and planted[0]["k"][0] == 1
    np.testing.assert_array_equal(c.load("k", "k2"), value("k2"))


def test_info_and_clear_skip_a_file_that_vanishes_while_listed(tmp_path, monkeypatch):
    """A file listed, then removed (by another clear) before it is measured: info counts what is there."""
    c = Cache(tmp_path / "cache")
    for k in ("k1", "k2"):
        c.store("k", k, value(k))
    (tmp_path / "cache" / "k" / ".k3.abc.tmp").write_bytes(b"x")  # a writer's temporary file
    real = cache_mod._in_flight

    def in_flight(p):
        (tmp_path / "cache" / "k" / "k1.npy").unlink(missing_ok=True)  # gone after the listing
        return real(p)

    monkeypatch.setattr(cache_mod, "_in_flight", in_flight)
    n, size = c.info()["k"]
    assert n == 2 and size == sum(p.stat().st_size for p in (tmp_path / "cache" / "k").glob("k[12].*"))
    assert c.clear()["k"][0] == 2


def _writer(root: str, seconds: float, q) -> None:
    c, errs, i = Cache(root), [], 0
    stop = time.time() + seconds
    while time.time() < stop:
        key = f"k{i % 4}"
        i += 1
        try:
            a = c.get(f"kind{i % 2}", key, lambda key=key: value(key), code=value)
            if not np.array_equal(a, value(key)):
                errs.append(f"{key}: another entry's array")
        except Exception as err:  # noqa: BLE001 (what reaches a command: reported by the test)
            errs.append(f"{type(err).__name__}: {err}")
    q.put(errs)


def test_writers_in_processes_and_threads_with_clear_and_info_meanwhile(tmp_path):
    """Three processes and three threads write the same keys for 3 s while three threads list and clear the cache:
    no write fails, every array read is the one its key names, and afterwards every entry reads back."""
    root = str(tmp_path / "cache")
    ctx = mp.get_context("spawn")
    q = ctx.Queue()
    procs = [ctx.Process(target=_writer, args=(root, 4.0, q)) for _ in range(3)]
    for p in procs:
        p.start()
    time.sleep(1.0)  # the processes are writing (spawn takes a moment)
    tq, errs = _Q(), []
    stop = time.time() + 3.0

    def admin():
        c = Cache(root)
        while time.time() < stop:
            for f in (c.info, c.clear):
                try:
                    f()
                except Exception as err:  # noqa: BLE001
                    errs.append(f"{f.__name__}: {type(err).__name__}: {err}")

    threads = [threading.Thread(target=_writer, args=(root, 3.0, tq)) for _ in range(3)]
    threads += [threading.Thread(target=admin) for _ in range(3)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    for p in procs:
        p.join(timeout=60)
        errs += q.get(timeout=60)
    errs += sum(tq.items, [])
    assert errs == [], errs[:5]
    c = Cache(root)
    for kind in ("kind0", "kind1"):
        for k in ("k0", "k1", "k2", "k3"):
            c.get(kind, k, lambda k=k: value(k), code=value)
            key = cache_mod.content_key(k, cache_mod.code_hash(value), *cache_mod._variant_part())
            np.testing.assert_array_equal(c.load(kind, key), value(k))


class _Q:
    """A queue for threads (``put`` only)."""

    def __init__(self):
        self.items = []

    def put(self, x):
        self.items.append(x)
