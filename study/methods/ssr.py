"""Screen-space ray tracing (McGuire and Mara, "Efficient GPU Screen-Space Ray Tracing", JCGT 3(4) 2014): a
perspective-correct DDA through the camera's own depth buffer, with the fallbacks engines ship.

The view searched is the camera's buffer (``Captured.screen``, :class:`study.impostor.screen.ScreenView`: z-depth
and colour of the environment without the object, per pixel). The ray x + R d (relative to the reference point o) is
clipped to d ≤ ``max_distance`` (default: the diagonal of ``Captured.room``, else 100 m) and to the near plane
z ≥ 0.01 m (a ray turning towards the camera ends there); both ends are projected to pixel coordinates P0, P1 with
k = 1/z at each. 1/z and the pixel position are affine along the projected segment, so the DDA steps ``stride``
pixels along its major axis (n = |P1 − P0|∞ / stride steps, step s = 0 … n, P0 + s·ΔP) and knows the ray's exact
depth range at step s, z ∈ [1/k(s − ½), 1/k(s + ½)] (clamped to the segment), without a division per pixel for the
position. At each step the pixel under the ray (floor of its coordinates) gives the buffer's depth z_b; the step
is a hit when the ray's range overlaps [z_b, z_b + ``thickness``] (the surface is taken to be ``thickness`` metres
thick behind its depth), the first such step along the ray is kept.

No hit ("no hit": NaN shown point) where the ray leaves the screen (the answer is off screen), reaches the segment's
end, passes behind geometry by more than ``thickness`` until then (what it would hit is hidden from the camera), or
exhausts ``max_steps``; also where its origin is off screen or behind the near plane. ``fallback`` traces those rays
with another method on the impostor, as engines fall back to a reflection probe: ``"proxy_box"`` (the room box as
a proxy; the default, as engines ship it, so the plain name is the hybrid), ``"localized"`` (the paper's search) or
``"sdf"`` (the distance field, :mod:`study.methods.sdf`: Lumen's chain of a screen trace, then a global distance
field trace, registered as ``ssr_sdf``, the tables' "ssr → sdf"); ``"none"`` shows nothing (screen-space tracing
alone). On a bare impostor without a camera buffer every ray goes to
the fallback.

Shown point of a hit: the ray point at depth clamp(z_b, range) of the hit step (perspective-correct parameter
along the segment), so a hit lies on the ray; its radiance is the colour buffer at the hit pixel
(:meth:`SSR.search`). Cost per ray (``Trace.lookups``): one depth fetch per step actually taken (the loop stops at
the hit or the exit), one colour fetch, plus the fallback's lookups on the rays it traces;
:meth:`SSR.lookups_per_ray` bounds it with every step taken and the fallback's bound.
"""

from __future__ import annotations

from typing import Annotated, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from study.backend import V3, Backend
from study.impostor.views import Captured, Views
from study.methods.base import REGISTRY, Found, Knob, Method, TracingMethod, register

NEAR = 0.01  # near plane of the clipped ray, metres


class Params(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)
    max_steps: Annotated[int, Field(ge=1, le=16384, description="DDA step budget (pixels)")] = 512
    stride: Annotated[float, Field(ge=1, le=64, description="pixels per DDA step")] = 1.0
    thickness: Annotated[
        float, Field(gt=0, le=100, description="assumed thickness of a surface behind its depth, metres")
    ] = 0.25
    max_distance: Annotated[float, Field(gt=0)] | None = Field(
        None, description="ray length, metres (default: the room's diagonal)"
    )
    fallback: Literal["none", "proxy_box", "localized", "sdf"] = Field(
        "proxy_box", description="method for the rays without a screen hit (none: no hit)"
    )


class ChainParams(Params):
    fallback: Literal["none", "proxy_box", "localized", "sdf"] = Field(
        "sdf", description="method for the rays without a screen hit (none: no hit)"
    )


