"""``study bench``: every method timed side by side with exact ray casting of the same rays.

Inputs
    batches : the secondary rays of the fig4 scene with the object at one position (``shading.object_rays``,
              camera resolution chosen by ``scene_res``), the same with the camera zoomed onto the object (every
              pixel sees it: a full frame of coherent secondary rays) and a synthetic batch (origins uniform in a cube of
              ±``extent`` m around the reference point, uniform unit directions, fixed seed).
    impostor: exact distances from the reference point through every texel centre (Embree on the same triangles);
              the RGB channels are a stand-in (|direction|): what a lookup costs does not depend on texel values.
Timed per batch
    method rows : each registered method (methods with ``iterations`` at each requested count) on each backend;
                  on Dr.Jit through the frozen path (``Backend.freeze``: recorded kernels replayed, no Python
                  tracing per call) and, for ``localized(iterations=10)``, also the plain traced path.
    exact rows  : Embree (embreex, ``threads`` chunks in parallel, it releases the GIL) and Mitsuba
                  ``scene.ray_intersect`` (``llvm_ad_rgb`` on the CPU, ``cuda_ad_rgb``/OptiX on the GPU).
Timing
    warm-up calls first (compilation, recording); then ``repeats`` repeats of ``inner`` back-to-back calls
    (``inner`` chosen so one repeat lasts ≥ 20 ms), each call's outputs evaluated, the device synchronised
    (``dr.sync_thread()``) before the clock is read; the median per call is reported.
Outputs (columns of ``bench.csv`` / ``bench.md``)
    ms_per_call, mrays_per_s, ms_per_frame (a 1024² frame = 1 048 576 rays at the measured rate),
    x_vs_embree / x_vs_mitsuba: the exact tracer's time for the same rays over the method's (> 1: the method
    is faster); Mitsuba is taken on the same device as the backend (LLVM for numpy and llvm, CUDA for cuda).
Scaling (``scaling.csv``, ``scaling.png``): cost vs ray count, iterations, cube resolution and scene complexity
    (an extra displaced heightfield of 10 … 10⁶ triangles over the floor, built here only, not a scene key).
"""
from __future__ import annotations

import gc
import importlib.metadata
import math
import os
import platform
import subprocess
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from study import analytic, cubemap
from study import backend as backends
from study import methods as registry
from study.case import env_info
from study.errors import StudyError
from study.scene import Scene

FRAME = 1024 * 1024          # rays of a 1024² frame


# ---------------------------------------------------------------------------------------------- inputs
@dataclass
class Batch:
    name: str
    x: np.ndarray             # (N, 3) world-space origins
    R: np.ndarray             # (N, 3) unit directions


def scene_rays(scene: Scene, position, res: int) -> Batch:
    """Secondary (reflected) rays of ``scene`` with the object at ``position``, camera res² and 1 sample/pixel."""
    from study.shading import object_rays
    sc = scene.with_updates({"object.center": list(position), "camera.width": res, "camera.height": res,
                             "render.supersample": 1})
    r = object_rays(sc)
    p = ", ".join(f"{c:g}" for c in position)
    return Batch(f"fig4 ({p}) {res}²", r.x, r.R)


def closeup_rays(scene: Scene, position, res: int) -> Batch:
    """As :func:`scene_rays`, with the camera aimed at the object and zoomed so that every pixel of the res²
    frame sees it: a full frame (res² rays) of coherent secondary rays, as when the mirror fills the screen."""
    from study.shading import object_rays
    c = np.asarray(position, float)
    eye = np.asarray(scene.camera.eye, float)
    a = math.asin(min(scene.object.radius / np.linalg.norm(c - eye), 1.0))       # angular radius of the sphere
    fov = math.degrees(2 * math.atan(math.tan(a) / math.sqrt(2))) * 0.98        # square frame inside the disc
    sc = scene.with_updates({"object.center": list(position), "camera.target": list(position),
                             "camera.fov": fov, "camera.width": res, "camera.height": res,
                             "render.supersample": 1})
    r = object_rays(sc)
    p = ", ".join(f"{v:g}" for v in position)
    return Batch(f"fig4 close-up ({p}) {res}²", r.x, r.R)


def synthetic_rays(scene: Scene, n: int, *, extent: float = 0.6, seed: int = 0) -> Batch:
    x, d = analytic.random_rays(n, extent=extent, seed=seed)
    return Batch(f"synthetic {n}", x + np.asarray(scene.reference.point), d)


