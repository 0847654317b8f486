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
request; the caller (:func:`study.measure.case.run_case`) merges the requests of every method of a case
(:meth:`Views.merge`), captures what was asked, and puts it into ``env.info`` (keys in :mod:`study.methods.base`):
``"layers"`` (list of EnvMap), ``"probes"`` ({:class:`ProbeSpec`: ProbeSet}) and ``"screen"`` (ScreenView).
"""

from __future__ import annotations

from dataclasses import dataclass, field

Vec3 = tuple[float, float, float]


@dataclass(frozen=True)
class ProbeSpec:
    """Where the probes of a :class:`~study.impostor.probes.ProbeSet` stand (besides probe 0, the reference point).

    ``points`` (world coordinates, metres) when given; otherwise the centres of a ``grid`` = (nx, ny, nz) of equal
    cells filling the environment's bounds (``env.info["room"]``), less those inside geometry or closer than
    ``clearance`` metres to a surface (:func:`study.impostor.probes.probe_points`)."""

    grid: tuple[int, int, int] = (2, 2, 2)
    points: tuple[Vec3, ...] | None = None
    clearance: float = 0.1


@dataclass(frozen=True)
class Views:
    """A request for views: ``layers`` depth layers from o (1: the plain impostor), the probe sets ``probes`` and,
    with ``screen``, the camera's depth and colour buffer."""

    layers: int = 1
    probes: tuple[ProbeSpec, ...] = field(default_factory=tuple)
    screen: bool = False

    @staticmethod
    def merge(*requests: Views) -> Views:
        """One request covering all of ``requests``: the most layers, every probe set once, a screen if any."""
        probes = tuple(dict.fromkeys(p for r in requests for p in r.probes))
        return Views(
            layers=max((r.layers for r in requests), default=1),
            probes=probes,
            screen=any(r.screen for r in requests),
        )
