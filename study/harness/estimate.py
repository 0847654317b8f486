"""How long a command will take, told before it starts: its cases × a cost model per stage, calibrated on the
machine that runs it.

A case's wall time splits into the stages of :data:`study.progress.CASE_PARTS` (inputs, renders, probes, exact,
traces, columns). Each stage's time is modelled as ``seconds per unit × units`` with units that scale as its work
(:func:`units`):

=========  ==========================================================================================
stage      unit
=========  ==========================================================================================
inputs     the camera's sub-pixel rays (W · H · supersample²)
renders    Mitsuba samples not in the cache: the impostor's faces and its second seed, the camera renders
           (background, two seeds with the object), the truth's two seeds along the object's rays; × max_depth / 4
probes     Mitsuba samples of the probes' cube maps not in the cache (``render.probe_spp``), × max_depth / 4
exact      the object's secondary rays (Embree's exact hits, outcome classes, the oracle)
traces     the object's rays × the methods' lookups per ray (their bounds, :meth:`Method.lookup_bound`)
columns    the object's pixels × the methods, and the methods (a fixed cost per method row: ``columns_method``);
           a sweep's (no pixel intervals) scaled by ``sweep_share``
=========  ==========================================================================================

The seconds per unit are a table in the repository (:data:`COSTS`, ``stage_costs.json`` beside this module) written
by ``PYTHONPATH=. .venv/bin/python scripts/calibrate_estimate.py``, which runs one small case cold and one warm on this
machine and divides each stage's measured time by its units. The object's rays and pixels are those of its bounding
sphere (:func:`study.harness.budget.object_pixels`: an upper bound). Renders and probes are counted only where the
cache does not hold the case's impostor (its radiance is what is checked; a cached impostor is taken to come with
its probes and camera renders, which the same command cached beside it), and an impostor shared by several cases
of one command only once.

This is a forecast, not a guard: :mod:`study.harness.budget` refuses what cannot finish; here the command says what
it expects before it starts (:func:`told`, shown by :func:`study.progress.expect`), and its ETA starts from it
until the first case has finished.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path

from study.cache import Cache
from study.progress import CASE_PARTS

#: The calibrated seconds per unit of every stage (:func:`units`), written by ``scripts/calibrate_estimate.py``.
COSTS = Path(__file__).with_name("stage_costs.json")
#: Seconds per unit before any calibration (a 2-core machine, numpy backend; order of magnitude only).
DEFAULT_RATES = {
    "inputs": 2e-6,
    "renders": 1 / 1.3e6,
    "probes": 1 / 1.3e6,
    "exact": 5e-6,
    "traces": 0.06e-6,
    "columns": 10e-6,
    "columns_method": 0.2,
    "sweep_share": 0.5,
    "case": 1.0,
}


@dataclass
class Forecast:
    """Seconds of a command's cases: ``stages`` per stage of :data:`CASE_PARTS` summed over ``cases``."""

    cases: int
    stages: dict[str, float] = field(default_factory=dict)
    fixed: float = 0.0  # per case: Python, kernels, tables
    jobs: int = 1

    @property
    def seconds(self) -> float:
        return (sum(self.stages.values()) + self.fixed) / max(self.jobs, 1)

    def __add__(self, other: Forecast) -> Forecast:
        keys = dict.fromkeys([*self.stages, *other.stages])
        return Forecast(self.cases + other.cases,
                        {k: self.stages.get(k, 0.0) + other.stages.get(k, 0.0) for k in keys},
                        self.fixed + other.fixed, max(self.jobs, other.jobs))  # fmt: skip


def rates(path: Path | None = None) -> dict[str, float]:
    """Seconds per unit of each stage: the calibrated table (:data:`COSTS`) over :data:`DEFAULT_RATES`."""
    path = COSTS if path is None else path
    try:
        table = json.loads(Path(path).read_text())["seconds_per_unit"]
    except (OSError, ValueError, KeyError, TypeError):
        table = {}
    return {**DEFAULT_RATES, **{k: float(v) for k, v in table.items() if k in DEFAULT_RATES}}


def cached_impostor(scene, cache: Cache | None) -> bool:
    """Whether ``cache`` holds the radiance of ``scene``'s impostor (the key :func:`study.measure.inputs.impostor`
    reads it under)."""
    if cache is None or cache.root is None:
        return False
    from study.cache import _variant_part, content_key
    from study.codehash import code_hash
    from study.impostor.capture import impostor_key, render_cube

    key = content_key(impostor_key(scene), code_hash(render_cube), *_variant_part())
    return (Path(cache.root) / "radiance" / f"{key}.json").is_file()


