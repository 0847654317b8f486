"""Convergence of a search as curves: one case, one method at every value of one parameter (a *ladder*: the
iterations of ``localized``, the secant steps or the samples per texel of the marches), every rung measured like a
method of any case (:func:`study.measure.case.run_case`: wrong fractions at the texel-relative and the fixed
tolerances, angles, image errors), and which rays a rung gets wrong, by cause, by length and by the surface they
hit (:func:`breakdown`).

Causes of a wrong ray (:data:`CAUSES`), in this order (the first that applies):

=============================  ==================================================================================
``hidden from o``              the exact hit is not held by o's views (:func:`study.measure.split.view_class`:
                               hidden, or escaping where o sees a wall): no search on them can show it
``no hit``                     the method found nothing (NaN shown point)
``undershoot, never bracketed`` ``localized`` only: no guess before the last overshot (|l|/|l'| > the band's upper
                               end, read on the impostor), so every step was the listing's eq.-2 step from the
                               last undershoot; needs the rungs 0 … k − 1 of the same ladder
``bracketed, not converged``   ``localized`` only: an overshoot was seen, the false-position steps did not close
``missed (held)``              any other method: the hit is held and shown, but wrong
=============================  ==================================================================================

Lengths are |exact − x| in the bins :data:`LENGTH_BINS` (m), escaping rays apart; surfaces are the environment's
surface names (:attr:`study.scene.RoomMesh.surfaces`) of the exact hit, ``(escapes)`` for a ray that leaves the
scene. The surface is found by casting from x along the exact hit's direction (mirror objects: the exact ray).
"""

from __future__ import annotations

from contextlib import contextmanager
from dataclasses import dataclass

import numpy as np

from study import backend as backends
from study.impostor.envmap import EnvMap
from study.measure import case as case_mod
from study.measure import split
from study.measure.inputs import impostor
from study.measure.outcomes import CORRECT, NO_HIT
from study.methods import Method
from study.methods import make as make_method
from study.reference.tracer import make_tracer

#: Causes of a wrong ray (module docstring), in the order they are tested.
CAUSES = (
    "hidden from o",
    "no hit",
    "undershoot, never bracketed",
    "bracketed, not converged",
    "missed (held)",
)
#: Bin edges of the exact ray's length |exact − x|, metres (the last bin is open).
LENGTH_BINS = (0.0, 0.5, 1.0, 2.0, 4.0)


@dataclass(frozen=True)
class Ladder:
    """One method at every value of one parameter: ``method(param=v)`` for v in ``values``; ``breakdown``: the
    values whose wrong rays :func:`breakdown` explains."""

    method: str
    param: str
    values: tuple
    breakdown: tuple = ()

    @property
    def name(self) -> str:
        """``method vs param``: the curve's name in tables and plots."""
        return f"{self.method} vs {self.param}"

    def rungs(self) -> list[Method]:
        return [make_method(self.method, **{self.param: v}) for v in self.values]


@contextmanager
def _per_ray():
    """Collect each trace's per-ray context (:class:`study.measure.case.RayContext`) by label while a case runs,
    through a column producer that writes no column."""
    seen: dict = {}

    def keep(ctx):
        seen[ctx.label] = ctx
        return {}

    case_mod.PRODUCERS.append(keep)
    try:
        yield seen
    finally:
        case_mod.PRODUCERS.remove(keep)


def run_ladders(scene, ladders: list[Ladder], *, cache, backend: str = "numpy", case_id: str = ""):
    """Every rung of every ladder on one case's rays: (rows, breakdown rows). A row is the case's row of that
    method (:func:`study.measure.case.run_case`, every column) with ``ladder`` (its name), ``param`` and ``value``
    added; the breakdown rows are :func:`breakdown`'s."""
    methods, where = [], []
    for ld in ladders:
        for v, m in zip(ld.values, ld.rungs()):
            if m.label not in {x.label for x in methods}:
                methods.append(m)
            where.append((ld, v, m.label))
    with _per_ray() as rays:
        out = case_mod.run_case(
            scene, methods, backend=backend, cache=cache, case_id=case_id, keep_images=False
        )
    by_label = {r["label"]: r for r in out.rows}
    rows = [{**by_label[lab], "ladder": ld.name, "param": ld.param, "value": v} for ld, v, lab in where]
    geo = _Geometry(scene, cache)
    parts = []
    for ld in ladders:
        labels = dict(zip(ld.values, (m.label for m in ld.rungs())))
        for k in ld.breakdown:
            if k in labels:
                parts += [
                    {"case": case_id, "ladder": ld.name, "value": k, **r}
                    for r in breakdown(rays, labels, k, ld, geo)
                ]
    return rows, parts


