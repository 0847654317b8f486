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

The seconds per unit are tables in the repository (:data:`COSTS`, ``stage_costs.json`` beside this module), one per
backend (``"backends": {"numpy": {...}, "llvm": {...}}``: the methods' traces run 4-100x faster on Dr.Jit's LLVM
backend than on numpy, so one table cannot serve both); the estimate reads the table of the backend the command runs
with (:func:`table_for`), and a backend without one gets numpy's with its line saying so. They are written by
``PYTHONPATH=. .venv/bin/python scripts/calibrate_estimate.py``: either one small case run cold and warm here, or
(``--from-reports reports``, :mod:`study.harness.estimate_fit`) fitted to the time splits of the figures' and
sweeps' last runs. The object's rays and pixels are those of its bounding
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
from study.harness import provenance
from study.harness.provenance import REPO
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
    source: str = "study/harness/stage_costs.json"  # which table the rates came from (:func:`table_for`)

    @property
    def seconds(self) -> float:
        return (sum(self.stages.values()) + self.fixed) / max(self.jobs, 1)

    def __add__(self, other: Forecast) -> Forecast:
        keys = dict.fromkeys([*self.stages, *other.stages])
        return Forecast(self.cases + other.cases,
                        {k: self.stages.get(k, 0.0) + other.stages.get(k, 0.0) for k in keys},
                        self.fixed + other.fixed, max(self.jobs, other.jobs), self.source)  # fmt: skip


def tables_in(path: Path) -> dict[str, dict]:
    """backend → its table of ``path``: ``{"backends": {name: table}}``, or the older single table (its
    ``backend``, numpy where it names none); {} where the file is missing or unreadable."""
    try:
        data = json.loads(Path(path).read_text())
    except (OSError, ValueError):
        return {}
    if not isinstance(data, dict):
        return {}
    if isinstance(data.get("backends"), dict):
        return {k: v for k, v in data["backends"].items() if isinstance(v, dict)}
    return {str(data.get("backend", "numpy")): data} if "seconds_per_unit" in data else {}


def table_for(backend: str = "numpy", path: Path | None = None) -> tuple[dict[str, float], str]:
    """(seconds per unit, where they come from) for a command on ``backend``: that backend's table in
    :data:`COSTS` over :data:`DEFAULT_RATES`; numpy's where ``backend`` has none (the line says so), the defaults
    where neither is there."""
    path = COSTS if path is None else Path(path)
    tables = tables_in(path)
    name = backend if backend in tables else "numpy"
    try:
        table = tables[name]["seconds_per_unit"]
        got = {k: float(v) for k, v in table.items() if k in DEFAULT_RATES}
    except (KeyError, TypeError, ValueError, AttributeError):
        return dict(DEFAULT_RATES), f"uncalibrated defaults (no table in {path.name})"
    where = f"{path.name}'s {name} table"
    if name != backend:
        where = f"{path.name}'s numpy table: none for {backend}"
    return {**DEFAULT_RATES, **got}, where


#: The key of a sweep case's first row that carries its stage times from its worker to the runner
#: (:func:`study.harness.runner.run_cases`), which takes it off the row and sums them (:func:`run_record`).
TIMES = "_time_split"


def run_record(seconds: float, computed: list[str], times: list) -> dict:
    """What a sweep's metadata.json says of its run: its wall ``seconds``, the ids of the cases it ``computed``
    and, where every one of them brought its stage times (``times``: a dict per case, or None), their sum per
    stage of :data:`CASE_PARTS` (``time_split``, core seconds: jobs at a time), what
    :mod:`study.harness.estimate_fit` calibrates the estimate from."""
    out = {"seconds": round(seconds, 1), "computed": len(computed), "computed_cases": list(computed)}
    if computed and len(times) == len(computed) and all(isinstance(t, dict) for t in times):
        out["time_split"] = {k: round(sum(float(t.get(k, 0.0)) for t in times), 3) for k in CASE_PARTS}
    return out


def rates(path: Path | None = None, backend: str = "numpy") -> dict[str, float]:
    """Seconds per unit of each stage on ``backend``: :func:`table_for` without its source."""
    return table_for(backend, path)[0]


