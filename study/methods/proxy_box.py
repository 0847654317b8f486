"""Parallax-corrected cube map with a box proxy (Bjorke 2004; Lagarde 2012; the reflection probes games ship).

The ray x + R d is intersected analytically with an axis-aligned box [bmin, bmax] (relative to the reference
point o): for each axis i, t_i = ((R_i > 0 ? bmax_i : bmin_i) − x_i) / R_i, t* = min_i t_i, and the lookup vector
is l = x + R t*. Exact when the room is the proxy; wrong wherever the scene departs from it (columns).

The proxy: ``box_min``/``box_max`` (world coordinates) when given; otherwise the room (``Captured.room``);
on a bare impostor without scene information, the box through the six walls seen along ±x, ±y, ±z (the room
itself when nothing stands on those axes). Invalid (NaN shown point) where x lies outside the box.

Open environments: the proxy box closes the open side, so an escaping ray hits the box there and is looked up
in the direction of that hit from the capture point — the background seen in another direction (wrong surface
in the outcome classes; right only where the background is uniform, as the Cornell box's black).
"""

from __future__ import annotations

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from study.backend import V3, Backend
from study.errors import StudyError
from study.impostor.views import Captured
from study.methods.base import Localization, Method, register

Vec3 = tuple[float, float, float]


class Params(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)
    box_min: Vec3 | None = Field(
        None,
        description="lower corner of the proxy box, world coordinates (default: the room, else fitted to the impostor)",
    )
    box_max: Vec3 | None = Field(None, description="upper corner of the proxy box, world coordinates")


def room_box(B, env: Captured) -> tuple[np.ndarray, np.ndarray]:
    """The room as (lo, hi) relative to o: ``env.room``, or fitted to the impostor's six axis distances."""
    env = Captured.of(env)
    o = env.origin()
    if env.room is not None:
        lo, hi = (np.asarray(c, float) for c in env.room)
        return lo - o, hi - o
    # through a texel centre next to each axis (face coordinates ±1/R), so the stored distance is exact there;
    # its component along the axis is the distance to the plane of a wall perpendicular to that axis
    axes = np.concatenate([np.eye(3), -np.eye(3)])
    w = (
        axes
        + (1.0 / env.res) * np.abs(np.roll(axes, 1, axis=1))
        + (1.0 / env.res) * np.abs(np.roll(axes, 2, axis=1))
    )
    w /= np.linalg.norm(w, axis=1, keepdims=True)
    d = B.numpy(env.distance(B.vec(w))).astype(float) * np.abs(w[axes != 0])  # plane distance per axis
    return -d[3:], d[:3]


@register
class ProxyBox(Method):
    name = "proxy_box"
    Params = Params

    def localize(self, B: Backend, env: Captured, x: V3, R: V3) -> Localization:
        p = self.params
        if (p.box_min is None) != (p.box_max is None):
            raise StudyError("give both box_min and box_max, or neither", key="method.box_min")
        if p.box_min is None:
            lo, hi = room_box(B, env)
        else:
            o = env.origin()
            lo, hi = np.asarray(p.box_min, float) - o, np.asarray(p.box_max, float) - o
        # ------------------------------------------------------------- slab exit distance t*
        t = None
        for xi, Ri, a, b in ((x.x, R.x, lo[0], hi[0]), (x.y, R.y, lo[1], hi[1]), (x.z, R.z, lo[2], hi[2])):
            plane = B.select(Ri > 0.0, xi * 0.0 + float(b), xi * 0.0 + float(a))  # the face the ray leaves by
            ti = B.select(Ri == 0.0, xi * 0.0 + np.float32(np.inf), (plane - xi) / Ri)
            t = ti if t is None else B.minimum(t, ti)
        inside = (
            (x.x >= lo[0])
            & (x.x <= hi[0])
            & (x.y >= lo[1])
            & (x.y <= hi[1])
            & (x.z >= lo[2])
            & (x.z <= hi[2])
        )
        l = x + R * t  # hit on the proxy
        return Localization(l=l, valid=inside & B.isfinite(t))

    def lookups_per_ray(self, res: int | None = None) -> float:
        return 1  # the shown point (the proxy hit is analytic)