@register
class SSR(TracingMethod):
    name = "ssr"
    Params = Params
    ratio_where_valid = True
    knob = Knob("max_steps", (16, 32, 64, 128, 256, 512))

    def _fallback(self) -> Method | None:
        return REGISTRY[self.params.fallback]() if self.params.fallback != "none" else None

    def views_needed(self) -> Views:
        fb = self._fallback()
        return Views.merge(Views(screen=True), *([fb.views_needed()] if fb else []))

    # ---------------------------------------------------------------------------------------------- the march
    def _march(self, B, scr, x: V3, R: V3, d_max: float):
        """(found, d, rgb, spent): hit flag, ray parameter of the shown point, colour at the hit pixel, steps."""
        p = self.params
        W, H = float(scr.width), float(scr.height)
        f = scr.forward
        # ------------------------------------------------------------- clip the ray and project its ends
        px0, py0, z0 = scr.project(x)
        Rz = R.x * float(f[0]) + R.y * float(f[1]) + R.z * float(f[2])
        d_near = (NEAR - z0) / B.select(Rz < -1e-9, Rz, Rz * 0.0 - 1.0)
        d_end = B.select(Rz < -1e-9, B.minimum(d_near, d_max), z0 * 0.0 + d_max)
        px1, py1, z1 = scr.project(x + R * d_end)
        k0, k1 = 1.0 / z0, 1.0 / z1
        dx, dy = px1 - px0, py1 - py0
        length = B.maximum(B.maximum(B.abs(dx), B.abs(dy)), 1e-6) / p.stride  # steps to the end
        sx, sy, sk = dx / length, dy / length, (k1 - k0) / length  # per step
        start = (z0 > NEAR) & scr.on_screen(px0, py0) & B.isfinite(length) & (d_end > 0.0)
        zero = z0 * 0.0

        # ------------------------------------------------------------- DDA over pixels
        def step(s, found, stop, hs, hj, hi, hz, spent):
            px, py = px0 + sx * s, py0 + sy * s
            active = ~found & ~stop
            leave = (s > length) | ~scr.on_screen(px, py)
            stop = stop | (active & leave)
            active = active & ~leave
            j = B.minimum(B.maximum(B.floor(px), 0.0), W - 1.0)
            i = B.minimum(B.maximum(B.floor(py), 0.0), H - 1.0)
            zb = scr.fetch(j, i)[3]
            za = 1.0 / (k0 + sk * B.maximum(s - 0.5, 0.0))
            zc = 1.0 / (k0 + sk * B.minimum(s + 0.5, length))
            hit = active & (B.maximum(za, zc) >= zb) & (B.minimum(za, zc) <= zb + p.thickness)
            spent = spent + B.select(active, zero + 1.0, zero)
            found = found | hit
            hs, hj, hi, hz = (B.select(hit, a, b) for a, b in ((s, hs), (j, hj), (i, hi), (zb, hz)))
            return s + 1.0, found, stop, hs, hj, hi, hz, spent

        never = start & ~start
        out = B.loop(p.max_steps, (zero, never, ~start, zero, zero, zero, zero, zero), step)
        _, found, _, hs, hj, hi, hz, spent = out
        # ------------------------------------------------------------- the shown point on the ray, its colour
        za = 1.0 / (k0 + sk * B.maximum(hs - 0.5, 0.0))
        zc = 1.0 / (k0 + sk * B.minimum(hs + 0.5, length))
        zh = B.minimum(B.maximum(hz, B.minimum(za, zc)), B.maximum(za, zc))
        s = B.select(B.abs(sk) > 1e-12, (1.0 / zh - k0) / B.select(B.abs(sk) > 1e-12, sk, zero + 1.0), hs)
        s = B.minimum(B.maximum(s, B.maximum(hs - 0.5, 0.0)), B.minimum(hs + 0.5, length))
        a = s / length  # fraction of the projected segment
        beta = a * k1 / (a * k1 + (1.0 - a) * k0)  # perspective-correct fraction of the ray
        rgbz = scr.fetch(hj, hi)
        return found & B.isfinite(beta), d_end * beta, rgbz[:3], spent

    def search(self, B: Backend, env: Captured, x: V3, R: V3) -> Found:
        """The DDA's hit where there is one (shown point on the ray, colour buffer radiance), the fallback's
        elsewhere."""
        p = self.params
        scr = env.need_screen(self.name)
        nan = float("nan")
        zero = x.x * 0.0
        if scr is not None:
            if p.max_distance is not None:
                d_max = p.max_distance
            elif env.room is not None:
                d_max = float(np.linalg.norm(np.subtract(env.room[1], env.room[0])))
            else:
                d_max = 100.0
            found, d, rgb, spent = self._march(B, scr, x, R, d_max)
            spent = spent + 1.0  # the colour fetch
        else:  # no camera buffer: nothing on screen
            found, d, rgb, spent = B.isfinite(x.x) & ~B.isfinite(x.x), x.x * nan, [x.x * nan] * 3, zero
        shown = x + R * d
        rad = V3(*rgb)
        valid, l = found, shown
        fb = self._fallback()
        if fb is not None:  # engines: a reflection probe where the screen has nothing

            def sel(a: V3, b: V3) -> V3:
                return V3(*(B.select(found, p, q) for p, q in zip((a.x, a.y, a.z), (b.x, b.y, b.z))))

            tr = fb.trace(B, env, x, R, check_origin=False)
            shown, rad, l = sel(shown, tr.shown), sel(rad, tr.radiance), sel(l, tr.l)
            spent = spent + B.select(found, zero, tr.lookups)
            valid = found | tr.valid
        safe = V3(*(B.select(valid, a, b) for a, b in zip((shown.x, shown.y, shown.z), (R.x, R.y, R.z))))
        ratio = B.length(safe) / env.distance(safe)  # diagnostic: 1 on the impostor
        return Found(l, shown, rad, ratio, valid, spent)

    def lookups_per_ray(self, res: int | None = None) -> float:
        # every step's depth fetch, the colour fetch, and the fallback's lookups
        fb = self._fallback()
        return self.params.max_steps + 1 + (fb.lookup_bound(res) if fb else 0)

    def volume_lookups(self, res: int | None = None) -> float:
        fb = self._fallback()
        return fb.volume_lookups(res) if fb else 0.0


@register
class SSRThenSDF(SSR):
    """``ssr`` whose fallback is ``sdf`` by default: the engine chain ssr → sdf (Lumen: screen trace first, the
    global distance field where the screen has nothing)."""

    name = "ssr_sdf"
    Params = ChainParams
