"""Classical prefiltered environment mapping (Karis 2013; the engines' default): read the GGX-prefiltered impostor
in the lobe's dominant direction at the level of the surface's roughness α, as if the shading point were the
reference point. At α = 0 it is ``classical``. Open environments: as ``classical``."""

from __future__ import annotations

from study.backend import V3, Backend
from study.impostor.views import Captured
from study.methods.base import register
from study.methods.glossy import PrefilteredMethod


@register
class Prefiltered(PrefilteredMethod):
    name = "prefiltered"

    def point(self, B: Backend, env: Captured, x: V3, d: V3):
        return d, B.abs(d.x) >= 0.0, x.x * 0.0

    def lookups_per_ray(self, res: int | None = None) -> float:
        return 1  # one trilinear fetch of the prefiltered chain
