"""One case end to end, as a pipeline of named stages: inputs → exact hits and references → traces → columns → rows.

A reader can follow one ray here: camera ray → object (``shading.object_rays``) → reflected ray (x, R) →
``method.trace`` on the chosen backend → shown point and radiance → Fresnel → composited image; the same ray →
Embree exact hit → outcome class and angular error; the images → image error against the oracle_map, the
truth_at_hit and Mitsuba (:mod:`study.measure.truth`), and the error split over every object pixel
(:mod:`study.measure.split`, which also defines the oracle).

The references are traces too (:class:`Traced`): ``oracle_map`` and ``truth_at_hit`` show the exact hit, with the
impostor's radiance and with the truth's; their rows come from the same producers as every method's
(:func:`study.measure.groups.row_of`: the built-in column groups, then the plug-ins' producers).
"""

from __future__ import annotations

import itertools
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from study import backend as backends
from study import columns, progress
from study.cache import Cache
from study.errors import StudyError
from study.impostor.envmap import EnvMap
from study.impostor.views import Lobe
from study.measure import (
    batched,
    bias,
    case_columns,
    lighting,
    metrics,
    outcomes,
    split,
    truth,
    workers,
    worth,
)
from study.measure.groups import row_of
from study.measure.inputs import camera_render, capture_views, finite, impostor, second_captures
from study.measure.producers import PRODUCERS, RayContext, producer  # noqa: F401 - plug-ins' road
from study.methods import Method
from study.optics import shading
from study.reference.tracer import make_tracer
from study.scene import Scene
from study.stats.spatial import ray_pixels


@dataclass
class CaseOutput:
    scene: Scene
    rows: list[dict]  # one per method (and one for the oracle)
    images: dict[str, np.ndarray] = field(default_factory=dict)  # label → (H, W, 3) linear RGB
    angle_maps: dict[str, np.ndarray] = field(default_factory=dict)  # label → (H, W) mean angular error, deg
    outcome_maps: dict[str, np.ndarray] = field(default_factory=dict)  # label → (H, W) majority outcome class
    #   (codes of study.measure.outcomes: 0 correct … 3 no hit; ties to the worse; NaN off the object)
    flip_maps: dict[str, np.ndarray] = field(
        default_factory=dict
    )  # label → (H, W) LDR-FLIP against truth_at_hit
    #   (metrics.flip_map over the whole frame; the flip_truth column is its mean over ``mask``)
    oracle: np.ndarray | None = None  # (H, W, 3) oracle_map (study.measure.split; unheld pixels marked)
    held: np.ndarray | None = None  # (H, W) pixels whose every hit o's views hold (the oracle's pixels)
    mitsuba: np.ndarray | None = None  # (H, W, 3) Mitsuba's render with the object (2 seeds)
    truth: np.ndarray | None = None  # (H, W, 3) truth_at_hit composited (study.measure.truth)
    occluded: np.ndarray | None = None  # (H, W) fraction of sub-pixel rays occluded from o
    mask: np.ndarray | None = None  # (H, W) pixels fully on the object
    times: dict[str, float] = field(default_factory=dict)  # wall time split (progress.Stages.split)

    def timed(self, mark: progress.Stages) -> CaseOutput:
        """This case with its stages' times (``mark`` ended: its last stage counted)."""
        mark.end()
        self.times = mark.split()
        return self


# ---------------------------------------------------------------------------------------------- cached inputs
def checked_lookups(m: Method, spent: np.ndarray, res: int) -> tuple[float, float]:
    """(mean, bound) of the lookups the rays of one trace spent; a ray over ``m.lookups_per_ray(res)`` is an
    error of the method (its bound is what budgets and floors count)."""
    bound = m.lookup_bound(res)
    spent = np.asarray(spent, np.float64)
    if spent.size and not spent.max() <= bound * (1 + 1e-6):
        raise StudyError(
            f"method {m.name!r} spent {spent.max():g} lookups on a ray, over its lookups_per_ray({res}) = "
            f"{bound:g}",
            key="method",
        )
    return (float(spent.mean()) if spent.size else 0.0), bound


