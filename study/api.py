"""The Python API for notebooks and scripts: :func:`load_scene` and :func:`evaluate`, which returns a :class:`Result`.

    import study
    scene = study.load_scene("scenes/room.toml", **{"object.radius": 0.3, "render.cube_res": 64})
    res = study.evaluate(scene, methods=["classical", "localized(iterations=3)"])
    res.table                    # pandas DataFrame: one row per method, and the oracle_map / truth_at_hit rows
    res.images["classical"]      # (H, W, 3) linear RGB; also "oracle_map", "truth_at_hit", "mitsuba"
    res.error_maps["classical"]  # (H, W) per-pixel RMS radiance error against truth_at_hit (NaN off the object)
    res.images["localized"]      # the name will do where one parameterisation ran; a wrong key names the keys
    res.save("reports/my-run")   # table, one multi-layer EXR, image grid, viewer page: written as one set

:func:`load_scene` reads a scene TOML, a mesh file (the environment: OBJ/PLY/GLB/STL/OFF), a Mitsuba XML file, a
Mitsuba scene dict (``{"type": "scene", ...}``, e.g. ``mitsuba.cornell_box()``) or a study scene dict; for mesh
and Mitsuba sources the placement keys left out (reference point, object, light, camera) are placed by
:mod:`study.scene.autoplace` (the Mitsuba scene's own camera where it has one), alike for a file and a TOML naming
it. ``scene.load_summary()`` is the one line of what the environment's file held and what was ignored (``study
run`` prints it to stderr). Overrides are dotted
scene keys, as keyword arguments (``**{"object.radius": 0.3}``) or an ``overrides`` dict. Methods registered from
outside the package (``@study.methods.register`` in a notebook cell, ``--plugin``, entry points) are part of
``methods="all"``. Errors are :class:`~study.errors.StudyError` (one line naming file and key).
"""

from __future__ import annotations

import base64
import copy
import html as _html
import io as _io
import os
import re
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from study import columns
from study import methods as registry
from study.errors import StudyError
from study.scene import Scene
from study.scene.models import MESH_SUFFIXES
from study.tables import REFERENCE_ROWS

#: file suffixes that :func:`load_scene` reads as an environment mesh, and as a Mitsuba scene
MITSUBA_SUFFIXES = (".xml",)


# ---------------------------------------------------------------------------------------------- scenes
def _set_dotted(data: dict, key: str, value: Any, *, source: str) -> None:
    node, parts = data, key.split(".")
    for p in parts[:-1]:
        node = node.setdefault(p, {})
        if not isinstance(node, dict):
            raise StudyError("not a table of the scene", file=source, key=key)
    node[parts[-1]] = value


def _environment_scene(env: dict, updates: dict, *, source: str) -> Scene:
    """A scene in a mesh or Mitsuba environment: ``updates``, and the placement keys they leave out suggested
    (:mod:`study.scene.autoplace`, as for a scene TOML naming the same environment)."""
    from study.scene import scene_from_dict

    data: dict = {"environment": env}
    for k, v in updates.items():
        _set_dotted(data, k, v, source=source)
    return scene_from_dict(data, source=source)


