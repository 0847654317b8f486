"""A Dr.Jit frozen function must never record while the garbage collector frees Dr.Jit objects: Dr.Jit then
aborts the whole process ("enqueue_host_func(): this function cannot be recorded!"). The bench's runner once left
layered's impostor in a reference cycle (and later gave the layer textures of its own that the recording
replaced); with the collector's threshold at 100 it aborted every time. Here, in a child process so that an abort
is a failed test and not a dead worker: the threshold at 10, cyclic garbage holding Dr.Jit textures made before
every call, the marching methods recorded and replayed."""

import subprocess
import sys
import textwrap

import pytest
from conftest import BACKENDS

SCRIPT = textwrap.dedent("""
    import gc
    gc.set_threshold(10, 2, 2)
    from study import backend as backends, methods
    from study.bench.timing import method_runner
    from study.impostor import analytic
    B = backends.get("llvm")
    tex = analytic.box_impostor(16, (-2.0, 0.0, -2.0), (2.0, 3.0, 2.0))
    x, d = analytic.random_rays(500, extent=0.8, seed=3)
    for name in ("layered", "linear_secant", "localized"):
        call, finish = method_runner(methods.make(name), B, tex, x, d, frozen=True)
        for _ in range(4):
            junk = [B.texture(tex)]  # cyclic garbage that holds a Dr.Jit texture
            junk.append(junk)
            del junk
            finish(call())
    print("ok")
""")


@pytest.mark.skipif("llvm" not in BACKENDS, reason="needs Dr.Jit LLVM")
def test_frozen_recordings_survive_an_eager_garbage_collector():
    p = subprocess.run([sys.executable, "-c", SCRIPT], capture_output=True, text=True, timeout=600)
    assert p.returncode == 0 and p.stdout.strip().endswith("ok"), p.stderr[-2000:]