def knob_columns(m: Method) -> dict:
    """The columns that place a method on its cost/accuracy curve: family (label without the knob), knob (the
    parameter's name, '' without one) and knob_value (NaN without one)."""
    return {
        "family": m.family(),
        "knob": m.knob.param if m.knob else "",
        "knob_value": float(m.knob_value) if m.knob else np.nan,
    }


# ---------------------------------------------------------------------------------------------- stage records
@dataclass
class ExactHits:
    """The exact answers for the object's rays: Embree's hits (escaping rays at ``FAR`` in their direction), which
    of them the reference point o cannot see, each ray's tolerance and which hits the camera's frame does not show."""

    point: np.ndarray  # (K, 3) exact hit
    escapes: np.ndarray  # (K,) the ray leaves the scene
    to_hit: np.ndarray  # (K, 3) exact hit − o
    occluded: np.ndarray  # (K,) the exact hit is hidden from o
    eps: np.ndarray  # (K,) outcome tolerance: max(1 cm, one texel at the hit)
    offscreen: np.ndarray  # (K,) the exact hit lies outside the camera's frame


@dataclass
class Traced:
    """One row's input: what a method (or a reference) shows for every ray, and its image."""

    method: str
    label: str
    knobs: dict  # family, knob, knob_value
    shown: np.ndarray  # (K, 3) the shown point
    image: np.ndarray  # (H, W, 3) the composited image
    ratio: np.ndarray  # (K,) the search's distance ratio at the end (1: converged)
    valid: np.ndarray  # (K,) rays the method answered
    lookups: float  # mean lookups per ray
    bound: float  # the method's lookups_per_ray bound
    seconds: float = 0.0
    reference: str = ""  # "oracle_map" / "truth_at_hit" for the references' rows
    over: np.ndarray | None = None  # pixels its image columns are taken over (None: every object pixel)
    flags: dict = field(default_factory=dict)  # the method's declared diagnostics: column → fraction of rays
    reads_views: bool = True  # False: it reads no cube map (Method.reads_views): no oracle/split columns


def _exact(scene: Scene, tracer, rays, o: np.ndarray) -> ExactHits:
    ex_o, ex_d = rays.exact_rays()  # dielectrics: the exactly traced rays
    point, escapes, hidden = split.exact_hits(tracer, ex_o, ex_d, o)  # escaping rays at FAR; hidden from o
    return ExactHits(
        point,
        escapes,
        point - o,
        occluded=hidden,
        eps=outcomes.tolerance(o, point, scene.render.cube_res),
        offscreen=outcomes.off_screen(scene.camera, point),
    )


def _trace(m: Method, B, env, x, R, rays, o: np.ndarray, F: np.ndarray, background, res: int) -> Traced:
    """``m`` on the case's rays (relative to o) on backend B: one kernel for all its outputs, then numpy; its image
    (a future until :func:`run_case` takes it) is composited on the columns' threads while the next method runs."""
    t0 = time.perf_counter()
    with np.errstate(divide="ignore", invalid="ignore"):  # numpy evaluates both sides of every select
        tr = m.trace(B, env, x, R)
    B.eval(*(getattr(tr.shown, c) for c in "xyz"), *(getattr(tr.radiance, c) for c in "xyz"), tr.ratio, tr.valid,
           tr.lookups)  # fmt: skip
    shown = B.to_numpy(tr.shown).astype(np.float64) + o
    rad = B.to_numpy(tr.radiance).astype(np.float64)
    ratio, valid = B.numpy(tr.ratio), B.numpy(tr.valid).astype(bool)
    seconds = time.perf_counter() - t0
    lookups, bound = checked_lookups(m, B.numpy(tr.lookups), res)
    if not np.isfinite(shown[valid]).all():
        raise StudyError(
            f"method {m.name!r} returned {int((~np.isfinite(shown[valid])).any(-1).sum())} non-finite "
            "point(s) on rays it marked valid (NaN or inf)",
            key="method",
        )
    image = workers.submit(
        shading.composite, rays, np.nan_to_num(rad) * F, background
    )  # beside the next trace
    flags = {
        k: float(np.mean(B.numpy(v).astype(bool))) if len(shown) else np.nan
        for k, v in (tr.flags or {}).items()
    }
    for k in flags:  # a method's diagnostics are declared columns, as a producer's
        if columns.declared(k) is None:
            raise StudyError(f"method {m.name!r} flags the column {k!r}, which is not declared", key="method")
    return Traced(m.name, m.label, knob_columns(m), shown, image, ratio, valid, lookups, bound, seconds,
                  flags=flags, reads_views=m.reads_views)  # fmt: skip