def load_scene(
    source: str | Path | dict | Scene, overrides: dict[str, Any] | None = None, **more: Any
) -> Scene:
    """A validated :class:`~study.scene.Scene` from ``source`` with dotted-key ``overrides`` (and ``**more``).

    Parameters
    ----------
    source : str, Path, dict or Scene
        A scene TOML file (a relative path missing from the working directory is looked up among the shipped
        ones: ``"scenes/room.toml"`` works from anywhere); a mesh file (OBJ, PLY, GLB, STL, OFF: the
        environment); a Mitsuba XML file; a Mitsuba scene dict (``"type": "scene"``); a study scene dict (the
        tables of a scene TOML); or a Scene.
    overrides, **more : dotted scene keys → values, e.g. ``{"object.radius": 0.3, "camera.width": 64}``.
    """
    if overrides is not None and not isinstance(overrides, Mapping):
        raise StudyError(
            f"overrides is a dict of dotted scene keys → values, not {type(overrides).__name__}",
            key="overrides",
        )
    updates = {**(overrides or {}), **more}
    if isinstance(source, Scene):
        return source.with_updates(updates) if updates else source
    if isinstance(source, dict):
        if source.get("type") == "scene":  # a Mitsuba scene dict
            return _environment_scene({"type": "mitsuba", "scene": source}, updates, source="<mitsuba dict>")
        from study.scene import scene_from_dict

        data = copy.deepcopy(source) if updates else source  # sets stay sets: refused as points
        for k, v in updates.items():
            _set_dotted(data, k, v, source="<scene dict>")
        return scene_from_dict(data, source="<scene dict>")
    if not isinstance(source, (str, Path)):
        raise StudyError(
            f"a scene source is a path, a dict or a Scene, not {type(source).__name__}", key="source"
        )
    from study.harness.config import shipped

    path = shipped(Path(source).expanduser())  # "scenes/room.toml" from any working directory
    if not path.is_file():
        raise StudyError("scene source not found", file=str(path))
    suffix = path.suffix.lower()
    if suffix in MESH_SUFFIXES:
        return _environment_scene({"type": "mesh", "file": str(path.resolve())}, updates, source=str(path))
    if suffix in MITSUBA_SUFFIXES:
        return _environment_scene({"type": "mitsuba", "file": str(path.resolve())}, updates, source=str(path))
    if suffix != ".toml":
        raise StudyError(
            f"not a scene source; allowed: .toml, {', '.join(MESH_SUFFIXES + MITSUBA_SUFFIXES)}",
            file=str(path),
        )
    from study.scene import load_scene_file as load_toml

    scene = load_toml(path)
    return scene.with_updates(updates, source=str(path)) if updates else scene


# ---------------------------------------------------------------------------------------------- methods
def method_list(spec: Any = "all", *, key: str = "methods") -> list:
    """Methods from ``"all"`` (the mirror methods), ``"glossy"`` (the glossy ones), a name, a label
    (``"localized(iterations=3)"``: parameters as TOML values), a :class:`~study.methods.Method`, a config table
    (``{"name": "localized", "iterations": [0, 1, 3]}``) or a list of these; a method asked for twice is kept once.
    Errors name ``key`` (and the entry's index)."""
    from study.harness.config import expand_methods

    out = []
    for i, s in enumerate(spec if isinstance(spec, (list, tuple)) else [spec]):
        try:
            out += _methods_of(s, expand_methods)
        except StudyError as err:
            raise StudyError(
                err.detail, key=f"{key}[{i}]" if isinstance(spec, (list, tuple)) else key
            ) from None
    first: dict = {}
    for m in out:
        first.setdefault(m.label, m)
    return list(first.values())


def _methods_of(s: Any, expand_methods) -> list:
    """The methods of one entry of :func:`method_list`."""
    if isinstance(s, registry.Method):
        return [s]
    if isinstance(s, str) and s not in ("all", "glossy"):
        m = re.fullmatch(r"\s*([A-Za-z_]\w*)\s*(?:\((.*)\))?\s*", s)
        if not m:
            raise StudyError(f"not a method name or label: {s!r}; allowed: {', '.join(registry.names())}")
        try:
            params = tomllib.loads(f"p = {{{m.group(2)}}}")["p"] if m.group(2) else {}
        except tomllib.TOMLDecodeError as err:
            raise StudyError(f"the parameters of {s!r} are not TOML values ({err})") from None
        s = {"name": m.group(1), **params}
    if not (s in ("all", "glossy") or isinstance(s, dict)):
        raise StudyError(f"not a method: {s!r}; a name, a label, a Method or a table")
    try:
        return expand_methods([s], source=None)
    except StudyError as err:
        what = err.key.split(".", 1)[1] if err.key and "." in err.key else ""
        raise StudyError(f"{what + ': ' if what and what != 'name' else ''}{err.detail}") from None


# ---------------------------------------------------------------------------------------------- results
class MissingKey(KeyError):
    """A key none of a result's mappings hold: its message names the keys that are (not KeyError's bare repr)."""

    def __str__(self) -> str:
        return str(self.args[0]) if self.args else ""


