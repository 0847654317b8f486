"""Convergence as curves (``study convergence``): wrong fractions, angles and image error of each search against its
iterations or steps, per case, how many it needs to reach a wrong fraction, per scene, and which rays it gets wrong.

Config (``configs/convergence.toml``)::

    figures = ["fig4.toml", "fig5.toml"]   # figure configs (relative to this file): their positions or cases are
                                           # the cases, each config one scene
    targets = [0.05, 0.01]                 # wrong fractions to reach
    reach = ["wrong_fraction_texel", "wrong_fraction_visible"]   # … in these columns
    [overrides]                            # dotted scene keys applied to every case (after the figure's own)
    [[ladders]]                            # one curve per case: method(param = v) for v in values
    method = "localized"
    param = "iterations"
    values = [0, 1, 2, 3]
    breakdown = [3]                        # rungs whose wrong rays are explained (study.measure.convergence)

Each case runs every rung of every ladder through :func:`study.measure.case.run_case` (its rows, every column), so
a rung's numbers are those of a method of the same name in any figure. Outputs (one set, :func:`study.io.write_set`):

* ``curves.csv``: one row per case × ladder × rung: ``scene``, ``case``, ``ladder``, ``param``, ``value`` and the
  columns of :data:`CURVE_COLUMNS`;
* ``reach.csv``: per scene × ladder × reach column × target: the smallest rung from which on every rung of the
  case is at or below the target (``value_to_reach``: the median over the cases, with the interval of
  :func:`study.stats.case_interval`: the cases' range below 10 cases, a bootstrap CI from 10; where a case
  never reaches it, it counts as inf, beyond the ladder, and the interval is the range), how many cases reach it
  (``reached``/``n_cases``) and each case's value (``per_case``);
* ``breakdown.csv``: :func:`study.measure.convergence.breakdown` of each case's breakdown rungs;
* ``convergence.png``: the curves (one panel per ladder × metric, a line per case, one colour per scene);
* ``index.md``: the reach table, the causes summed over each scene's cases, and what each file holds;
* ``metadata.json``.
"""

from __future__ import annotations

import json
import math
import time
from pathlib import Path
from typing import Any, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from study import columns
from study import methods as registry
from study.cache import Cache
from study.errors import StudyError
from study.harness.config import load_figure_config
from study.harness.runner import metadata
from study.io import locked, png_bytes, write_set
from study.measure.convergence import CAUSES, Ladder, run_ladders
from study.stats import case_interval
from study.tables import markdown, to_csv
from study.validation import validate_file

#: The columns of ``curves.csv`` beside the ladder's (those a row has): the results table's view "curves".
CURVE_COLUMNS = tuple(columns.view("curves"))
#: The plotted metrics: (column, axis label, log axis): the declared columns of view "convergence" (study/columns.py).
PANELS = tuple((c.name, c.axis, True) for c in columns.in_view("convergence"))
#: Below this a fraction is drawn at it on the log axis (0 wrong).
LOG_FLOOR = 1e-4


class LadderSpec(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)
    method: str
    param: str
    values: list[float | int] = Field(min_length=1)
    breakdown: list[float | int] = []


class ConvergenceConfig(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)
    kind: Literal["convergence"] = "convergence"  # the figure kind (study.report.kinds.convergence)
    figures: list[str] = Field(min_length=1)
    ladders: list[LadderSpec] = Field(min_length=1)
    targets: list[float] = [0.05, 0.01]
    reach: list[str] = ["wrong_fraction_texel", "wrong_fraction_visible", "wrong_fraction_1cm"]
    overrides: dict[str, Any] = {}


def load_convergence(path: str | Path) -> tuple[ConvergenceConfig, list[Ladder]]:
    """The config and its ladders; a method or parameter that does not exist is one line naming it."""
    cfg = validate_file(ConvergenceConfig, path)
    ladders = []
    for i, s in enumerate(cfg.ladders):
        ld = Ladder(s.method, s.param, tuple(s.values), tuple(s.breakdown))
        if s.method not in registry.REGISTRY:
            raise StudyError(f"unknown method {s.method!r}; allowed: {', '.join(registry.names())}",
                             file=str(path), key=f"ladders[{i}].method")  # fmt: skip
        try:
            ld.rungs()
        except Exception as err:  # the parameter or a value (pydantic, or the registry's own line)
            first = getattr(err, "detail", None) or str(err).splitlines()[0]
            raise StudyError(f"{s.method}: {first}", file=str(path), key=f"ladders[{i}].param") from None
        missing = [k for k in s.breakdown if k not in s.values]
        if missing:
            raise StudyError(f"breakdown {missing[0]!r} is not among the values", file=str(path),
                             key=f"ladders[{i}].breakdown")  # fmt: skip
        ladders.append(ld)
    return cfg, ladders


