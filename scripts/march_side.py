"""The marches' close-up kernels and their floors, one tree at a time, for a side-by-side run of two trees (issue 56).

    PYTHONPATH=<tree> python scripts/march_side.py --tree NAME [--backend llvm|cuda] [--scene-res 1024]
        [--cube-res 256] [--repeats 5] [--out DIR] [--methods a,b] [--no-time]
    python scripts/march_side.py --compare DIR        (after runs of two or more trees into DIR)

The tree is the ``study`` package first on PYTHONPATH (this script only uses what every tree since 635ec81 has:
study.bench's batches, floors and timing), so the same script times main and a branch on one warm machine:
``scripts/device_run.sh marches`` runs it for $OLD and this tree, twice each, interleaved (old, new, old, new).

Per method (:data:`ROWS`: linear_secant(1), layered(1), multi_probe, probe_blend, ssr_hiz and localized(10) at their
bench defaults) on the bench's fig4 close-up batch (:func:`study.bench.batches.closeup_rays`, ``--scene-res``² rays,
the impostor's distances exact from Embree at ``--cube-res``), as ``study bench`` times it (frozen path, probe sets
and the camera's buffer from :mod:`study.bench.timing`): the kernels' device time per 1024² frame (Dr.Jit's kernel
history), the wall time, the mean lookups per ray, the measured floor (:func:`study.bench.floors.method_floor`) and
both times over it, and over localized(10)'s. Writes ``march-<tree>-<backend>-<run>.csv`` and the methods' outputs
(shown point, radiance, ratio, valid, lookups per ray) as ``.npz`` beside it.

``--compare DIR``: per method and tree, the median kernel time of its runs, × floor, × localized(10), and the ratio
to the first tree's (``old`` where there is one); and whether each tree's outputs are bit-identical to the first
tree's (NaNs equal), per output. ``--variant``: this branch's restructures undone one by one (:func:`variant`), each
timed as a tree of its own (``--tree new-tables-off``), for the step-by-step times.
"""

from __future__ import annotations

import argparse
import csv
import time
from pathlib import Path

import numpy as np

ROWS = [  # (method, params): the bench's labels of issue 56
    ("localized", {"iterations": 10}),
    ("linear_secant", {"steps_per_texel": 1.0}),
    ("layered", {"steps_per_texel": 1.0}),
    ("multi_probe", {"steps_per_texel": 1.0}),
    ("probe_blend", {}),
    ("ssr_hiz", {}),
]
OUTPUTS = ("shown", "radiance", "ratio", "valid", "lookups")


def setup(backend: str, scene_res: int, cube_res: int, repeats: int, timed: bool, synthetic: bool = False):
    """(B, tex, batch, o, info, screen, tracer, floors) of the bench's close-up batch on ``backend`` (floors: {}
    without ``timed``; screen: a callable that makes the camera's buffer, for the methods that read it)."""
    from study import backend as backends
    from study.bench import floors as floor_model
    from study.bench.batches import closeup_rays, distance_texels, room_triangles, synthetic_rays
    from study.bench.timing import bench_screen, camera_depth
    from study.harness.config import load_figure_config
    from study.measure.inputs import env_info
    from study.reference.embree import Tracer

    cfg, scene, _ = load_figure_config(Path("configs/fig4.toml"))
    position = tuple(cfg.positions[2])
    o = np.asarray(scene.reference.point, float)
    V, F = room_triangles(scene)
    tracer = Tracer.from_triangles(V, F)
    tex = distance_texels(tracer, o, cube_res)
    batch = closeup_rays(scene, position, scene_res)
    if synthetic:  # random rays within 0.6 m of o (every direction: face changes, grazing rays), same camera
        batch = synthetic_rays(scene, scene_res**2, camera=batch.camera)
    B = backends.get(backend)
    info = env_info(scene)
    made = []

    def screen():  # made on first use (its Hi-Z pyramid: kernels of their own, which ncu need not profile)
        if not made:
            made.append(bench_screen(camera_depth(batch.camera, tracer), batch.camera, o, B))
        return made[0]

    big = backend == "cuda"
    if not timed:
        return B, tex, batch, o, info, screen, tracer, {}
    floors = floor_model.measure(
        B,
        cube_res,
        n_lanes=1 << (22 if big else 14),
        fetches=64 if big else 16,
        copy_floats=1 << (28 if big else 22),
        repeats=repeats,
    )
    return B, tex, batch, o, info, screen, tracer, floors


