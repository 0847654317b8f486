"""The search core of the methods that march along a ray and then refine: a linear search for sign changes of a
function g(t) on uniform samples, then secant (regula falsi) steps inside the bracket found, by default with the
Illinois rule. Written once against the array backend (:mod:`study.backend`), so it runs on numpy and Dr.Jit; used
by :mod:`study.methods.linear_secant`, :mod:`study.methods.layered` and the object's own distance map
(:class:`study.optics.distance_map.DistanceMap`). It registers no method.

Contract (backend ``B``, N rays, every array 1-D float32 of length N unless said otherwise):
    g        callable t ↦ g(t) (an (N,) array of t → an (N,) array). For :func:`first_crossing` and
             :func:`sign_changes` it may instead return a list of arrays: several functions sampled at the same t
             (the layers of a layered map), searched in one pass (one kernel per step on Dr.Jit); ``g0`` is then a
             list too and so is the result, one entry per function. :func:`first_entry` always takes a list.
    t0, g0   start of the search and g(t0). g0 is passed in, not evaluated here: the caller counts that lookup and
             may adjust it (the distance map forces its start to count as g < 0).
    dt       step per ray ((N,) array or float); samples t_k = t0 + k dt for k = 1..``steps``, each clamped to
             ``t_max`` when given (a ray whose range ends earlier repeats t_max). Or a :class:`Samples` that makes
             the t_k inside the loop (:func:`arc_samples`: equal angles along the arc of the t = d/(d+a)
             parameterization). g is evaluated ``steps`` times on every ray: the cost of the scan is ``steps``
             lookups per function, plus the caller's g0.
    default  (t_lo, g_lo, t_hi, g_hi): the bracket of rays where no sign change is found; None: the whole range,
             (t0, g0, last sample, g at it).

A :class:`Bracket` (t_lo, g_lo, t_hi, g_hi, found) holds two consecutive samples t_lo < t_hi with the sign
change between them where ``found`` ((N,) bool), the default elsewhere. "Sign" means g < 0 against g ≥ 0:
:func:`first_crossing` finds the first step from g < 0 to g ≥ 0 (the ray passes from in front of a surface to
behind it), :func:`sign_changes` the first ``count`` changes in either direction, :func:`first_entry` the first
step into the inside of nested surfaces (the layers of a layered map) that is not skin. :func:`refine` spends
``steps`` more evaluations of g on secant steps inside a bracket and returns the final bracket;
:func:`secant_point` gives its secant point t_lo − g_lo (t_hi − t_lo) / (g_hi − g_lo), the estimate of the root
(not finite where g_hi = g_lo, as on a bracket without a sign change).

Hierarchical march: :func:`first_crossing` and :func:`first_entry` take ``skip`` (a :class:`~study.methods.march.Skip`
that proves blocks of samples free of crossings from a min pyramid); they then read the same samples at per-ray k
(:meth:`Samples.direct`), skip what it proves, stop each ray at its crossing and give the texel march's bracket
(:mod:`study.methods.march`); ``skip.lookups`` then holds the lookups each ray spent.

Every search and the secant steps are one loop through the backend (:meth:`study.backend.Backend.loop`): on Dr.Jit
one symbolic loop (``dr.while_loop``), so a march of n samples is one kernel whose state stays in registers, not
n kernels that write and read the whole state back; on numpy a Python loop, with the same operations in the same
order. g is traced once and must not evaluate (no ``B.eval``, no transfer to the host); the arrays it reads are
captured. Each search function has a slow, obvious ``_ref`` twin (one ray, plain Python floats) in
:mod:`study.methods.search_ref` that the tests compare it with; :func:`arc_samples` is checked against the arc's
geometry.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any, NamedTuple

from study.methods.march import Direct, Skip, every, march, reread, t_of


class Bracket(NamedTuple):
    t_lo: Any  # the last sample before the sign change
    g_lo: Any  # g(t_lo)
    t_hi: Any  # the first sample after it
    g_hi: Any  # g(t_hi)
    found: Any  # a sign change was found (else the bracket is the default)


def secant_point(b: Bracket):
    """t where the chord through (t_lo, g_lo) and (t_hi, g_hi) crosses zero (arrays or floats)."""
    return b.t_lo - b.g_lo * (b.t_hi - b.t_lo) / (b.g_hi - b.g_lo)


# ---------------------------------------------------------------------------------------------- samples along t
class Samples:
    """The samples t_k (k = 1..steps) of a search, made inside its loop: ``state`` is the tuple of arrays carried
    from step to step, ``at(k, state)`` returns (t_k, the next state); k is a Python int on numpy and in unrolled
    loops, a Dr.Jit Float in a symbolic loop. Calling the object, ``samples(k)`` for k = 1, 2, … in order, gives
    the same t_k outside a loop."""

    state: tuple = ()
    top: float | None = None  # the largest t it gives (None: not known); a clamp to t_max ≥ top is left out

    def at(self, k, state):
        raise NotImplementedError

    def __call__(self, k):
        if k == 1 or not hasattr(self, "_seq"):
            self._seq = self.state
        t, self._seq = self.at(k, self._seq)
        return t

    def direct(self, k, within: bool = False):
        """t_k for a per-ray k (an array), no state, as a search that skips reads it (``within``: k ≤ steps)."""
        raise NotImplementedError


class _Uniform(Samples):
    def __init__(self, t0, dt):
        self.t0, self.dt = t0, dt

    def at(self, k, state):
        return self.t0 + self.dt * k, state  # t0 + k dt (k exact in float32)

    def direct(self, k, within: bool = False):
        return self.t0 + self.dt * k


def _samples(t0, dt) -> Samples:
    return dt if isinstance(dt, Samples) else _Uniform(t0, dt)


def _next(B, smp: Samples, k, state, t_max):
    """The sample of loop iteration k (0-based: t_{k+1}), clamped to ``t_max``, and the sampler's next state."""
    t, state = smp.at(k + 1, state)
    return (B.minimum(t, t_max) if t_max is not None else t), state