def convergence_cases(
    cfg: ConvergenceConfig, path: Path, extra: dict | None = None
) -> list[tuple[str, str, Any]]:
    """(scene name, case id, scene) of every case: each figure config's positions or cases (its first seed's), with
    this config's overrides and then ``extra`` (the command line's ``--set``)."""
    out = []
    for f in cfg.figures:
        fpath = Path(f) if Path(f).is_absolute() else path.parent / f
        fcfg, scene, _ = load_figure_config(fpath)
        stem = fpath.stem
        for suffix, _, over in fcfg.case_list(replicates=False):  # wrong hits are geometry: seeds add nothing
            sc = scene.with_updates({**over, **cfg.overrides, **(extra or {})}, source=str(path))
            out.append((stem, f"{stem}-{suffix}", sc))
    return out


def to_reach(values, column: list[float], target: float) -> float:
    """The smallest of ``values`` (ascending) from which on every ``column`` value is ≤ ``target``; NaN if none."""
    ok = np.asarray(column, float) <= target
    if not ok[-1]:
        return math.nan
    first = len(ok) - int(np.argmin(ok[::-1])) if not ok.all() else 0
    return float(values[first])


def reach_rows(rows: list[dict], cfg: ConvergenceConfig) -> list[dict]:
    """``reach.csv``'s rows (module docstring)."""
    out = []
    scenes = list(dict.fromkeys(r["scene"] for r in rows))
    for scene in scenes:
        for ladder in dict.fromkeys(r["ladder"] for r in rows):
            sel = [r for r in rows if r["scene"] == scene and r["ladder"] == ladder]
            by_case = {}
            for r in sel:
                by_case.setdefault(r["case"], []).append(r)
            for col in cfg.reach:
                for t in cfg.targets:
                    per = {}
                    for c, rs in by_case.items():
                        rs = sorted(rs, key=lambda r: r["value"])
                        per[c] = to_reach([r["value"] for r in rs], [r.get(col, math.nan) for r in rs], t)
                    v = [x for x in per.values() if math.isfinite(x)]
                    if len(v) == len(per):
                        med, lo, hi, _, kind = case_interval(v)
                    else:  # a case that never reaches it counts as beyond the ladder (inf): median and range
                        every = [x if math.isfinite(x) else math.inf for x in per.values()]
                        med, lo, hi, kind = float(np.median(every)), min(every), math.inf, "range"
                    out.append({
                        "scene": scene, "ladder": ladder, "column": col, "target": t, "value_to_reach": med,
                        "lo": lo, "hi": hi, "interval": kind, "reached": len(v), "n_cases": len(per),
                        "per_case": "; ".join(f"{c}: {x:g}" if math.isfinite(x) else f"{c}: not reached"
                                              for c, x in per.items()),
                    })  # fmt: skip
    return out


def cause_summary(parts: list[dict], scene_of: dict) -> list[dict]:
    """The causes of the wrong rays summed over each scene's cases, per ladder and rung: share of the wrong rays
    and of all rays."""
    acc: dict = {}
    for p in parts:
        if p["by"] != "cause":
            continue
        key = (scene_of[p["case"]], p["ladder"], p["value"])
        a = acc.setdefault(key, {"rays": {}, "wrong": dict.fromkeys(CAUSES, 0)})
        a["rays"][p["case"]] = p["n_rays"]
        a["wrong"][p["group"]] += p["n_wrong"]
    out = []
    for (scene, ladder, value), a in acc.items():
        n, w = sum(a["rays"].values()), sum(a["wrong"].values())
        row = {"scene": scene, "ladder": ladder, "value": value, "rays": n, "wrong": w}
        row |= {c: f"{a['wrong'][c] / n:.2%} ({a['wrong'][c] / max(w, 1):.0%})" for c in CAUSES}
        out.append(row)
    return out


