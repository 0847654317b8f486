"""scripts/wall_profile.py: every thread's samples, not the main thread's alone (what cProfile sees)."""

import sys
import textwrap

from conftest import load_script


def _load():
    return load_script("wall_profile")


def test_a_worker_thread_s_busy_function_and_the_main_thread_s_wait_are_told_apart(tmp_path, monkeypatch):
    (tmp_path / "busy_demo.py").write_text(
        textwrap.dedent(
            """
            import threading, time
            def spin_in_worker(seconds):
                end = time.perf_counter() + seconds
                while time.perf_counter() < end:
                    sum(range(200))
            if __name__ == "__main__":
                t = threading.Thread(target=spin_in_worker, args=(0.6,), name="demo-worker")
                t.start()
                t.join()
            """
        )
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setattr(sys, "argv", sys.argv[:1])
    out = tmp_path / "profile.txt"
    assert _load().main([str(out), "--interval", "0.005", "-m", "busy_demo"]) == 0
    text = out.read_text()
    worker = text.split("## demo-worker")[1].split("\n## ")[0]
    main = text.split("## MainThread")[1].split("\n## ")[0]
    assert "spin_in_worker" in worker and "busy" in worker.splitlines()[0]
    assert (
        "spin_in_worker" not in main
    )  # the main thread only waited (join): idle, not busy in the worker's code
    idle = float(main.splitlines()[0].split("idle ")[1].split(" s")[0])
    assert idle >= 0.3