def _read(B, g, smp: Samples, k, state, t_max, skip, look):
    """(t_{k+1}, g there, the sampler's next state); from the hierarchical march's Look of that sample if given."""
    if look is not None:
        return look.t, skip.value(look), state
    t, state = _next(B, smp, k, state, t_max)
    return t, g(t), state


class arc_samples(Samples):  # noqa: N801 - used as a function
    """Samples in equal angles along the arc that the t = d/(d+a) parameterization walks (p(t) = (1 − t) x + t a R
    turns from x̂ to R; θ the angle between them, ``cos_theta`` = x̂·R per ray): t_k for k = 1..``steps``
    where p(t_k) has turned by φ_k = k π/``steps`` (a half turn in ``steps`` steps), t_k = 1 from the arc's end on
    (φ_k ≥ θ). On the arc t(φ) = sin φ / (sin φ + sin(θ − φ)) = sin φ / (sin θ cos φ + (1 − cos θ) sin φ), so a
    step never turns the lookup direction by more than π/``steps`` (uniform steps in t turn it up to
    1/cos²(θ/2) times faster in the middle of the arc than at its ends). (cos φ_k, sin φ_k) is the state, carried
    from step to step by a rotation by π/``steps`` (the same constants at every step, and no data from the host,
    so that a frozen function can replay it); t is homogeneous in it, so the rounding drift of its length
    cancels."""

    def __init__(self, B, cos_theta, steps: int, table=None):
        c = cos_theta
        self.B, self.c, self.steps, self.table = B, c, steps, table  # table: tabulate()'s (or another's)
        self.s, self.c1 = B.sqrt(B.maximum(1.0 - c * c, 0.0)), 1.0 - c  # sin θ, 1 − cos θ, made once
        self.one, self.top = c * 0.0 + 1.0, 1.0  # t ≤ 1
        self.cd, self.sd = math.cos(math.pi / steps), math.sin(math.pi / steps)
        big = B.maximum(c, 2.0)  # = 2, but computed: Dr.Jit must not fold the rotation
        self.state = (big * 0.5, big - 2.0)  # cos φ_0, sin φ_0 (φ_0 = 0), not literals

    def at(self, k, state):
        B, c = self.B, self.c
        end = k >= self.steps  # φ = π: every arc has ended
        if end is True:
            return self.one, state
        cp, sp = state
        cp, sp = cp * self.cd - sp * self.sd, sp * self.cd + cp * self.sd
        t = sp / B.maximum(self.s * cp + self.c1 * sp, 1e-30)
        t = B.select(cp > c, B.minimum(t, 1.0), self.one)
        if end is not False:
            t = B.select(end, self.one, t)
        return t, (cp, sp)

    def tabulate(self):
        """On Dr.Jit, before a loop: cos φ_k, sin φ_k (k = 0 … steps) in tables, made as :meth:`direct` makes them
        (the same bits), read there with a gather each for a sine and a cosine (~90 instructions) per sample; cos
        φ_steps is −2 (not −1), below every cos θ, so that the arc's end gives t = 1 with no test of k."""
        B = self.B
        if B.name != "numpy" and self.table is None:
            phi = (j := B.arange(self.steps + 1)) * (math.pi / self.steps)
            self.table = (B.select(j < float(self.steps), B.cos(phi), phi * 0.0 - 2.0), B.sin(phi))
            B.eval(*self.table)

    def direct(self, k, within: bool = False):
        """t_k with φ_k = k π/steps from sin and cos (the rotation's value up to rounding; :meth:`tabulate`'s)."""
        B, c = self.B, self.c
        if self.table is not None:
            i = k if within else B.minimum(k, float(self.steps))  # k ≥ steps: the table's end, cos −2: t = 1
            cp, sp = B.gather(self.table[0], i), B.gather(self.table[1], i)
        else:
            phi = k * (math.pi / self.steps)
            cp, sp = B.cos(phi), B.sin(phi)
        t = sp / B.maximum(self.s * cp + self.c1 * sp, 1e-30)
        t = B.select(cp > c, B.minimum(t, 1.0), self.one)
        return t if self.table is not None else B.select(k >= float(self.steps), self.one, t)

    def __call__(self, k):
        t = super().__call__(k)
        self.B.eval(t, *self._seq)  # outside a loop: keep Dr.Jit's graph short
        return t


