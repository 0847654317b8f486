"""Distance-based roughness (Lagarde 2012): parallax-corrected prefiltered probes (``proxy_box_prefiltered``)
whose roughness is scaled by the lobe's footprint seen from the probe, α′ = α |l − x| / |l| with l the proxy's hit:
a surface near what it reflects looks sharp. At α = 0 it is ``proxy_box``; open environments and the proxy: as
``proxy_box``."""

from __future__ import annotations

from study.methods.base import register
from study.methods.proxy_box_prefiltered import ProxyBoxPrefiltered


@register
class DistanceRoughness(ProxyBoxPrefiltered):
    name = "distance_roughness"
    footprint = True
