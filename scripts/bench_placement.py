"""Benchmark (not a test): automatic placement in a generated room of about 300,000 triangles.

The room is a 12 m × 4 m × 9 m box whose walls are finely tessellated, with a grid of pillars (finely tessellated
cylinders) standing on the floor, written as a binary PLY (or an OBJ, read by study's own reader) in a temporary
folder. Timed: reading it
(``geometry``), and placing the reference point, object, camera and light (``study.load_scene`` of the file,
which suggests every placement key and checks them), each cold (a fresh process state for the mesh).

    PYTHONPATH=$PWD .venv/bin/python scripts/bench_placement.py [--triangles 300000] [--format ply|obj]
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np


def grid_quad(p0, du, dv, n: int):
    """An n × n grid of quads (2 n² triangles) spanning p0 + [0, 1] du + [0, 1] dv; winding as du × dv."""
    s = np.linspace(0, 1, n + 1)
    uu, vv = np.meshgrid(s, s, indexing="ij")
    V = p0 + uu[..., None] * du + vv[..., None] * dv
    i = np.arange((n + 1) ** 2).reshape(n + 1, n + 1)
    a, b, c, d = i[:-1, :-1], i[1:, :-1], i[1:, 1:], i[:-1, 1:]
    F = np.concatenate([np.stack([a, b, c], -1).reshape(-1, 3), np.stack([a, c, d], -1).reshape(-1, 3)])
    return V.reshape(-1, 3), F


def cylinder(cx, cz, r, h, n_around: int, n_up: int):
    """An open cylinder (outward normals) standing on y = 0."""
    th = np.linspace(0, 2 * np.pi, n_around + 1)
    y = np.linspace(0, h, n_up + 1)
    T, Y = np.meshgrid(th, y, indexing="ij")
    V = np.stack([cx + r * np.cos(T), Y, cz + r * np.sin(T)], -1).reshape(-1, 3)
    i = np.arange((n_around + 1) * (n_up + 1)).reshape(n_around + 1, n_up + 1)
    a, b, c, d = i[:-1, :-1], i[1:, :-1], i[1:, 1:], i[:-1, 1:]
    F = np.concatenate([np.stack([a, c, b], -1).reshape(-1, 3), np.stack([a, d, c], -1).reshape(-1, 3)])
    return V, F


def room(triangles: int):
    lo, hi = np.array([0.0, 0.0, 0.0]), np.array([12.0, 4.0, 9.0])
    ex, ey, ez = np.diag(hi - lo)
    n = int(np.sqrt(triangles * 0.6 / 12))  # the six walls take ~60 %
    parts = [
        grid_quad(lo, ez, ex, n),
        grid_quad(lo + ey, ex, ez, n),
        grid_quad(lo, ey, ez, n),
        grid_quad(lo + ex, ez, ey, n),
        grid_quad(lo, ex, ey, n),
        grid_quad(lo + ez, ey, ex, n),
    ]
    per = int(triangles * 0.4 / 12 / 2)
    k = int(np.sqrt(per))
    for x in (3.0, 6.0, 9.0):
        for z in (2.0, 4.5, 7.0, 8.0):
            parts.append(cylinder(x, z, 0.3, 4.0, k, max(1, per // k)))
    V, F, off = [], [], 0
    for v, f in parts:
        V.append(v)
        F.append(f + off)
        off += len(v)
    return np.concatenate(V), np.concatenate(F)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--triangles", type=int, default=300_000)
    ap.add_argument("--format", choices=("ply", "obj"), default="ply", help="the file written and read")
    args = ap.parse_args()
    import trimesh

    import study
    from study.scene.environment import geometry

    V, F = room(args.triangles)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / f"big_room.{args.format}"
        data = trimesh.Trimesh(V, F, process=False).export(file_type=args.format)
        path.write_bytes(data if isinstance(data, bytes) else data.encode())
        t0 = time.perf_counter()
        env = geometry({"type": "mesh", "file": str(path)})
        t1 = time.perf_counter()
        scene = study.load_scene(path)
        t2 = time.perf_counter()
    print(env.summary)
    print(
        f"read {t1 - t0:.2f} s; placement (suggest every key + checks) {t2 - t1:.2f} s; total {t2 - t0:.2f} s"
    )
    print(
        f"reference.point {np.round(scene.reference.point, 2).tolist()}, object.center "
        f"{np.round(scene.object.center, 2).tolist()} r {scene.object.radius:.2f}, camera.eye "
        f"{np.round(scene.camera.eye, 2).tolist()}, light {np.round(scene.light.position, 2).tolist()} "
        f"{scene.light.intensity[0]:.1f} W/sr"
    )


if __name__ == "__main__":
    main()