def variant(name: str) -> None:
    """Undo one of this branch's restructures (issue 56), to time each step in the same run: ``tables-off`` (the
    arc samples' sine and cosine per ray, not from tables), ``look-off`` (sample k + 1 made on each side of the
    march's branch, not once before it, and a jump's arc point made again: both go with ``Skip.shared``),
    ``both-off``; ``branch-off`` (the march's two sides both made on every lane and selected, ``dr.select``, not
    a ``dr.if_stmt`` per iteration: whether the branch costs more than the side a lane does not need); ``""``
    none. A tree without the restructure ignores it."""
    from study.methods import layered, linear_secant, march, multi_probe, search

    if name == "branch-off":

        class Selected:  # the backend with its branch made of selects, for the march alone
            def __init__(self, B):
                self._B = B

            def __getattr__(self, key):
                return getattr(self._B, key)

            def branch(self, cond, state, true_fn, false_fn):
                a, b = true_fn(*state), false_fn(*state)
                return tuple(self._B.select(cond, p, q) for p, q in zip(a, b))

        def selected(B, *args, **kw):  # the searches call the march through search's name for it
            return march.march(Selected(B), *args, **kw)

        search.march = selected

    if name in ("tables-off", "both-off") and hasattr(search.arc_samples, "tabulate"):
        search.arc_samples.tabulate = lambda self: None
    if name in ("look-off", "both-off"):
        plain = linear_secant.skipper

        def unlooked(*args, **kw):
            s = plain(*args, **kw)
            if s is not None and hasattr(s, "look"):
                s.look = None
            return s

        for mod in (linear_secant, layered, multi_probe):
            mod.skipper = unlooked


def run(a) -> None:
    from study import methods
    from study.bench import floors as floor_model
    from study.bench.timing import FRAME, bench_probes, method_runner, time_method

    t0 = time.perf_counter()
    variant(a.variant)
    B, tex, batch, o, info, screen, tracer, floors = setup(
        a.backend, a.scene_res, a.cube_res, a.repeats, not a.no_time, a.synthetic
    )
    x, R = batch.x - o, batch.R
    names = set(a.methods.split(",")) if a.methods else None
    rows, dump = [], {}
    for name, params in ROWS:
        if names is not None and name not in names:
            continue
        m = methods.make(name, **params)
        sets = {sp: bench_probes(sp, tracer, tex, o, info["room"], B) for sp in m.views_needed().probes}
        kw = dict(info=info, screen=screen() if m.views_needed().screen else None, probe_sets=sets)
        call, finish = method_runner(m, B, tex, x, R, frozen=False, **kw)
        out = call()
        finish(out)
        shown, rad, ratio, valid, spent = out
        for key, v in zip(
            OUTPUTS, (B.to_numpy(shown), B.to_numpy(rad), B.numpy(ratio), B.numpy(valid), B.numpy(spent))
        ):
            dump[f"{m.label}/{key}"] = np.asarray(v)
        row = {"tree": a.tree, "run": a.run, "backend": a.backend, "method": m.label, "rays": len(x)}
        row["lookups_mean"] = float(np.mean(B.numpy(spent)))
        if not a.no_time:
            spent_l, kernel = [], []
            t = time_method(
                m, B, tex, x, R, frozen=True, repeats=a.repeats, spent=spent_l, kernel=kernel, **kw
            )
            floor = floor_model.method_floor(m, floors, "coherent", FRAME, a.cube_res, spent_l[0]) * 1e3
            row.update(
                ms_per_frame=t / len(x) * FRAME * 1e3,
                kernel_ms_per_frame=kernel[0] / len(x) * FRAME * 1e3,
                floor_ms_per_frame=floor,
            )
            row["kernel_x_floor"] = row["kernel_ms_per_frame"] / floor
        rows.append(row)
        print(a.tree, {k: (round(v, 4) if isinstance(v, float) else v) for k, v in row.items()}, flush=True)
    a.out.mkdir(parents=True, exist_ok=True)
    stem = a.out / f"march-{a.tree}-{a.backend}{'-synthetic' if a.synthetic else ''}-{a.run}"
    np.savez_compressed(stem.with_suffix(".npz"), **dump)
    cols = list(dict.fromkeys(k for r in rows for k in r))
    with open(stem.with_suffix(".csv"), "w", newline="") as f:
        w = csv.DictWriter(f, cols)
        w.writeheader()
        w.writerows(rows)
    print(
        f"{a.tree}: {len(rows)} methods, {len(x)} rays, {a.backend}, {time.perf_counter() - t0:.0f} s",
        flush=True,
    )


