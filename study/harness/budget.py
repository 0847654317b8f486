"""The resource guard: memory and time of every case estimated before anything runs, refused beyond a limit.

An estimate is meant to catch settings off by orders of magnitude (a 4096² image × supersample 8 asks for
hundreds of GiB, ``render.spp`` = 4·10⁶ for days), not to predict a run to the second: it is an upper bound of a
cold run (nothing cached) from the rough rates below, measured on the development machine (2 cores, numpy
backend, ``configs/sweep.toml``-like cases). The limits are the global options ``study --max-memory GIB`` (per
case, times ``--jobs``) and ``study --max-minutes MIN`` (for the whole command); the refusal names the scene key
whose value drives the estimate. :func:`preflight` also refuses a case whose camera cannot see the object at all
(its bounding sphere outside the view); :func:`study.measure.case.run_case` counts the object's pixels exactly.

An estimate can still be wrong, so ``--max-minutes`` also holds while the command runs (:func:`time_limit`, armed by
the command line): past it, the run stops at the next stage boundary (or inside a long stage, at a
:func:`study.progress.checkpoint`) with exit 3, and the outputs of earlier runs stay as they were (output sets are
written only at the end). Workers get the deadline with their work (:func:`study.harness.runner.run_cases`).
"""

from __future__ import annotations

import contextlib
import math
import os
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from study import backend as backends
from study import progress as pg
from study.errors import EnvironmentProblem, StudyError
from study.impostor.capture import impostor_key
from study.impostor.views import Views
from study.methods import Method
from study.scene import Scene

MITSUBA_SAMPLES_PER_S = 1.3e6  # path-traced samples per second (llvm_ad_rgb, max_depth 4, 2 cores); ∝ 4/depth
SECONDS_PER_SUBPIXEL = 12e-6  # per camera sub-pixel ray: rays, object hit, compositing, image metrics
SECONDS_PER_OBJECT_RAY = 1e-6  # per ray leaving the object, per method: exact hit, outcome classes, metrics
SECONDS_PER_LOOKUP = 0.06e-6  # one cube-map lookup of one ray by a method (numpy; Dr.Jit is faster)
SECONDS_PER_STEP = (
    0.5e-3  # one array step of a method over all rays (Method.host_steps; stochastic: 0.36–0.41 ms)
)
SECONDS_PER_CASE = 3.0  # fixed: Embree scene, Mitsuba's kernels compiled, tables
SECONDS_PER_IMPOSTOR = 2.0  # fixed per impostor captured (radiance cube + Embree distances)
BYTES_BASE = 512 << 20  # Python, Mitsuba, Dr.Jit and Embree loaded
BYTES_PER_SUBPIXEL = 256  # camera rays and per-pixel images
BYTES_PER_OBJECT_RAY = 1024  # every method's arrays for one ray leaving the object (measured: ~0.8 KiB)
BYTES_PER_TEXEL = 64  # one cube-map texel: radiance + distance, float32, in a few copies
BYTES_PER_LAYER_TEXEL = 80  # one texel of one depth layer (layered methods)
BYTES_PER_SDF_NODE = (
    80  # one node of a distance field while built (float64 distance, cosine, EDT and indices)
)
SECONDS_PER_SDF_NODE = 1.2e-6  # building a field, per node (2.5 s for 128³ on fig5's room, 2 shared cores)
BYTES_PER_TRIANGLE = 350  # one environment triangle: study's arrays, Embree's BVH, Mitsuba's mesh
SECONDS_PER_TRIANGLE = 30e-6  # per environment triangle and case: Embree and Mitsuba scenes, renders' set-up
DEFAULT_MAX_MEMORY_GIB = 16.0  # of a 24 GiB machine
DEFAULT_MAX_MINUTES = 120.0


@dataclass
class Limits:
    max_memory_gib: float = DEFAULT_MAX_MEMORY_GIB
    max_minutes: float = DEFAULT_MAX_MINUTES


#: The limits in force: set by the CLI's global options (:func:`set_limits`), defaults otherwise.
LIMITS = Limits()


def set_limits(
    max_memory_gib: float = DEFAULT_MAX_MEMORY_GIB, max_minutes: float = DEFAULT_MAX_MINUTES
) -> None:
    for key, v in (("--max-memory", max_memory_gib), ("--max-minutes", max_minutes)):
        if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
            raise StudyError(
                f"must be a positive number of {'GiB' if 'memory' in key else 'minutes'}, got {v}", key=key
            )
    LIMITS.max_memory_gib, LIMITS.max_minutes = float(max_memory_gib), float(max_minutes)


