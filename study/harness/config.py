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

Unknown keys, unknown methods and unknown method parameters are errors naming the file and the key.
"""
from __future__ import annotations

import itertools
from pathlib import Path
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, model_validator

from study import methods as registry
from study.errors import StudyError
from study.methods import Method
from study.scene import Scene, Vec3, load_scene, scene_from_dict
from study.validation import validate_file


class FigureConfig(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)
    scene: str | dict[str, Any]
    overrides: dict[str, Any] = {}
    positions: list[Vec3] | None = Field(None, min_length=1)
    cases: list[dict[str, Any]] | None = Field(None, min_length=1)
    methods: MethodSpecs = "all"
    grid: list[str] | None = None
    occlusion_panel: bool = False       # add a column showing which rays' exact hits are hidden from o

    @model_validator(mode="after")
    def _one_of(self):
        if (self.positions is None) == (self.cases is None):
            raise ValueError("give either positions or cases (one image row each)")
        return self

    def case_list(self) -> list[tuple[str, str, dict[str, Any]]]:
        """(case id suffix, row label, scene overrides) per image row."""
        if self.positions is not None:
            return [(f"p{i}", f"({p[0]:g}, {p[1]:g}, {p[2]:g})", {"object.center": list(p)})
                    for i, p in enumerate(self.positions)]
        out = []
        for i, c in enumerate(self.cases):
            c = dict(c)
            name = str(c.pop("name", f"c{i}"))
            out.append((name, name, c))
        return out


def base_scene(spec: str | dict, *, config_path: Path) -> Scene:
    if isinstance(spec, dict):
        try:
            return scene_from_dict(spec, source=str(config_path))
        except StudyError as err:          # keys of an inline scene are under "scene." in the config file
            raise StudyError(err.detail, file=str(config_path), key=f"scene.{err.key}") from None
    p = Path(spec)
    return load_scene(p if p.is_absolute() else config_path.parent / p)


MethodSpecs = Literal["all"] | list[Literal["all"] | dict[str, Any]]


def configured_scene(cfg, path: Path) -> Scene:
    """The base scene of a config (``cfg.scene``: a path relative to the config file, or an inline table) with
    the config's ``[overrides]`` applied."""
    scene = base_scene(cfg.scene, config_path=path)
    if cfg.overrides:
        scene = scene.with_updates(cfg.overrides, source=f"{path} [overrides]")
    return scene


def expand_methods(specs: MethodSpecs, *, source: str) -> list[Method]:
    """The methods a config asks for. ``"all"`` (alone or as a list entry) is every registered method with its
    default parameters; a table is {name, param = value | [values]}, lists expanding into the Cartesian product.
    A method that two entries ask for is kept once, where it first appears."""
    out = []
    for i, spec in enumerate([specs] if isinstance(specs, str) else specs):
        if spec == "all":
            out += registry.all_methods()
            continue
        spec = dict(spec)
        name = spec.pop("name", None)
        if not isinstance(name, str):
            raise StudyError(f"each method needs a name; allowed: {', '.join(registry.names())}",
                             file=source, key=f"methods[{i}].name")
        keys = list(spec)
        values = [v if isinstance(v, list) else [v] for v in spec.values()]
        for combo in itertools.product(*values):
            try:
                out.append(registry.make(name, **dict(zip(keys, combo))))
            except StudyError as err:
                raise StudyError(err.detail, file=source, key=f"methods[{i}]" + (
                    "." + err.key.split(".", 1)[1] if err.key and "." in err.key else ".name")) from None
    return list({m.label: m for m in reversed(out)}.values())[::-1]


def load_figure_config(path: str | Path) -> tuple[FigureConfig, Scene, list[Method]]:
    path = Path(path)
    cfg = validate_file(FigureConfig, path)
    scene = configured_scene(cfg, path)
    for i, (_, _, over) in enumerate(cfg.case_list()):
        scene.with_updates(over, source=f"{path} {'positions' if cfg.positions is not None else 'cases'}[{i}]")
    methods = expand_methods(cfg.methods, source=str(path))
    return cfg, scene, methods