def heightfield(scene: Scene, triangles: int) -> tuple[np.ndarray, np.ndarray]:
    """A displaced grid over the floor with about ``triangles`` triangles (≥ 2): (V, 3), (F, 3).

    Height 2…10 cm above the floor (bumps of a few cm), inset 5 cm from the walls; below every batch's origins."""
    k = max(1, int(round(math.sqrt(triangles / 2))))
    lo, hi = np.asarray(scene.room.min, float), np.asarray(scene.room.max, float)
    s = np.linspace(0, 1, k + 1)
    gx = lo[0] + 0.05 + s * (hi[0] - lo[0] - 0.1)
    gz = lo[2] + 0.05 + s * (hi[2] - lo[2] - 0.1)
    X, Z = np.meshgrid(gx, gz, indexing="ij")
    Y = lo[1] + 0.06 + 0.04 * np.sin(7.3 * X) * np.cos(5.1 * Z)
    V = np.stack([X, Y, Z], -1).reshape(-1, 3)
    i, j = np.meshgrid(np.arange(k), np.arange(k), indexing="ij")
    a = (i * (k + 1) + j).ravel()
    b, c, d = a + 1, a + k + 1, a + k + 2
    F = np.concatenate([np.stack([a, b, d], -1), np.stack([a, d, c], -1)])
    return V.astype(np.float32), F.astype(np.int32)


