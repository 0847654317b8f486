"""The exact tracer of the render device (:func:`study.runtime.render_device`): Embree on the CPU, Mitsuba's
OptiX ray queries on CUDA — one interface (``intersect``, ``distance``, ``mesh``, ``threads``)."""

from __future__ import annotations

from study import runtime
from study.reference.embree import Tracer
from study.reference.optix import MitsubaTracer
from study.scene import RoomMesh


def make_tracer(mesh: RoomMesh, *, device: str | None = None) -> Tracer | MitsubaTracer:
    """The exact tracer of ``mesh`` on ``device`` (default: the render device): Embree on ``"cpu"``,
    :class:`~study.reference.optix.MitsubaTracer` (``cuda_ad_rgb``, OptiX) on ``"cuda"``."""
    device = device or runtime.render_device()
    if device == "cuda":
        return MitsubaTracer(mesh, variant=runtime.VARIANTS["cuda"])
    return Tracer(mesh)