def _reference_trace(name: str, image: np.ndarray, exact: ExactHits, over: np.ndarray) -> Traced:
    """A reference as a trace: the exact hit shown on every ray, one lookup for the oracle (its impostor read)."""
    K = len(exact.point)
    knobs = {"family": name, "knob": "", "knob_value": np.nan}
    n = 1 if name == "oracle_map" else 0
    return Traced(name, name, knobs, exact.point, image, np.ones(K), np.ones(K, bool), n, n, reference=name,
                 over=over)  # fmt: skip


# ---------------------------------------------------------------------------------------------- the case
def run_case(scene: Scene, methods: list[Method], **options) -> CaseOutput:
    """Every method and both references on the same rays of one case: their rows (one per trace,
    :func:`study.measure.groups.row_of`) and, with ``keep_images``, their images and per-pixel maps
    (:func:`start_case`'s options, and the case it finishes)."""
    return start_case(scene, methods, **options)()


def start_case(
    scene: Scene,
    methods: list[Method],
    *,
    backend: str = "numpy",
    cache: Cache | None = None,
    case_id: str = "",
    keep_images: bool = True,
    intervals: bool | None = None,
) -> Callable[[], CaseOutput]:
    """:func:`run_case` up to its columns' threads: returns once its own thread's part is done (the Dr.Jit work of
    every stage), with a function that waits for the rest and gives the case, so that the next case can start
    meanwhile (a figure's cases: :mod:`study.outputs.figures`). ``intervals`` (default ``keep_images``): a figure's
    columns, the pixel intervals and the FLIP maps; False: a sweep's (its images, with ``keep_images``, leave its
    rows as they are)."""
    intervals = keep_images if intervals is None else intervals
    cache = cache or Cache(None)
    B = backends.get(backend)
    mark = progress.Stages()  # load, capture, probes, references, methods, metrics (study.progress)

    # ------------------------------------------------------------------ inputs: rays, impostor, renders, views
    mark("load")
    tracer = make_tracer(scene.mesh())
    rays = shading.object_rays(scene, occluder=tracer.distance)  # an empty case is refused before rendering
    if int(rays.full.sum()) < 4:  # too few object pixels: every image metric would be NaN
        raise StudyError(f"the camera sees {int(rays.full.sum())} pixel(s) fully on the object, at least 4 are "
                         "needed; move object.center into view, closer, or turn camera.target towards it (or raise "
                         "camera.width/height)", key="object.center")  # fmt: skip
    o = np.asarray(scene.reference.point, float)
    worth.refuse_void(scene, (exact := _exact(scene, tracer, rays, o)).escapes, case_id)  # all into a void
    mark("capture")
    imp = impostor(scene, cache, tracer)
    background = camera_render(scene, cache, with_object=False)
    finite(scene, "impostor radiance", imp.radiance)
    finite(scene, "camera render", background)
    mark("probes")
    lobe = Lobe(scene.object.alpha, B.vec(rays.N), scene.render.seed) if rays.src is None else None
    env = capture_views(scene, methods, imp, B, cache=cache, tracer=tracer, background=background, lobe=lobe,
                        truth_along=(pair := truth.TruthPair(scene, cache, rays)).along)  # fmt: skip

    # ------------------------------------------------------------------ exact hits and references
    mark("references")
    seeds = [camera_render(sc, cache, with_object=True)  # Mitsuba with the object, two seeds
             for sc in (scene, scene.with_updates({"render.seed": scene.render.seed + truth.SEED_OFFSET}))]  # fmt: skip
    finite(scene, "render", *seeds)
    mitsuba = (seeds[0] + seeds[1]) / 2
    F = shading.fresnel(scene, rays)
    mask = rays.full
    ref = truth.build(scene, cache, rays, F, background, seeds, pair())  # truth_at_hit (once), noise images
    held = split.held(exact.occluded, exact.escapes)  # hits o's views hold: seen from o, or escaping
    held_px = split.held_pixels(rays, held)
    nb = backends.get("numpy")
    oracle_of = lambda e: _oracle(e, nb, exact, ref, held, rays, F, background)  # noqa: E731
    oracle_img = split.mark(oracle_of(EnvMap(imp.texels(), nb)), held_px | ~mask)  # unheld pixels: MARK
    oracle_seed, oracle_coarse = (oracle_of(EnvMap(t, nb)) for t in second_captures(scene, cache, imp))
    on_held = mask & held_px  # the pixels whose every hit the views hold: where the oracle has a value

    # ------------------------------------------------------------------ traces: the references, every method
    mark("methods")
    traces = [_reference_trace("oracle_map", oracle_img, exact, on_held),  # the oracle over the pixels it holds
              _reference_trace("truth_at_hit", ref.image, exact, mask)]  # fmt: skip
    x, R = B.vec(rays.x - o), B.vec(rays.R)
    traces += [_trace(m, B, env, x, R, rays, o, F, background, scene.render.cube_res) for m in methods]
    for t in traces[2:]:
        t.image = t.image.result()  # each composited on the columns' threads while the next method ran

    # ------------------------------------------------------------------ columns and rows
    mark("metrics")
    refs = _Refs(ref, mitsuba, oracle_img, oracle_seed, oracle_coarse, held_px, on_held, mask,
                 sigma=truth.noise_rms(ref.noise, mask), against=scene.render.flip_against)  # fmt: skip
    base = _base_columns(scene, case_id, backend, rays, exact, o, mitsuba)
    out = CaseOutput(scene, [], oracle=oracle_img, mitsuba=mitsuba, truth=ref.image, mask=mask, held=held_px,
                     occluded=rays.per_pixel(exact.occluded.astype(float), fill=0.0))  # fmt: skip
    by_trace = _method_columns(traces, refs, backend, intervals)  # every method's, one pass per reference
    rows = _rows(traces, by_trace, refs, B, backend, rays, exact, held, base, keep_images, intervals)
    mark.end()  # the rest on the columns' threads: the case is done when its rows are
    return lambda: _finished(out, rows, mark)


