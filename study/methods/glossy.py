"""Glossy reflections: what the methods for rough objects (``object.alpha`` > 0) share.

A glossy method answers, per secondary ray (x, mirror direction R) leaving a surface of GGX roughness α with normal
n (both from :class:`study.impostor.views.Lobe`, ``Captured.lobe``), the *average radiance of the lobe*
∫ L f (n·l) dl / ∫ f (n·l) dl, f without Fresnel; the case multiplies it by the directional albedo E
(:func:`study.optics.shading.fresnel`), so E × average is the reflected radiance. Its shown point (outcome
classes, angular error) is the point it found for the lobe's centre.

The prefiltered methods (:class:`PrefilteredMethod`) take the lobe's dominant direction d
(:func:`study.impostor.ggx.dominant_direction`), find a point l for the ray x + d t as a mirror method would, and
read the prefiltered impostor (:mod:`study.impostor.prefilter`) towards l at the level of a roughness α′:

======================  ===========================  =====================================================
method                  the point l                  α′
======================  ===========================  =====================================================
prefiltered             l = d (classical)            α (the engines' default: distant lighting)
proxy_box_prefiltered   the proxy box's hit          α (parallax-corrected probes)
distance_roughness      the proxy box's hit          α |l − x| / |l| (Lagarde 2012)
localized_prefiltered   the paper's search along d   α |l − x| / |l| (the lobe's footprint at the hit)
======================  ===========================  =====================================================

At α = 0 every one of them is its mirror method (d = R, α′ = 0 reads level 0, the impostor itself). The
``stochastic`` method samples the lobe instead and localizes every sample (:mod:`study.methods.stochastic`).

On a bare impostor (no ``Captured.lobe``, no prefiltered chain: the fallback) every glossy method is its mirror
twin (α = 0, the impostor as the only level).

Glossy methods set ``glossy = True``: ``methods = "all"`` leaves them out (the mirror figures keep their cost and
tables) and ``methods = "glossy"`` asks for them (:func:`study.harness.config.expand_methods`).
"""

from __future__ import annotations

from typing import ClassVar

from study.backend import V3, Backend
from study.impostor import ggx
from study.impostor.prefilter import footprint_alpha
from study.impostor.views import Captured, Views
from study.methods.base import Found, TracingMethod


def eye(n: V3, R: V3) -> V3:
    """v, the direction towards the eye: R reflected about n."""
    return n * (2.0 * n.dot(R)) - R


class GlossyMethod(TracingMethod):
    """A method for rough objects: its Found's radiance is the lobe's average (module docstring)."""

    glossy: ClassVar[bool] = True


class PrefilteredMethod(GlossyMethod):
    """Dominant direction → a point l (:meth:`point`) → the prefiltered impostor at α′ (module docstring)."""

    #: α′ = α |l − x| / |l| (the footprint seen from o) instead of α
    footprint: ClassVar[bool] = False

    def views_needed(self) -> Views:
        return Views(prefiltered=True)

    def point(self, B: Backend, env: Captured, x: V3, d: V3):
        """(l, valid, lookups spent before the final read) for the ray x + d t."""
        raise NotImplementedError

    def search(self, B: Backend, env: Captured, x: V3, R: V3) -> Found:
        lobe, pre = env.need_lobe(self.name, R), env.need_prefiltered(self.name)
        d = ggx.dominant_direction(B, lobe.normal, R, lobe.alpha)
        l, valid, spent = self.point(B, env, x, d)
        a = footprint_alpha(B, lobe.alpha, x, l) if self.footprint else x.x * 0.0 + lobe.alpha
        r, g, b, _ = pre.lookup(l, a)
        dist = env.distance(l)  # the lobe centre's point in the impostor itself
        lhat = B.normalize(l)
        return Found(l, lhat * dist, V3(r, g, b), B.length(l) / dist, valid, spent + 1.0)