class _Geometry:
    """What the breakdown needs of a case beyond its rays: o, the impostor's distances, the exact tracer."""

    def __init__(self, scene, cache):
        self.o = np.asarray(scene.reference.point, float)
        self.tracer = make_tracer(scene.mesh())
        self.nb = backends.get("numpy")
        self.env = EnvMap(impostor(scene, cache, self.tracer).texels(), self.nb)  # cached: no capture again
        self.names = tuple(scene.mesh().surfaces)

    def ratio(self, shown) -> np.ndarray:
        """|l|/|l'| of shown points (N, 3), world space, read on the impostor (NaN where none is shown)."""
        v = np.asarray(shown, float) - self.o
        ok = np.all(np.isfinite(v), axis=-1)
        d = np.asarray(self.env.distance(self.nb.vec(np.where(ok[:, None], v, 1.0))), float)
        return np.where(ok, np.linalg.norm(v, axis=-1) / d, np.nan)

    def surface(self, x, exact, escapes) -> list[str]:
        u = np.asarray(exact, float) - np.asarray(x, float)
        u /= np.linalg.norm(u, axis=-1, keepdims=True)
        sid = self.tracer.intersect(x, u)["surface"]
        return [
            "(escapes)" if e else (self.names[s] if 0 <= s < len(self.names) else "?")
            for s, e in zip(sid, escapes)
        ]


def _cls(ctx) -> np.ndarray:
    """(N,) outcome codes of a trace's context (its ``classes`` is the :class:`~study.measure.outcomes.Outcomes`)."""
    return np.asarray(getattr(ctx.classes, "cls", ctx.classes))


def causes(ctx, escapes, label_of: dict, k, ladder: Ladder, geo: _Geometry, seen: dict) -> np.ndarray:
    """(N,) index into :data:`CAUSES` of each ray's cause (−1 where the ray is correct)."""
    c = _cls(ctx)
    held = split.held(ctx.occluded, escapes)
    out = np.full(c.shape, -1, np.int64)
    wrong = c != CORRECT
    if ladder.method == "localized" and ladder.param == "iterations":
        band_hi = make_method("localized").params.band_hi
        earlier = [seen[label_of[j]].shown for j in range(int(k)) if j in label_of and label_of[j] in seen]
        over = np.zeros(c.shape, bool)
        for s in earlier:
            with np.errstate(invalid="ignore"):
                over |= geo.ratio(s) > band_hi
        rest = np.where(over, 3, 2)
    else:
        rest = np.full(c.shape, 4)
    out = np.where(wrong, np.where(~held, 0, np.where(c == NO_HIT, 1, rest)), out)
    return out


def breakdown(seen: dict, label_of: dict, k, ladder: Ladder, geo: _Geometry) -> list[dict]:
    """Which rays rung ``k`` of ``ladder`` gets wrong (texel-relative tolerance), three ways: ``by`` = ``cause``
    (:data:`CAUSES`), ``length`` (bins of |exact − x|) and ``surface`` (the exact hit's surface). One row per
    group: ``group``, ``n_rays`` (rays in it), ``n_wrong``, ``wrong_fraction`` (within it) and ``share_of_wrong``
    (of all the rung's wrong rays)."""
    ctx = seen[label_of[k]]
    escapes = np.linalg.norm(ctx.exact - ctx.x, axis=-1) >= 0.5 * split.FAR
    wrong = _cls(ctx) != CORRECT
    total = max(int(wrong.sum()), 1)
    cause = causes(ctx, escapes, label_of, k, ladder, geo, seen)
    length = np.linalg.norm(ctx.exact - ctx.x, axis=-1)
    edges = np.asarray(LENGTH_BINS)
    bin_of = np.clip(np.searchsorted(edges, length, side="right") - 1, 0, len(edges) - 1)
    length_names = [f"{a:g}–{b:g} m" for a, b in zip(edges[:-1], edges[1:])] + [f"≥ {edges[-1]:g} m"]
    groups = {
        "cause": [(name, cause == i) for i, name in enumerate(CAUSES)],
        "length": [(n, (bin_of == i) & ~escapes) for i, n in enumerate(length_names)]
        + [("(escapes)", escapes)],
    }
    surf = np.asarray(geo.surface(ctx.x, ctx.exact, escapes), object)
    groups["surface"] = [(s, surf == s) for s in sorted(set(surf))]
    rows = []
    for by, items in groups.items():
        for name, sel in items:
            n, nw = int(sel.sum()), int((sel & wrong).sum())
            if by == "cause":  # a cause holds wrong rays only: its share of the rung's rays
                n = int(wrong.size)
            if n == 0:
                continue
            rows.append(
                {
                    "by": by,
                    "group": name,
                    "n_rays": n,
                    "n_wrong": nw,
                    "wrong_fraction": nw / n,
                    "share_of_wrong": nw / total,
                }  # fmt: skip
            )
    return rows
