"""The hierarchical search against the texel march, side by side in one run, on the bench's close-up batch.

    PYTHONPATH=. python scripts/hier_bench.py [--backend llvm|cuda] [--scene-res 1024] [--repeats 5] [--out DIR]

For linear_secant(1), layered(1) and multi_probe(1) on probe 0 alone (each with ``hierarchical`` False: the texel
march, and True: the min-pyramid march, with its blocks cut at the cube's face edges and, for the first two, as
before that cut, without) and localized(10): ms per 1024² frame (frozen path, as ``study bench`` times it), the
measured floor and the time over it (:func:`study.bench.floors.method_floor` at the measured mean lookups per ray),
mean lookups per ray (``Trace.lookups``), and the time over localized(10)'s; the same for the time the device spent
in the kernels (``kernel_*``: Dr.Jit's kernel history, CUDA events, without the host's share of a call, which
bounds localized(10)'s wall time on the GPU: :func:`study.bench.timing.kernel_seconds`). The fig4 scene's object at the
bench's default position (configs/fig4.toml, position 2), the close-up batch of
:func:`study.bench.batches.closeup_rays` at ``--scene-res``² rays, the impostor's distances exact from Embree at cube
resolution 256. Writes ``hier-<backend>.csv`` and ``.md`` to ``--out`` (default reports/performance) and prints the
table. Targets (on one H200, ``--backend cuda``): ≤ 60 lookups per ray and ≤ 3× localized(10)'s time for
linear_secant and layered, linear_secant ≤ 1.5× its floor.
"""

from __future__ import annotations

import argparse
import contextlib
import time
from pathlib import Path

import numpy as np

from study import backend as backends
from study import methods
from study.bench import floors as floor_model
from study.bench.batches import closeup_rays, distance_texels, room_triangles
from study.bench.timing import FRAME, time_method
from study.harness.config import load_figure_config
from study.measure.inputs import env_info
from study.methods import layered, linear_secant
from study.reference.embree import Tracer
from study.tables import columns_of, markdown, write_csv

ROWS = [  # (method, params, blocks cut at the cube's face edges)
    ("localized", {"iterations": 10}, True),
    ("linear_secant", {"steps_per_texel": 1.0, "hierarchical": False}, True),
    ("linear_secant", {"steps_per_texel": 1.0, "hierarchical": True}, False),
    ("linear_secant", {"steps_per_texel": 1.0, "hierarchical": True}, True),
    ("layered", {"steps_per_texel": 1.0, "hierarchical": False}, True),
    ("layered", {"steps_per_texel": 1.0, "hierarchical": True}, False),
    ("layered", {"steps_per_texel": 1.0, "hierarchical": True}, True),
    # multi_probe on probe 0 alone (no probe set here)
    ("multi_probe", {"steps_per_texel": 1.0, "hierarchical": False}, True),
    ("multi_probe", {"steps_per_texel": 1.0, "hierarchical": True}, True),
]


@contextlib.contextmanager
def edges_cut(cut: bool):
    """The hierarchical march with its blocks cut at face edges (the default, Skip.edge), or without the cut (the
    march before it: a block across an edge is tried, fails and is halved)."""
    plain = linear_secant.skipper

    def uncut(*a):
        s = plain(*a)
        if s is not None:
            s.edge = None
        return s

    if not cut:
        linear_secant.skipper = layered.skipper = uncut
    try:
        yield
    finally:
        linear_secant.skipper = layered.skipper = plain


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--backend", default="llvm", choices=["llvm", "cuda"])
    ap.add_argument("--scene-res", type=int, default=1024)
    ap.add_argument("--cube-res", type=int, default=256)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--out", type=Path, default=Path("reports/performance"))
    a = ap.parse_args()
    t_start = time.perf_counter()
    cfg, scene, _ = load_figure_config(Path("configs/fig4.toml"))
    position = tuple(cfg.positions[2])
    o = np.asarray(scene.reference.point, float)
    V, F = room_triangles(scene)
    tex = distance_texels(Tracer.from_triangles(V, F), o, a.cube_res)
    batch = closeup_rays(scene, position, a.scene_res)
    x, R = batch.x - o, batch.R
    B = backends.get(a.backend)
    big = a.backend == "cuda"
    floors = floor_model.measure(
        B,
        a.cube_res,
        n_lanes=1 << (22 if big else 16),
        fetches=64 if big else 16,
        copy_floats=1 << (28 if big else 24),
        repeats=a.repeats,
    )
    info = env_info(scene)
    rows = []
    for name, params, cut in ROWS:
        m = methods.make(name, **params)
        spent: list = []
        kernel: list = []
        with edges_cut(cut):
            t = time_method(
                m, B, tex, x, R, frozen=True, repeats=a.repeats, info=info, spent=spent, kernel=kernel
            )
        ms = t / len(x) * FRAME * 1e3
        floor = floor_model.method_floor(m, floors, "coherent", FRAME, a.cube_res, spent[0]) * 1e3
        rows.append(
            {
                "method": name,
                "search": ("hierarchical" if cut else "hierarchical, blocks not cut at face edges")
                if params.get("hierarchical")
                else "texel march"
                if "hierarchical" in params
                else "",
                "ms_per_frame": ms,
                "kernel_ms_per_frame": kernel[0] / len(x) * FRAME * 1e3,
                "floor_ms": floor,
                "x_floor": ms / floor,
                "lookups_per_ray": spent[0],
                "lookups_bound": m.lookup_bound(a.cube_res),
            }
        )
        print(f"{m.label}: {ms:.3f} ms/frame, {spent[0]:.1f} lookups/ray", flush=True)
    base, kbase = rows[0]["ms_per_frame"], rows[0]["kernel_ms_per_frame"]
    for r in rows:
        r["x_localized10"] = r["ms_per_frame"] / base
        r["kernel_x_localized10"] = r["kernel_ms_per_frame"] / kbase
    a.out.mkdir(parents=True, exist_ok=True)
    stem = a.out / f"hier-{a.backend}"
    write_csv(rows, stem.with_suffix(".csv"))
    stem.with_suffix(".md").write_text(markdown(rows, columns_of(rows)) + "\n")
    print(f"{batch.name}, {len(x)} rays, {a.backend}, {time.perf_counter() - t_start:.0f} s")
    for r in rows:
        print(
            f"{r['method']:14s} {r['search'][:24]:24s} {r['ms_per_frame']:9.3f} ms  ×floor {r['x_floor']:6.2f}  "
            f"lookups {r['lookups_per_ray']:7.1f}  ×localized(10) {r['x_localized10']:6.2f}  "
            f"kernels {r['kernel_ms_per_frame']:7.3f} ms ×localized(10) {r['kernel_x_localized10']:6.2f}"
        )


if __name__ == "__main__":
    main()