def cached_impostor(scene, cache: Cache | None) -> bool:
    """Whether ``cache`` holds the radiance of ``scene``'s impostor (the key :func:`study.measure.inputs.impostor`
    reads it under)."""
    if cache is None or cache.root is None:
        return False
    from study.cache import _variant_part, content_key
    from study.codehash import code_hash
    from study.impostor.capture import impostor_key, render_cube

    key = content_key(impostor_key(scene), code_hash(render_cube), *_variant_part())
    return cache.holds("radiance", key)


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
             table: dict[str, float] | None = None, backend: str = "numpy",
             seen: set[str] | None = None) -> Forecast:  # fmt: skip
    """The :class:`Forecast` of running ``methods`` on each of ``scenes`` (a command's cases, in order) on
    ``backend`` (its table, :func:`table_for`; ``table``: these rates instead): an impostor already cached or
    captured by an earlier case of the list (or of ``seen``, the impostor keys earlier commands capture; the
    keys of these cases are added to it) costs no renders (module docstring); ``jobs`` cases at a time."""
    from study.impostor.capture import impostor_key

    rate, source = (table, "the given rates") if table else table_for(backend)
    seen = set() if seen is None else seen
    est = Forecast(0, dict.fromkeys(CASE_PARTS, 0.0), jobs=jobs, source=source)
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
            + (f" ({split})" if split else "") + f"; from {est.source}")  # fmt: skip


def tell(
    scenes, methods, *, cache: Cache | None = None, intervals: bool = True, jobs: int = 1, what: str = "",
    backend: str = "numpy",
):  # fmt: skip
    """Say the :func:`forecast` of these cases on ``backend`` before they start (:func:`study.progress.expect`: a
    line on stderr, and the ETA of the current task starts from it); a no-op without a progress reporter."""
    from study import progress

    if progress.current() is None:
        return
    est = forecast(scenes, methods, cache=cache, intervals=intervals, jobs=jobs, backend=backend)
    progress.expect(est.seconds, told(est, what))


def teller(methods, cache: Cache | None, backend: str = "numpy", *, jobs: int = 1, intervals: bool = True):
    """``cases → None``: :func:`tell` for a command's cases (scenes, or a sweep's
    :class:`~study.harness.sweep.Case` list) with ``methods`` on ``backend``; what
    :func:`study.harness.budget.check_cases` calls (its ``tell``) once it accepted them, and a sweep's runner with
    the cases left."""
    return lambda cases: tell([getattr(c, "scene", c) for c in cases], methods, cache=cache, intervals=intervals,
                              jobs=jobs, backend=backend)  # fmt: skip


def config_estimate(path, *, backend: str = "numpy", cache: Cache | None = None, seen: set[str] | None = None
                    ) -> Forecast:  # fmt: skip
    """The :class:`Forecast` of a figure config (``study figure``): its cases (positions or cases × seeds) with its
    methods, as :func:`study.outputs.figures.figure_positions` expands them, on ``backend`` (``seen``: as
    :func:`forecast`)."""
    from study.harness.config import load_figure_config

    cfg, scene, methods = load_figure_config(path)
    preset = {}
    scenes = [scene.with_updates({**over, **preset}) for _, _, over in cfg.case_list()]
    return forecast(scenes, methods, cache=cache, intervals=True, backend=backend, seen=seen)


#: Where the last runs' metadata.json are (``reports/NAME``, ``reports/sweep-STEM``, :data:`MEASURED`).
REPORTS = REPO / "reports"

#: The commands the stage model does not count (their cases are neither a figure's nor a sweep's) → the folder under
#: reports/ whose metadata.json holds the ``seconds`` their last run took (with its ``backend`` and ``cpus``).
MEASURED = {"caustics-sweep": "fig8/sweep", "animate": "animation", "convergence": "convergence"}


def read_meta(path: Path) -> dict | None:
    try:
        meta = json.loads(Path(path).read_text())
    except (OSError, ValueError):
        return None
    return meta if isinstance(meta, dict) else None


def measured(command: str, reports: Path | None = None) -> tuple[float, str] | None:
    """(seconds, where they come from) of ``command``'s last run (:data:`MEASURED`), or None where it wrote none."""
    root = REPORTS if reports is None else Path(reports)
    name = MEASURED.get(command.split()[0] if command.split() else "")
    meta = read_meta(root / str(name) / "metadata.json") if name else None
    try:
        seconds = float(meta["seconds"])  # type: ignore[index]
    except (KeyError, TypeError, ValueError):
        return None
    return seconds, f"its last run, {meta.get('backend', '?')} on {meta.get('cpus', '?')} cores"