#: The command's deadline for worker processes: ``<time.time() at which it stops> <minutes>``.
DEADLINE_ENV = "STUDY_DEADLINE"


@contextlib.contextmanager
def time_limit(limits: Limits | None = None) -> Iterator[None]:
    """``--max-minutes`` held while the block runs (the command line's commands): from now, past the limit, the
    next :func:`study.progress.checkpoint` raises :func:`over_time` (exit 3); worker processes started meanwhile
    inherit the deadline (``$STUDY_DEADLINE``, :func:`inherited_time_limit`)."""
    minutes = (limits or LIMITS).max_minutes
    at = time.time() + minutes * 60
    before = os.environ.get(DEADLINE_ENV)
    os.environ[DEADLINE_ENV] = f"{at!r} {minutes!r}"
    try:
        with pg.deadline(at, lambda: over_time(minutes)):
            yield
    finally:
        if before is None:
            os.environ.pop(DEADLINE_ENV, None)
        else:
            os.environ[DEADLINE_ENV] = before


def deadline_spec() -> str | None:
    """The deadline in force (:func:`time_limit`) as text to hand to a worker (:func:`inherited_time_limit`)."""
    return os.environ.get(DEADLINE_ENV)


@contextlib.contextmanager
def inherited_time_limit(spec: str | None) -> Iterator[None]:
    """In a worker (a process, a Dask worker): the deadline of the command that gave it work (``spec``, from
    :func:`deadline_spec`); none without one."""
    try:
        at, minutes = (float(v) for v in (spec or "").split())
    except ValueError:
        yield
        return
    with pg.deadline(at, lambda: over_time(minutes)):
        yield


def bounded(task: Callable[[Any], tuple]) -> Callable[[Any], tuple]:
    """A runner's ``task`` (case → (function, args)) whose function runs under the deadline in force now
    (:func:`deadline_spec`) wherever it runs: in this process, a worker process or on a Dask worker."""
    spec = deadline_spec()
    if spec is None:
        return task

    def within_deadline(case) -> tuple:
        fn, args = task(case)
        return run_within, (spec, fn, *args)

    return within_deadline


def run_within(spec: str, fn: Callable[..., Any], *args) -> Any:
    """Worker: ``fn(*args)`` under the deadline ``spec`` (module-level, so worker processes can import it)."""
    with inherited_time_limit(spec):
        return fn(*args)


def over_time(minutes: float) -> EnvironmentProblem:
    """The error of a run stopped at its time limit: exit 3 (this machine is slower than estimated)."""
    return EnvironmentProblem(
        f"stopped: the command ran past its limit of {minutes:g} min, longer than estimated; the outputs of "
        "earlier runs are kept (finished cases of a sweep resume); raise --max-minutes",
        key="--max-minutes",
    )


@dataclass
class Estimate:
    bytes: float
    seconds: float
    memory: dict[str, float] = field(default_factory=dict)  # part (a scene key) → bytes
    time: dict[str, float] = field(default_factory=dict)  # part (a scene key) → seconds


def _camera_frame(scene: Scene) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    c = scene.camera
    f = np.subtract(c.target, c.eye)
    f = f / np.linalg.norm(f)
    right = np.cross(f, c.up)
    right /= np.linalg.norm(right)
    return f, right, np.cross(right, f)


def object_pixels(scene: Scene) -> float:
    """Pixels the object's bounding sphere covers (0 when it lies outside the view; an upper bound otherwise)."""
    c = scene.camera
    f, right, up = _camera_frame(scene)
    p = np.subtract(scene.object.center, c.eye)
    r = scene.object.radius
    tx = math.tan(math.radians(c.fov) / 2)
    ty = tx * c.height / c.width
    x, y, z = float(p @ right), float(p @ up), float(p @ f)
    for t, s in ((tx, x), (ty, y)):  # the four side planes of the view frustum, then the eye
        if (z * t - abs(s)) / math.hypot(1.0, t) < -r:
            return 0.0
    if z <= -r:
        return 0.0
    d2 = float(p @ p) - r * r
    if z <= 0 or d2 <= 0:
        return float(c.width * c.height)
    radius_px = r / math.sqrt(d2) / tx * c.width / 2
    return float(min(c.width * c.height, math.pi * radius_px**2))