class Maps(dict):
    """A result's label → array mapping that also takes the keys a person would type: the method's name
    (``"localized"``) where one parameterisation of it ran (the label is ``"localized(iterations=3)"``), and a
    label spelled with other spaces (``"localized( iterations = 3 )"``). A key it cannot resolve raises a
    :class:`KeyError` that names the keys it holds; one that fits several labels names those."""

    what = "maps"  # the attribute's name, for messages

    def _label(self, key: Any) -> Any:
        """The stored label ``key`` stands for; :class:`MissingKey` where none or several."""
        if dict.__contains__(self, key):
            return key
        if isinstance(key, str):
            bare = re.sub(r"\s+", "", key)
            same = [k for k in self if isinstance(k, str) and re.sub(r"\s+", "", k) == bare]
            if len(same) == 1:
                return same[0]
            runs = [k for k in self if isinstance(k, str) and "(" not in bare and k.split("(", 1)[0] == bare]
            if len(runs) == 1:
                return runs[0]
            if len(runs) > 1:
                raise MissingKey(
                    f"{self.what}[{key!r}]: {key} ran with {len(runs)} parameterisations; name one: "
                    + ", ".join(map(repr, runs))
                )
        raise MissingKey(
            f"{self.what}[{key!r}]: no such key; valid keys: {', '.join(map(repr, self)) or 'none'}"
        )

    def __getitem__(self, key: Any) -> np.ndarray:
        return dict.__getitem__(self, self._label(key))

    def __contains__(self, key: Any) -> bool:
        try:
            self._label(key)
        except KeyError:
            return False
        return True

    def get(self, key: Any, default: Any = None) -> Any:
        return self[key] if key in self else default


def _maps(what: str, data: Mapping | None) -> Maps:
    out = Maps(data or {})
    out.what = what
    return out


