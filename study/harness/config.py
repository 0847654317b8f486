"""Figure and study configs (TOML): a base scene, object positions, and the methods to compare.

Example (``configs/fig4.toml``)::

    scene = "../scenes/room.toml"     # path relative to this file, or an inline [scene] table
    positions = [[0.0, 1.5, 0.0], [0.6, 1.2, 0.3]]   # object centres, one image row each
    grid = ["classical", "localized(iterations=10)"]  # methods shown in the image grid (default: all)

    [overrides]                      # dotted scene keys, applied to the base scene
    "render.cube_res" = 256

    [[methods]]
    name = "classical"

    [[methods]]
    name = "localized"
    iterations = [0, 1, 3, 10]       # a list expands into one method per value

Instead of ``positions``, a figure may list ``cases``: each a table of dotted scene overrides, one image row each,
with an optional ``name`` (``configs/fig6.toml``)::

    [[cases]]
    name = "glass-sphere-single"
    "object.material" = { type = "dielectric", ior = 1.5 }
    "render.refraction" = "single"

Every position (or case) is measured once per seed with ``seeds = [0, 1, 2]`` (``render.seed``: the impostor's,
the references' and the stochastic methods' samples drawn anew; ids ``p0``, then ``p0-s1``, …); the grid's picture
shows the first seed's rows, those ``picture = [0, 3]`` names (by index; default all). A seed redraws the Monte
Carlo parts only, so the report pools a geometry's seeds (:mod:`study.report.geometry`): statistics over cases count
distinct geometries, and shipped figures have ≥ 12 of them, one seed each (``tests/report/test_figure_seeds.py``).

Unknown keys, unknown methods and unknown method parameters are errors naming the file and the key; so are
method parameters that are not finite (``inf``, ``nan``) and booleans or strings given for numbers.

Before any case is built, :func:`figure_estimate` prices the figure from its config alone: the first seed's cases (every
position or case, or :data:`ESTIMATE_SAMPLE` of them spread evenly) priced by :func:`study.harness.budget.estimate`,
times the seeds. :func:`load_figure_config` refuses a figure over ``--max-minutes`` from it at once, naming the axis
that costs (``seeds``, ``positions`` or ``cases``) and the limit, so that 100 000 seeds are refused in well under a
second instead of after their 100 000 scenes were validated.
"""

from __future__ import annotations

import itertools
import math
import re
from pathlib import Path
from typing import Annotated, Any, Literal, NamedTuple

from pydantic import BaseModel, ConfigDict, Field, StrictBool, StrictInt, model_validator

from study import methods as registry
from study.errors import StudyError
from study.harness import budget
from study.io import file_stem
from study.methods import Method
from study.scene import Scene, Vec3, load_scene_file, scene_from_dict
from study.scene.models import MAX_SEED
from study.validation import validate_file


