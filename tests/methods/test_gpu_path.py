"""Whole studies on the GPU (issue 15), checked here on the CPU: the render device setting, the exact tracer of each
device (Mitsuba's ray queries stand in for OptiX through ``llvm_ad_rgb``), the cache key's variant, and Dask's
one-worker-per-GPU cluster."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import BACKENDS, error_output, run_cli

from study import runtime
from study.cache import Cache
from study.harness.config import load_figure_config
from study.reference.embree import Tracer
from study.reference.optix import MitsubaTracer
from study.reference.tracer import make_tracer

needs_llvm = pytest.mark.skipif("llvm" not in BACKENDS, reason="needs Dr.Jit LLVM (Mitsuba llvm_ad_rgb)")


@pytest.fixture
def cpu_device(monkeypatch):
    """The render device as a test may change it, restored afterwards."""
    monkeypatch.setenv("STUDY_RENDER_DEVICE", "cpu")
    monkeypatch.setitem(runtime.VARIANTS, "cuda", runtime.VARIANTS["cuda"])
    return monkeypatch


def _rays(scene, n, seed=0):
    rng = np.random.default_rng(seed)
    o = np.asarray(scene.reference.point) + rng.uniform(-0.6, 0.6, (n, 3))
    d = rng.normal(size=(n, 3))
    return o, d / np.linalg.norm(d, axis=1, keepdims=True)


@needs_llvm
@pytest.mark.parametrize("config", ["configs/fig4.toml", "configs/fig5.toml"])
def test_mitsuba_tracer_agrees_with_embree(config):
    """Same triangles, same rays: hit distance, point and uv within 1e-4, the same triangle and surface, the same
    misses (rays aimed out of the room's open side, if any, included)."""
    _, scene, _ = load_figure_config(config)
    o, d = _rays(scene, 20000)
    a = Tracer(scene.mesh()).intersect(o, d)
    b = MitsubaTracer(scene.mesh(), variant="llvm_ad_rgb").intersect(o, d)
    hit = np.isfinite(a["t"])
    assert hit.mean() > 0.9
    assert np.array_equal(hit, np.isfinite(b["t"]))
    assert np.max(np.abs(a["t"][hit] - b["t"][hit])) < 1e-4
    assert np.max(np.abs(a["point"][hit] - b["point"][hit])) < 1e-4
    assert np.nanmax(np.abs(a["uv"] - b["uv"])) < 1e-4
    assert np.array_equal(a["prim"], b["prim"]) and np.array_equal(a["surface"], b["surface"])
    db = MitsubaTracer(scene.mesh(), variant="llvm_ad_rgb").distance(o, d)
    assert np.allclose(db[hit], a["t"][hit], atol=1e-4) and np.all(np.isinf(db[~hit]))


@needs_llvm
def test_make_tracer_follows_the_render_device(cpu_device):
    _, scene, _ = load_figure_config("configs/fig4.toml")
    assert isinstance(make_tracer(scene.mesh()), Tracer)
    assert runtime.current_variant() == "llvm_ad_rgb"
    runtime.VARIANTS["cuda"] = "llvm_ad_rgb"  # stand-in for cuda_ad_rgb on this machine
    runtime.set_render_device("cuda")
    t = make_tracer(scene.mesh())
    assert isinstance(t, MitsubaTracer) and t.variant == "llvm_ad_rgb"
    with pytest.raises(ValueError):
        runtime.set_render_device("opencl")
    runtime.set_render_device("cpu")
    with runtime.using_render_device("cuda"):
        assert runtime.current_variant() == "llvm_ad_rgb" and runtime.render_device() == "cuda"
    assert runtime.render_device() == "cpu"


def test_cache_entries_of_another_device_are_not_found(cpu_device, tmp_path):
    """An array cached on the CPU is recomputed with the render device on CUDA (the variant is in the key) and
    found again on the CPU; CPU keys are those of before (no variant part for the default)."""
    runtime.VARIANTS["cuda"] = "scalar_rgb"  # any other variant: the key is what is tested
    cache, calls = Cache(tmp_path), []

    def make():
        calls.append(runtime.render_device())
        return np.full((2, 3), len(calls), np.float32)

    a = cache.get("k", "key", make, code=make)
    runtime.set_render_device("cuda")
    b = cache.get("k", "key", make, code=make)
    runtime.set_render_device("cpu")
    c = cache.get("k", "key", make, code=make)
    assert calls == ["cpu", "cuda"]
    assert a[0, 0] == 1 and b[0, 0] == 2 and c[0, 0] == 1


def test_cuda_backend_without_gpu_is_one_line_environment_error(cpu_device, tmp_path):
    res = run_cli(
        *[
            "figure",
            "fig4",
            "--backend",
            "cuda",
            "--out",
            str(tmp_path / "o"),
            "--cache",
            str(tmp_path / "c"),
        ],
    )
    if res.exit_code == 0:
        pytest.skip("a GPU is present")
    assert res.exit_code == 3, res.output
    assert len(error_output(res).splitlines()) == 1 and "cuda" in res.output.lower()
    assert runtime.render_device() == "cpu"  # the command's setting does not outlive it


def test_local_gpus_without_gpu_is_one_line_environment_error(cpu_device, tmp_path):
    cpu_device.setenv("CUDA_VISIBLE_DEVICES", "")
    res = run_cli(
        *[
            "sweep",
            "configs/sweep_tiny.toml",
            "--dask",
            "local-gpus",
            "--out",
            str(tmp_path / "o"),
            "--cache",
            str(tmp_path / "c"),
            "--no-plots",
        ],
    )
    assert res.exit_code == 3, res.output
    assert "no GPU visible" in res.output and "--dask" in res.output


def test_gpu_cluster_pins_one_worker_per_gpu(cpu_device):
    """local-gpus: per_gpu workers per listed GPU, each with its own CUDA_VISIBLE_DEVICES and the render device."""
    pytest.importorskip("distributed")
    import os

    from distributed import Client

    from study.harness.cluster import gpu_cluster, visible_gpus

    cpu_device.setenv("CUDA_VISIBLE_DEVICES", "0,1")
    assert visible_gpus() == ["0", "1"]
    with gpu_cluster(per_gpu=2) as cluster, Client(cluster) as client:
        client.wait_for_workers(4, timeout=60)
        env = client.run(lambda: (os.environ["CUDA_VISIBLE_DEVICES"], os.environ["STUDY_RENDER_DEVICE"]))
    assert sorted(env.values()) == [("0", "cpu"), ("0", "cpu"), ("1", "cpu"), ("1", "cpu")]


def test_libllvm_candidates_are_the_environments_lib_first(tmp_path, monkeypatch):
    """The environment's own libLLVM (the PyPI wheel karellen-llvm-core puts it in <prefix>/lib/) comes before the
    system's; lib/ and one folder below are read, a deeper one is not (a recursive walk of /usr/lib took 1 s of
    every process start on the GPU machine); a libLLVM older than 16 is never a candidate."""
    for rel in (
        "lib/libLLVM.so.21.1",
        "lib/llvm/libLLVM-20.so",
        "lib/a/b/libLLVM-22.so",
        "lib/libLLVM-15.so",
    ):
        (tmp_path / rel).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / rel).write_bytes(b"")
    monkeypatch.setattr(runtime.sys, "prefix", str(tmp_path))
    found = runtime.candidates()
    ours = [p for p in found if p.startswith(str(tmp_path))]
    assert ours == [str(tmp_path / "lib/libLLVM.so.21.1"), str(tmp_path / "lib/llvm/libLLVM-20.so")]
    assert found[: len(ours)] == ours