@dataclass(eq=False)
class Result:
    """What :func:`evaluate` measured on one scene.

    ``table``: pandas DataFrame, one row per method and the reference rows ``oracle_map`` (exact hit shaded with what
    the reference point's views hold; hits hidden from it are magenta and left out, :mod:`study.measure.split`) and
    ``truth_at_hit`` (exact hit, Mitsuba radiance); every column of a results table
    (``docs/usage.md``: *What is measured*). Arrays are keyed by method label, (H, W) over the camera image:
    ``images`` (H, W, 3) linear RGB, with the references ``oracle_map``, ``truth_at_hit`` and ``mitsuba`` (Mitsuba's
    render with the object); ``error_maps``: RMS over RGB of the image minus ``truth_at_hit``; ``flip_maps``: LDR-FLIP
    against ``truth_at_hit``; ``angle_maps``: mean angular error at the shading point (degrees);
    ``outcome_maps``: majority outcome class (0 correct, 1 wrong depth, 2 wrong surface, 3 no hit). Error maps are
    NaN off the object (``mask``: the pixels fully on it)."""

    scene: Scene
    table: Any
    images: dict[str, np.ndarray] = field(default_factory=dict)
    error_maps: dict[str, np.ndarray] = field(default_factory=dict)
    flip_maps: dict[str, np.ndarray] = field(default_factory=dict)
    angle_maps: dict[str, np.ndarray] = field(default_factory=dict)
    outcome_maps: dict[str, np.ndarray] = field(default_factory=dict)
    mask: np.ndarray | None = None
    backend: str = "numpy"
    occluded: np.ndarray | None = None
    file: str | None = (
        None  # the scene's file (resolved), where it came from one: named in titles and index.json
    )
    #: the case's wall time by part (:meth:`study.progress.Stages.split`), kept in index.json as "time_split"
    times: dict[str, float] = field(default_factory=dict)

    def __post_init__(
        self,
    ) -> None:  # keys a person would type (:class:`Maps`), for every mapping of the result
        for name in ("images", "error_maps", "flip_maps", "angle_maps", "outcome_maps"):
            setattr(self, name, _maps(name, getattr(self, name)))

    @property
    def labels(self) -> list[str]:
        return list(self.table["label"])

    def summary(self) -> str:
        s, r = self.scene, self.scene.render
        env = getattr(getattr(s, "environment", None), "type", "box")
        obj = s.object.shape if s.object.shape != "mesh" else f"mesh {Path(s.object.file).name}"
        return (
            f"{env} environment, {obj} (radius {s.object.radius:g}, {s.object.material.type}), camera "
            f"{s.camera.width}×{s.camera.height}, cube {r.cube_res}², backend {self.backend}, "
            f"{len(self.table) - len(REFERENCE_ROWS)} method(s)"
        )

    def notes(self) -> list[str]:
        """What the run says about its light and samples (:func:`study.measure.lighting.notes`)."""
        from study.measure.lighting import notes

        return notes(self.table.to_dict("records"), self.scene)

    def shown(self):
        """The table's leading columns (the declared view "run" of :mod:`study.columns`) for display."""
        return self.table[[c for c in columns.view("run") if c in self.table.columns]]

    def __repr__(self) -> str:
        return f"Result({self.summary()})\n" + self.shown().to_string(
            index=False, float_format=lambda v: f"{v:.4g}"
        )

    def _repr_html_(self) -> str:
        from study.measure.metrics import to_ldr

        thumbs = []
        for label in ["mitsuba", *self.labels]:
            if label in self.images:
                buf = _io.BytesIO()
                from PIL import Image

                Image.fromarray((to_ldr(self.images[label]) * 255 + 0.5).astype(np.uint8)).save(buf, "PNG")
                src = base64.b64encode(buf.getvalue()).decode()
                thumbs.append(
                    f'<figure style="display:inline-block;margin:2px;text-align:center">'
                    f'<img src="data:image/png;base64,{src}" width="96" style="image-rendering:pixelated">'
                    f'<figcaption style="font-size:75%">{_html.escape(label)}</figcaption></figure>'
                )
        table = self.shown().to_html(index=False, float_format=lambda v: f"{v:.4g}", na_rep="–", escape=True)
        return f"<div><b>study result</b>: {_html.escape(self.summary())}{table}<div>{''.join(thumbs)}</div></div>"

    def save(self, out: str | Path) -> list[Path]:
        """Write what ``study run`` writes, as a figure's outputs are named (:mod:`study.outputs.run_files`): the
        table (``table.csv``, ``table.parquet``), the scene (``scene.json``), one multi-layer EXR ``exr/run.exr``
        (every image and map as a named layer: ``classical``, ``angle-classical``, …, ``mask``; label → layer in
        ``index.json``), the image grid ``run.png``, a viewer page ``index.html``, as one output set (every byte made
        first; ``""`` a StudyError, a file study did not write kept: :func:`study.io.write_set`). Returns the files."""
        from study.io import json_text, out_dir, write_set
        from study.outputs.run_files import result_files
        from study.tables import to_csv

        out = out_dir(out, key="out")
        rows = self.table.to_dict("records")
        buf = _io.BytesIO()
        self.table.to_parquet(buf, index=False)
        labels = [lab for lab in self.labels if lab not in REFERENCE_ROWS]
        name = Path(self.file).name if self.file else None
        files, index = result_files(
            self._case(),
            rows,
            labels,
            title=f"{name}: {self.summary()}" if name else self.summary(),
            name=name,
        )
        index.update(file=self.file, name=name, time_split=self.times)  # study report finds runs by file
        files.update(
            {
                "table.csv": to_csv(rows),
                "table.parquet": buf.getvalue(),
                "scene.json": self.scene.model_dump_json(indent=2),
                "index.json": json_text(index, indent=2),
            }
        )
        old = [
            "images",
            "error_maps",
            "flip_maps",
            "angle_maps",
            "outcome_maps",
            "mask.exr",
        ]  # earlier layout
        return sorted(write_set(out, files, ["exr", "viewer", *old]))

    def _case(self):
        """The result as a case of a figure (the attributes :mod:`study.outputs.viewer` reads)."""
        from types import SimpleNamespace

        return SimpleNamespace(
            scene=self.scene,
            images=self.images,
            truth=self.images.get("truth_at_hit"),
            oracle=self.images.get("oracle_map"),
            mitsuba=self.images.get("mitsuba"),
            angle_maps=self.angle_maps,
            outcome_maps=self.outcome_maps,
            flip_maps=self.flip_maps,
            error_maps=self.error_maps,
            occluded=self.occluded,
            mask=self.mask,
        )


