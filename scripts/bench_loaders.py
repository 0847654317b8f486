"""Loader benchmark: study's OBJ reader against trimesh on the same large files, side by side in one run.

A grid of 1 M triangles (501 × 1001 vertices) written as OBJ in three forms — plain (``v x y z`` / ``f a b c``),
with tabs and indentation (study's former slow path, now read alike), and with ``v/vt`` corners — and each read
``--repeat`` times by :func:`study.scene.obj.read_obj` and by ``trimesh.load(force="mesh", process=False)``; the
medians and their ratio go to ``reports/performance/loaders.md`` (target: study ≤ 2× trimesh). trimesh is not timed
on the tab form, which it misreads (tests/scene/test_real_files.py).

    PYTHONPATH=. .venv/bin/python scripts/bench_loaders.py            # about 2 minutes on 2 cores
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def grid(nx: int, ny: int) -> tuple[np.ndarray, np.ndarray]:
    x, y = np.meshgrid(np.linspace(0, 1, nx), np.linspace(0, 1, ny), indexing="ij")
    V = np.c_[x.ravel(), y.ravel(), np.zeros(x.size)]
    i, j = np.meshgrid(np.arange(nx - 1), np.arange(ny - 1), indexing="ij")
    a = (i * ny + j).ravel()
    b, c, d = a + ny, a + ny + 1, a + 1
    F = np.concatenate([np.c_[a, b, c], np.c_[a, c, d]])
    return V, F


def write(path: Path, V, F, form: str) -> None:
    if form == "tabs":
        vs = "".join(f"  v\t{x:.6f}\t{y:.6f}\t{z:g}\n" for x, y, z in V)
        fs = "".join(f"\tf\t{a}\t{b}\t{c}\n" for a, b, c in F + 1)
    elif form == "uv":
        vs = "".join(f"v {x:.6f} {y:.6f} {z:g}\nvt {x:.6f} {y:.6f}\n" for x, y, z in V)
        fs = "".join(f"f {a}/{a} {b}/{b} {c}/{c}\n" for a, b, c in F + 1)
    else:
        vs = "".join(f"v {x:.6f} {y:.6f} {z:g}\n" for x, y, z in V)
        fs = "".join(f"f {a} {b} {c}\n" for a, b, c in F + 1)
    path.write_text(vs + fs)


def timed(fn, repeat: int) -> tuple[float, object]:
    ts, out = [], None
    for _ in range(repeat):
        t = time.perf_counter()
        out = fn()
        ts.append(time.perf_counter() - t)
    return statistics.median(ts), out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--nx", type=int, default=501)
    ap.add_argument("--ny", type=int, default=1001)
    ap.add_argument("--out", default=str(ROOT / "reports" / "performance" / "loaders.md"))
    a = ap.parse_args()
    import trimesh

    from study.codehash import code_hash
    from study.scene.obj import read_obj

    V, F = grid(a.nx, a.ny)
    rows = []
    with tempfile.TemporaryDirectory() as d:
        for form in ("plain", "tabs", "uv"):
            p = Path(d) / f"{form}.obj"
            write(p, V, F, form)
            mb = p.stat().st_size / 2**20
            ts, loaded = timed(lambda p=p: read_obj(p, "bench", (0.5, 0.5, 0.5)), a.repeat)
            n = sum(len(x.F) for x in loaded.pieces)
            assert n == len(F), (form, n)
            tt = None
            if form != "tabs":
                tt, m = timed(lambda p=p: trimesh.load(str(p), force="mesh", process=False), a.repeat)
                assert len(m.faces) == len(F)
            rows.append((form, mb, ts, tt))
            print(
                f"{form:6s} {mb:6.1f} MB  study {ts:6.2f} s  trimesh {tt if tt else float('nan'):6.2f} s",
                flush=True,
            )
    lines = [
        "# Loader benchmark: study's OBJ reader beside trimesh",
        "",
        f"{len(F):,} triangles ({a.nx} × {a.ny} vertices), median of {a.repeat} reads each, both in one run on this "
        f"machine; code {code_hash(read_obj, trimesh)} (study's reader and trimesh {trimesh.__version__}). "
        "Made by `PYTHONPATH=. .venv/bin/python scripts/bench_loaders.py`. Target: study ≤ 2× trimesh.",
        "",
        "| form | MB | study s | trimesh s | study / trimesh |",
        "|---|---:|---:|---:|---:|",
    ]
    for form, mb, ts, tt in rows:
        ratio = f"{ts / tt:.2f}×" if tt else "— (trimesh misreads tabs)"
        lines.append(f"| {form} | {mb:.1f} | {ts:.2f} | {tt:.2f} | {ratio} |" if tt else
                     f"| {form} | {mb:.1f} | {ts:.2f} | — | {ratio} |")  # fmt: skip
    Path(a.out).parent.mkdir(parents=True, exist_ok=True)
    Path(a.out).write_text("\n".join(lines) + "\n")
    print(f"wrote {a.out}")


if __name__ == "__main__":
    main()
