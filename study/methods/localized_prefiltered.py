"""The paper's localized lookup for rough surfaces: its false-position search (``localized``) along the lobe's
dominant direction, then the prefiltered impostor read towards the hit at the level of the lobe's footprint seen
from the reference point, α′ = α |l − x| / |l|. At α = 0 it is ``localized``; open environments: as ``localized``."""

from __future__ import annotations

from study.backend import V3, Backend
from study.impostor.views import Captured
from study.methods.base import Knob, register
from study.methods.glossy import PrefilteredMethod
from study.methods.localized import Localized, Params


@register
class LocalizedPrefiltered(PrefilteredMethod):
    name = "localized_prefiltered"
    Params = Params
    knob = Knob("iterations", (0, 1, 3, 10, 20))
    footprint = True

    def _mirror(self) -> Localized:
        return Localized(**self.params.model_dump(exclude_unset=True))

    def point(self, B: Backend, env: Captured, x: V3, d: V3):
        m = self._mirror()
        loc = m.localize(B, env, x, d)
        spent = loc.lookups if loc.lookups is not None else x.x * 0.0 + (m.lookup_bound(env.res) - 1)
        return loc.l, loc.valid, spent

    def lookups_per_ray(self, res: int | None = None) -> float:
        return self._mirror().lookups_per_ray(res)  # the search, then one trilinear fetch for its last read
