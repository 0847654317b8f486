"""The hierarchical march of the searches in :mod:`study.methods.search`: blocks of samples that a min pyramid
(:mod:`study.impostor.pyramid`) proves to lie in front of every surface are skipped in one lookup, and a ray stops
at its crossing; see :class:`Skip`. Written against the array backend (numpy and Dr.Jit): one per-lane loop
(:meth:`study.backend.Backend.while_loop`) whose body reads either a block's bound or the next sample
(:meth:`study.backend.Backend.branch`: a ray pays only the lookup of its own side). It registers no method.

A step is bound by the instructions it issues rather than by its reads, so it makes each value once: sample
k + 1 (its :class:`Look`) before the branch, for either side; the arc's sine and cosine from tables
(:meth:`study.methods.search.arc_samples.tabulate`); no arc point for a jump (:attr:`Skip.shared`); loop invariants
before the loop; the pyramid's level made from its index, not read (:attr:`study.impostor.pyramid.MinPyramid.made`);
no clamp that a value already obeys (t ≤ 1, k ≤ n, the face edges ≤ n); the lookups from the loop's own count where
each iteration is one; each with the same operations as a value made where it is used, so hits, validity and
lookups are the same bits. ``scripts/march_ir.py`` counts the loop's instructions (linear_secant: 371 for both sides of
the branch, 59 of them the bilinear lookup that CUDA makes in one texture instruction), ``scripts/march_side.py``
times it against another tree.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any, NamedTuple


class Direct:
    """A sampler read at per-ray k (its ``direct``), with no state: the samples of a hierarchical march."""

    state: tuple = ()

    def __init__(self, smp):
        self.smp = smp
        if hasattr(smp, "tabulate"):  # before the loop: its body must not evaluate
            smp.tabulate()

    def at(self, k, state):
        return self.smp.direct(k), state


class Skip:
    """How a search skips samples: ``reach(k, k_b, t_a, t_b)`` → (N,) the last sample of k + 1 … k_b (at t_a …
    t_b) up to which every function searched is proven < 0 (in front of every surface: no crossing, no entry),
    from one read of a min pyramid (:meth:`study.impostor.pyramid.MinPyramid.bound`); k where none is, k_b where
    the whole block is. After the search, ``lookups`` holds per ray the lookups the march spent: pyramid reads,
    samples read × functions, and the re-read of the bracket's start (g0 not included).

    The march (Hi-Z style): a block of w samples after the last one read (first :data:`FIRST`: the widest) is tried
    in one pyramid read; cleared, the march jumps over it and doubles w; cleared part of the way (the bound holds
    the ray off the surface up to a point inside the block), it jumps there and tries w = 2 next; not cleared at
    all, it halves w; at w = 1 it reads the next sample as the texel march does, and tries w = 2 next, or, where a
    block of 2 was just not cleared (the ray is at a surface), after reading one more sample alone. A ray stops at
    its crossing (its kept entry). Only cleared samples are skipped, so the bracket is the texel march's (the
    samples come from :meth:`Samples.direct`, equal to the march's up to rounding); the bracket's start, when
    skipped, is read once after the march.
    ``edge(k)`` (optional) → (N,) the last sample on the face of sample k + 1 (≤ n): a block is cut there, as the
    pyramid bounds one face at a time (a block across an edge is never cleared, so cutting it loses nothing).
    At most :func:`iterations` iterations, each one lookup per function at most.
    ``look(t)`` (optional) → the :class:`Look` of the sample at t, read by both sides of an iteration (the sample
    read as the block's start): the march makes it once per iteration, before the branch (a GPU warp whose lanes
    take both sides computes it once, not twice), and hands it to ``reach`` (as ``t_a``) and to the sample read
    (``step(k, *state, look=…)``), which then make the same values from it as they would from t; ``value(look)``
    (set by the method that searches: g at the Look, the same bits as g(t)) is what the sample read reads then.
    Without ``value`` the march makes no Look."""

    def __init__(self, reach: Callable, edge: Callable | None = None, look: Callable | None = None):
        self.reach, self.edge, self.look, self.lookups = reach, edge, look, None
        self.value: Callable | None = None
        self.last = None  # after the march: per ray, the sample it stopped at (read or jumped to)

    @property
    def shared(self) -> bool:
        """The march makes a :class:`Look` per step (``look`` and ``value`` given); then a jump leaves the state's
        t_prev as it was (``jumped(ok, None, …)``: no arc point is made for it) and the sample read gives the
        search its k in place of t_prev (the bracket's start holds a sample index, made t by :func:`t_of` after
        the march)."""
        return self.look is not None and self.value is not None


def t_of(B, smp, k, t0, t_max):
    """t of sample k per ray (``smp.direct``, clamped to ``t_max``), t0 at k = 0: what t_prev holds at sample k in
    a march that makes it at every read and jump, the same bits (with :attr:`Skip.shared` the march keeps k)."""
    t = smp.direct(k)
    t = B.minimum(t, t_max) if t_max is not None else t
    return B.select(k > 0.0, t, t0)


class Look(NamedTuple):
    """A sample's lookup, shared by the sample read and the pyramid read: t, the ray point p(t), |p|, p's face
    coordinates (:func:`study.impostor.cubemap.face_uv`; the face offset by the map's first face in a stack), and
    1 − t."""

    t: Any
    p: Any
    length: Any
    face: Any
    u: Any
    v: Any
    rest: Any


#: The first block a march tries, in samples: None, the widest (≥ n: the rest of the arc's first face, as every
#: block is cut at the face's edge). Most rays start far in front of every surface (a reflection ray's first
#: stretch), so one pyramid read clears the face or jumps part of it at once. Mean lookups per ray of linear_secant
#: by the first block (scripts/march_rules.py: LLVM, 512² rays, cube 256², no second read at a surface): fig4's
#: close-up 16.11 (16), 14.59 (64), 13.46 (the widest); random rays near o 18.83, 17.17, 15.82.
FIRST: int | None = None
#: Where a block of 2 after a sample read was not cleared, read one more sample alone before trying 2 again
#: (False: try 2 after every read); see :func:`march`.
AT_SURFACE = True


def iterations(steps: int) -> int:
    """The most iterations of the hierarchical march over ``steps`` samples: a sample read or a jump (the whole
    block or part of it) at most ``steps`` times, each followed by at most one halving, and the halvings of the
    first block (from the widest, 2^bitlength(steps − 1), down to 1)."""
    return 2 * steps + max(steps - 1, FIRST or 1).bit_length() + 2


def every(masks):
    """The lanes where every mask holds."""
    out = masks[0]
    for m in masks[1:]:
        out = out & m
    return out


def reread(B, g: Callable, value, t):
    """``value`` where a sample was read, g(t) where a skip left it unread (−∞)."""
    return B.select(value == -math.inf, g(t), value)


def march(B, smp, n: int, t_max, state, step, skip: Skip, *, G, done, busy, jumped, cost=None, active=None):
    """The march of :class:`Skip`: ``step(k, *state)`` reads sample k + 1 as the texel march's loop body does,
    ``jumped(ok, t_b, *state)`` is the state after a jump to the sample t_b where ``ok`` (t_b None: with
    :attr:`Skip.shared`); ``done(*state)`` stops a
    ray, ``busy(*state)`` (or None) keeps it reading sample by sample; ``cost(*state)`` (or None: G) the lookups
    of the sample read that led to ``state``; ``active`` (a mask, or None: every ray) the rays that march, the
    others start at sample n (no iteration: a GPU warp none of whose rays marches ends at once). Returns the final
    state; sets ``skip.lookups``."""
    zero = state[0] * 0.0
    two, half = zero + 2.0, zero + 0.5  # (a literal would be made again in every step)
    top = float(1 << max(n - 1, 0).bit_length())  # the widest block: ≥ n samples
    if isinstance(t_max, float) and smp.top is not None and smp.top <= t_max:
        t_max = None  # no t above it: the clamp leaves every t as it is

    def t_at(k):  # k ≤ n on every lane that runs
        t = smp.direct(k, within=True)
        return B.minimum(t, t_max) if t_max is not None else t

    # the lookups spent, in the state (none where each iteration is one lookup: the loop counts them)
    ns = 0 if cost is None and G == 1 else 1

    def fine(k, w, *s, la=None):  # the next sample, as the texel march reads it
        spent, s = s[:ns], s[ns:]
        s = step(k, *s) if la is None else step(k, *s, look=la)
        # w = 1: the block of 2 after the previous read was not cleared (the ray is at a surface, and its next block
        # of 2 mostly fails too: a pyramid read for nothing): read one more sample alone (w = ½, which no halving
        # reaches) before trying 2 again (AT_SURFACE; scripts/march_rules.py measures it). Reading every sample alone
        # from then on saves no more, and a ray that grazes a surface early would read sample by sample to the end.
        after = B.select(w == 1.0, half, two) if AT_SURFACE else two
        return (k + 1.0, after, *(x + (cost(*s) if cost is not None else float(G)) for x in spent), *s)

    def coarse(k, w, *s, la=None):  # a block of w samples in one pyramid read
        spent, s = s[:ns], s[ns:]
        # not past n, nor across a face's edge (the edge ≤ n)
        kb = B.minimum(k + w, float(n)) if skip.edge is None else B.minimum(k + w, skip.edge(k))
        # the last sample proven in front: k (none) … kb (all)
        kn = skip.reach(k, kb, t_at(k + 1.0) if la is None else la, t_at(kb))
        whole, part = kn >= kb, kn > k
        w = B.select(whole, B.minimum(w * 2.0, top), B.select(part, two, w * 0.5))
        return (kn, w, *(x + 1.0 for x in spent), *jumped(part, t_at(kn) if la is None else None, *s))

    def body(k, w, *s):
        fine_now = (w <= 1.0) | busy(*s[ns:]) if busy is not None else w <= 1.0
        if not skip.shared:
            return B.branch(fine_now, (k, w, *s), fine, coarse)
        la = skip.look(t_at(k + 1.0))  # sample k + 1: either side reads it
        return B.branch(fine_now, (k, w, *s), lambda *a: fine(*a, la=la), lambda *a: coarse(*a, la=la))

    k0 = zero if active is None else B.select(active, zero, zero + float(n))
    out = B.while_loop(
        (k0, zero + (top if FIRST is None else float(min(FIRST, top))), *(zero,) * ns, *state),
        lambda k, w, *s: (k < float(n)) & ~done(*s[ns:]),
        body,
        limit=iterations(n),
        counted=ns == 0,
    )
    # (the loop's count, k, w, state) or (k, w, spent, state)
    skip.lookups = (out[0] if ns == 0 else out[2]) + float(G)  # + the re-read of the bracket's start
    skip.last = out[1 - ns]
    return out[3:]