def estimate(
    scene: Scene, methods: list[Method], *, impostor: bool = True, lookups: float | None = None
) -> Estimate:
    """Memory and time of one case (:func:`study.measure.case.run_case`) with ``methods``; ``impostor``: count
    capturing its impostor (False when another case of the same command captures the same one); ``lookups``:
    the methods' cube-map lookups per ray together, where known (measured: a results table's
    ``lookups_per_ray``), instead of their bound before any run (every step on every ray)."""
    c, r = scene.camera, scene.render
    sub = c.width * c.height * r.supersample**2
    glass = 2 if scene.object.material.type == "dielectric" else 1
    rays = min(float(sub), object_pixels(scene) * r.supersample**2) * glass
    rate = MITSUBA_SAMPLES_PER_S * 4 / max(r.max_depth + 2 * (glass - 1), 4)
    texels = 6 * r.cube_res**2
    layers = max((m.layers_needed() for m in methods), default=1)
    if lookups is None:
        lookups = sum(m.lookup_bound(r.cube_res) for m in methods)  # bounds: no method spends more
    steps = sum(_host_steps(m, r.cube_res) for m in methods)  # whatever the rays: a loop over samples, …
    # one more path-traced set of rays for exact shading (sdf(shading="exact"), hit_cache's escaping rays); the
    # exact query on a mirror object reads the truth's own values (study.measure.inputs.exact_shading): no more
    mirror = glass == 1 and scene.object.alpha == 0
    shade = int(any(m.views_needed().shade and (m.reads_views or not mirror) for m in methods))
    shade += sum(
        getattr(m, "queries", 0) for m in methods if m.glossy
    )  # traced_glossy: K lobe rays a ray, shaded
    sub_key = "render.supersample" if r.supersample > 1 else "camera.width"
    tris = _triangles(scene)
    mem = {
        "environment": tris * BYTES_PER_TRIANGLE,
        sub_key: sub * BYTES_PER_SUBPIXEL + rays * BYTES_PER_OBJECT_RAY,
        "render.cube_res": texels * (BYTES_PER_TEXEL + (BYTES_PER_LAYER_TEXEL * layers if layers > 1 else 0)),
    }
    time = {
        "environment": tris * SECONDS_PER_TRIANGLE,
        # camera renders, the truth's two seeds and exact shading's own seed (sdf(shading="exact"), glass, rough)
        "render.spp": (3 * c.width * c.height + (2 + shade) * rays) * r.spp / rate,
        sub_key: SECONDS_PER_CASE + sub * SECONDS_PER_SUBPIXEL + rays * len(methods) * SECONDS_PER_OBJECT_RAY,
        "methods": rays * lookups * SECONDS_PER_LOOKUP + steps * SECONDS_PER_STEP,
    }
    if impostor:
        time["render.cube_spp"] = SECONDS_PER_IMPOSTOR + texels * r.cube_spp / rate
    probes = sum(
        len(p.points) if p.points is not None else int(np.prod(p.grid))  # cube maps at more points
        for p in Views.merge(*(m.views_needed() for m in methods)).probes
    )  # (at most: grid cells)
    nodes = sum(f.res**3 for f in Views.merge(*(m.views_needed() for m in methods)).sdfs)
    if nodes:  # distance fields (built once per environment and cached; counted per case, the worst case)
        mem["method.res"] = nodes * BYTES_PER_SDF_NODE
        time["method.res"] = nodes * SECONDS_PER_SDF_NODE
    if probes:
        mem["render.cube_res"] += probes * texels * BYTES_PER_TEXEL
        if impostor:
            time["render.cube_spp"] += probes * (SECONDS_PER_IMPOSTOR + texels * r.cube_spp / rate)
    return Estimate(BYTES_BASE + sum(mem.values()), sum(time.values()), mem, time)


def _host_steps(m: Method, res: int) -> float:
    """:meth:`Method.host_steps` at ``res``, which must be a finite number ≥ 0 (as the lookup bound)."""
    v = m.host_steps(res)
    try:
        steps = float(v)
    except (TypeError, ValueError):
        steps = math.nan
    if not (math.isfinite(steps) and steps >= 0):
        raise StudyError(
            f"host_steps() of {m.name!r} gave {v!r}; it must be a finite number of steps ≥ 0 (the budget counts it)",
            key="method",
        )
    return steps


def _triangles(scene: Scene) -> float:
    """The environment's triangle count (its mesh is loaded with the scene: placement needed it)."""
    try:
        return float(len(scene.mesh().faces))
    except Exception:  # an environment that cannot be meshed fails later, with its own message
        return 0.0