# ---------------------------------------------------------------------------------------------- linear search
def first_crossing(
    B, g: Callable, t0, g0, dt, steps: int, *, t_max=None, default=None, skip=None, active=None
):
    """The first step from g < 0 to g ≥ 0: a :class:`Bracket` (a list of them when g returns a list). With
    ``skip``, the hierarchical march (:class:`Skip`): the same bracket, from fewer lookups; ``active`` (a mask, with
    ``skip``): the rays that march, the others read no sample (their bracket is ``default``'s, not found)."""
    return _scan(
        B, g, t0, g0, dt, steps, t_max=t_max, default=default, count=1, rising=True, first=True, skip=skip,
        active=active,
    )  # fmt: skip


def sign_changes(
    B,
    g: Callable,
    t0,
    g0,
    dt,
    steps: int,
    *,
    count: int = 2,
    t_max: float | None = None,
    default: tuple | None = None,
):
    """The first ``count`` sign changes in either direction (g < 0 → g ≥ 0 or back), in order along t: a list of
    ``count`` :class:`Bracket`\\ s (a list of such lists, one per function, when g returns a list)."""
    return _scan(
        B, g, t0, g0, dt, steps, t_max=t_max, default=default, count=count, rising=False, first=False
    )


def _scan(B, g, t0, g0, dt, steps, *, t_max, default, count, rising, first, skip=None, active=None):
    many = isinstance(g0, (list, tuple))
    G = len(g0) if many else 1
    never = B.isfinite(t0) & ~B.isfinite(t0)  # all False
    smp = _samples(t0, dt) if skip is None else Direct(_samples(t0, dt))
    # per function, per crossing: found, t_lo, g_lo, t_hi, g_hi (the default, or a placeholder until the end)
    start = [tuple(default) if default is not None else (t0, gp, t0, gp) for gp in (g0 if many else [g0])]
    state = (
        t0,
        *(g0 if many else [g0]),
        *(v for s in start for _ in range(count) for v in (never, *s)),
        *smp.state,
    )  # t_prev, g_prev per function, the crossings, the sampler's
    ns = len(smp.state)

    def step(k, t_prev, *rest, look=None):
        g_prev, flat, sst = list(rest[:G]), rest[G : len(rest) - ns], rest[len(rest) - ns :]
        t, gts, sst = _read(B, g, smp, k, sst, t_max, skip, look)
        gts = gts if many else [gts]
        out = []
        for i, gt in enumerate(gts):
            change = (g_prev[i] < 0.0) & (gt >= 0.0) if rising else (g_prev[i] < 0.0) != (gt < 0.0)
            before = None  # found of the previous crossing, before this step
            for j in range(count):
                f, *b = flat[(i * count + j) * 5 : (i * count + j + 1) * 5]
                new = change & ~f if before is None else change & before & ~f
                before = f
                lo = t_prev if look is None else k  # Skip.shared: sample k's index, its t after the march
                out += [f | new, *(B.select(new, v, o) for v, o in zip((lo, g_prev[i], t, gt), b))]
        return (t, *gts, *out, *sst)

    if skip is None:
        t_last, *rest = B.loop(steps, state, step, index=True)
    else:  # count = 1, rising: done where every function's crossing is found
        t_last, *rest = march(
            B,
            smp.smp,
            steps,
            t_max,
            state,
            step,
            skip,
            G=G,
            active=active,
            done=lambda *s: every([s[1 + G + 5 * i] for i in range(G)]),
            busy=None,
            jumped=lambda ok, t_b, t_prev, *s: (
                t_prev if t_b is None else B.select(ok, t_b, t_prev),
                *(B.select(ok, -math.inf, gp) for gp in s[:G]),
                *s[G:],
            ),
        )
    g_last, flat = rest[:G], rest[G : len(rest) - ns]
    cross = [[flat[(i * count + j) * 5 : (i * count + j + 1) * 5] for j in range(count)] for i in range(G)]
    if skip is not None:  # g at a bracket's start that a skip left unread (−∞): one more read of each
        pick = (lambda i: lambda t: g(t)[i]) if many else (lambda i: g)
        if skip.shared:  # the brackets' starts hold sample indices (found) or the default
            cross = [[(f, B.select(f, t_of(B, smp.smp, lo, t0, t_max), lo), *b)] for ((f, lo, *b),) in cross]
            t_last = t_of(B, smp.smp, skip.last, t0, t_max)
        cross = [
            [[f, t_lo, reread(B, pick(i), g_lo, t_lo), t_hi, g_hi]]
            for i, ((f, t_lo, g_lo, t_hi, g_hi),) in enumerate(cross)
        ]
        if default is None:
            g_last = [reread(B, pick(i), gl, t_last) for i, gl in enumerate(g_last)]
            skip.lookups = skip.lookups + G
    # ----------------------------------------------------------------------- rays without a crossing
    if default is None:  # the whole range: (t0, g0, last sample, g there)
        cross = [
            [
                [f, t_lo, g_lo, B.select(f, t_hi, t_last), B.select(f, g_hi, gp)]
                for f, t_lo, g_lo, t_hi, g_hi in c
            ]
            for c, gp in zip(cross, g_last)
        ]
    out = [[Bracket(t_lo, g_lo, t_hi, g_hi, f) for f, t_lo, g_lo, t_hi, g_hi in c] for c in cross]
    out = [c[0] for c in out] if first else out
    return out if many else out[0]