def one_behind(started):
    """(key, case, seconds waited) for each (key, finish) of ``started`` (:func:`start_case`'s), finished one case
    behind: a case's columns' threads run on while the next case starts (its Dr.Jit work on this thread)."""
    pending = None
    for item in itertools.chain(started, [None]):  # lazily: a case starts once the one before it is started
        if pending is not None:
            t0 = time.perf_counter()
            case = pending[1]()
            yield pending[0], case, time.perf_counter() - t0
        pending = item


def _finished(out: CaseOutput, rows: list, mark: progress.Stages) -> CaseOutput:
    """``out`` with its rows and maps, once the columns' threads made them (the wait counted in its columns)."""
    t0 = time.perf_counter()
    for t, r, maps, fmap in (f.result() for f in rows):
        out.rows.append(r)
        if maps is not None:
            out.images[t.label], out.flip_maps[t.label] = t.image, fmap
            out.angle_maps[t.label], out.outcome_maps[t.label] = maps
    mark.seconds["metrics"] = mark.seconds.get("metrics", 0.0) + time.perf_counter() - t0
    return out.timed(mark)


def _rows(traces, by_trace, refs, B, backend, rays, exact, held, base, keep_images, intervals):
    """Futures of (trace, row, (angle map, outcome map) or None, FLIP map), per trace in order. Dr.Jit's part (the
    outcome classes, the references' FLIP and image means) runs on this thread, each row (study.measure.groups),
    its maps and the references' numpy columns on the columns' threads (study.measure.workers); with a plug-in
    producer every row is made on this thread (it may use Dr.Jit)."""
    pixels = ray_pixels(rays.hit, rays.src)  # each ray's pixel (the ray intervals' clusters), once per case
    classes = {id(t): _classify(B, backend, rays, t.shown, exact) for t in traces}

    def row(t, cols, fmap):
        cols = cols() if callable(cols) else cols  # a method's: its share of the stack's columns
        oc, ang = classes[id(t)], metrics.angular_error(rays.x, t.shown, exact.point)
        r = row_of(RayContext(rays.x, rays.R, t.shown, exact.point, exact.occluded, oc, ang, t.image,
                              refs.truth.image, refs.mask, t.label, trace=t, rays=rays, hits=exact, pixels=pixels,
                              held=held, image_columns=cols, case_columns=base))  # fmt: skip
        if not keep_images or t.reference:
            return t, r, None, fmap
        return t, r, (rays.per_pixel(ang, fill=np.nan),
                      outcomes.majority(rays.per_pixel(outcomes.class_fractions(oc), fill=np.nan))), fmap  # fmt: skip

    go = workers.submit if not PRODUCERS else workers.here
    made = {id(t): go(row, t, *by_trace[id(t)]) for t in traces if id(t) in by_trace}  # the methods'
    for t in traces:
        if id(t) not in made:  # a reference's: its columns here, beside the methods' rows
            made[id(t)] = go(row, t, _image_columns(t, refs, None, backend, intervals), None)
    return [made[id(t)] for t in traces]