class FigureConfig(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)
    scene: str | dict[str, Any]
    overrides: dict[str, Any] = {}
    positions: list[Vec3] | None = Field(None, min_length=1)
    cases: list[dict[str, Any]] | None = Field(None, min_length=1)
    methods: MethodSpecs = "all"
    grid: list[str] | None = None
    occlusion_panel: StrictBool = False  # add a column showing which rays' exact hits are hidden from o
    outcome_panel: StrictBool = False  # add per grid method a map of its per-ray outcome classes
    #: the figure kind that makes it (study.report.kinds): "grid", "glossy", or a plug-in's
    kind: str = "grid"
    #: replicates: every position (or case) once per seed (``render.seed``: the impostor's, the references' and
    #: the stochastic methods' samples drawn anew); the grid's picture shows the first seed's rows only
    seeds: list[Annotated[StrictInt, Field(ge=0, le=MAX_SEED)]] | None = Field(None, min_length=1)
    #: the positions (or cases) the grid's picture shows, by index from 0 (default: every one); all are measured
    picture: list[Annotated[StrictInt, Field(ge=0)]] | None = Field(None, min_length=1)

    @model_validator(mode="after")
    def _one_of(self):
        if (self.positions is None) == (self.cases is None):
            raise ValueError("give either positions or cases (one image row each)")
        if self.seeds is not None and len(set(self.seeds)) < len(self.seeds):
            raise ValueError(f"seeds repeat ({self.seeds}); give distinct seeds, one replicate each")
        n = len(self.positions if self.positions is not None else self.cases)
        pic = self.picture or []
        if max(pic, default=0) >= n or len(set(pic)) < len(pic):
            raise ValueError(f"picture {self.picture}: distinct indices from 0 to {n - 1} (of the {n} rows)")
        return self

    def _rows(self) -> list[tuple[str, str, dict[str, Any]]]:
        if self.positions is not None:
            return [
                (f"p{i}", f"({p[0]:g}, {p[1]:g}, {p[2]:g})", {"object.center": list(p)})
                for i, p in enumerate(self.positions)
            ]
        out = []
        for i, c in enumerate(self.cases):
            c = dict(c)
            name = str(c.pop("name", f"c{i}"))
            out.append((name, name, c))
        return out

    def pictured(self) -> list[int]:
        """The indices into :meth:`case_list` of the cases the grid's picture shows: the first seed's, those
        ``picture`` names (all by default)."""
        return list(self.picture if self.picture is not None else range(len(self._rows())))

    def case_list(self, replicates: bool = True) -> list[tuple[str, str, dict[str, Any]]]:
        """(case id suffix, row label, scene overrides) per case: per seed (the first seed first, its ids and
        labels as without seeds; then ``<id>-s<seed>``), each position or case; without ``replicates`` the first
        seed's only (what does not depend on the seed: the geometry's convergence)."""
        rows = self._rows()
        if self.seeds is None:
            return rows
        if not replicates:
            return [(sid, lab, {**over, "render.seed": self.seeds[0]}) for sid, lab, over in rows]
        return [
            (sid if j == 0 else f"{sid}-s{seed}", lab if j == 0 else f"{lab} seed {seed}",
             {**over, "render.seed": seed})
            for j, seed in enumerate(self.seeds)
            for sid, lab, over in rows
        ]  # fmt: skip

    def key_of(self, i: int) -> str:
        """The config key of case ``i`` of :meth:`case_list`: ``positions[2]`` or ``cases[2]`` (at every seed)."""
        return f"{'positions' if self.positions is not None else 'cases'}[{i % len(self._rows())}]"

    def case_count(self) -> int:
        """Cases of the figure: positions (or cases) × seeds."""
        return len(self._rows()) * len(self.seeds or [None])


def base_scene(spec: str | dict, *, config_path: Path) -> Scene:
    if isinstance(spec, dict):
        try:
            return scene_from_dict(spec, source=str(config_path))
        except StudyError as err:  # keys of an inline scene are under "scene." in the config file
            raise StudyError(err.detail, file=str(config_path), key=f"scene.{err.key}") from None
    p = Path(spec)
    return load_scene_file(p if p.is_absolute() else config_path.parent / p)


MethodSpecs = Literal["all", "glossy"] | list[str | dict[str, Any]]


#: Quality presets of ``study figure --quality``: scene keys applied to every case after the config's own.
#: ``preview`` is the config as written (what scripts/reproduce.sh and CI make on a CPU); ``paper`` renders at the
#: paper's 1024² with the config's framing, one ray per pixel (the resolution gives the rays), for a GPU machine.
QUALITY: dict[str, dict] = {
    "preview": {},
    "paper": {"camera.width": 1024, "camera.height": 1024, "render.supersample": 1},
}


def quality_overrides(quality: str) -> dict:
    """The scene keys of a quality preset; an unknown name is one line naming the allowed ones."""
    if quality not in QUALITY:
        raise StudyError(f"unknown quality {quality!r}; allowed: {', '.join(QUALITY)}", key="--quality")
    return QUALITY[quality]


