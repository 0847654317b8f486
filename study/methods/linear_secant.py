"""Linear search then secant steps (Umenhoffer, Patow, Szirmay-Kalos, GPU Gems 3 ch. 17, 2007).

The ray x + R d is parameterized by t ∈ [0, 1]: d(t) = a t / (1 − t) with a = |x|, so that the ray point is
p(t) / (1 − t) with p(t) = (1 − t) x + t a R; uniform steps in t walk the great-circle arc from x̂ to R on the
direction sphere. The step count of a ray comes from the arc length, n = max(n_max (1 − x̂·R) / 2, n_min).

The surface test is written on p, which stays finite up to t = 1 (the point at infinity in direction R):
g(t) = |p(t)| − (1 − t) |p(t)'| (|v'| the stored distance towards v), g < 0 in front of the environment surface
("undershoot", the paper's |l|/|l'| < 1), g > 0 behind it. g(1) = a > 0, so every ray that starts in front of the
surface has a crossing.

Phases (both from the search core :mod:`study.methods.search`): (1) linear search for the FIRST pair of consecutive
samples with g < 0 then g ≥ 0; (2) ``secant_steps`` secant (false-position) steps on g inside that bracket, keeping
the side by the sign of g, by default with the Illinois rule (when the same end is replaced twice in a row, the
other end's g is halved; plain false position stalls on one side and left errors of centimetres after 10 steps on a
column face); the result is the secant point of the final bracket. The secant works on g(t) instead of the chapter's
q(d) because q is infinite at t = 1; both vanish at the same points. Invalid (NaN shown point) where no crossing is
found (x itself behind the environment surface and the ray never comes out in front of it).
"""
from __future__ import annotations

from typing import Annotated

from pydantic import BaseModel, ConfigDict, Field, model_validator

from study.methods.base import Knob, Localization, Method, register
from study.methods.search import first_crossing, refine, secant_point


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


@register
class LinearSecant(Method):
    name = "linear_secant"
    Params = Params
    knob = Knob("linear_steps", (10, 30, 60, 120))    # a finer linear search steps over fewer thin crossings

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
        g0 = g(zero)
        # bracket: last undershoot, first overshoot (no crossing: the whole arc, t = 0 to the point at infinity)
        br = first_crossing(B, g, zero, g0, dt, p.linear_steps, t_max=1.0, default=(zero, g0, zero + 1.0, a))

        # ------------------------------------------------------------- secant steps inside the bracket
        br = refine(B, g, br, p.secant_steps, illinois=p.illinois, rising=True)
        t = secant_point(br)
        l = (x * (1.0 - t) + R * (a * t)) / B.maximum(1.0 - t, 1e-7)   # x + R d(t)
        return Localization(l=l, valid=br.found & B.isfinite(t))

    def lookups_per_ray(self) -> int:
        # g(0), the linear steps (the vectorized loop spends n_max on every ray; rays with a shorter arc repeat
        # t = 1 and a per-ray loop on a GPU would stop after n of them), the secant steps, the shown point
        return 1 + self.params.linear_steps + self.params.secant_steps + 1
