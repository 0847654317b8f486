"""Output sets and locks under races: a sibling's live temporary directory is not anybody's leftover, and an
interrupt while the lock is being taken leaves no lock file behind."""

import fcntl
import os

import pytest

from study import io


def test_cleanup_spares_a_siblings_live_temp_dir(tmp_path):
    """`out` and `out.new-x` side by side: a run on `out` removes `out`'s own leftover, not the live temporary
    directory of the run writing `out.new-x` (which matched the old glob `.out.new-*`)."""
    live = tmp_path / ".out.new-x.new-abcd1234"  # what mkdtemp makes for a run on out.new-x
    stale = tmp_path / ".out.new-zz_9ab12"  # a killed run's leftover for out
    for d in (live, stale):
        d.mkdir()
        (d / "fig8.csv").write_text("a\n")
    with io.output_set(tmp_path / "out", ["t.txt"]) as tmp:
        (tmp / "t.txt").write_text("new")
    assert (live / "fig8.csv").read_text() == "a\n"
    assert not stale.exists()
    assert (tmp_path / "out" / "t.txt").read_text() == "new"


@pytest.mark.parametrize("when", ["flock", "same_file"])
def test_interrupt_while_locking_leaves_no_lock(tmp_path, monkeypatch, when):
    """SIGINT/SIGTERM (a KeyboardInterrupt) right after the lock file is created: no `.lock` is left and the
    directory made for it is removed again."""
    real_flock, real_same = fcntl.flock, io._same_file
    calls = {"n": 0}

    def flock(f, op):
        calls["n"] += 1
        if when == "flock" and calls["n"] == 1:
            raise KeyboardInterrupt
        return real_flock(f, op)

    def same_file(path, f):
        calls["same"] = calls.get("same", 0) + 1
        if when == "same_file" and calls["same"] == 1:
            raise KeyboardInterrupt
        return real_same(path, f)

    monkeypatch.setattr(io.fcntl, "flock", flock)
    monkeypatch.setattr(io, "_same_file", same_file)
    out = tmp_path / "o"
    with pytest.raises(KeyboardInterrupt), io.locked(out):
        pass
    assert not (out / io.LOCK).exists() and not out.exists()


def test_interrupted_second_command_keeps_the_holders_lock(tmp_path, monkeypatch):
    """The second command is interrupted while it finds the directory held: the holder's lock file stays."""
    out = tmp_path / "o"
    with io.locked(out):
        holder = os.stat(out / io.LOCK).st_ino
        with pytest.raises(io.EnvironmentProblem):
            with io.locked(out):
                pass
        assert os.stat(out / io.LOCK).st_ino == holder
    assert not (out / io.LOCK).exists()