# ---------------------------------------------------------------------------------------------- producers
@dataclass
class _Refs:
    """What every image is measured against."""

    truth: truth.Truth
    mitsuba: np.ndarray
    oracle: np.ndarray
    oracle_seed: np.ndarray
    oracle_coarse: np.ndarray
    held_px: np.ndarray
    on_held: np.ndarray
    mask: np.ndarray
    sigma: float
    against: tuple


def _oracle(env, nb, exact: ExactHits, ref, held, rays, F, background) -> np.ndarray:
    """oracle_map from one capture (:func:`study.measure.split.oracle_radiance`)."""
    looked = np.stack([np.asarray(c) for c in env.lookup(nb.vec(exact.to_hit))[:3]], -1)
    rad = split.oracle_radiance(looked, ref.along, held, exact.escapes)
    return shading.composite(rays, np.nan_to_num(rad) * F, background)


def _classify(B, backend: str, rays, shown: np.ndarray, exact: ExactHits) -> np.ndarray:
    """Outcome classes against the exact hits, on the methods' backend."""
    if backend == "numpy":
        return outcomes.classify(rays.x, rays.R, shown, exact.point, eps=exact.eps, exact_origin=rays.exact_x)
    return outcomes.classify_on(
        B, rays.x, rays.R, shown, exact.point, eps=exact.eps, exact_origin=rays.exact_x
    )