def _probes(methods) -> int:
    from study.impostor.views import Views

    specs = Views.merge(*(m.views_needed() for m in methods)).probes
    return sum(len(p.points) if p.points is not None else math.prod(p.grid) for p in specs)


def units(scene, methods, *, rendered: bool = True, intervals: bool = True) -> dict[str, float]:
    """The units of each stage of one case (module docstring); ``rendered`` False: its renders and probes are
    cached (0 samples); ``intervals``: a figure's columns or a sweep's (``sweep_share`` of them, where a unit
    counts)."""
    from study.harness.budget import object_pixels

    c, r = scene.camera, scene.render
    sub = c.width * c.height * r.supersample**2
    glass = 2 if scene.object.material.type == "dielectric" else 1
    pixels = min(float(c.width * c.height), object_pixels(scene))
    rays = min(float(sub), pixels * r.supersample**2) * glass
    depth = max(r.max_depth, 1) / 4
    texels = 6 * r.cube_res**2
    samples = texels * r.cube_spp * (1 + 1 / 8) + 3 * c.width * c.height * r.spp + 2 * rays * r.spp
    probe_samples = _probes(methods) * texels * (r.probe_spp or r.cube_spp)
    lookups = sum(m.lookup_bound(r.cube_res) for m in methods)
    return {
        "inputs": float(sub),
        "renders": samples * depth if rendered else 0.0,
        "probes": probe_samples * depth if rendered else 0.0,
        "exact": rays,
        "traces": rays * lookups,
        "columns": pixels * len(methods),
        "columns_method": float(len(methods)),
        "sweep_share": 0.0 if intervals else 1.0,
    }


def forecast(scenes, methods, *, cache: Cache | None = None, intervals: bool = True, jobs: int = 1,
             table: dict[str, float] | None = None) -> Forecast:  # fmt: skip
    """The :class:`Forecast` of running ``methods`` on each of ``scenes`` (a command's cases, in order): an
    impostor already cached or captured by an earlier case of the list costs no renders (module docstring);
    ``jobs`` cases at a time."""
    from study.impostor.capture import impostor_key

    rate = table or rates()
    seen: set[str] = set()
    est = Forecast(0, dict.fromkeys(CASE_PARTS, 0.0), jobs=jobs)
    for sc in scenes:
        k = impostor_key(sc)
        rendered = k not in seen and not cached_impostor(sc, cache)
        seen.add(k)
        n = units(sc, methods, rendered=rendered, intervals=intervals)
        share = rate["sweep_share"] if n.pop("sweep_share") else 1.0
        for stage, v in n.items():
            cost = v * rate[stage] * (share if stage.startswith("columns") else 1.0)
            est.stages["columns" if stage.startswith("columns") else stage] += cost
        est.fixed += rate["case"]
        est.cases += 1
    return est


def span(seconds: float) -> str:
    """``42 s``, ``3 min 12 s``, ``1 h 02 min``."""
    if seconds < 60:
        return f"{seconds:.0f} s"
    m, s = divmod(round(seconds), 60)
    return f"{m} min {s} s" if m < 60 else f"{m // 60} h {m % 60:02d} min"


def told(est: Forecast, what: str = "") -> str:
    """One line for the start of a command: the total and its largest stages."""
    parts = sorted(((v, k) for k, v in est.stages.items() if v >= 0.5), reverse=True)
    split = ", ".join(f"{k} {span(v)}" for v, k in parts[:4])
    per = f", {est.jobs} at a time" if est.jobs > 1 else ""
    n = f"{est.cases} case{'s' if est.cases != 1 else ''}"
    return (f"estimate{' ' + what if what else ''}: about {span(est.seconds)} for {n}{per}"
            + (f" ({split})" if split else "") + "; from study/harness/stage_costs.json")  # fmt: skip


def tell(
    scenes, methods, *, cache: Cache | None = None, intervals: bool = True, jobs: int = 1, what: str = ""
):
    """Say the :func:`forecast` of these cases before they start (:func:`study.progress.expect`: a line on stderr,
    and the ETA of the current task starts from it); a no-op without a progress reporter."""
    from study import progress

    if progress.current() is None:
        return
    est = forecast(scenes, methods, cache=cache, intervals=intervals, jobs=jobs)
    progress.expect(est.seconds, told(est, what))


def teller(methods, cache: Cache | None, *, jobs: int = 1, intervals: bool = True):
    """``cases → None``: :func:`tell` for a command's cases (scenes, or a sweep's
    :class:`~study.harness.sweep.Case` list) with ``methods``; what :func:`study.harness.budget.check_cases` calls
    (its ``tell``) once it accepted them, and a sweep's runner with the cases left."""
    return lambda cases: tell([getattr(c, "scene", c) for c in cases], methods, cache=cache, intervals=intervals,
                              jobs=jobs)  # fmt: skip


