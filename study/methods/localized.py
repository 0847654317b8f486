"""The paper's localized lookup: false position on |l|/|l'| along the ray ("Hit", Szirmay-Kalos et al. 2005).

Faithful to the HLSL listing with the errata of shared/paper/NOTES.md: the first guess is eq. 2 with the
overshoot at infinity (the point r seen in direction R), then NITER steps of false position between the last
undershooting and overshooting guesses (eq. 3), leaving a guess alone inside the band 0.999 < |l|/|l'| < 1.001.
Before any overshoot has been seen, eq. 2 is used again from the current undershoot.

Open environments: a texel with no surface holds FAR (:data:`study.impostor.cubemap.FAR`); eq. 2 then starts at
d = FAR·(1 − q(0)), i.e. at infinity along R, where q = 1 and the search stops: the ray escapes. A ray that in
truth hits a wall near the open side, while R seen from o escapes, is shown at infinity (wrong depth).
"""

from __future__ import annotations

from typing import Annotated

from pydantic import BaseModel, ConfigDict, Field

from study.backend import V3, Backend
from study.impostor.views import Captured
from study.methods.base import Knob, Localization, Method, register


class Params(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)
    iterations: Annotated[
        int, Field(ge=0, le=1000, description="false-position steps (the listing's NITER)")
    ] = 10
    band_lo: Annotated[
        float,
        Field(
            gt=0, le=1, description="|l|/|l'| below this: the guess undershoots (is in front of the surface)"
        ),
    ] = 0.999
    band_hi: Annotated[
        float, Field(ge=1, description="|l|/|l'| above this: the guess overshoots (lies behind the surface)")
    ] = 1.001


@register
class Localized(Method):
    name = "localized"
    Params = Params
    knob = Knob("iterations", (0, 1, 3, 10, 20))  # false-position steps

    def localize(self, B: Backend, env: Captured, x: V3, R: V3) -> Localization:
        p = self.params
        # ------------------------------------------------------------- start: eq. 2 from p = x, overshoot at r
        r_len = env.distance(R)  # |r|
        pun = B.length(x) / env.distance(x)  # |p|/|p'| of the last undershoot (p = x at d = 0)
        dun = pun * 0.0  # ray parameter of the last undershoot
        dov = pun * 0.0  # ray parameter of the last overshoot (0: none yet)
        pov = pun * 0.0  # |p|/|p'| of the last overshoot (read only once dov != 0)
        dl = r_len * (1.0 - pun)  # eq. 2

        # ------------------------------------------------------------- false-position iterations
        def iteration(dl, dun, pun, dov, pov):
            l = x + R * dl  # ray equation
            llp = B.length(l) / env.distance(l)  # |l|/|l'|
            under = llp < p.band_lo
            over = llp > p.band_hi
            step_under = B.select(
                dov == 0.0,
                r_len * (1.0 - llp),  # eq. 2
                (dl - dov) * (1.0 - llp) / (llp - pov),
            )  # eq. 3
            step_over = (dl - dun) * (1.0 - llp) / (llp - pun)  # eq. 3
            dun, pun = B.select(under, dl, dun), B.select(under, llp, pun)
            dov, pov = B.select(over, dl, dov), B.select(over, llp, pov)
            dl = dl + B.select(under, step_under, B.select(over, step_over, 0.0))
            return dl, dun, pun, dov, pov

        # one recorded loop on Dr.Jit (the whole search is one kernel), a Python loop on numpy
        dl, dun, pun, dov, pov = B.loop(p.iterations, (dl, dun, pun, dov, pov), iteration)
        l = x + R * dl  # ray equation
        return Localization(l=l, valid=B.isfinite(dl))

    def lookups_per_ray(self, res: int | None = None) -> float:
        return 3 + self.params.iterations  # |r|, |x'|, one per iteration, the shown point

    def host_steps(self, res: int | None = None) -> float:
        return self.lookups_per_ray(res)  # every iteration a step over all rays, in lock-step