def convergence_plot(rows: list[dict], ladders: list[Ladder]) -> bytes:
    """``convergence.png``: rows = ladders, columns = :data:`PANELS`; one line per case, one colour per scene."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from study.outputs.plots import colour

    scenes = list(dict.fromkeys(r["scene"] for r in rows))
    fig, axes = plt.subplots(len(ladders), len(PANELS), figsize=(3.1 * len(PANELS), 2.6 * len(ladders)),
                             squeeze=False)  # fmt: skip
    for i, ld in enumerate(ladders):
        sel = [r for r in rows if r["ladder"] == ld.name]
        for j, (col, ylabel, logy) in enumerate(PANELS):
            ax = axes[i, j]
            for c in dict.fromkeys(r["case"] for r in sel):
                rs = sorted((r for r in sel if r["case"] == c), key=lambda r: r["value"])
                y = np.array([r.get(col, math.nan) for r in rs], float)
                if col.startswith("wrong_fraction"):
                    y = np.maximum(y, LOG_FLOOR)
                k = scenes.index(rs[0]["scene"])
                ax.plot([r["value"] for r in rs], y, "-o", ms=2.5, lw=1, color=colour(k), alpha=0.8,
                        label=rs[0]["scene"])  # fmt: skip
            if col.startswith("wrong_fraction"):
                for t in (0.05, 0.01):
                    ax.axhline(t, color="0.6", lw=0.7, ls=":")
            if logy:
                ax.set_yscale("log")
            ax.set_xlabel(ld.param, fontsize=8)
            ax.set_title(f"{ld.method}: {ylabel}", fontsize=8)
            ax.tick_params(which="both", labelsize=7)
            ax.grid(alpha=0.3, lw=0.5)
    handles = {
        h.get_label(): h for ax in axes.flat for h in ax.get_lines() if not h.get_label().startswith("_")
    }
    fig.legend(list(handles.values()), list(handles), loc="upper center", ncol=max(1, len(handles)), fontsize=8,
               frameon=False)  # fmt: skip
    fig.tight_layout(rect=(0, 0, 1, 0.96))
    return png_bytes(fig, dpi=100)


def convergence_page(cfg_path, reach: list[dict], causes: list[dict], n_cases: int) -> str:
    """``index.md``."""
    shown = [dict(r, value_to_reach=_range(r)) for r in reach]
    return "\n".join([
        "# Convergence of the searches",
        "",
        f"Made by `study convergence {cfg_path}` from {n_cases} cases. Each rung of each ladder is measured as a "
        "method of the case (study.measure.case.run_case): curves.csv holds every column per case and rung, "
        "convergence.png draws them (a line per case, a colour per scene; the dotted lines are 5 % and 1 %; a "
        f"wrong fraction of 0 is drawn at {LOG_FLOOR:g}).",
        "",
        "![curves](convergence.png)",
        "",
        "## Rungs to reach a wrong fraction",
        "",
        "The smallest rung from which on the case stays at or below the target; the median over the cases that "
        "reach it, with the cases' range below 10 cases (a bootstrap 95 % CI from 10 on); a case that never reaches "
        "it within the ladder counts as beyond it (not reached) in the median and the range.",
        "",
        markdown(shown, ["scene", "ladder", "column", "target", "value_to_reach", "reached", "n_cases"]),
        "",
        "## Which rays are wrong",
        "",
        "Per scene, ladder and rung: the share of all rays wrong for each cause (in brackets: of the wrong rays); "
        "breakdown.csv also splits them by ray length and by the surface of the exact hit, per case.",
        "",
        markdown(causes, ["scene", "ladder", "value", "rays", "wrong", *CAUSES]),
        "",
    ])  # fmt: skip


def _range(r: dict) -> str:
    def g(v):
        return f"{v:g}" if math.isfinite(v) else "not reached"

    kind = " (range)" if r["interval"] == "range" else ""
    return f"{g(r['value_to_reach'])} [{g(r['lo'])}, {g(r['hi'])}]{kind}"


def run_convergence(config: str | Path, out: str | Path, *, backend: str = "numpy", cache=".cache",
                overrides: dict | None = None) -> list[dict]:  # fmt: skip
    """Run every case of ``config`` (module docstring), write the outputs under ``out``; returns curves.csv's
    rows. The entry point of ``study convergence``."""
    path = Path(config)
    cfg, ladders = load_convergence(path)
    todo = convergence_cases(cfg, path, overrides)
    store = Cache(cache)
    t0 = time.perf_counter()
    rows, parts = [], []
    with locked(out):
        for scene_name, cid, sc in todo:
            rs, ps = run_ladders(sc, ladders, cache=store, backend=backend, case_id=cid)
            rows += [{"scene": scene_name, "case": cid, **{k: r[k] for k in ("ladder", "param", "value")},
                      **{k: r[k] for k in CURVE_COLUMNS if k in r}} for r in rs]  # fmt: skip
            parts += [{"scene": scene_name, **p} for p in ps]
        reach = reach_rows(rows, cfg)
        causes = cause_summary(parts, {c: s for s, c, _ in todo})
        meta = metadata(path, backend=backend, seed=0, methods=[ld.name for ld in ladders], cases=len(todo),
                        seconds=time.perf_counter() - t0, overrides=overrides or {})  # fmt: skip
        files = {
            "curves.csv": to_csv(rows),
            "reach.csv": to_csv(reach),
            "breakdown.csv": to_csv(parts),
            "convergence.png": convergence_plot(rows, ladders),
            "index.md": convergence_page(config, reach, causes, len(todo)),
            "metadata.json": json.dumps(meta, indent=1, default=str),
        }
        write_set(out, files, lock=False)
    return rows