def first_entry(
    B,
    g: Callable,
    t0,
    g0: list,
    dt,
    steps: int,
    *,
    hold: int,
    t_max: float | None = None,
    default: tuple | None = None,
    skip: Skip | None = None,
    cost: Callable | None = None,
):
    """The first step into the inside of nested surfaces that is not skin: a (:class:`Bracket`, e) pair. With
    ``skip``, the hierarchical march (:class:`Skip`, proving g_0 < 0: in front of every surface); ``cost(g_0)``:
    the lookups of a sample read, given g_0 there (default K; g may read the other layers only where g_0 ≥ 0 and
    return g_0 for them elsewhere, which leaves c and the entries as they are).

    ``g`` returns K functions ordered g_0 ≥ g_1 ≥ … (the layers of a layered map, nearest first: behind layer k
    means behind every nearer one). At each sample, c = how many have g ≥ 0 (the layers the point is behind);
    the point is *inside* where c is odd (between a surface facing o and the next, facing away: inside a solid),
    or where c = K and the last two functions are equal (the last layer repeats the one before: the room's wall,
    beyond which all is solid; behind a last layer of its own, a solid's far face, the point is outside).

    An entry is a step from outside to inside; it is *kept* when the ray is still inside ``hold`` samples later, or
    comes back out in front (c back at or below its value before the entry: the ray clipped a solid's edge) and c
    then stays put for ``hold`` samples; it is *dropped* when the ray leaves to the far side first (c above it: the
    ray passed behind a silhouette, through the skin that bilinear interpolation stretches across the depth jump of
    two layers at once), or when c changes again within ``hold`` samples of such a clip (the bilinear skin is a
    saddle that a ray can cut twice within a texel); the search then goes on. An entry still pending at the last
    sample is kept.

    The bracket is that of the function e whose sign changed at the entry (e = c before the entry where c rose,
    c after it where c fell; an (N,) float array), on the kept entry's two samples; ``default`` (or the start,
    as for :func:`sign_changes`) and e = 0 where none was kept. Cost: ``steps`` evaluations of every function."""
    K = len(g0)
    zero = t0 * 0.0

    def count(gs):
        c = zero
        for gi in gs:
            c = c + B.select(gi >= 0.0, zero + 1.0, zero)
        return c

    def inside(c, gs):
        m = (c == float(K)) & (gs[-1] == gs[-2]) if K > 1 else c == float(K)
        for v in range(1, K + 1, 2):
            m = m | (c == float(v))
        return m

    def pick(gs, e):  # gs[e] per ray
        out = gs[-1]
        for i in range(K - 2, -1, -1):
            out = B.select(e == float(i), gs[i], out)
        return out

    g_prev, c_prev = list(g0), count(g0)
    in_prev = inside(c_prev, g_prev)
    never = in_prev & ~in_prev
    res = (*(default if default is not None else (t0, pick(g0, zero), t0, pick(g0, zero))), zero)
    smp = _samples(t0, dt) if skip is None else Direct(_samples(t0, dt))
    # state: g_prev (K), c_prev, in_prev, t_prev, found, pend, clip, age, c_pend, res (5), pb (the pending entry:
    # t_lo, g_lo, t_hi, g_hi, e; 5), the sampler's
    state = (*g_prev, c_prev, in_prev, t0, never, never, never, zero, zero, *res, *res, *smp.state)

    def step(k, *s, look=None):
        g_prev, (c_prev, in_prev, t_prev, found, pend, clip, age, c_pend) = list(s[:K]), s[K : K + 8]
        res, pb, sst = s[K + 8 : K + 13], s[K + 13 : K + 18], s[K + 18 :]
        t, gs, sst = _read(B, g, smp, k, sst, t_max, skip, look)
        gs, lo = list(gs), (t_prev if look is None else k)  # Skip.shared: lo is sample k's index (t after)
        c = count(gs)
        ins = inside(c, gs)
        # ---------------------------------------------------- decide the pending entries
        age = age + 1.0
        held = pend & ~clip & (age >= float(hold))  # still inside (or through) after hold
        out = pend & ~clip & ~held & ~ins
        back = out & (c <= c_pend)  # came back out in front: a clip …
        quiet = clip & (c == c_pend) & (age >= float(hold))  # … kept once c stays put for hold
        drop = (out & ~back) | (clip & (c != c_pend))
        keep = held | quiet | (back if hold <= 0 else never)
        res = tuple(B.select(keep, v, r) for v, r in zip(pb, res))
        found, pend = found | keep, pend & ~keep & ~drop
        clip = pend & (clip | back)
        c_pend, age = B.select(back, c, c_pend), B.select(back, zero, age)
        # ---------------------------------------------------- a new entry
        new = ~found & ~pend & ins & ~in_prev
        e = B.select(c > c_prev, c_prev, c)
        pb = tuple(B.select(new, v, o) for v, o in zip((lo, pick(g_prev, e), t, pick(gs, e), e), pb))
        c_pend, age, pend = B.select(new, c_prev, c_pend), B.select(new, zero, age), pend | new
        if hold <= 0:
            res, found, pend = tuple(B.select(new, v, r) for v, r in zip(pb, res)), found | new, pend & ~new
        return (*gs, c, ins, t, found, pend, clip, age, c_pend, *res, *pb, *sst)

    if skip is None:
        s = B.loop(steps, state, step, index=True)
    else:  # a skipped block is in front of every layer: c = 0, outside, the g's unread (−∞)
        s = march(
            B,
            smp.smp,
            steps,
            t_max,
            state,
            step,
            skip,
            G=K,
            done=lambda *s: s[K + 3],
            busy=lambda *s: s[K + 4],
            cost=(lambda *s: cost(s[0])) if cost is not None else None,
            jumped=lambda ok, t_b, *s: (
                *(B.select(ok, -math.inf, gp) for gp in s[:K]),
                B.select(ok, zero, s[K]),
                s[K + 1] & ~ok,
                s[K + 2] if t_b is None else B.select(ok, t_b, s[K + 2]),
                *s[K + 3 :],
            ),
        )
    found, pend, res, pb = s[K + 3], s[K + 4], s[K + 8 : K + 13], s[K + 13 : K + 18]
    res, found = tuple(B.select(pend, v, r) for v, r in zip(pb, res)), found | pend
    if skip is not None:  # g at the bracket's start that a skip left unread: one more read of every layer
        lo = B.select(found, t_of(B, smp.smp, res[0], t0, t_max), res[0]) if skip.shared else res[0]
        gt = list(g(lo))
        res = (lo, reread(B, lambda t: pick(gt, res[4]), res[1], lo), *res[2:])
        if cost is not None:  # the re-read's own cost (the march counted K)
            skip.lookups = skip.lookups + (cost(gt[0]) - float(K))
    return Bracket(*res[:4], found), res[4]


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


