"""``--dask`` refuses what is not a cluster and never hangs: a bad value is bad input (exit 2, before any work);
a peer that accepts and stays silent, an HTTP server, or a scheduler without workers is the environment's problem
(exit 3) within the timeout ($STUDY_DASK_TIMEOUT, seconds). Each run: one line on stderr, no traceback."""

import http.server
import os
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from study.errors import StudyError
from study.harness.cluster import check_address

ROOT = Path(__file__).resolve().parents[2]
TINY = ROOT / "configs" / "sweep_tiny.toml"


def sweep(tmp_path, dask: str, timeout: float = 3):
    env = {**os.environ, "STUDY_DASK_TIMEOUT": str(timeout)}
    t0 = time.perf_counter()
    proc = subprocess.run(
        [sys.executable, "-m", "study.cli", "sweep", str(TINY), "--out", str(tmp_path / "o"),
         "--cache", str(tmp_path / "c"), "--no-plots", "--dask", dask],
        cwd=ROOT, env=env, capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    lines = proc.stderr.strip().splitlines()
    assert "Traceback" not in proc.stderr, proc.stderr
    err = [ln for ln in lines if ln.startswith("error:")]  # besides the progress bar: one error line
    assert len(err) == len(lines[lines.index(err[0]) :]) == 1 if err else True, lines
    return proc.returncode, err, time.perf_counter() - t0


@pytest.mark.parametrize("value", ["", "  ", "banana", "tcp://", "http//x:1"])
def test_bad_dask_values_are_refused_naming_the_allowed_ones(value):
    with pytest.raises(StudyError, match="allowed: 'local', 'local-gpus'"):
        check_address(value)


@pytest.mark.parametrize("value", ["local", "local-gpus", "tcp://10.0.0.1:8786", " tls://h:1 "])
def test_good_dask_values_pass(value):
    assert check_address(value) == value.strip()


def test_cli_refuses_banana_and_empty_before_work(tmp_path):
    for value in ("banana", ""):
        code, err, _ = sweep(tmp_path, value)
        assert code == 2 and err[-1].startswith("error: --dask:"), err
        assert not (tmp_path / "o").exists()


@pytest.fixture
def silent_server():
    """A TCP port that accepts connections and never says a word."""
    srv = socket.socket()
    srv.bind(("127.0.0.1", 0))
    srv.listen(8)
    conns, stop = [], threading.Event()

    def serve():
        srv.settimeout(0.2)
        while not stop.is_set():
            try:
                conns.append(srv.accept()[0])
            except OSError:
                pass

    t = threading.Thread(target=serve, daemon=True)
    t.start()
    yield srv.getsockname()[1]
    stop.set()
    t.join(2)
    for c in conns:
        c.close()
    srv.close()


@pytest.mark.slow
def test_silent_peer_is_an_environment_error_within_the_timeout(tmp_path, silent_server):
    code, err, seconds = sweep(tmp_path, f"tcp://127.0.0.1:{silent_server}")
    assert code == 3 and "cannot reach the Dask scheduler" in err[-1], err
    assert seconds < 60


@pytest.mark.slow
def test_http_server_is_an_environment_error_within_the_timeout(tmp_path):
    httpd = http.server.ThreadingHTTPServer(("127.0.0.1", 0), http.server.SimpleHTTPRequestHandler)
    threading.Thread(target=httpd.serve_forever, daemon=True).start()
    try:
        code, err, seconds = sweep(tmp_path, f"tcp://127.0.0.1:{httpd.server_address[1]}")
    finally:
        httpd.shutdown()
    assert code == 3 and "Dask scheduler" in err[-1], err
    assert seconds < 60


@pytest.mark.slow
def test_scheduler_without_workers_is_an_environment_error(tmp_path):
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(n_workers=0, dashboard_address=None, processes=True) as cluster:
        code, err, seconds = sweep(tmp_path, cluster.scheduler_address)
    assert code == 3 and "no Dask worker joined" in err[-1], err
    assert seconds < 60