def _base_columns(
    scene: Scene, case_id: str, backend: str, rays, exact: ExactHits, o: np.ndarray, mitsuba
) -> dict:
    """The case's own columns, the same in each of its rows (whether it is worth looking at: study.measure.worth)."""
    return {
        "case": case_id,
        "cube_res": scene.render.cube_res,
        "object_x": scene.object.center[0],
        "object_y": scene.object.center[1],
        "object_z": scene.object.center[2],
        **({"object_alpha": scene.object.alpha} if scene.object.alpha > 0 else {}),  # rough objects only
        "backend": backend,
        "displacement": float(
            np.linalg.norm(np.subtract(scene.object.center, o)) / np.linalg.norm(np.subtract(*scene.bounds()))
        ),
        "rays": len(rays.x),
        "occluded_fraction": float(exact.occluded.mean()) if len(exact.occluded) else np.nan,
        **rays.stats,
        **lighting.light_columns(scene),  # the file's own lights against study's (study.scene.lights)
        **worth.worth_columns(scene, mitsuba, rays.full, exact.escapes, exact.point),
    }


def _method_columns(traces: list[Traced], r: _Refs, backend: str, intervals: bool) -> dict:
    """id(trace) → (a function giving its image columns, its FLIP map or None) of every method's trace, measured
    together, one pass per reference (:func:`study.measure.batched.method_columns_later`: FLIP here, the rest on
    the columns' threads, gathered there once); the references' rows take :func:`_image_columns`."""
    ran = [t for t in traces if not t.reference]
    if not ran:
        return {}
    cols, maps = batched.method_columns_later(
        np.stack([t.image for t in ran]), r, backend=backend, intervals=intervals
    )
    every = workers.submit(cols)  # after every part it waits on (submitted first: study.measure.workers)
    return {id(t): ((lambda i=i: every.result()[i]), f) for i, (t, f) in enumerate(zip(ran, maps))}


def _image_columns(t: Traced, r: _Refs, fmap, backend: str, intervals: bool):
    """One image against every reference: the oracle (on held pixels; unheld ones take the image's value, as FLIP
    and SSIM filter across pixels and a marked neighbour must not count), the truth, Mitsuba; the truth's own
    columns, pixel intervals and the error split. The per-trace path: the references' rows take it; the methods'
    are measured together by :func:`study.measure.batched.method_columns`, to the same values. Returns a function
    giving the columns: what runs on the backend's arrays (FLIP, and on Dr.Jit the means) is measured here, the
    numpy rest (intervals, the split) on the columns' threads (:mod:`study.measure.workers`)."""
    over = r.mask if t.over is None else t.over
    img = t.image
    here = {
        **metrics.image_errors(np.where((r.held_px | ~r.mask)[..., None], r.oracle, img), img, mask=r.on_held,
                               suffix="oracle", backend=backend, with_flip="oracle" in r.against),
        **metrics.image_errors(r.truth.image, img, mask=over, suffix="truth", flip_emap=fmap, backend=backend,
                               with_flip="truth" in r.against),
        **metrics.image_errors(r.mitsuba, img, mask=over, suffix="mitsuba", backend=backend,
                               with_flip="mitsuba" in r.against),
    }  # fmt: skip
    made = truth.means(img, r.truth, r.mitsuba, mask=over, backend=backend)

    def rest():
        return {
            **truth.columns(img, r.truth, r.mitsuba, mask=over, made=made),
            **case_columns.pixel_columns(img, r.truth.image, mask=over,  # σ over the pixels of truth.columns
                                         sigma=truth.noise_rms(r.truth.noise, over),
                                         rel_eps=truth.REL_EPS, emap=fmap),
            **split.split_columns(img, r.truth.image, r.truth.noise, r.oracle, r.oracle_seed, r.oracle_coarse,
                                  mask=over, held_px=r.held_px, intervals=intervals),  # sweeps: values only
            **bias.bias_columns(img, r.truth.image, mask=over & r.held_px),  # signed: a gain shows with its sign
        }  # fmt: skip

    later = workers.submit(rest)

    def cols():
        out = {**here, **later.result()}
        if t.reference == "truth_at_hit":  # the truth is not split against itself
            out.update({k: np.nan for k in out if k.startswith("dec_")})
        return out

    return cols