def refine(
    B, g: Callable, bracket: Bracket, steps: int, *, illinois: bool = True, rising: bool = False
) -> Bracket:
    """``steps`` secant steps inside ``bracket`` (one evaluation of g each): the secant point t replaces the end
    on its side of the sign change, the end whose g has the same sign (g < 0 or g ≥ 0); with ``rising`` (the
    bracket is known to run from g < 0 to g ≥ 0, as from :func:`first_crossing`), the lo end where g(t) < 0 — the
    same choice where a sign change was found. With ``illinois``, an end replaced twice in a row halves the other
    end's g (plain false position stalls on one side). Returns the final bracket (``found`` passed through); its
    :func:`secant_point` is the estimate."""
    t_lo, g_lo, t_hi, g_hi, found = bracket

    def step(t_lo, g_lo, t_hi, g_hi, side):  # side: +1 the last step replaced the lo end, −1 hi, 0 none
        t = t_lo - g_lo * (t_hi - t_lo) / (g_hi - g_lo)  # secant point
        gt = g(t)
        replace_lo = (gt < 0.0) if rising else ((gt < 0.0) == (g_lo < 0.0))
        return secant_update(B, replace_lo, t, gt, t_lo, g_lo, t_hi, g_hi, side, illinois=illinois)

    t_lo, g_lo, t_hi, g_hi, _ = B.loop(steps, (t_lo, g_lo, t_hi, g_hi, t_lo * 0.0), step)
    return Bracket(t_lo, g_lo, t_hi, g_hi, found)