@needs_llvm
def test_every_tracer_s_hits_are_its_intersect_s_and_make_the_screen_buffers():
    """hits() (t, prim) of both tracers is their own intersect()'s t and prim, bit for bit, and the screen's buffers
    (screen.buffers, what a case's inputs call on the render device's tracer) come out of either: the same
    pixels hit, depths within 1e-4."""
    from study.impostor.screen import buffers

    _, scene, _ = load_figure_config("configs/fig4.toml")
    scene = scene.model_copy(update={"camera": scene.camera.model_copy(update={"width": 96, "height": 64})})
    o, d = _rays(scene, 9000)
    made = []
    for tracer in (Tracer(scene.mesh(), threads=3), MitsubaTracer(scene.mesh(), variant="llvm_ad_rgb")):
        full = tracer.intersect(o, d)
        t, prim = tracer.hits(o, d)
        np.testing.assert_array_equal(t, full["t"])
        np.testing.assert_array_equal(prim, full["prim"])
        made.append(buffers(scene, tracer))
    (da, na), (db, nb) = made
    assert da.shape == (64, 96) and na.shape == (64, 96, 3)
    assert np.array_equal(np.isfinite(da), np.isfinite(db)) and np.isfinite(da).mean() > 0.9
    assert np.nanmax(np.abs(np.where(np.isfinite(da), da - db, 0.0))) < 1e-4
    assert np.mean(np.all(na == nb, axis=-1)) > 0.99  # the same triangle but at an edge the two may split