def same(p: np.ndarray, q: np.ndarray) -> bool:
    """Bit-identical arrays, NaNs equal."""
    return p.shape == q.shape and p.dtype == q.dtype and p.tobytes() == q.tobytes()


def compare(out: Path) -> None:
    rows, dumps = [], {}
    for f in sorted(out.glob("march-*.csv")):
        with open(f) as fh:
            got = list(csv.DictReader(fh))
        rows += got
        if got:
            dumps.setdefault(got[0]["tree"], []).append(np.load(f.with_suffix(".npz")))
    trees = sorted(dict.fromkeys(r["tree"] for r in rows), key=lambda t: (t != "old", t))  # old first

    def med(tree, method, key):
        v = [float(r[key]) for r in rows if r["tree"] == tree and r["method"] == method and r.get(key)]
        return float(np.median(v)) if v else float("nan")

    methods_ = list(dict.fromkeys(r["method"] for r in rows))
    loc = next((m for m in methods_ if m.startswith("localized")), None)
    print(
        f"{'method':34s} {'tree':16s} {'kernel ms':>10s} {'x floor':>8s} {'x loc10':>8s} {'x ' + trees[0]:>8s}"
        f" {'lookups':>8s}  outputs vs {trees[0]}"
    )
    for m in methods_:
        for t in trees:
            k = med(t, m, "kernel_ms_per_frame")
            fl = med(t, m, "floor_ms_per_frame")
            base = med(trees[0], m, "kernel_ms_per_frame")
            kl = med(t, loc, "kernel_ms_per_frame") if loc else float("nan")
            diff = []
            for key in OUTPUTS:
                a0 = dumps[trees[0]][0][f"{m}/{key}"]
                if any(not same(a0, d[f"{m}/{key}"]) for d in dumps[t]):
                    diff.append(key)
            print(
                f"{m:34s} {t:16s} {k:10.4f} {k / fl:8.2f} {k / kl:8.2f} {k / base:8.3f} "
                f"{med(t, m, 'lookups_mean'):8.2f}  {'identical' if not diff else 'DIFFER: ' + ','.join(diff)}"
            )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--tree", default="new")
    ap.add_argument("--run", default="0")
    ap.add_argument("--backend", default="llvm", choices=["numpy", "llvm", "cuda"])
    ap.add_argument("--scene-res", type=int, default=1024)
    ap.add_argument("--cube-res", type=int, default=256)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--methods", default="")
    ap.add_argument(
        "--synthetic", action="store_true", help="random rays near o instead of the close-up batch"
    )
    ap.add_argument("--no-time", action="store_true", help="outputs only (numpy has no kernels to time)")
    ap.add_argument("--out", type=Path, default=Path("out-march"))
    ap.add_argument("--variant", default="", choices=["", "tables-off", "look-off", "both-off", "branch-off"])
    ap.add_argument("--compare", type=Path, default=None)
    a = ap.parse_args()
    if a.compare is not None:
        compare(a.compare)
    else:
        run(a)


if __name__ == "__main__":
    main()