def configured_scene(cfg, path: Path) -> Scene:
    """The base scene of a config (``cfg.scene``: a path relative to the config file, or an inline table) with
    the config's ``[overrides]`` applied."""
    scene = base_scene(cfg.scene, config_path=path)
    if cfg.overrides:
        scene = scene.with_updates(cfg.overrides, source=f"{path} [overrides]")
    return scene


def expand_methods(specs: MethodSpecs, *, source: str) -> list[Method]:
    """The methods a config asks for. ``"all"`` (alone or as a list entry) is every registered mirror method with
    its default parameters, ``"glossy"`` every glossy one (``Method.glossy``); a name is that method with its
    defaults; a table is {name, param = value | [values]}, lists expanding into the Cartesian product.
    A method that two entries ask for is kept once, where it first appears."""
    out = []
    for i, spec in enumerate([specs] if isinstance(specs, str) else specs):
        if spec == "all":
            out += registry.all_methods()
            continue
        if spec == "glossy":  # the methods for rough objects (study.methods.glossy)
            out += registry.glossy_methods()
            continue
        if isinstance(spec, str):  # a bare name: the method with its defaults
            if spec not in registry.REGISTRY:
                raise StudyError(
                    f'unknown method {spec!r}; allowed: "all", "glossy", {", ".join(registry.names())} (or a '
                    "table { name = …, parameter = value })",
                    file=source,
                    key=f"methods[{i}]",
                )
            spec = {"name": spec}
        spec = dict(spec)
        name = spec.pop("name", None)
        if not isinstance(name, str):
            raise StudyError(
                f"each method needs a name; allowed: {', '.join(registry.names())}",
                file=source,
                key=f"methods[{i}].name",
            )
        keys = list(spec)
        values = [v if isinstance(v, list) else [v] for v in spec.values()]
        for combo in itertools.product(*values):
            for k, v in zip(keys, combo):
                _check_param(registry.REGISTRY.get(name), k, v, source=source, key=f"methods[{i}].{k}")
            try:
                out.append(registry.make(name, **dict(zip(keys, combo))))
            except StudyError as err:
                raise StudyError(
                    err.detail,
                    file=source,
                    key=f"methods[{i}]"
                    + ("." + err.key.split(".", 1)[1] if err.key and "." in err.key else ".name"),
                ) from None
    return list({m.label: m for m in reversed(out)}.values())[::-1]


def _check_param(cls, name: str, value, *, source: str, key: str) -> None:
    """A method parameter's value holds no non-finite number, and no boolean or string where the parameter
    takes numbers (pydantic would read true as 1 and inf as a valid float)."""
    field = getattr(getattr(cls, "Params", None), "model_fields", {}).get(name)
    text = repr(field.annotation) if field is not None else ""
    for v in value if isinstance(value, (list, tuple)) else [value]:
        if isinstance(v, (list, tuple)):
            _check_param(cls, name, v, source=source, key=key)
        elif isinstance(v, float) and not math.isfinite(v):
            raise StudyError(f"Input should be a finite number, got {v}", file=source, key=key)
        elif isinstance(v, bool) and field is not None and "bool" not in text:
            raise StudyError("Input should be a valid number, not a boolean", file=source, key=key)
        elif isinstance(v, str) and field is not None and "str" not in text and "Literal" not in text:
            raise StudyError("Input should be a valid number, not a string", file=source, key=key)


#: the directory that holds the shipped ``configs/`` and ``scenes/`` (the repository root of this package)
ROOT = Path(__file__).resolve().parents[2]


def shipped(path: str | Path) -> Path:
    """``path`` as given where it exists (absolute, or relative to the working directory); else, for a relative
    path, the shipped file of that name under :data:`ROOT` (``configs/fig4.toml`` from any working directory);
    else ``path`` unchanged (reading it then says it is not found)."""
    path = Path(path)
    if path.exists() or path.is_absolute() or not (ROOT / path).exists():
        return path
    return ROOT / path


