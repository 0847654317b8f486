"""The search core of the methods that march along a ray and then refine: a linear search for sign changes of a
function g(t) on uniform samples, then secant (regula falsi) steps inside the bracket found, by default with the
Illinois rule. Written once against the array backend (:mod:`study.backend`), so it runs on numpy and Dr.Jit; used
by :mod:`study.methods.linear_secant`, :mod:`study.methods.layered` and the object's own distance map
(:class:`study.optics.distance_map.DistanceMap`). It registers no method.

Contract (backend ``B``, N rays, every array 1-D float32 of length N unless said otherwise):
    g        callable t ↦ g(t) (an (N,) array of t → an (N,) array). For :func:`first_crossing` and
             :func:`sign_changes` it may instead return a list of arrays: several functions sampled at the same t
             (the layers of a layered map), searched in one pass (one kernel per step on Dr.Jit); ``g0`` is then a
             list too and so is the result, one entry per function.
    t0, g0   start of the search and g(t0). g0 is passed in, not evaluated here: the caller counts that lookup and
             may adjust it (the distance map forces its start to count as g < 0).
    dt       step per ray ((N,) array or float); samples t_k = t0 + k dt for k = 1..``steps``, each clamped to
             ``t_max`` when given (a ray whose range ends earlier repeats t_max). g is evaluated ``steps`` times on
             every ray: the cost of the scan is ``steps`` lookups per function, plus the caller's g0.
    default  (t_lo, g_lo, t_hi, g_hi): the bracket of rays where no sign change is found; None: the whole range,
             (t0, g0, last sample, g at it).

A :class:`Bracket` (t_lo, g_lo, t_hi, g_hi, found) holds two consecutive samples t_lo < t_hi with the sign
change between them where ``found`` ((N,) bool), the default elsewhere. "Sign" means g < 0 against g ≥ 0:
:func:`first_crossing` finds the first step from g < 0 to g ≥ 0 (the ray passes from in front of a surface to
behind it), :func:`sign_changes` the first ``count`` changes in either direction. :func:`refine` spends
``steps`` more evaluations of g on secant steps inside a bracket and returns the final bracket;
:func:`secant_point` gives its secant point t_lo − g_lo (t_hi − t_lo) / (g_hi − g_lo), the estimate of the root
(not finite where g_hi = g_lo, as on a bracket without a sign change).

Each function has a slow, obvious ``_ref`` twin (one ray, plain Python floats) that the tests compare it with.
"""
from __future__ import annotations

from collections.abc import Callable
from typing import Any, NamedTuple


class Bracket(NamedTuple):
    t_lo: Any        # the last sample before the sign change
    g_lo: Any        # g(t_lo)
    t_hi: Any        # the first sample after it
    g_hi: Any        # g(t_hi)
    found: Any       # a sign change was found (else the bracket is the default)


def secant_point(b: Bracket):
    """t where the chord through (t_lo, g_lo) and (t_hi, g_hi) crosses zero (arrays or floats)."""
    return b.t_lo - b.g_lo * (b.t_hi - b.t_lo) / (b.g_hi - b.g_lo)


# ---------------------------------------------------------------------------------------------- linear search
def first_crossing(B, g: Callable, t0, g0, dt, steps: int, *, t_max: float | None = None,
                   default: tuple | None = None):
    """The first step from g < 0 to g ≥ 0: a :class:`Bracket` (a list of them when g returns a list)."""
    return _scan(B, g, t0, g0, dt, steps, t_max=t_max, default=default, count=1, rising=True, first=True)


def sign_changes(B, g: Callable, t0, g0, dt, steps: int, *, count: int = 2, t_max: float | None = None,
                 default: tuple | None = None):
    """The first ``count`` sign changes in either direction (g < 0 → g ≥ 0 or back), in order along t: a list of
    ``count`` :class:`Bracket`\\ s (a list of such lists, one per function, when g returns a list)."""
    return _scan(B, g, t0, g0, dt, steps, t_max=t_max, default=default, count=count, rising=False, first=False)


def _scan(B, g, t0, g0, dt, steps, *, t_max, default, count, rising, first):
    many = isinstance(g0, (list, tuple))
    g_prev = list(g0) if many else [g0]                # g at the previous sample, per function
    never = B.isfinite(t0) & ~B.isfinite(t0)          # all False
    # per function, per crossing: found, t_lo, g_lo, t_hi, g_hi (the default, or a placeholder until the end)
    start = [tuple(default) if default is not None else (t0, gp, t0, gp) for gp in g_prev]
    cross = [[[never, *s] for _ in range(count)] for s in start]
    t_prev = t0                                        # the previous sample
    for k in range(1, steps + 1):
        t = t0 + dt * float(k)
        t = B.minimum(t, t_max) if t_max is not None else t
        gts = g(t) if many else [g(t)]
        for i, gt in enumerate(gts):
            if rising:
                change = (g_prev[i] < 0.0) & (gt >= 0.0)
            else:
                change = (g_prev[i] < 0.0) != (gt < 0.0)
            before = None                              # found of the previous crossing, before this step
            for j, (f, *b) in enumerate(cross[i]):
                new = change & ~f if before is None else change & before & ~f
                before = f
                cross[i][j] = [f | new, *(B.select(new, v, o) for v, o in zip((t_prev, g_prev[i], t, gt), b))]
            g_prev[i] = gt
        t_prev = t
        B.eval(*g_prev, *(v for c in cross for b in c for v in b))   # one small kernel per step (Dr.Jit)
    # ----------------------------------------------------------------------- rays without a crossing
    if default is None:                                # the whole range: (t0, g0, last sample, g there)
        cross = [[[f, t_lo, g_lo, B.select(f, t_hi, t_prev), B.select(f, g_hi, gp)] for f, t_lo, g_lo, t_hi, g_hi in c]
                 for c, gp in zip(cross, g_prev)]
    out = [[Bracket(t_lo, g_lo, t_hi, g_hi, f) for f, t_lo, g_lo, t_hi, g_hi in c] for c in cross]
    out = [c[0] for c in out] if first else out
    return out if many else out[0]