def evaluate(
    scene: str | Path | dict | Scene,
    methods: Any = "all",
    *,
    backend: str = "numpy",
    cache: str | Path | None = ".cache",
    overrides: dict[str, Any] | None = None,
    source: str | None = None,
    allow_mismatch: bool = False,
) -> Result:
    """Run every method on ``scene`` (anything :func:`load_scene` takes) and measure it (one case,
    :func:`study.measure.case.run_case`).

    Parameters
    ----------
    methods : ``"all"`` (every registered method at its defaults, the notebook's own too), or a list of names,
        labels (``"localized(iterations=3)"``), Method objects or config tables (:func:`method_list`).
    backend : ``"numpy"``, ``"llvm"`` or ``"cuda"``: where the methods run.
    cache : directory of cached impostors and Mitsuba renders (None: no cache).
    overrides : dotted scene keys applied first.
    source : the name refusals give (the budget's, say); default the scene's file, else ``evaluate``.
    allow_mismatch : score methods that do not model the object's surface (rows marked ``surface_mismatch``).

    Returns
    -------
    Result
    """
    import pandas as pd

    from study.cache import Cache, flush
    from study.harness import budget, estimate
    from study.harness.config import surface_methods
    from study.measure.case import run_case
    from study.measure.metrics import flip_map
    from study.tables import columns_of

    if cache is not None and not isinstance(cache, str | os.PathLike):
        raise StudyError(f"cache is a directory path or None, not {type(cache).__name__}", key="cache")
    named = source if source is not None else str(scene) if isinstance(scene, str | os.PathLike) else None
    source = named or "evaluate"
    scene = load_scene(scene, overrides)
    chosen = not (isinstance(methods, str) and methods == "all")  # the default set: the surface's family
    ms, wrong = surface_methods(scene, method_list(methods), chosen=chosen, allow_mismatch=allow_mismatch)
    budget.check_backend(backend)
    budget.check_cases([("run", scene)], ms, source=source, tell=estimate.teller(ms, Cache(cache), backend))
    from study import runtime

    with runtime.using_render_device("cuda" if backend == "cuda" else None):  # renders, hits too (as the CLI)
        case = run_case(scene, ms, backend=backend, cache=Cache(cache) if cache else None, case_id="run")
    flush()  # the cache's entries on disk: a failed write is this call's error
    mask = np.asarray(case.mask, bool)
    images = {"oracle_map": case.oracle, "truth_at_hit": case.truth, "mitsuba": case.mitsuba, **case.images}
    flips = {"oracle_map": flip_map(case.truth, case.oracle), **case.flip_maps}
    errors = {
        k: np.where(mask, np.sqrt(np.mean((np.asarray(v, float) - case.truth) ** 2, axis=-1)), np.nan)
        for k, v in images.items()
        if k not in ("truth_at_hit",)
    }
    rows = [{**r, "surface_mismatch": 1.0} if r["label"] in wrong else r for r in case.rows]
    table = pd.DataFrame(rows, columns=columns_of(rows))
    return Result(
        scene,
        table,
        images=images,
        error_maps=errors,
        flip_maps={k: np.where(mask, v, np.nan) for k, v in flips.items()},
        angle_maps=dict(case.angle_maps),
        outcome_maps=dict(case.outcome_maps),
        mask=mask,
        backend=backend,
        occluded=None if case.occluded is None else np.asarray(case.occluded, np.float32),
        file=scene_file(named, scene),
        times=dict(case.times),
    )


def scene_file(source: str | None, scene: Scene) -> str | None:
    """The file a scene came from, resolved: ``source`` where it names one, else its environment's file."""
    from study.harness.config import shipped

    if source and (p := shipped(Path(source).expanduser())).is_file():
        return str(p.resolve())
    return getattr(getattr(scene, "environment", None), "file", None)