def config_estimate(path, *, backend: str = "numpy", cache: Cache | None = None) -> Forecast:
    """The :class:`Forecast` of a figure config (``study figure``): its cases (positions or cases × seeds) with its
    methods, as :func:`study.outputs.figures.figure_positions` expands them."""
    from study.harness.config import load_figure_config

    cfg, scene, methods = load_figure_config(path)
    preset = {}
    scenes = [scene.with_updates({**over, **preset}) for _, _, over in cfg.case_list()]
    return forecast(scenes, methods, cache=cache, intervals=True)


#: The commands the stage model does not count (their cases are neither a figure's nor a sweep's) → the folder under
#: reports/ whose metadata.json holds the ``seconds`` their last run took (with its ``backend`` and ``cpus``).
MEASURED = {"caustics-sweep": "fig8/sweep", "animate": "animation", "convergence": "convergence"}


def measured(command: str, reports: Path | None = None) -> tuple[float, str] | None:
    """(seconds, where they come from) of ``command``'s last run (:data:`MEASURED`), or None where it wrote none."""
    root = Path(__file__).resolve().parents[2] / "reports" if reports is None else Path(reports)
    name = MEASURED.get(command.split()[0] if command.split() else "")
    try:
        meta = json.loads((root / str(name) / "metadata.json").read_text())
        seconds = float(meta["seconds"])
    except (OSError, ValueError, KeyError, TypeError):
        return None
    return seconds, f"its last run, {meta.get('backend', '?')} on {meta.get('cpus', '?')} cores"


def step_estimates(commands, *, cache: Cache | None = None, reports: Path | None = None):
    """One (command, seconds or None, how it was found) per command: ``figure NAME`` (its config,
    ``configs/NAME.toml``) and ``sweep PATH`` (its cases, a sweep's columns) from the stage model, the commands of
    :data:`MEASURED` from their last run's seconds, None for anything else. An impostor cached by an earlier
    command is not counted again only where the cache holds it (each command is modelled on its own)."""
    from study.harness.sweep import load_sweep

    root = Path(__file__).resolve().parents[2]
    out = []
    for cmd in commands:
        words = cmd.split()
        if len(words) >= 2 and words[0] == "figure":
            est = config_estimate(root / "configs" / f"{words[1]}.toml", cache=cache)
            out.append((cmd, est.seconds, f"{est.cases} cases, stage model"))
        elif len(words) >= 2 and words[0] == "sweep":
            sw = load_sweep(root / words[1])
            est = forecast([c.scene for c in sw.cases], sw.methods, cache=cache, intervals=False)
            out.append((cmd, est.seconds, f"{est.cases} cases, stage model"))
        elif words:
            m = measured(cmd, reports)
            out.append((cmd, *(m or (None, "not modelled, no measured run"))))
    return out


def wall(steps, cores: int) -> float:
    """Wall seconds of ``steps`` ((command, core seconds or None, …), each command's single-core seconds) on
    ``cores`` cores kept busy: their sum over the cores, never less than the longest command."""
    known = [s for _, s, _ in steps if s is not None]
    return max(sum(known) / max(cores, 1), max(known, default=0.0))


def main(argv=None) -> None:
    """``python -m study.harness.estimate [--jobs J] [--cache DIR] COMMAND...``: the estimate of ``study``
    commands, one line per command (:func:`step_estimates`: seconds on one core) and the total on ``jobs`` cores
    (:func:`wall`)."""
    import argparse

    ap = argparse.ArgumentParser(description=main.__doc__.splitlines()[0])
    ap.add_argument("--jobs", type=int, default=1)
    ap.add_argument("--cache", default=".cache")
    ap.add_argument("commands", nargs="*")
    args = ap.parse_args(argv)
    steps = step_estimates(args.commands, cache=Cache(args.cache))
    for cmd, sec, how in sorted(steps, key=lambda x: -(x[1] or 0)):
        print(f"  {cmd}: {'unknown' if sec is None else 'about ' + span(sec)} ({how})")
    known = [s for _, s, _ in steps if s is not None]
    left = [c for c, s, _ in steps if s is None]
    print(
        f"estimate: about {span(wall(steps, args.jobs))} wall for {len(steps)} commands on {args.jobs} cores "
        f"({span(sum(known))} of commands on one); from study/harness/stage_costs.json and the measured runs above"
        + (f"; not counted: {', '.join(left)}" if left else "")
    )


if __name__ == "__main__":
    main()
