"""What a method searches, and what it asks the caller to capture: image-based views of the environment.

A *view* is a set of texels, each holding a depth (or distance) and a radiance, and the projection that takes a
point of space to its texel. study has three kinds, all bound to one array backend:

==============================  =====================================================================================
view                            depth, radiance, projection
==============================  =====================================================================================
:class:`~study.impostor.envmap.EnvMap`  a cube map from one point (the reference point o): distance |p − o|,
                                the radiance seen there; cube projection (:mod:`study.impostor.cubemap`). Depth layers
                                (:mod:`study.impostor.layers`) are more cube maps from the same point.
:class:`~study.impostor.probes.ProbeSet`  N cube maps from N points (probe 0 is o itself), stacked into one texture:
                                distance from each probe's centre; the cube projection about that centre.
:class:`~study.impostor.screen.ScreenView`  the camera's own buffer: z-depth along the view axis and the colour of the
                                camera's render of the environment (no object); the camera's perspective projection.
==============================  =====================================================================================

A method says which views it searches with :meth:`study.methods.base.Method.views_needed`, a :class:`Views`
request; the caller merges the requests of every method (:meth:`Views.merge`), captures what was asked and hands
the methods one :class:`Captured`: the impostor, the views captured besides it and the scene knowledge (reference
point, room box, open environment). Callers: :func:`study.measure.inputs.capture_views` (cases and caustic maps) and
:func:`study.bench.timing.method_runner` (the bench: copies of the impostor as layers, nothing else).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from study.errors import StudyError
from study.impostor.envmap import EnvMap
from study.impostor.screen import ScreenView

Vec3 = tuple[float, float, float]


@dataclass(frozen=True)
class ProbeSpec:
    """Where the probes of a :class:`~study.impostor.probes.ProbeSet` stand (besides probe 0, the reference point).

    ``points`` (world coordinates, metres) when given; otherwise the centres of a ``grid`` = (nx, ny, nz) of equal
    cells filling the environment's bounds (``Captured.room``), less those inside geometry or closer than
    ``clearance`` metres to a surface (:func:`study.impostor.probes.probe_points`)."""

    grid: tuple[int, int, int] = (2, 2, 2)
    points: tuple[Vec3, ...] | None = None
    clearance: float = 0.1


@dataclass(frozen=True)
class SdfSpec:
    """A signed distance field of the environment (:mod:`study.impostor.sdf`): ``res`` grid nodes along each axis
    of the cube holding the environment, exact distances within ``band`` voxels of a surface."""

    res: int = 64
    band: float = 4.0


@dataclass(frozen=True)
class Views:
    """A request for views: ``layers`` depth layers from o (1: the plain impostor), the probe sets ``probes``,
    with ``screen`` the camera's depth and colour buffer, the distance fields ``sdfs``, with ``shade`` the
    exact shading of points (``Captured.shade``) and with ``hits`` the exact tracer's first hits (``Captured.hits``)."""

    layers: int = 1
    probes: tuple[ProbeSpec, ...] = field(default_factory=tuple)
    screen: bool = False
    sdfs: tuple[SdfSpec, ...] = field(default_factory=tuple)
    shade: bool = False
    prefiltered: bool = False  # the GGX-prefiltered mip chain of the impostor (study.impostor.prefilter)
    hits: bool = False  # the exact tracer's first hits (not a view: the scene's own triangles, Captured.hits)
    caches: tuple[int, ...] = ()  # hit-lighting caches at these grid resolutions (Captured.cached)

    @staticmethod
    def merge(*requests: Views) -> Views:
        """One request covering all of ``requests``: the most layers, every probe set once, a screen if any."""
        probes = tuple(dict.fromkeys(p for r in requests for p in r.probes))
        return Views(
            layers=max((r.layers for r in requests), default=1),
            probes=probes,
            screen=any(r.screen for r in requests),
            sdfs=tuple(dict.fromkeys(s for r in requests for s in r.sdfs)),
            shade=any(r.shade for r in requests),
            prefiltered=any(r.prefiltered for r in requests),
            hits=any(r.hits for r in requests),
            caches=tuple(sorted({c for r in requests for c in r.caches})),
        )


