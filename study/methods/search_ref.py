"""The slow, obvious twins of the search core (:mod:`study.methods.search`): one ray, plain Python floats, the
same contract; the tests compare the vectorized searches with them. ``dt`` may be a callable k ↦ t_k here too
(an :func:`~study.methods.search.arc_samples` called in order gives plain floats per ray). It registers no
method."""

from __future__ import annotations

from collections.abc import Callable

from study.methods.search import Bracket, secant_point


def sign_changes_ref(
    g: Callable[[float], float],
    t0: float,
    g0: float,
    dt: float,
    steps: int,
    *,
    count: int = 2,
    t_max: float | None = None,
    default: tuple | None = None,
    rising: bool = False,
) -> list[Bracket]:
    """One ray, plain floats: the first ``count`` sign changes (``rising``: only g < 0 → g ≥ 0)."""
    found = []
    t_prev, g_prev = t0, g0
    for k in range(1, steps + 1):
        t = dt(k) if callable(dt) else t0 + dt * k
        if t_max is not None:
            t = min(t, t_max)
        gt = g(t)
        change = (g_prev < 0 and gt >= 0) if rising else ((g_prev < 0) != (gt < 0))
        if change and len(found) < count:
            found.append(Bracket(t_prev, g_prev, t, gt, True))
        t_prev, g_prev = t, gt
    fill = tuple(default) if default is not None else (t0, g0, t_prev, g_prev)
    return found + [Bracket(*fill, False)] * (count - len(found))


def first_crossing_ref(
    g: Callable[[float], float],
    t0: float,
    g0: float,
    dt: float,
    steps: int,
    *,
    t_max: float | None = None,
    default: tuple | None = None,
) -> Bracket:
    """One ray, plain floats: the first step from g < 0 to g ≥ 0."""
    return sign_changes_ref(g, t0, g0, dt, steps, count=1, t_max=t_max, default=default, rising=True)[0]


def refine_ref(
    g: Callable[[float], float], bracket: Bracket, steps: int, *, illinois: bool = True, rising: bool = False
) -> Bracket:
    """One ray, plain floats: ``steps`` secant (Illinois) steps inside ``bracket``."""
    t_lo, g_lo, t_hi, g_hi, found = bracket
    last = 0  # which end the last step replaced: +1 lo, −1 hi
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


def first_entry_ref(
    g: Callable[[float], list],
    t0: float,
    g0: list,
    dt,
    steps: int,
    *,
    hold: int,
    t_max: float | None = None,
    default: tuple | None = None,
) -> tuple[Bracket, int]:
    """One ray, plain floats: the first kept entry into the inside of nested surfaces (see :func:`first_entry`)."""
    K = len(g0)

    def count(gs):
        return sum(1 for v in gs if v >= 0)

    def inside(c, gs):
        return c % 2 == 1 or (c == K and (K == 1 or gs[-1] == gs[-2]))

    g_prev, t_prev = list(g0), t0
    pending = None  # [age, c before the entry (after a clip), bracket, e, clip]
    for k in range(1, steps + 1):
        t = dt(k) if callable(dt) else t0 + dt * k
        if t_max is not None:
            t = min(t, t_max)
        gs = list(g(t))
        c, c_prev = count(gs), count(g_prev)
        ins, in_prev = inside(c, gs), inside(c_prev, g_prev)
        if pending is not None:
            pending[0] += 1
            age, c_pend, br, e, clip = pending
            if clip:  # waiting for c to stay put after a clip
                if c != c_pend:
                    pending = None
                elif age >= hold:
                    return br, e
            elif age >= hold:
                return br, e
            elif not ins:
                if c > c_pend:
                    pending = None  # left to the far side: skin
                elif hold <= 0:
                    return br, e
                else:
                    pending = [0, c, br, e, True]
        if pending is None and ins and not in_prev:
            e = min(c, c_prev)
            pending = [0, c_prev, Bracket(t_prev, g_prev[e], t, gs[e], True), e, False]
            if hold <= 0:
                return pending[2], e
        g_prev, t_prev = gs, t
    if pending is not None:
        return pending[2], pending[3]
    fill = tuple(default) if default is not None else (t0, g0[0], t0, g0[0])
    return Bracket(*fill, False), 0
