"""``study bench``: the options and the main table (every method × backend × batch, with the exact rows).

Method rows: every registered method (or those named in ``methods``), each at every value of its knob's ladder
(``Method.ladder()``; with ``ladder=False`` at its defaults only), on each backend; on Dr.Jit through the frozen
path (``Backend.freeze``: recorded kernels replayed, no Python tracing per call) and, for the ``focus`` method at
its defaults (the paper's ``localized``), also the plain traced path. numpy is timed on at most
``numpy_max_rays`` rays of a batch.
A method that is the exact query itself (``traced``, whose class names its ``bench_query``) is not timed again:
its row takes the time measured for that query (:func:`exact_query_row`).
Exact rows: Embree on every core, and Mitsuba's ``ray_intersect`` (full SurfaceInteraction) and the cheapest exact
queries for the same question, ``ray_intersect_preliminary`` (hit distance) and ``ray_test`` (occlusion), on the
device of each backend asked for.
Ratios: x_vs_embree / x_vs_mitsuba / x_vs_preliminary / x_vs_ray_test = the exact query's time for the same rays over
the method's (> 1: the method is faster); Mitsuba is taken on the same device as the backend (LLVM for numpy and
llvm, CUDA for cuda). Floors (:mod:`study.bench.floors`, measured in the same run on each Dr.Jit backend):
floor_ms_per_frame and x_floor = the method's time over its floor.
The options are checked before anything runs (:func:`check_options`): ranges, and the memory the ray batches need
against ``--max-memory`` (:mod:`study.harness.budget`).
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass

import numpy as np

from study import backend as backends
from study import methods as registry
from study.bench import carry
from study.bench import floors as floor_model
from study.bench.batches import (
    Batch,
    closeup_rays,
    direction_sorted,
    distance_texels,
    room_triangles,
    scene_rays,
    synthetic_rays,
)
from study.bench.machine import available_backends, machine_info
from study.bench.scaling import knob_values, scaling_rows
from study.bench.timing import (
    FRAME,
    QUERIES,
    SHADING,
    Exact,
    bench_probes,
    bench_screen,
    camera_depth,
    mitsuba_variant,
    ms_per_frame,
    rate_row,
    time_method,
)
from study.codehash import code_hash
from study.errors import StudyError
from study.harness import budget
from study.impostor.views import Views
from study.measure.inputs import env_info
from study.methods import Method
from study.scene import Scene


@dataclass
class BenchOptions:
    position: tuple = (1.1, 0.9, 0.6)  # object centre for the fig4 batch
    scene_res: int = 1024  # camera res² for the fig4 batch
    synthetic: int = FRAME  # rays of the synthetic batch
    methods: tuple = ()  # names of the methods timed; () = every registered one
    ladder: bool = True  # each method at every value of its knob's ladder (else defaults)
    cube_res: int = 256
    backends: tuple = ()  # () = all available
    repeats: int = 5
    numpy_max_rays: int = 1 << 16  # numpy is timed on at most this many rays of a batch
    focus: str = "localized"  # the method of the scaling studies and of the plain-path rows
    scaling: bool = True
    ray_counts: tuple = (256**2, 512**2, 1024**2, 2048**2)
    knob_extra: tuple = (2, 5, 15)  # knob values tried besides the focus method's ladder (finer curve)
    cube_resolutions: tuple = (64, 128, 256, 512, 1024)
    triangles: tuple = (0, 100, 1000, 10_000, 100_000, 1_000_000)
    tag: str = ""  # device tag in file names and tables (default: cpu / gpu name)
    floors: bool = True  # measure fetch-rate and bandwidth floors (Dr.Jit backends)


#: Allowed ranges of the numeric options: (option, attribute, lowest, highest).
RANGES = [
    ("--repeats", "repeats", 1, 1000),
    ("--scene-res", "scene_res", 8, 4096),
    ("--rays", "synthetic", 1, 1 << 24),
    ("--cube-res", "cube_res", 4, 4096),
    ("--numpy-max-rays", "numpy_max_rays", 1, 1 << 24),
]


def check_options(opt: BenchOptions) -> None:
    """Refuse options out of range (a StudyError naming the option): 0, negative or huge counts, a tag that is
    not a plain file-name part, ray batches that need more memory than ``--max-memory``."""
    for key, attr, lo, hi in RANGES:
        v = getattr(opt, attr)
        if isinstance(v, bool) or not isinstance(v, int) or not lo <= v <= hi:
            raise StudyError(f"must be an integer in {lo}..{hi}, got {v!r}", key=key)
    if not re.fullmatch(r"[A-Za-z0-9][A-Za-z0-9_.-]{0,63}|", opt.tag):
        raise StudyError(
            f"must be letters, digits, '_', '.', '-' (a part of file names), got {opt.tag!r}", key="--tag"
        )
    rays = 2 * opt.scene_res**2 + opt.synthetic
    need = (
        budget.BYTES_BASE + rays * budget.BYTES_PER_OBJECT_RAY + 6 * opt.cube_res**2 * budget.BYTES_PER_TEXEL
    )
    if need > budget.LIMITS.max_memory_gib * (1 << 30):
        key = "--scene-res" if 2 * opt.scene_res**2 > opt.synthetic else "--rays"
        raise StudyError(
            f"the ray batches would need about {need / (1 << 30):.1f} GiB, over the limit of "
            f"{budget.LIMITS.max_memory_gib:g} GiB (--max-memory): lower {key}",
            key=key,
        )


def bench_methods(opt: BenchOptions) -> list[Method]:
    """The methods timed: each one named (every mirror method by default, as ``"all"``, and ``hit_cache``, priced
    from the exact query: not the glossy ones) at each knob value of its ladder, or at its defaults only without
    ``opt.ladder``. An unknown name is a StudyError."""
    exact = [n for n, c in registry.REGISTRY.items() if getattr(c, "bench_query", None) and not c.glossy]
    default = [m.name for m in registry.all_methods()] + exact  # "all" leaves hit_cache out
    chosen = [registry.make(n) for n in dict.fromkeys(opt.methods or default)]
    return [v for m in chosen for v in (m.ladder() if opt.ladder else [m])]


def run_bench(
    scene: Scene, opt: BenchOptions, log=print, on_table=None
) -> tuple[list[dict], list[dict], dict]:
    """Time everything; returns (bench rows, scaling rows, machine info). ``on_table(rows, info)`` is called
    with the main table before the scaling studies start (so it is kept if they fail)."""
    check_options(opt)
    names = list(opt.backends) or available_backends()
    for n in names:
        budget.check_backend(n)  # unknown or unavailable: StudyError now
    methods = bench_methods(opt)  # unknown methods: StudyError now
    plain_too = registry.make(opt.focus).label  # also timed on the plain traced path
    if opt.scaling:
        knob_values(opt)  # invalid knob values: StudyError now
    info = machine_info()
    info["tag"] = opt.tag or ("gpu" if "cuda" in names else "cpu")
    info["code"] = code_hash(run_bench, *{type(m) for m in methods})  # the code that makes these numbers
    o = np.asarray(scene.reference.point, float)
    V, F = room_triangles(scene)
    exact = Exact(V, F, opt.repeats, log)
    tex = distance_texels(exact.tracer, o, opt.cube_res)
    batches = [
        scene_rays(scene, opt.position, opt.scene_res),
        closeup_rays(scene, opt.position, opt.scene_res),
    ]
    batches.append(synthetic_rays(scene, opt.synthetic, camera=batches[0].camera))
    batches.append(direction_sorted(batches[-1]))  # ray reordering of the incoherent batch
    rows = []

    # ------------------------------------------------------------------ exact ray casting of each batch
    for b in batches:
        n = len(b.x)
        rows.append(
            rate_row(
                {
                    "batch": b.name,
                    "backend": f"cpu x{exact.tracer.threads}",
                    "path": "embree",
                    "label": "exact: Embree",
                    "triangles": len(F),
                    "cube_res": "",
                },
                exact.embree(b),
                n,
            )
        )
        for dev in sorted({"cuda" if nm == "cuda" else "llvm" for nm in names}):
            v = mitsuba_variant(dev)
            for q in QUERIES:  # full SurfaceInteraction, then the cheapest exact queries
                t = exact.mitsuba(b, v, q)
                if np.isfinite(t):
                    row = rate_row(
                        {
                            "batch": b.name,
                            "backend": dev,
                            "path": q,
                            "label": f"exact: Mitsuba {v}",
                            "triangles": len(F),
                            "cube_res": "",
                        },
                        t,
                        n,
                    )
                    row["kernel_ms_per_frame"] = ms_per_frame(exact.mitsuba_kernels(b, v, q), n)
                    rows.append(row)
        log(f"exact ray casting of {b.name} timed")

    # ------------------------------------------------------------------ measured floors (Dr.Jit backends)
    floors = {}
    for nm in names if opt.floors else []:
        if nm == "numpy":
            continue
        big = nm == "cuda"
        floors[nm] = floor_model.measure(
            backends.get(nm),
            opt.cube_res,
            n_lanes=1 << (22 if big else 16),
            fetches=64 if big else 16,
            copy_floats=1 << (28 if big else 24),
            repeats=opt.repeats,
        )
        log(f"floors on {nm}: " + ", ".join(f"{k} {v / 1e9:.3g} G/s" for k, v in floors[nm].items()))
    info["floors"] = [r for nm, f in floors.items() for r in floor_model.floor_rows(f, opt.cube_res, nm)]

    # ------------------------------------------------------------------ every method on every backend
    info_env = env_info(scene)
    want_screen = any(m.views_needed().screen for m in methods)
    specs = Views.merge(*(m.views_needed() for m in methods)).probes  # the probe methods' sets
    probe_sets = {nm: {sp: bench_probes(sp, exact.tracer, tex, o, info_env["room"], backends.get(nm)) for sp in specs}
                  for nm in names}  # fmt: skip
    deferred: list = []  # (row index, method, batch, backend) of the exact-query methods' rows
    for b in batches:
        depth = camera_depth(b.camera, exact.tracer) if want_screen and b.camera is not None else None
        for nm in names:
            B = backends.get(nm)
            scr = bench_screen(depth, b.camera, o, B) if depth is not None else None
            k = len(b.x) if nm != "numpy" else opt.numpy_max_rays
            x, R = b.x[:k] - o, b.R[:k]
            paths = ["frozen"] if nm != "numpy" else ["plain"]
            for m in methods:
                if getattr(m, "bench_query", None):  # the exact query as a method: its time is the query's,
                    deferred.append((len(rows), m, b, nm))  # priced after every method is timed (below)
                    rows.append({})
                    continue
                extra = ["plain"] if nm != "numpy" and m.label == plain_too else []
                for path in paths + extra:
                    spent: list = []
                    kernel: list = []
                    kw = dict(repeats=opt.repeats, info=info_env, spent=spent, kernel=kernel, screen=scr,
                              probe_sets=probe_sets[nm])  # fmt: skip
                    try:
                        t = time_method(m, B, tex, x, R, frozen=path == "frozen", **kw)
                    except Exception as err:  # e.g. a method whose arrays a frozen function cannot see
                        log(f"{m.label} on {nm} ({path}) failed: {str(err).splitlines()[0][:160]}")
                        if path != "frozen":
                            raise
                        path = "plain"
                        t = time_method(m, B, tex, x, R, frozen=False, **kw)
                    row = rate_row(
                        {
                            "batch": b.name,
                            "backend": nm,
                            "path": path,
                            "label": m.label,
                            "triangles": len(F),
                            "cube_res": opt.cube_res,
                        },
                        t,
                        len(x),
                    )
                    # lookups_mean: the measured mean (Trace.lookups); bytes per ray from it
                    row.update(carry.cost_columns(spent[-1], m.lookup_bound(opt.cube_res)))
                    # the device's share alone (Dr.Jit's kernel history; none on numpy): a short kernel's wall
                    # time is the host's (tracing or replaying, launching) on a fast GPU
                    row["kernel_ms_per_frame"] = ms_per_frame(kernel[-1], len(x))
                    rows.append(with_floor(with_ratios(row, exact, b, nm), m, floors.get(nm), b))
            log(f"methods on {nm}, {b.name} timed")

    # ------------------------------------------------------------------ the exact query priced with its shading
    price_exact(rows, deferred, exact, batches, names, floors, scene, len(F))
    log("the exact query priced")

    if on_table:
        on_table(rows, info)
    scaling = scaling_rows(scene, opt, names, o, tex, exact, log) if opt.scaling else []
    return rows, scaling, info


def price_exact(rows, deferred, exact: Exact, batches, names, floors: dict, scene, triangles: int) -> None:
    """Fill the exact-query methods' rows (``deferred``: (row index, method, batch, backend)) and append the
    shading's own rows (:data:`~study.bench.timing.SHADING` per batch and Mitsuba device). Run after every method
    is timed: Mitsuba's material calls must not run between the frozen recordings on CUDA (Dr.Jit aborts). The
    shading's point light is the scene's."""
    light = (tuple(scene.light.position), tuple(scene.light.intensity))
    for i, m, b, nm in deferred:
        row = exact_query_row(m, exact, b, nm, triangles, floors.get(nm), light=light)
        rows[i] = with_ratios(row, exact, b, nm)
    for b in batches:  # what a renderer does at the hit besides finding it: traced's shading
        for dev in sorted({"cuda" if nm == "cuda" else "llvm" for nm in names}):
            v = mitsuba_variant(dev)
            t_sh, k_sh = exact.shading(b, v, light)
            for part in SHADING:
                if np.isfinite(t_sh[part]):
                    row = rate_row({"batch": b.name, "backend": dev, "path": part, "label": f"exact: Mitsuba {v}",
                                    "triangles": triangles, "cube_res": ""}, t_sh[part], len(b.x))  # fmt: skip
                    row["kernel_ms_per_frame"] = ms_per_frame(k_sh[part], len(b.x))
                    rows.append(row)


def exact_query_row(
    m: Method,
    exact: Exact,
    b: Batch,
    backend: str,
    triangles: int,
    floors: dict | None = None,
    *,
    light: tuple | None = None,
) -> dict:
    """The row of a method that is the exact query itself (``traced``: ``m.bench_query``), from the time the bench
    measured for that query on the same rays and device (Mitsuba's variant of the backend's device; Embree on
    every core for numpy, which is the case's tracer there) rather than timed twice. Its path names the query;
    lookups are its bound (the hit's radiance read, not in the time); no floor (a traversal, not fetches). A method
    of K queries a ray (``queries``: ``traced_glossy``) takes K times the query's time.

    A method that makes the query and reads something at the hit (``hit_cache``: its cache; it inherits
    ``bench_query``, declares none) is priced, not timed (its read runs on the host): the query's time plus its
    lookups as 4-channel fetches at the measured rate of the batch's pattern and the ray's bytes at the measured
    bandwidth (:func:`study.bench.floors.method_floor`'s terms), which is also its floor (``x_floor`` = 1: nothing
    above the hardware's rates is modelled); on numpy (no floors measured) the query's time alone.

    A method that shades its hits as a renderer would (``shades_hit``: ``traced``, ``traced_glossy``) is priced
    with that shading (path ``shaded``): the full ``ray_intersect`` (the SurfaceInteraction the material needs)
    plus :data:`~study.bench.timing.SHADING` (the material towards the scene's point light ``light`` and the shadow
    ray), measured on the same rays and device (on numpy: Embree's query plus the shading on LLVM, the same CPU);
    ``query_ms_per_frame`` states the bare query (``bench_query``) beside it."""
    n = len(b.x)
    v = mitsuba_variant(backend)
    if backend == "numpy":
        path, t, kern = "embree", exact.embree(b), math.nan
    else:
        path, t = m.bench_query, exact.mitsuba(b, v, m.bench_query)
        kern = exact.mitsuba_kernels(b, v, m.bench_query)
    bare = t
    if getattr(m, "shades_hit", False) and light is not None:
        t_sh, k_sh = exact.shading(b, v, light)
        if (
            backend != "numpy"
        ):  # the SurfaceInteraction the material needs: the full query, not the preliminary
            t, kern = exact.mitsuba(b, v, "ray_intersect"), exact.mitsuba_kernels(b, v, "ray_intersect")
        t, kern, path = t + sum(t_sh.values()), kern + sum(k_sh.values()), "shaded"
    k = getattr(m, "queries", 1)  # traced_glossy(samples=K): K queries a ray
    reads = floors and "bench_query" not in vars(type(m))
    p = batch_pattern(b)
    read = (
        n * (m.lookup_bound() / floors[f"fetch_4ch_{p}"] + floor_model.BYTES_PER_RAY / floors["bandwidth"])
        if reads
        else 0.0
    )
    t, kern = t * k + read, kern * k + read
    base = {"batch": b.name, "backend": backend, "path": path, "label": m.label, "triangles": triangles,
            "cube_res": ""}  # fmt: skip
    row = rate_row(base, t, n)
    row.update(carry.cost_columns(m.lookup_bound(), m.lookup_bound()))
    row["kernel_ms_per_frame"] = ms_per_frame(kern, n)
    row["query_ms_per_frame"] = ms_per_frame(
        bare * k, n
    )  # the bare exact query(ies), without shading or reads
    if not reads:
        return {**row, "floor_ms_per_frame": "", "x_floor": "", "kernel_x_floor": ""}
    fl = ms_per_frame(t, n)  # the query and the read, both at the measured rates: at its floor
    return {
        **row,
        "floor_ms_per_frame": fl,
        "x_floor": row["ms_per_frame"] / fl,
        "kernel_x_floor": row["kernel_ms_per_frame"] / fl,
    }


def with_ratios(row: dict, exact: Exact, b: Batch, backend: str) -> dict:
    """``row`` plus x_vs_embree, x_vs_mitsuba, x_vs_preliminary and x_vs_ray_test: the exact query's time per ray
    over the method's (wall times), and kernel_x_vs_preliminary: the same for the cheapest exact query on the
    kernels' device time alone (NaN where the method has none: numpy)."""
    per_ray = row["ms_per_call"] / row["rays"]
    n = len(b.x)
    row["x_vs_embree"] = exact.embree(b) * 1e3 / n / per_ray
    row["x_vs_mitsuba"] = exact.mitsuba(b, mitsuba_variant(backend)) * 1e3 / n / per_ray
    row["x_vs_preliminary"] = (
        exact.mitsuba(b, mitsuba_variant(backend), "ray_intersect_preliminary") * 1e3 / n / per_ray
    )
    row["x_vs_ray_test"] = exact.mitsuba(b, mitsuba_variant(backend), "ray_test") * 1e3 / n / per_ray
    # the same on the device's time alone: the kernels of the cheapest exact query over the method's kernels
    kern = ms_per_frame(exact.mitsuba_kernels(b, mitsuba_variant(backend), "ray_intersect_preliminary"), n)
    row["kernel_x_vs_preliminary"] = kern / row.get("kernel_ms_per_frame", math.nan)
    return row


def batch_pattern(b: Batch) -> str:
    """The fetch pattern of a batch's floor: random for the synthetic batch, coherent for the scene's rays and for
    rays sorted by direction."""
    return "random" if b.name.startswith("synthetic") and "sorted" not in b.name else "coherent"


def with_floor(row: dict, m: Method, floors: dict | None, b: Batch) -> dict:
    """``row`` plus floor_ms_per_frame (:func:`study.bench.floors.method_floor` of a 1024² frame, at the row's
    measured ``lookups_mean``), x_floor (the method's time over its floor; 1 = at the floor) and kernel_x_floor
    (the kernels' device time over it); empty where no floor was measured (numpy)."""
    if not floors:
        return {**row, "floor_ms_per_frame": "", "x_floor": "", "kernel_x_floor": ""}
    fl = floor_model.method_floor(
        m, floors, batch_pattern(b), FRAME, int(row["cube_res"]), row.get("lookups_mean")
    )
    fl *= 1e3
    kern = row.get("kernel_ms_per_frame", float("nan"))
    return {**row, "floor_ms_per_frame": fl, "x_floor": row["ms_per_frame"] / fl, "kernel_x_floor": kern / fl}
