"""The unit of replication: a case's geometry (the object's position, the scene, the object), not its seed.

A figure's ``seeds`` measure each position (or case) once per ``render.seed`` (:mod:`study.harness.config`: ids
``p0``, then ``p0-s1``, …; a sweep with a ``render.seed`` axis the same way). The seed draws only the Monte Carlo
parts anew (the impostor's radiance, the references, the stochastic methods' samples): every geometric column
(wrong fractions, angles, distances, ray counts) is the same at every seed of a geometry. Counting those rows as
cases counts copies, so every statistic over cases (the median's interval, the paired Wilcoxon test, the smallest
detectable difference, the per-case separations) runs on :func:`pooled` rows: one per geometry and method, each
numeric column the mean over the geometry's seeds (the same value for the geometric columns; for image columns the
mean, whose noise the seeds average; an interval's ``_lo``/``_hi`` the mean of the seeds' bounds, as wide as one
seed's: conservative for the mean), with ``seeds`` the number of rows pooled.
"""

from __future__ import annotations

import math
import re

#: a replicate's case id: the first seed's id, then ``-s<seed>`` (:meth:`study.harness.config.FigureConfig.case_list`)
SEED_SUFFIX = re.compile(r"-s\d+$")
#: a sweep's seed axis (``axis:<scene key>`` columns name the sweep's axes)
SEED_AXIS = "axis:render.seed"
#: the column of a pooled row that counts the seeds it averages
SEEDS = "seeds"


def _key(row: dict) -> tuple:
    if SEED_AXIS in row:  # a sweep over seeds: the other axes name the geometry
        return tuple(sorted((k, str(v)) for k, v in row.items() if k.startswith("axis:") and k != SEED_AXIS))
    return (SEED_SUFFIX.sub("", str(row["case"])),)


def geometry_ids(tab: list[dict]) -> dict[str, str]:
    """case id → the id of its geometry (the first case of that geometry in table order)."""
    first: dict[tuple, str] = {}
    out: dict[str, str] = {}
    for r in tab:
        c = r["case"]
        if c not in out:
            out[c] = first.setdefault(_key(r), c)
    return out


def seeds_per_geometry(tab: list[dict]) -> int:
    """The most cases (seeds) any geometry of ``tab`` has: 1 where nothing is pooled."""
    ids = geometry_ids(tab)
    n: dict[str, int] = {}
    for g in ids.values():
        n[g] = n.get(g, 0) + 1
    return max(n.values(), default=1)


def _number(v) -> bool:
    return isinstance(v, int | float) and not isinstance(v, bool)


def _mean(values: list) -> float:
    ok = [float(v) for v in values if _number(v) and math.isfinite(v)]
    if ok:
        return sum(ok) / len(ok)
    return next((float(v) for v in values if _number(v)), math.nan)  # inf stays inf, all-NaN stays NaN


def pooled(tab: list[dict]) -> list[dict]:
    """One row per geometry and label (module docstring): ``tab`` itself where every geometry has one case (so a
    pooled table pools to itself); else rows whose ``case`` is the geometry's id, numeric columns averaged over
    its seeds (non-numeric ones the first seed's), and ``seeds`` the rows averaged."""
    ids = geometry_ids(tab)
    if len(set(ids.values())) == len(ids):
        return tab
    groups: dict[tuple[str, str], list[dict]] = {}
    for r in tab:
        groups.setdefault((ids[r["case"]], r["label"]), []).append(r)
    out = []
    for (geo, _), rows in groups.items():
        keys = list(dict.fromkeys(k for r in rows for k in r))
        row = {}
        for k in keys:
            vals = [r.get(k) for r in rows]
            row[k] = _mean(vals) if any(_number(v) for v in vals) else rows[0].get(k)
        row["case"], row[SEEDS] = geo, len(rows)
        out.append(row)
    return out