def _hours(s: float) -> str:
    return f"{s / 3600:.1f} h" if s >= 3600 else f"{s / 60:.1f} min" if s >= 60 else f"{s:.0f} s"


def _gib(b: float) -> str:
    return f"{b / (1 << 30):.1f} GiB"


def _scene_key(key: str, scene: Scene, methods: list[Method] = ()) -> str:
    """``key = value`` for the message (``methods``: the costliest of them)."""
    if key == "methods":
        res = scene.render.cube_res
        worst = max(methods, key=lambda m: m.lookup_bound(res) + _host_steps(m, res), default=None)
        return "methods (their lookups per ray" + (f"; the costliest {worst.label})" if worst else ")")
    if key == "environment":
        return f"the environment's {int(_triangles(scene)):,} triangles (environment.file)"
    if key == "method.res":
        return "the distance fields' grid nodes (method.res of sdf)"
    if key == "camera.width":
        return f"camera.width × camera.height = {scene.camera.width} × {scene.camera.height}"
    part, name = key.split(".")
    return f"{key} = {getattr(getattr(scene, part), name)}"


def check_cases(
    cases: list[tuple[str, Scene]],
    methods: list[Method],
    *,
    source: str | None = None,
    jobs: int = 1,
    limits: Limits | None = None,
    tell: Callable[[list[Scene]], None] | None = None,
) -> list[Estimate]:
    """Refuse (StudyError naming ``source``, the case and the key to lower) when a case is out of view
    (:func:`preflight`), when one case needs more than ``--max-memory`` (× ``jobs`` running at once) or when all
    of them together need more than ``--max-minutes``. ``cases``: (id, scene) pairs. Returns the estimates. ``tell``
    (:func:`study.harness.estimate.teller`) is then given the scenes: it says how long they will take."""
    limits = limits or LIMITS
    seen, ests = set(), []
    for cid, sc in cases:
        preflight(sc, source=source, case=cid)
        k = impostor_key(sc)
        ests.append(estimate(sc, methods, impostor=k not in seen))
        seen.add(k)
        e = ests[-1]
        if e.bytes * max(jobs, 1) > limits.max_memory_gib * (1 << 30):
            key = max(e.memory, key=e.memory.get)
            per = f" per case × {jobs} jobs" if jobs > 1 else ""
            raise StudyError(
                f"case {cid} would need about {_gib(e.bytes)}{per}, over the limit of "
                f"{limits.max_memory_gib:g} GiB (--max-memory); most of it for {_scene_key(key, sc)}: "
                "lower it" + (" or --jobs" if jobs > 1 else ""),
                file=source,
                key=key,
            )
    total = sum(e.seconds for e in ests) / max(jobs, 1)
    if total > limits.max_minutes * 60:
        i = int(np.argmax([e.seconds for e in ests]))
        parts: dict[str, float] = {}
        for e in ests:
            for k, v in e.time.items():
                parts[k] = parts.get(k, 0.0) + v
        key = max(parts, key=parts.get)
        what = f"{len(ests)} cases" if len(ests) > 1 else f"case {cases[0][0]}"
        raise StudyError(
            f"{what} would take about {_hours(total)} here, over the limit of {limits.max_minutes:g} "
            f"min (--max-minutes); most of it for {_scene_key(key, cases[i][1], methods)}: lower it or raise "
            "--max-minutes",
            file=source,
            key=key,
        )
    if tell is not None:
        tell([sc for _, sc in cases])
    return ests


def preflight(scene: Scene, *, source: str | None = None, case: str = "") -> None:
    """Refuse a case whose camera cannot see any of the object (its bounding sphere lies outside the view)."""
    if object_pixels(scene) == 0:
        where = f" (case {case})" if case else ""
        raise StudyError(
            f"the camera does not see the object{where}: its bounding sphere lies outside the view; "
            "move object.center into view or turn camera.target towards it",
            file=source,
            key="object.center",
        )


def check_backend(name: str) -> None:
    """The backend can run here: an unknown name is bad input (exit 2), one this machine lacks (cuda without a
    GPU, Dr.Jit without a usable libLLVM) a problem of the environment (exit 3)."""
    if name not in backends.BACKENDS:
        backends.get(name)  # the StudyError listing what is allowed
    try:
        backends.get(name)
    except EnvironmentProblem:
        raise
    except StudyError as err:
        raise EnvironmentProblem(err.detail, key="backend") from None