@dataclass(frozen=True, eq=False)
class Lobe:
    """The rough surface the secondary rays leave: GGX roughness ``alpha`` (0: a mirror) and each ray's unit
    shading normal ``normal`` (a V3 on the backend, one per ray, in the rays' order); the glossy methods need
    both, as the direction towards the eye is the reflection of R about the normal. ``seed``: the case's
    ``render.seed``, which stochastic methods mix into their own (a figure's seeds draw their samples anew)."""

    alpha: float
    normal: Any
    seed: int = 0


@dataclass(frozen=True, eq=False)
class Captured:
    """What a method is given to search: the impostor, the other views captured for it, and scene knowledge.

    impostor   the distance impostor from the reference point o (:class:`~study.impostor.envmap.EnvMap`); a
               Captured answers ``lookup``, ``distance``, ``res``, ``B``, ``tex`` and ``dist`` as the impostor
               does, so a method's search reads it like an EnvMap
    layers     depth layers from o, nearest first (:mod:`study.impostor.layers`); () when none were captured
    probes     {:class:`ProbeSpec`: ProbeSet} cube maps at several points, probe 0 the impostor
               (:mod:`study.impostor.probes`)
    screen     the camera's depth and colour buffer (:class:`~study.impostor.screen.ScreenView`), or None
    sdfs       {:class:`SdfSpec`: SdfGrid} signed distance fields of the environment (:mod:`study.impostor.sdf`)
    shade      exact shading, not an image-based view: a function (origins, dirs), world (N, 3) numpy arrays →
               (N, 3) radiance arriving along each ray (Mitsuba, the scene without the object; on the case's
               exact rays truth_at_hit's own values: :func:`study.measure.inputs.exact_shading`), or None
    hits       the exact query, not an image-based view: a function (origins, dirs), world (N, 3) numpy arrays →
               (N, 3) first hits on the environment's triangles (the case's exact tracer, Embree or OptiX;
               non-finite where the ray leaves the scene), or None
    cached     hit-lighting caches (:mod:`study.impostor.hitcache`): a function (res, origins, dirs) → (N, 3)
               radiance the cache of grid resolution ``res`` holds at each ray's exact hit, or None
    reference  o in world coordinates (None: unknown; methods then take the origin)
    room       the room box (min, max), world coordinates: ``reference.box`` where given, else the environment's
               bounds (None: unknown; proxies then fit a box or sphere to the impostor's own distances)
    open       some texels of the impostor see no surface (distance ``cubemap.FAR``): the escape rule of
               :meth:`study.methods.base.Method.trace` applies
    prefiltered  the GGX-prefiltered mip chain of the impostor (:class:`~study.impostor.prefilter.MipChain`),
               or None
    lobe       the surface the rays leave (:class:`Lobe`: roughness and per-ray normals), or None
    fallback   what to do when a method asks for a view that is missing: False (cases, caustic maps) → a
               StudyError naming the view; True (a bare impostor, as in the analytic tests, and the bench, which
               times lookups) → the method's documented fallback (the impostor as the only layer or probe, no
               screen buffer, the room box's distance field)
    """

    impostor: EnvMap
    layers: tuple[EnvMap, ...] = ()
    probes: Mapping[ProbeSpec, Any] = field(default_factory=dict)  # ProbeSet (probes.py imports this module)
    screen: ScreenView | None = None
    sdfs: Mapping[SdfSpec, Any] = field(default_factory=dict)  # SdfGrid (sdf.py imports this module)
    shade: Any = None  # (origins, dirs) world (N, 3) numpy → (N, 3) radiance along each ray, path traced
    hits: Any = None  # (origins, dirs) world (N, 3) numpy → (N, 3) exact first hits (non-finite: no hit)
    cached: Any = None  # (res, origins, dirs) → (N, 3) radiance of the hit-lighting cache at the exact hit
    #   (study.impostor.hitcache at grid resolution res), NaN where the ray hits nothing
    reference: tuple[float, float, float] | None = None
    room: tuple[Vec3, Vec3] | None = None
    open: bool = False
    fallback: bool = False
    prefiltered: Any = None  # MipChain (prefilter.py imports envmap, as this module does)
    lobe: Lobe | None = None

    @staticmethod
    def of(env) -> Captured:
        """``env`` itself when it is a Captured; a bare impostor (an EnvMap) wrapped with ``fallback=True``."""
        return env if isinstance(env, Captured) else Captured(impostor=env, fallback=True)

    # ------------------------------------------------------------------ the impostor's interface
    @property
    def B(self):
        return self.impostor.B

    @property
    def res(self) -> int:
        return getattr(self.impostor, "res", 0)

    @property
    def tex(self):
        return self.impostor.tex

    @property
    def dist(self):
        return self.impostor.dist

    def lookup(self, v) -> list:
        return self.impostor.lookup(v)

    def distance(self, v):
        return self.impostor.distance(v)

    # ------------------------------------------------------------------ scene knowledge and views, checked
    def origin(self) -> np.ndarray:
        """o in world coordinates (the origin when unknown)."""
        return np.asarray(self.reference if self.reference is not None else (0.0, 0.0, 0.0), float)

    def _missing(self, method: str, what: str) -> StudyError:
        return StudyError(
            f"method {method!r} needs {what}, which its caller did not capture (views_needed() asks for it)",
            key="method",
        )

    def need_layers(self, method: str, n: int) -> list:
        """The first ``n`` depth layers; without layers, the impostor alone where one layer is asked for or the
        Captured falls back."""
        if len(self.layers) >= n or (self.layers and self.fallback):
            return list(self.layers[:n])
        if self.fallback or (n <= 1 and not self.layers):
            return [self.impostor]
        raise self._missing(method, f"{n} depth layers (Captured.layers has {len(self.layers)})")

    def need_probes(self, method: str, spec: ProbeSpec):
        """The probe set ``spec``; None on a fallback Captured without it (the impostor as the only probe)."""
        if spec in self.probes:
            return self.probes[spec]
        if self.fallback:
            return None
        raise self._missing(method, f"the probe set {spec} (Captured.probes)")

    def need_prefiltered(self, method: str):
        """The prefiltered mip chain; on a fallback Captured without one, the impostor as its only level (what
        α = 0 reads)."""
        if self.prefiltered is not None:
            return self.prefiltered
        if self.fallback:
            return _SharpOnly(self.impostor)
        raise self._missing(method, "the prefiltered impostor (Captured.prefiltered)")

    def need_lobe(self, method: str, R) -> Lobe:
        """The rays' surface: roughness and normals; on a fallback Captured without one, a mirror (α = 0) whose
        normal is R itself (v = R: the lobe is R alone, whatever the true normal)."""
        if self.lobe is not None:
            return self.lobe
        if self.fallback:
            return Lobe(0.0, R)
        raise self._missing(method, "the rays' surface roughness and normals (Captured.lobe)")

    def need_screen(self, method: str):
        """The camera's buffer; None on a fallback Captured without one."""
        if self.screen is not None or self.fallback:
            return self.screen
        raise self._missing(method, "the camera's screen buffer (Captured.screen)")

    def need_sdf(self, method: str, spec: SdfSpec):
        """The distance field ``spec``; None on a fallback Captured without it."""
        if spec in self.sdfs:
            return self.sdfs[spec]
        if self.fallback:
            return None
        raise self._missing(method, f"the distance field {spec} (Captured.sdfs)")

    def need_shade(self, method: str):
        """The exact shading function; None on a fallback Captured without it."""
        if self.shade is not None or self.fallback:
            return self.shade
        raise self._missing(method, "exact shading (Captured.shade)")

    def need_cached(self, method: str):
        """The hit-lighting caches' reads (:attr:`cached`); None on a fallback Captured without them."""
        if self.cached is not None or self.fallback:
            return self.cached
        raise self._missing(method, "a hit-lighting cache (Captured.cached)")

    def need_hits(self, method: str):
        """The exact tracer's first hits; None on a fallback Captured without them."""
        if self.hits is not None or self.fallback:
            return self.hits
        raise self._missing(method, "the exact tracer's hits (Captured.hits)")


@dataclass(frozen=True)
class _SharpOnly:
    """A prefiltered chain of one level, the impostor itself: every roughness reads it (the fallback)."""

    impostor: Any

    def lookup(self, v, alpha) -> list:
        return self.impostor.lookup(v)
