"""Classical environment mapping (Blinn and Newell 1976): look up the ray direction R itself.

Exact when the ray starts at the reference point (x = 0) or the environment is infinitely far away.

Open environments: where direction R sees no surface, the lookup reads the background and the shown
point lies at infinity along R (exact for the escaping rays, whatever x).
"""

from __future__ import annotations

from study.backend import V3, Backend
from study.impostor.views import Captured
from study.methods.base import Localization, Method, register


@register
class Classical(Method):
    name = "classical"

    def localize(self, B: Backend, env: Captured, x: V3, R: V3) -> Localization:
        return Localization(l=R, valid=B.abs(R.x) >= 0.0)  # always a hit: the environment in direction R

    def lookups_per_ray(self, res: int | None = None) -> float:
        return 1  # the shown point
