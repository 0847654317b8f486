"""Declarative sweeps: a base scene, axes that override scene keys, the methods to compare → one tidy table.

A sweep file (TOML)::

    scene = "../scenes/room.toml"            # or an inline [scene] table
    seed = 0                                 # → render.seed (default: the scene's)
    zip = [["object.center", "columns"]]     # axes that move together (default: Cartesian product of all)

    [overrides]                              # dotted scene keys applied to the base scene first
    "render.spp" = 16

    [axes]
    "render.cube_res" = [64, 128, 256]                                   # a list of values
    "object.center" = { line = { from = [0, 1.5, 0], to = [1.5, 0.6, 1], steps = 4 } }   # points along a line
    "columns" = { named = { none = [], small = [ {center = [1, 1], footprint = [0.3, 0.3], height = 2} ] } }

    [[methods]]                              # as in figure configs; list parameters expand
    name = "localized"
    iterations = [0, 1, 3, 10]

Each case (one combination of axis values) is run (:mod:`study.harness.runner`) by
:func:`study.measure.case.run_case` with every method; its rows get one column per axis holding the value's label.
Cases are identified by a content key (scene, methods, backend, and the hash of the code that computes them,
:func:`study.codehash.code_hash`): a finished case is stored under ``<out>/cases/<key>.json`` (atomically) and not
recomputed while its key, methods and rows still match, so a killed sweep resumes where it stopped, and a change of
code recomputes what it touches. A case's id and axis labels are not part of its identity: they come from the
expansion of the config as it is now. When every case is done, the table ``<out>/results.csv`` (in case order),
``<out>/metadata.json`` (versions, config hash, seed, git commit, backend) and the curves are swapped in together;
a failed or killed sweep leaves the previous ones as they were. One command at a time may write to an output
directory (a lock file; a second one stops with a clear message).
"""

from __future__ import annotations

import hashlib
import itertools
import json
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Any

from pydantic import BaseModel, ConfigDict, Discriminator, Field, Tag

from study.codehash import code_hash
from study.errors import StudyError
from study.harness.config import MethodSpecs, configured_scene, expand_methods
from study.measure.case import run_case
from study.measure.producers import PRODUCERS
from study.methods import Method
from study.scene import Scene
from study.scene.schema import MAX_SEED, Int, Vec3
from study.scene.sources import key_fields
from study.validation import validate_file


class Line(BaseModel):
    model_config = ConfigDict(extra="forbid", populate_by_name=True, allow_inf_nan=False)
    start: Vec3 = Field(alias="from")
    end: Vec3 = Field(alias="to")
    steps: Int = Field(ge=1, le=1000)


class Axis(BaseModel):
    model_config = ConfigDict(extra="forbid")
    values: list[Any] | None = None
    named: dict[str, Any] | None = None
    line: Line | None = None


#: An axis: a plain list of values, or a table (values, named or line). Which one is decided by the input's type
#: (a discriminator), so an error inside a table names that table's key (``axes.K.line.steps``), not "a valid list".
AxisSpec = Annotated[
    Annotated[list[Any], Tag("<list>")] | Annotated[Axis, Tag("<table>")],
    Discriminator(lambda v: "<table>" if isinstance(v, dict | Axis) else "<list>"),
]


class SweepConfig(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)
    scene: str | dict[str, Any]
    seed: Int | None = Field(default=None, ge=0, le=MAX_SEED)
    overrides: dict[str, Any] = {}
    axes: dict[str, AxisSpec] = {}
    zip: list[list[str]] = []
    methods: MethodSpecs = "all"


@dataclass
class Case:
    index: int
    id: str  # c0000, c0001, … in sweep order
    scene: Scene
    labels: dict[str, str]  # axis key → value label
    key: str = ""  # content key (scene, methods, backend, code hash)


@dataclass
class Sweep:
    path: Path
    config: SweepConfig
    methods: list[Method]
    cases: list[Case]
    config_hash: str


def _label(v) -> str:
    """A value's label in the table; an integral float keeps its point (16.0), so it never reads as the int 16."""
    if isinstance(v, float):
        s = f"{v:g}"
        return s + ".0" if s.lstrip("-").isdigit() else s
    if isinstance(v, (list, tuple)) and all(isinstance(x, (int, float)) for x in v):
        return "(" + ", ".join(f"{x:g}" for x in v) + ")"
    return json.dumps(v, sort_keys=True) if not isinstance(v, str) else v