def last_run(meta_path: Path, config: Path, backend: str) -> dict | None:
    """The metadata.json of a figure's or sweep's last run where it describes this run to come: the same
    ``backend``, the same config file (its ``config_sha256``), this machine's CPU count, with a ``time_split``
    and ``seconds``; None otherwise."""
    import os

    meta = read_meta(meta_path)
    if not meta or meta.get("backend") != backend or meta.get("cpus") != os.cpu_count():
        return None
    try:
        sha = provenance.config_sha(config)
    except OSError:
        return None
    split = meta.get("time_split")
    if meta.get("config_sha256") != sha or not isinstance(split, dict) or "seconds" not in meta:
        return None
    if meta.get("quality", "preview") != "preview":
        return None
    return meta


#: A last run rendered (its renders or probes) where they took at least this share of what the model prices for
#: rendering all of them; less, it found them in the cache (a read is a small fraction of a render).
RENDERED = 0.2


def from_last_run(meta: dict, est: Forecast, cases: int, cold: Forecast | None = None) -> float:
    """Core seconds of ``cases`` cases from their command's last run (:func:`last_run`): its measured seconds
    per case, a figure's ``seconds`` (its cases) and ``outputs``, a sweep's summed stage times over the
    ``computed`` cases it ran and the model's fixed cost per case. Renders and probes as the cache stands now:
    ``est`` the stage model with today's cache, ``cold`` the same with nothing cached (``est`` where None); where
    the last run rendered (:data:`RENDERED`) its measured seconds × the share ``est``/``cold`` still to render,
    else (it read them from a cache since gone, say) the model's."""
    split = {k: float(v) for k, v in meta["time_split"].items()}
    ran = max(int(meta.get("computed", meta.get("cases", cases))), 1)
    drawn = 0.0
    for stage in ("renders", "probes"):
        had, now = split.get(stage, 0.0) * cases / ran, est.stages.get(stage, 0.0)
        full = (cold or est).stages.get(stage, 0.0)
        drawn += had * now / full if full > 0 and had >= RENDERED * full else now
    rendered = split.get("renders", 0.0) + split.get("probes", 0.0)
    if "computed" in meta:  # a sweep: its cases' stage times (core seconds) and the cases it computed
        per = (sum(split.get(k, 0.0) for k in CASE_PARTS) - rendered) / ran + est.fixed / max(est.cases, 1)
        return per * cases + drawn
    return (float(meta["seconds"]) + split.get("outputs", 0.0) - rendered) * cases / ran + drawn


def _backend_of(words: list[str], default: str) -> str:
    """The ``--backend X`` (or ``--backend=X``) among a command's words, else ``default``."""
    for i, w in enumerate(words):
        if w == "--backend" and i + 1 < len(words):
            return words[i + 1]
        if w.startswith("--backend="):
            return w.split("=", 1)[1]
    return default


def _done(out: Path, case) -> bool:
    """Whether ``out/cases`` holds ``case``'s file under its key (the sweep runner reuses it; its rows are not
    checked here)."""
    try:
        return json.loads((out / "cases" / f"{case.key}.json").read_text()).get("key") == case.key
    except (OSError, ValueError, AttributeError):
        return False


