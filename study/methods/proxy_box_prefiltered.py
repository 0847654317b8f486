"""Parallax-corrected prefiltered probes (Lagarde 2012; the reflection probes games ship for rough surfaces): the
ray along the lobe's dominant direction meets the proxy box (``proxy_box``), and the prefiltered impostor is read
towards that point at the level of the surface's roughness α. At α = 0 it is ``proxy_box``; open environments and
the proxy: as ``proxy_box``."""

from __future__ import annotations

from study.backend import V3, Backend
from study.impostor.views import Captured
from study.methods.base import register
from study.methods.glossy import PrefilteredMethod
from study.methods.proxy_box import Params, ProxyBox


@register
class ProxyBoxPrefiltered(PrefilteredMethod):
    name = "proxy_box_prefiltered"
    Params = Params

    def point(self, B: Backend, env: Captured, x: V3, d: V3):
        loc = ProxyBox(**self.params.model_dump(exclude_unset=True)).localize(B, env, x, d)
        return loc.l, loc.valid, x.x * 0.0

    def lookups_per_ray(self, res: int | None = None) -> float:
        return 1  # the proxy hit is analytic; one trilinear fetch