def load_figure_config(
    path: str | Path, *, name: str | None = None
) -> tuple[FigureConfig, Scene, list[Method]]:
    """A figure config (``path``: see :func:`shipped`), its base scene with the overrides, and its methods; a
    figure over ``--max-minutes`` (:func:`figure_estimate`) or a case out of view or over ``--max-memory`` is refused
    before its cases are built. ``name``: the figure's (case ids ``<name>-p0``, …; default the config's stem)."""
    path = shipped(path)
    cfg = validate_file(FigureConfig, path)
    scene = configured_scene(cfg, path)
    methods = expand_methods(cfg.methods, source=str(path))
    check_estimate(_estimate(cfg, scene, methods, path, name=name), source=str(path))
    for i, (_, _, over) in enumerate(cfg.case_list()):
        scene.with_updates(
            over, source=f"{path} {'positions' if cfg.positions is not None else 'cases'}[{i}]"
        )
    return cfg, scene, methods


# ---------------------------------------------------------------------------------------------- the estimate
#: At most this many of the first seed's positions (or cases) are priced one by one; the rest are taken to cost
#: what these cost on average.
ESTIMATE_SAMPLE = 64


class FigureEstimate(NamedTuple):
    """What a figure will cost, from its config alone (:func:`figure_estimate`).

    ``seconds``: the whole figure, cold (nothing cached), at :mod:`study.harness.budget`'s rates; ``cases``:
    positions (or cases) × seeds; ``breakdown``: ``axes`` (axis → count: ``seeds``, ``positions`` or ``cases``),
    ``per_case`` (seconds, on average), ``parts`` (scene key → seconds over the figure, the keys of
    :class:`study.harness.budget.Estimate`), ``priced`` (the (case id, scene) pairs priced one by one, the first
    seed's), ``whole`` (whether those are every case)."""

    seconds: float
    cases: int
    breakdown: dict


def figure_estimate(config: str | Path, *, quality: str = "preview") -> FigureEstimate:
    """The figure of ``config`` priced before any case is built (``quality``: a preset of :data:`QUALITY`).

    Parameters
    ----------
    config : a figure config file (:func:`shipped`)
    quality : the preset its cases get (``study figure --quality``)

    Returns
    -------
    FigureEstimate
        seconds, cases and the breakdown by axis and scene key (what ``study figure`` may print first).
    """
    path = shipped(config)
    cfg = validate_file(FigureConfig, path)
    scene = configured_scene(cfg, path)
    methods = expand_methods(cfg.methods, source=str(path))
    return _estimate(cfg, scene, methods, path, preset=quality_overrides(quality))


def _estimate(
    cfg, scene: Scene, methods: list[Method], path: Path, *, name=None, preset=None
) -> FigureEstimate:
    rows, seeds = cfg._rows(), cfg.seeds or [None]
    axis = "positions" if cfg.positions is not None else "cases"
    idx = sorted({round(x) for x in _spread(len(rows), ESTIMATE_SAMPLE)})
    stem = name or file_stem(Path(path).stem)
    priced = []
    for i in idx:
        suffix, _, over = rows[i]
        seed = {} if seeds[0] is None else {"render.seed": seeds[0]}
        priced.append((f"{stem}-{suffix}", scene.with_updates({**over, **seed, **(preset or {})},
                                                             source=f"{path} {axis}[{i}]")))  # fmt: skip
    seen, ests = set(), []
    for _, sc in priced:
        k = budget.impostor_key(sc)
        ests.append(budget.estimate(sc, methods, impostor=k not in seen))
        seen.add(k)
    scale = len(rows) / len(idx) * len(seeds)
    parts: dict[str, float] = {}
    for e in ests:
        for k, v in e.time.items():
            parts[k] = parts.get(k, 0.0) + v * scale
    total = sum(e.seconds for e in ests) * scale
    n = len(rows) * len(seeds)
    axes = {axis: len(rows), **({"seeds": len(seeds)} if cfg.seeds is not None else {})}
    return FigureEstimate(
        total,
        n,
        {"axes": axes, "per_case": total / n, "parts": parts, "priced": priced, "whole": n == len(priced),
         "methods": methods},
    )  # fmt: skip