def step_estimates(commands, *, cache: Cache | None = None, reports: Path | None = None, backend: str = "numpy",
                   fresh: bool = False):  # fmt: skip
    """One (command, seconds or None, how it was found) per command, each on ``backend`` (or its own
    ``--backend``): ``figure NAME`` (its config, ``configs/NAME.toml``) and ``sweep PATH`` (its cases not already
    in ``reports/sweep-STEM/cases``, a sweep's columns) from the stage model with the backend's table, the
    commands of :data:`MEASURED` from their last run's seconds, None for anything else.

    Where ``reports/NAME`` (``reports/sweep-STEM``) holds a last run of the same config on the same backend and
    CPU count (:func:`last_run`), its measured stage times are used instead (:func:`from_last_run`): the same
    cases measured on this machine are more accurate than the stage model, whose rates are one average over
    every figure and sweep (a figure's methods and pixels differ from that average); renders and probes still
    come from the model with today's cache. ``fresh``: the stage model alone, as if no case were done and no
    figure had run (how a calibration is checked against a run it did not see). An impostor is rendered once:
    by the first command of the list that needs it, unless the cache holds it (the commands share the cache;
    run two at a time, a later one may start before the first has captured it and render it too, uncounted)."""
    from study.harness.sweep import load_sweep

    reports = REPORTS if reports is None else Path(reports)
    out, seen = [], set()  # the impostors the commands before capture
    for cmd in commands:
        words = cmd.split()
        b = _backend_of(words, backend)
        if len(words) >= 2 and words[0] == "figure":
            config = REPO / "configs" / f"{words[1]}.toml"
            est = config_estimate(config, cache=cache, backend=b, seen=seen)
            last = None if fresh else last_run(reports / words[1] / "metadata.json", config, b)
            if last:
                how = f"{est.cases} cases, its last run, {b} on {last['cpus']} cores; renders as cached"
                cold = config_estimate(config, cache=None, backend=b)  # nothing cached: what it rendered
                out.append((cmd, from_last_run(last, est, est.cases, cold), how))
            else:
                out.append((cmd, est.seconds, f"{est.cases} cases, stage model, {est.source}"))
        elif len(words) >= 2 and words[0] == "sweep":
            sw = load_sweep(REPO / words[1], backend=b)
            where = reports / f"sweep-{Path(words[1]).stem}"
            todo = sw.cases if fresh else [c for c in sw.cases if not _done(where, c)]
            done = f" ({len(sw.cases) - len(todo)} done already)" if len(todo) < len(sw.cases) else ""
            est = forecast(
                [c.scene for c in todo], sw.methods, cache=cache, intervals=False, backend=b, seen=seen
            )
            last = None if fresh or not todo else last_run(where / "metadata.json", REPO / words[1], b)
            if last and "computed" in last:
                how = f"{len(todo)} cases{done}, its last run, {b} on {last['cpus']} cores; renders as cached"
                cold = forecast([c.scene for c in todo], sw.methods, cache=None, intervals=False, backend=b)
                out.append((cmd, from_last_run(last, est, len(todo), cold), how))
            else:
                out.append((cmd, est.seconds, f"{len(todo)} cases{done}, stage model, {est.source}"))
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
    """``python -m study.harness.estimate [--backend B] [--jobs J] [--cache DIR] [--reports DIR] [--fresh]
    COMMAND...``: the estimate of ``study`` commands on backend B, one line per command (:func:`step_estimates`:
    seconds on one core) and the total on ``jobs`` cores (:func:`wall`)."""
    import argparse

    ap = argparse.ArgumentParser(description=main.__doc__.splitlines()[0])
    ap.add_argument("--jobs", type=int, default=1)
    ap.add_argument("--backend", default="numpy", help="where the commands' methods run (their --backend)")
    ap.add_argument("--cache", default=".cache")
    ap.add_argument(
        "--reports", default=None, help="the last runs' folder (default: the repository's reports/)"
    )
    ap.add_argument(
        "--fresh", action="store_true", help="the stage model alone: no sweep case done, no last run"
    )
    ap.add_argument("commands", nargs="*")
    args = ap.parse_args(argv)
    steps = step_estimates(args.commands, cache=Cache(args.cache), reports=args.reports, backend=args.backend,
                           fresh=args.fresh)  # fmt: skip
    for cmd, sec, how in sorted(steps, key=lambda x: -(x[1] or 0)):
        print(f"  {cmd}: {'unknown' if sec is None else 'about ' + span(sec)} ({how})")
    known = [s for _, s, _ in steps if s is not None]
    left = [c for c, s, _ in steps if s is None]
    source = table_for(args.backend)[1]
    print(
        f"estimate: about {span(wall(steps, args.jobs))} wall for {len(steps)} commands on {args.jobs} cores, "
        f"{args.backend} ({span(sum(known))} of commands on one); from {source} and the runs above"
        + (f"; not counted: {', '.join(left)}" if left else "")
    )


if __name__ == "__main__":
    main()