# ---------------------------------------------------------------------------------------------- secant steps
def secant_update(B, replace_a, t, gt, ta, ga, tb, gb, side, *, illinois: bool = True):
    """One bracket update of the secant (regula falsi) search: the new point (t, g(t)) replaces end a where
    ``replace_a``, else end b. ``side`` remembers which end the last step replaced (+1 a, −1 b); with the
    Illinois rule, an end replaced twice in a row halves the other end's g against one-sided stagnation.
    Returns (ta, ga, tb, gb, side)."""
    if illinois:
        gb = B.select(replace_a & (side > 0.0), gb * 0.5, gb)
        ga = B.select(~replace_a & (side < 0.0), ga * 0.5, ga)
    ta, ga = B.select(replace_a, t, ta), B.select(replace_a, gt, ga)
    tb, gb = B.select(replace_a, tb, t), B.select(replace_a, gb, gt)
    return ta, ga, tb, gb, B.select(replace_a, side * 0.0 + 1.0, side * 0.0 - 1.0)


def refine(B, g: Callable, bracket: Bracket, steps: int, *, illinois: bool = True, rising: bool = False) -> Bracket:
    """``steps`` secant steps inside ``bracket`` (one evaluation of g each): the secant point t replaces the end
    on its side of the sign change, the end whose g has the same sign (g < 0 or g ≥ 0); with ``rising`` (the
    bracket is known to run from g < 0 to g ≥ 0, as from :func:`first_crossing`), the lo end where g(t) < 0 — the
    same choice where a sign change was found. With ``illinois``, an end replaced twice in a row halves the other
    end's g (plain false position stalls on one side). Returns the final bracket (``found`` passed through); its
    :func:`secant_point` is the estimate."""
    t_lo, g_lo, t_hi, g_hi, found = bracket
    side = t_lo * 0.0                                  # +1: the last step replaced the lo end, −1: hi, 0: none
    for _ in range(steps):
        t = t_lo - g_lo * (t_hi - t_lo) / (g_hi - g_lo)   # secant point
        gt = g(t)
        replace_lo = (gt < 0.0) if rising else ((gt < 0.0) == (g_lo < 0.0))
        t_lo, g_lo, t_hi, g_hi, side = secant_update(B, replace_lo, t, gt, t_lo, g_lo, t_hi, g_hi, side,
                                                     illinois=illinois)
        B.eval(t_lo, g_lo, t_hi, g_hi, side)          # one small kernel per step (Dr.Jit)
    return Bracket(t_lo, g_lo, t_hi, g_hi, found)


# ---------------------------------------------------------------------------------------------- reference twins
def sign_changes_ref(g: Callable[[float], float], t0: float, g0: float, dt: float, steps: int, *, count: int = 2,
                     t_max: float | None = None, default: tuple | None = None,
                     rising: bool = False) -> list[Bracket]:
    """One ray, plain floats: the first ``count`` sign changes (``rising``: only g < 0 → g ≥ 0)."""
    found = []
    t_prev, g_prev = t0, g0
    for k in range(1, steps + 1):
        t = t0 + dt * k
        if t_max is not None:
            t = min(t, t_max)
        gt = g(t)
        change = (g_prev < 0 and gt >= 0) if rising else ((g_prev < 0) != (gt < 0))
        if change and len(found) < count:
            found.append(Bracket(t_prev, g_prev, t, gt, True))
        t_prev, g_prev = t, gt
    fill = tuple(default) if default is not None else (t0, g0, t_prev, g_prev)
    return found + [Bracket(*fill, False)] * (count - len(found))


def first_crossing_ref(g: Callable[[float], float], t0: float, g0: float, dt: float, steps: int, *,
                       t_max: float | None = None, default: tuple | None = None) -> Bracket:
    """One ray, plain floats: the first step from g < 0 to g ≥ 0."""
    return sign_changes_ref(g, t0, g0, dt, steps, count=1, t_max=t_max, default=default, rising=True)[0]


def refine_ref(g: Callable[[float], float], bracket: Bracket, steps: int, *, illinois: bool = True,
               rising: bool = False) -> Bracket:
    """One ray, plain floats: ``steps`` secant (Illinois) steps inside ``bracket``."""
    t_lo, g_lo, t_hi, g_hi, found = bracket
    last = 0                                           # which end the last step replaced: +1 lo, −1 hi
    for _ in range(steps):
        t = secant_point(Bracket(t_lo, g_lo, t_hi, g_hi, found))
        gt = g(t)
        lo = gt < 0 if rising else ((gt < 0) == (g_lo < 0))
        if lo:
            if illinois and last > 0:
                g_hi *= 0.5
            t_lo, g_lo, last = t, gt, 1
        else:
            if illinois and last < 0:
                g_lo *= 0.5
            t_hi, g_hi, last = t, gt, -1
    return Bracket(t_lo, g_lo, t_hi, g_hi, found)