def room_triangles(scene: Scene, extra: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """The scene's triangles plus, if ``extra`` > 0, a heightfield of about that many triangles."""
    m = scene.mesh()
    V, F = m.vertices.astype(np.float32), m.faces.astype(np.int32)
    if extra > 0:
        hV, hF = heightfield(scene, extra)
        V, F = np.concatenate([V, hV]), np.concatenate([F, hF + len(V)])
    return V, F


def distance_texels(V: np.ndarray, F: np.ndarray, o, res: int) -> np.ndarray:
    """(6, R, R, 4) impostor texels: exact distance (Embree) from o through texel centres, RGB = |direction|."""
    emb = Embree(V, F)
    dirs = cubemap.texel_directions(res).reshape(-1, 3)
    t = emb.distance(np.broadcast_to(np.asarray(o, np.float32), dirs.shape), dirs)
    if not np.all(np.isfinite(t)):
        raise StudyError("some texel rays from the reference point escape the room", key="reference.point")
    return np.concatenate([np.abs(dirs), t[:, None]], -1).reshape(6, res, res, 4).astype(np.float32)


# ---------------------------------------------------------------------------------------------- exact tracers
class Embree:
    """embreex scene of (V, F); ``distance`` casts chunks on ``threads`` threads (embreex releases the GIL)."""

    def __init__(self, V, F, threads: int | None = None):
        from embreex import rtcore_scene as rtcs
        from embreex.mesh_construction import TriangleMesh
        self.scene = rtcs.EmbreeScene()
        TriangleMesh(self.scene, np.ascontiguousarray(V, np.float32), np.ascontiguousarray(F, np.int32))
        self.threads = threads or os.cpu_count() or 1
        self.pool = ThreadPoolExecutor(self.threads) if self.threads > 1 else None

    def _run(self, o, d):
        res = self.scene.run(o, d, output=1)
        return np.where(res["geomID"] != -1, res["tfar"], np.inf)

    def distance(self, o, d) -> np.ndarray:
        o = np.ascontiguousarray(o, np.float32)
        d = np.ascontiguousarray(d, np.float32)
        if self.pool is None or len(o) < 4096:
            return self._run(o, d)
        cuts = np.linspace(0, len(o), self.threads + 1).astype(int)
        parts = self.pool.map(lambda ab: self._run(o[ab[0]:ab[1]], d[ab[0]:ab[1]]), zip(cuts[:-1], cuts[1:]))
        return np.concatenate(list(parts))


def mitsuba_scene(V, F, variant: str):
    """A Mitsuba scene holding the triangles (V, F) as one mesh, in ``variant``."""
    from study.reference.mitsuba import _mesh, mi
    m = mi(variant)
    bsdf = m.load_dict({"type": "diffuse"})
    mesh = _mesh(m, "room", V, F, np.zeros((len(V), 2), np.float32), bsdf)
    return m, m.load_dict({"type": "scene", "room": mesh})


# ---------------------------------------------------------------------------------------------- timing
def median_time(call, finish, *, repeats: int, warmup: int = 2, min_repeat_s: float = 0.02) -> float:
    """Median seconds per ``call()``; ``finish(out)`` evaluates one call's outputs, ``finish(None)`` syncs.

    ``inner`` calls per repeat (each evaluated), one device sync before each clock read."""
    for _ in range(warmup):
        finish(call()); finish(None)
    t0 = time.perf_counter()
    finish(call()); finish(None)
    once = time.perf_counter() - t0
    inner = max(1, min(1000, int(min_repeat_s / max(once, 1e-7))))
    ts = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        for _ in range(inner):
            finish(call())
        finish(None)
        ts.append((time.perf_counter() - t0) / inner)
    return float(np.median(ts))


def _method_runner(m, B, tex_np, x, R, *, frozen: bool, info: dict | None = None):
    """(call, finish) for one method on one backend: call() traces (or replays) and returns the outputs.

    ``info`` is the scene knowledge methods may use (room, reference point). A method that searches several
    layers gets the impostor itself as each layer (the bench times lookups; texel values do not change their
    cost) and runs unfrozen: a frozen function cannot see textures kept inside ``env.info``."""
    env = backends.EnvMap(tex_np, B, info=info)
    if m.layers_needed() > 1:
        env.info["layers"] = [env] * m.layers_needed()
        frozen = False
    X, RR = B.vec(x), B.vec(R)
    B.eval(X.x, X.y, X.z, RR.x, RR.y, RR.z)

    def trace(tex, dist, X, RR):                 # textures as arguments: a frozen function sees only those
        env.tex, env.dist = tex, dist
        t = m.trace(B, env, X, RR)
        return t.shown, t.radiance, t.ratio, t.valid

    fn = B.freeze(trace) if frozen else trace
    tex, dist = env.tex, env.dist

    def finish(out):
        if out is None:
            B.sync()
        else:
            s, r, ratio, valid = out
            B.eval(s.x, s.y, s.z, r.x, r.y, r.z, ratio, valid)
    return (lambda: fn(tex, dist, X, RR)), finish


def time_method(m, B, tex_np, x, R, *, frozen: bool, repeats: int, info: dict | None = None) -> float:
    # Garbage left by earlier runs (reference cycles) must not be freed while a frozen function records:
    # freeing Dr.Jit memory then is an unrecordable host call that aborts the process.
    gc.collect()
    B.sync()
    gc.disable()
    try:
        call, finish = _method_runner(m, B, tex_np, x, R, frozen=frozen, info=info)
        return median_time(call, finish, repeats=repeats)
    finally:
        gc.enable()


def time_embree(emb: Embree, x, R, *, repeats: int) -> float:
    o, d = np.ascontiguousarray(x, np.float32), np.ascontiguousarray(R, np.float32)
    return median_time(lambda: emb.distance(o, d), lambda out: None, repeats=repeats)


def time_mitsuba(m, scene, x, R, *, repeats: int) -> float:
    import drjit as dr
    ray = m.Ray3f(m.Point3f(np.ascontiguousarray(x.T, np.float32)), m.Vector3f(np.ascontiguousarray(R.T, np.float32)))
    dr.eval(ray)

    def finish(si):
        if si is None:
            dr.sync_thread()
        else:
            dr.eval(si.t, si.p)
    return median_time(lambda: scene.ray_intersect(ray), finish, repeats=repeats)


# ---------------------------------------------------------------------------------------------- environment
def available_backends() -> list[str]:
    out = ["numpy"]
    for name in ("llvm", "cuda"):
        try:
            backends.get(name)
            out.append(name)
        except Exception:
            pass
    return out


def _mitsuba_variant(backend: str) -> str:
    return "cuda_ad_rgb" if backend == "cuda" else "llvm_ad_rgb"


def machine_info() -> dict:
    cpu = platform.processor() or "?"
    try:
        for line in open("/proc/cpuinfo"):
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    info = {"cpu": cpu, "cores": os.cpu_count(), "python": platform.python_version(), "gpu": ""}
    for pkg in ("numpy", "drjit", "mitsuba", "embreex"):
        try:
            info[pkg] = importlib.metadata.version(pkg)
        except importlib.metadata.PackageNotFoundError:
            info[pkg] = "-"
    try:
        q = subprocess.run(["nvidia-smi", "--query-gpu=name,driver_version,memory.total", "--format=csv,noheader"],
                           capture_output=True, text=True, timeout=20)
        info["gpu"] = q.stdout.strip().splitlines()[0] if q.returncode == 0 and q.stdout.strip() else ""
    except (OSError, subprocess.SubprocessError):
        pass
    info["libllvm"] = os.environ.get("DRJIT_LIBLLVM_PATH", "")
    return info


# ---------------------------------------------------------------------------------------------- the bench
@dataclass
class BenchOptions:
    position: tuple = (1.1, 0.9, 0.6)           # object centre for the fig4 batch
    scene_res: int = 1024                       # camera res² for the fig4 batch
    synthetic: int = FRAME                      # rays of the synthetic batch
    iterations: tuple = (0, 1, 3, 10, 20)
    cube_res: int = 256
    backends: tuple = ()                        # () = all available
    repeats: int = 5
    numpy_max_rays: int = 1 << 16               # numpy is timed on at most this many rays of a batch
    scaling: bool = True
    ray_counts: tuple = (256 ** 2, 512 ** 2, 1024 ** 2, 2048 ** 2)
    scaling_iterations: tuple = (0, 1, 2, 3, 5, 10, 15, 20)
    cube_resolutions: tuple = (64, 128, 256, 512, 1024)
    triangles: tuple = (0, 100, 1000, 10_000, 100_000, 1_000_000)
    tag: str = ""                               # device tag in file names and tables (default: cpu / gpu name)


def _method_list(iterations) -> list:
    out = []
    for name in registry.names():
        cls = registry.REGISTRY[name]
        if "iterations" in cls.Params.model_fields:
            out += [registry.make(name, iterations=n) for n in iterations]
        else:
            out.append(registry.make(name))
    return out


def _rate_row(base: dict, seconds: float, rays: int) -> dict:
    return {**base, "rays": rays, "ms_per_call": seconds * 1e3, "mrays_per_s": rays / seconds / 1e6,
            "ms_per_frame": seconds / rays * FRAME * 1e3}


class _Exact:
    """Embree and Mitsuba timings of one batch on one set of triangles, computed once and shared."""

    def __init__(self, V, F, repeats, log):
        self.V, self.F, self.repeats, self.log = V, F, repeats, log
        self.emb = Embree(V, F)
        self.mi: dict[str, tuple] = {}
        self.t: dict[tuple, float] = {}

    def embree(self, batch: Batch) -> float:
        key = ("embree", batch.name)
        if key not in self.t:
            self.t[key] = time_embree(self.emb, batch.x, batch.R, repeats=self.repeats)
        return self.t[key]

    def mitsuba(self, batch: Batch, variant: str) -> float:
        key = (variant, batch.name)
        if key not in self.t:
            try:
                if variant not in self.mi:
                    self.mi[variant] = mitsuba_scene(self.V, self.F, variant)
                m, sc = self.mi[variant]
                from study.reference.mitsuba import mi
                mi(variant)
                self.t[key] = time_mitsuba(m, sc, batch.x, batch.R, repeats=self.repeats)
            except Exception as err:        # a variant missing on this machine: no number, say why
                self.log(f"mitsuba {variant} unavailable: {str(err).splitlines()[0][:120]}")
                self.t[key] = math.nan
        return self.t[key]


def run_bench(scene: Scene, opt: BenchOptions, log=print, on_table=None) -> tuple[list[dict], list[dict], dict]:
    """Time everything; returns (bench rows, scaling rows, machine info). ``on_table(rows, info)`` is called
    with the main table before the scaling studies start (so it is kept if they fail)."""
    info = machine_info()
    names = list(opt.backends) or available_backends()
    for n in names:
        backends.get(n)                                        # unknown or unavailable: StudyError now
    tag = opt.tag or ("gpu" if "cuda" in names else "cpu")
    info["tag"] = tag
    o = np.asarray(scene.reference.point, float)
    V, F = room_triangles(scene)
    tex = distance_texels(V, F, o, opt.cube_res)
    exact = _Exact(V, F, opt.repeats, log)
    batches = [scene_rays(scene, opt.position, opt.scene_res), closeup_rays(scene, opt.position, opt.scene_res),
               synthetic_rays(scene, opt.synthetic)]
    rows = []

    # ------------------------------------------------------------------ exact ray casting of each batch
    for b in batches:
        n = len(b.x)
        rows.append(_rate_row({"batch": b.name, "backend": f"cpu x{exact.emb.threads}", "path": "embree",
                               "label": "exact: Embree", "triangles": len(F), "cube_res": ""},
                              exact.embree(b), n))
        for dev in sorted({"cuda" if nm == "cuda" else "llvm" for nm in names}):
            v = _mitsuba_variant(dev)
            t = exact.mitsuba(b, v)
            if np.isfinite(t):
                rows.append(_rate_row({"batch": b.name, "backend": dev, "path": "ray_intersect",
                                       "label": f"exact: Mitsuba {v}", "triangles": len(F), "cube_res": ""}, t, n))
        log(f"exact ray casting of {b.name} timed")

    # ------------------------------------------------------------------ every method on every backend
    for b in batches:
        for nm in names:
            B = backends.get(nm)
            x, R = (b.x - o, b.R) if nm != "numpy" else (b.x[:opt.numpy_max_rays] - o, b.R[:opt.numpy_max_rays])
            paths = ["frozen"] if nm != "numpy" else ["plain"]
            for m in _method_list(opt.iterations):
                extra = ["plain"] if nm != "numpy" and m.label == "localized(iterations=10)" else []
                for path in paths + extra:
                    try:
                        t = time_method(m, B, tex, x, R, frozen=path == "frozen", repeats=opt.repeats,
                                        info=env_info(scene))
                    except Exception as err:    # e.g. a method whose arrays a frozen function cannot see
                        log(f"{m.label} on {nm} ({path}) failed: {str(err).splitlines()[0][:160]}")
                        if path != "frozen":
                            raise
                        path = "plain"
                        t = time_method(m, B, tex, x, R, frozen=False, repeats=opt.repeats,
                                        info=env_info(scene))
                    row = _rate_row({"batch": b.name, "backend": nm, "path": path, "label": m.label,
                                     "triangles": len(F), "cube_res": opt.cube_res}, t, len(x))
                    rows.append(_with_ratios(row, exact, b, nm))
            log(f"methods on {nm}, {b.name} timed")

    if on_table:
        on_table(rows, info)
    scaling = _scaling(scene, opt, names, o, tex, exact, log) if opt.scaling else []
    return rows, scaling, info


def _with_ratios(row: dict, exact: _Exact, b: Batch, backend: str) -> dict:
    per_ray = row["ms_per_call"] / row["rays"]
    n = len(b.x)
    row["x_vs_embree"] = exact.embree(b) * 1e3 / n / per_ray
    row["x_vs_mitsuba"] = exact.mitsuba(b, _mitsuba_variant(backend)) * 1e3 / n / per_ray
    return row


def _scaling(scene, opt, names, o, tex, exact, log) -> list[dict]:
    """Cost (ms per call) vs rays, iterations, cube resolution, triangles; numpy only up to numpy_max_rays."""
    rows = []
    fast = [n for n in names if n != "numpy"]
    loc10 = registry.make("localized", iterations=10)

    def method_row(study, value, nm, m, t_tex, b, cube):
        B = backends.get(nm)
        x, R = b.x - o, b.R
        if nm == "numpy":
            x, R = x[:opt.numpy_max_rays], R[:opt.numpy_max_rays]
        t = time_method(m, B, t_tex, x, R, frozen=nm != "numpy", repeats=max(3, opt.repeats // 2),
                        info=env_info(scene))
        rows.append(_rate_row({"study": study, "value": value, "backend": nm, "label": m.label,
                               "cube_res": cube}, t, len(x)))

    def exact_rows(study, value, ex, b):
        rows.append(_rate_row({"study": study, "value": value, "backend": "embree", "label": "exact: Embree"},
                              ex.embree(b), len(b.x)))
        for dev in sorted({"cuda" if nm == "cuda" else "llvm" for nm in names}):
            t = ex.mitsuba(b, _mitsuba_variant(dev))
            if np.isfinite(t):
                rows.append(_rate_row({"study": study, "value": value, "backend": f"mitsuba-{dev}",
                                       "label": "exact: Mitsuba"}, t, len(b.x)))

    # ------------------------------------------------------------------ rays
    for n in opt.ray_counts:
        b = synthetic_rays(scene, n, seed=1)
        for nm in names:
            if nm == "numpy" and n > opt.numpy_max_rays * 4:
                continue
            method_row("rays", n, nm, loc10, tex, b, opt.cube_res)
        exact_rows("rays", n, exact, b)
        log(f"scaling: {n} rays")
    # ------------------------------------------------------------------ iterations
    b = synthetic_rays(scene, opt.synthetic, seed=2)
    for it in opt.scaling_iterations:
        for nm in names:
            method_row("iterations", it, nm, registry.make("localized", iterations=it), tex, b, opt.cube_res)
    log("scaling: iterations")
    # ------------------------------------------------------------------ cube resolution
    V, F = room_triangles(scene)
    for res in opt.cube_resolutions:
        t_tex = distance_texels(V, F, o, res)
        for nm in fast or names:
            method_row("cube_res", res, nm, loc10, t_tex, b, res)
    log("scaling: cube resolution")
    # ------------------------------------------------------------------ scene complexity (random and coherent rays)
    close = closeup_rays(scene, opt.position, opt.scene_res)
    for extra in opt.triangles:
        V, F = room_triangles(scene, extra)
        ex = _Exact(V, F, max(3, opt.repeats // 2), log)
        t_tex = distance_texels(V, F, o, opt.cube_res)
        for bb, kind in ((b, "synthetic"), (close, "close-up")):
            n0 = len(rows)
            exact_rows("triangles", len(F), ex, bb)
            for nm in fast or names:
                method_row("triangles", len(F), nm, loc10, t_tex, bb, opt.cube_res)
            for r in rows[n0:]:
                r["label"] += f" ({kind})"
        log(f"scaling: {len(F)} triangles")
    return rows


# ---------------------------------------------------------------------------------------------- outputs
def markdown_table(rows: list[dict], cols: list[str]) -> str:
    def fmt(v):
        if isinstance(v, float):
            return "" if math.isnan(v) else f"{v:.4g}"
        return str(v)
    lines = ["| " + " | ".join(cols) + " |", "|" + "---|" * len(cols)]
    lines += ["| " + " | ".join(fmt(r.get(c, "")) for c in cols) + " |" for r in rows]
    return "\n".join(lines)


BENCH_COLS = ["batch", "backend", "path", "label", "rays", "ms_per_call", "mrays_per_s", "ms_per_frame",
              "x_vs_embree", "x_vs_mitsuba"]


def header(info: dict) -> str:
    gpu = info.get("gpu") or "none"
    return (f"machine: {info['cpu']}, {info['cores']} cores; GPU: {gpu}\n\n"
            f"versions: Python {info['python']}, numpy {info['numpy']}, drjit {info['drjit']}, "
            f"mitsuba {info['mitsuba']}, embreex {info['embreex']}; libLLVM {info['libllvm'] or '-'}")


def write_outputs(rows, scaling, info, out: Path) -> list[Path]:
    from study.capture import _atomic_write
    from study.results import to_csv
    out.mkdir(parents=True, exist_ok=True)
    tag = info["tag"]
    files = [out / f"bench-{tag}.csv", out / f"bench-{tag}.md"]
    _atomic_write(files[0], to_csv(rows).encode())
    md = f"# study bench ({tag})\n\n{header(info)}\n\n{markdown_table(rows, BENCH_COLS)}\n"
    _atomic_write(files[1], md.encode())
    if scaling:
        files.append(out / f"scaling-{tag}.csv")
        _atomic_write(files[-1], to_csv(scaling).encode())
        files.append(out / f"scaling-{tag}.png")
        plot_scaling(scaling, files[-1], title=f"study bench scaling ({tag}: {info.get('gpu') or info['cpu']})")
    return files


def plot_scaling(rows: list[dict], path: Path, *, title: str) -> None:
    """Four log-scale panels (rays, iterations, cube resolution, triangles), one line per backend × method;
    exact tracers dashed."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    studies = [("rays", "rays per call", "ms per call", True),
               ("iterations", "iterations of localized", "ms per 1024² frame", False),
               ("cube_res", "cube resolution (localized, 10 iterations)", "ms per 1024² frame", True),
               ("triangles", "triangles in the room (+ displaced heightfield)", "ms per 1024² frame", True)]
    fig, axes = plt.subplots(2, 2, figsize=(13, 9))
    for ax, (study, xlabel, ylabel, logx) in zip(axes.ravel(), studies):
        sub = [r for r in rows if r["study"] == study]

        def key(r):
            lab = r["label"].split("(")[0] if study == "iterations" else r["label"]
            return f"{lab} [{r['backend']}]"
        for k in dict.fromkeys(key(r) for r in sub):
            pts = sorted((float(r["value"]), float(r["ms_per_call"] if study == "rays" else r["ms_per_frame"]))
                         for r in sub if key(r) == k)
            ax.plot(*zip(*pts), "--" if k.startswith("exact") else "-", marker="o", ms=3, label=k)
        ax.set_xscale("log" if logx else "linear")
        ax.set_yscale("log")
        ax.set_xlabel(xlabel); ax.set_ylabel(ylabel); ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".tmp.png")
    fig.savefig(tmp, dpi=100)
    plt.close(fig)
    tmp.replace(path)