def _axis_values(key: str, spec, source: str) -> list[tuple[str, Any]]:
    if isinstance(spec, list):
        vals = [(_label(v), v) for v in spec]
    elif spec.line is not None:
        a, b, n = spec.line.start, spec.line.end, spec.line.steps
        pts = [[a[i] + (b[i] - a[i]) * (k / (n - 1) if n > 1 else 0.0) for i in range(3)] for k in range(n)]
        vals = [(_label(p), p) for p in pts]
    elif spec.named is not None:
        vals = list(spec.named.items())
    elif spec.values is not None:
        vals = [(_label(v), v) for v in spec.values]
    else:
        raise StudyError(
            "an axis needs a list, or one of values, named, line", file=source, key=f"axes.{key}"
        )
    if not vals:
        raise StudyError("an axis needs at least one value", file=source, key=f"axes.{key}")
    return vals


def load_sweep(path: str | Path, *, backend: str = "numpy") -> Sweep:
    """Read, validate and expand a sweep file: every case's scene is validated before anything runs."""
    path = Path(path)
    cfg = validate_file(SweepConfig, path)
    scene = configured_scene(cfg, path)
    if cfg.seed is not None:
        scene = scene.with_updates({"render.seed": cfg.seed}, source=str(path))
    methods = expand_methods(cfg.methods, source=str(path))

    # ------------------------------------------------------------------ axes → groups (zipped or single)
    axes = {k: _axis_values(k, v, str(path)) for k, v in cfg.axes.items()}
    zipped = set()
    groups: list[list[str]] = []
    for i, z in enumerate(cfg.zip):
        for k in z:
            if k not in axes:
                raise StudyError(
                    f"{k!r} is not an axis; axes: {', '.join(axes)}", file=str(path), key=f"zip[{i}]"
                )
            if k in zipped:
                raise StudyError(f"{k!r} is in two zip groups", file=str(path), key=f"zip[{i}]")
        if len({len(axes[k]) for k in z}) > 1:
            raise StudyError(
                "zipped axes need the same number of values: "
                + ", ".join(f"{k} has {len(axes[k])}" for k in z),
                file=str(path),
                key=f"zip[{i}]",
            )
        zipped |= set(z)
        groups.append(list(z))
    groups += [[k] for k in axes if k not in zipped]

    # ------------------------------------------------------------------ cases: product over the groups
    cases = []
    per_group = [[{k: axes[k][i] for k in g} for i in range(len(axes[g[0]]))] for g in groups]
    for idx, combo in enumerate(itertools.product(*per_group) if groups else [()]):
        chosen = {k: lv for part in combo for k, lv in part.items()}
        try:
            sc = scene.with_updates({k: v for k, (_, v) in chosen.items()}, source=f"{path} [axes]")
        except StudyError as err:
            labels = ", ".join(f"{k}={lab}" for k, (lab, _) in chosen.items())
            raise StudyError(f"{err.detail} (case {labels})", file=str(path), key=f"axes.{err.key}") from None
        cases.append(Case(idx, f"c{idx:04d}", sc, {k: lab for k, (lab, _) in chosen.items()}))
    code = case_code(methods)  # once: the same for every case
    for c in cases:
        c.key = case_key(c.scene, methods, backend, code=code)
    return Sweep(path, cfg, methods, cases, hashlib.sha256(path.read_bytes()).hexdigest()[:16])


def case_code(methods: list[Method]) -> str:
    """The hash of the code that computes a case's rows: :func:`study.measure.case.run_case` and what it imports,
    each method's class, and every column producer registered now (a plug-in's column changes the rows, so a case
    cached without it is not resumed: :data:`study.measure.producers.PRODUCERS`)."""
    return code_hash(run_case, *PRODUCERS, *[type(m) for m in methods])


def case_key(scene: Scene, methods: list[Method], backend: str, code: str | None = None) -> str:
    """The content key of a case: its scene, the methods' labels, the backend, and the hash of the code that
    computes its rows (:func:`case_code`; ``code``, when given, is that hash, computed once for many cases)."""
    blob = json.dumps(
        {
            "scene": key_fields(scene),
            "methods": [m.label for m in methods],
            "backend": backend,
            "code": code or case_code(methods),
        },
        sort_keys=True,
    )
    return hashlib.sha256(blob.encode()).hexdigest()[:20]