def _spread(n: int, k: int) -> list[float]:
    """``min(n, k)`` indices spread evenly over 0 … n − 1, the first and the last among them."""
    m = min(n, k)
    return [0.0] if m == 1 else [i * (n - 1) / (m - 1) for i in range(m)]


def check_estimate(est: FigureEstimate, *, source: str, limits: budget.Limits | None = None) -> None:
    """Refuse a figure before its cases are built: a priced case out of view or over ``--max-memory``
    (:func:`study.harness.budget.check_cases`, its messages), and the whole over ``--max-minutes``, naming the axis
    that multiplies the cost (the one with the most entries: ``seeds``, ``positions`` or ``cases``) and the limit.
    Where the priced cases are the whole figure, the time is judged by ``check_cases`` as well (its message)."""
    limits = limits or budget.LIMITS
    b = est.breakdown
    budget.check_cases(b["priced"], b["methods"], source=source,
                       limits=budget.Limits(limits.max_memory_gib, math.inf))  # fmt: skip
    if est.seconds <= limits.max_minutes * 60:
        return
    if b["whole"]:
        budget.check_cases(b["priced"], b["methods"], source=source, limits=limits)
    axes = b["axes"]
    axis = max(axes, key=lambda a: (axes[a], a == "seeds"))
    product = " × ".join(f"{v:,} {a}" for a, v in axes.items())
    part = max(b["parts"], key=b["parts"].get)
    raise StudyError(
        f"{product} = {est.cases:,} cases at about {budget._hours(b['per_case'])} each would take about "
        f"{budget._hours(est.seconds)} here, over the limit of {limits.max_minutes:g} min (--max-minutes); the "
        f"axis that costs is {axis} ({axes[axis]:,}; each case most for "
        f"{budget._scene_key(part, b['priced'][0][1], b['methods'])}): lower it or raise --max-minutes",
        file=source,
        key=axis,
    )


#: A name that becomes one folder or file under ``--out`` / ``reports/``: a word character first, then word
#: characters, ``.`` and ``-`` (no path separator, no ``..``, nothing a shell reads as an option).
PLAIN_NAME = re.compile(r"\w[\w.-]{0,99}")


def plain_name(name: str, key: str = "name") -> str:
    """``name`` if it names one folder or file under the output directory (:data:`PLAIN_NAME`, as a config's
    stem would: no separator, no ``..``); else a StudyError naming ``key`` and what is allowed (exit 2)."""
    if not isinstance(name, str) or not PLAIN_NAME.fullmatch(name):
        raise StudyError(
            f"{str(name)[:80]!r} is not a plain name: letters, digits, '_', '.', '-', starting with a letter, digit "
            "or '_' (no path separator, no '..'); outputs go under --out or reports/",
            key=key,
        )
    return name


def surface_methods(scene, methods: list[Method], *, chosen: bool, allow_mismatch: bool) -> tuple[list, set]:
    """The methods for the object's surface: mirror methods (``Method.glossy`` False) model smooth mirrors and
    glass, glossy ones rough conductors (``object.alpha`` > 0). Where the user chose no methods (``chosen`` False:
    the default set), the family that fits the surface; a chosen method that does not fit is a StudyError naming
    it, unless ``allow_mismatch``. Returns the methods and the labels that do not fit (their rows are marked)."""
    rough = scene.object.alpha > 0
    if not chosen and any(m.glossy != rough for m in methods):
        methods = registry.glossy_methods() if rough else registry.all_methods()
    wrong = {m.label for m in methods if m.glossy != rough}
    if wrong and not allow_mismatch:
        what = (
            f"object.alpha = {scene.object.alpha:g}: a rough surface"
            if rough
            else "a smooth (mirror or glass) object"
        )
        kind = "smooth mirrors and glass" if rough else "rough conductors"
        raise StudyError(
            f"{what}, but {', '.join(sorted(wrong))} model {kind}; choose methods that fit (methods = "
            f'"{"glossy" if rough else "all"}"), or allow the mismatch (--allow-mismatch) to score them anyway',
            key="methods",
        )
    return methods, wrong
