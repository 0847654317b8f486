"""Linear search then secant steps (Umenhoffer, Patow, Szirmay-Kalos, GPU Gems 3 ch. 17, 2007).

The ray x + R d is parameterized by t ∈ [0, 1]: d(t) = a t / (1 − t) with a = |x|, so that the ray point is
p(t) / (1 − t) with p(t) = (1 − t) x + t a R; uniform steps in t walk the great-circle arc from x̂ to R on the
direction sphere. The step count of a ray comes from the arc length, n = max(n_max (1 − x̂·R) / 2, n_min).

The surface test is written on p, which stays finite up to t = 1 (the point at infinity in direction R):
g(t) = |p(t)| − (1 − t) |p(t)'| (|v'| the stored distance towards v), g < 0 in front of the environment surface
("undershoot", the paper's |l|/|l'| < 1), g > 0 behind it. g(1) = a > 0, so every ray that starts in front of the
surface has a crossing.

Phases: (1) linear search for the FIRST pair of consecutive samples with g < 0 then g ≥ 0; (2) ``secant_steps``
secant (false-position) steps on g inside that bracket, keeping the side by the sign of g, by default with the
Illinois rule (when the same end is replaced twice in a row, the other end's g is halved; plain false position
stalls on one side and left errors of centimetres after 10 steps on a column face); the result is the secant
point of the final bracket. The secant works on g(t) instead of the chapter's q(d) because q is infinite at
t = 1; both vanish at the same points. Invalid (NaN shown point) where no crossing is found (x itself behind the
environment surface and the ray never comes out in front of it).
"""
from __future__ import annotations

import math
from typing import Annotated

from pydantic import BaseModel, ConfigDict, Field, model_validator

from study.methods.base import Localization, Method, register


class LinearSearchParams(BaseModel):
    """The linear search's step counts (shared with ``layered``)."""
    model_config = ConfigDict(extra="forbid", frozen=True)
    linear_steps: Annotated[int, Field(ge=1, le=4096)] = 30     # n_max: steps for a half-turn arc
    min_linear_steps: Annotated[int, Field(ge=1, le=4096)] = 10  # n_min

    @model_validator(mode="after")
    def _order(self):
        if self.min_linear_steps > self.linear_steps:
            raise ValueError("min_linear_steps must not exceed linear_steps")
        return self


class Params(LinearSearchParams):
    secant_steps: Annotated[int, Field(ge=0, le=100)] = 4        # secant lookups after the linear search
    illinois: bool = True                                        # Illinois rule against one-sided stagnation


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


@register
class LinearSecant(Method):
    name = "linear_secant"
    Params = Params

    def localize(self, B, env, x, R):
        p = self.params
        # ------------------------------------------------------------- parameterization and step count
        xl = B.length(x)                               # |x|
        a = B.maximum(xl, 1e-6)                        # a = |x| (kept > 0: rays from o walk along R itself)
        cos = x.dot(R) / a                             # x̂·R
        n = B.maximum(p.linear_steps * (1.0 - cos) * 0.5, float(p.min_linear_steps))
        dt = 1.0 / B.minimum(n, float(p.linear_steps))  # step in t of this ray

        def g(t):
            pt = x * (1.0 - t) + R * (a * t)           # p(t)
            return B.length(pt) - (1.0 - t) * env.distance(pt)

        # ------------------------------------------------------------- linear search for the first crossing
        zero = xl * 0.0
        t_prev, g_prev = zero, g(zero)                 # sample k − 1
        found = g_prev != g_prev                       # all False
        t_l, g_l, t_p, g_p = zero, g_prev, zero + 1.0, a   # bracket: last undershoot, first overshoot
        for k in range(1, p.linear_steps + 1):
            t = B.minimum(dt * float(k), 1.0)
            gt = g(t)
            cross = ~found & (g_prev < 0.0) & (gt >= 0.0)
            t_l, g_l = B.select(cross, t_prev, t_l), B.select(cross, g_prev, g_l)
            t_p, g_p = B.select(cross, t, t_p), B.select(cross, gt, g_p)
            found = found | cross
            t_prev, g_prev = t, gt
            B.eval(t_l, g_l, t_p, g_p, found, g_prev)  # one small kernel per step (Dr.Jit compiles it fast)

        # ------------------------------------------------------------- secant steps inside the bracket
        def secant():
            return t_l - g_l * (t_p - t_l) / (g_p - g_l)

        side = zero                                    # +1: last step replaced t_l, −1: t_p, 0: none yet
        for _ in range(p.secant_steps):
            t = secant()
            gt = g(t)
            t_l, g_l, t_p, g_p, side = secant_update(B, gt < 0.0, t, gt, t_l, g_l, t_p, g_p, side,
                                                     illinois=p.illinois)
            B.eval(t_l, g_l, t_p, g_p, side)
        t = secant()
        l = (x * (1.0 - t) + R * (a * t)) / B.maximum(1.0 - t, 1e-7)   # x + R d(t)
        return Localization(l=l, valid=found & B.isfinite(t))

    def lookups_per_ray(self) -> int:
        # g(0), the linear steps (the vectorized loop spends n_max on every ray; rays with a shorter arc repeat
        # t = 1 and a per-ray loop on a GPU would stop after n of them), the secant steps, the shown point
        return 1 + self.params.linear_steps + self.params.secant_steps + 1
