"""Hi-Z screen-space reflections (AMD FidelityFX SSSR, ``ffx_sssr.h``): a march over a min-depth pyramid of the
camera's buffer, one level up after each cell it clears and one down where it cannot, SSSR's validation of the hit
by a confidence, and a blend to the environment by that confidence.

Screen space. The view searched is the camera's buffer (``Captured.screen``, :class:`study.impostor.screen.ScreenView`:
z-depth and colour of the environment without the object). A point has pixel coordinates (px, py) and the depth
coordinate d = −1/z (z its depth along the view axis; d grows away from the camera, as SSSR's depth): all three are
affine along the projection of a straight line, so the ray x + R s (s ≥ 0, relative to o) is the screen-space line
P(t) = P₀ + t·D, P₀ the projection of x and D = z₀²·dP/ds at s = 0; the ray point of t is s = t z₀²/(1 − t z₀ R_f)
(R_f = R·f, f the view axis). Every t the march reaches is a point ahead of x in front of the camera.

The pyramid (SSSR's depth hierarchy): level 0 holds d of every pixel (0 where the pixel sees no surface), padded to a
power of two with 0 (no occluder); level m holds the minimum over 2×2 cells of level m − 1, up to one cell.

The march (FFX_SSSR_HierarchicalRaymarch). At level 0 the ray first leaves x's own pixel (InitialAdvanceRay: the
nearer of the two pixel planes it points to, nudged 0.005 px beyond); then each iteration reads the cell of the
current level under the ray (one lookup, its minimum d_s), whose half box is bounded by the cell's two exit planes
in x and y and, where the ray moves away from the camera (D_d > 0), the plane d = d_s. The ray is *above* the cell
where d_s > d(t) (nearer than every surface in it): then it advances to the nearest of those planes, and it
*skipped* the cell when that plane was not d = d_s: one level up (none above the top), else one level down. The
march ends below level 0 (the ray stands on the surface of its pixel), after ``max_iterations`` reads (SSSR then
validates the ray's place all the same), or where the ray leaves the screen (no hit; SSSR lets it run on and rejects
it as outside the frustum). ``min_occupancy``: SSSR's early exit of glossy rays, a wave of 32 consecutive rays stops
when no more than this many of its rays still march, the stopped rays keeping their place as the hit (0, the
default, as SSSR does for mirror rays: off; on, it runs the march as a host loop).

Validation (FFX_SSSR_ValidateHit): the confidence c of the hit at pixel (j, i) = ⌊P(t)⌋ is 0 where the ray left
the screen or did not start on it (x off screen or behind the near plane), where it moved < 2 px from its start
along both axes (self-reflection), where the pixel sees no surface (the background), where the pixel's surface faces
along the ray (a back face: n·R > 0, n the G-buffer's normal, :func:`study.impostor.screen.normal_buffer`; for a
buffer without normals, as the bench's, reconstructed from the depths by :func:`depth_normal`); else c = vignette ·
(1 − smoothstep(0, ``thickness``, δ))², δ the view-space distance between the ray's point and the pixel's surface
(both on the pixel's eye ray; SSSR reads that depth from its half-resolution copy, here from the full buffer),
vignette the screen-border fade (smoothstep over 5 % of the screen's height on each side).

Blend. Radiance c · (colour buffer at the hit pixel) + (1 − c) · (the environment's), the environment being the
``fallback`` method traced on the impostor (as ``ssr``'s fallback: ``proxy_box`` by default, ``localized``, ``sdf``,
or ``classical``, the plain environment map SSSR samples); with ``"none"`` the colour buffer's radiance where c ≥ ½
and no hit elsewhere. Shown point (the outcome classes, as for ``ssr``): the ray's point at the hit where c ≥ ½
(the screen's answer weighs most), the fallback's elsewhere. On a bare impostor without a camera buffer every ray
goes to the fallback. Cost per ray (``Trace.lookups``): the pyramid reads the march made, 2 for the validation of a
ray that started (the hit pixel's depth and colour, one fetch; its normal; 5 where four neighbours' depths stand in
for the normal), and the fallback's lookups on rays with c < 1 (the blend needs the environment);
:meth:`SSRHiZ.lookups_per_ray` bounds it with ``max_iterations`` reads. ``thickness`` defaults to ``ssr``'s 0.25 m.
:func:`hiz_march_ref` is the march's slow twin (one ray, the minima taken from level 0).
"""

from __future__ import annotations

import math
import weakref
from dataclasses import dataclass
from typing import Annotated, Any, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from study.backend import V3, Backend
from study.impostor.views import Captured, Views
from study.methods.base import REGISTRY, Found, Knob, Method, TracingMethod, register
from study.methods.ssr import NEAR  # near plane: an origin nearer to the camera plane is not traced on screen

FAR_Z = 1e30  # the buffer's depth where a pixel sees no surface is above this
NUDGE = 0.005  # pixels beyond a cell's plane (SSSR's uv_offset at the most detailed level)
WAVE = 32  # rays per wave of the occupancy exit
BIG = 3.0e38  # SSSR's FLOAT_MAX: the t of a plane the ray never reaches


class Params(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)
    max_iterations: Annotated[
        int,
        Field(ge=1, le=4096, description="most pyramid reads per ray (SSSR's max traversal intersections)"),
    ] = 128
    thickness: Annotated[
        float,
        Field(
            gt=0, le=100, description="depth buffer thickness, metres: confidence 0 this far off the surface"
        ),
    ] = 0.25
    min_occupancy: Annotated[
        int,
        Field(
            ge=0, le=WAVE, description="a wave of 32 rays stops when at most this many still march (0: off)"
        ),
    ] = 0
    fallback: Literal["none", "classical", "proxy_box", "localized", "sdf"] = Field(
        "proxy_box", description="the environment blended in by 1 − confidence (none: no hit there)"
    )


def hiz_levels(z: np.ndarray) -> list[np.ndarray]:
    """The min pyramid of a (H, W) z-depth buffer: level 0 is d = −1/z (0 where no surface) padded to a power of
    two with 0, each further level the minimum over 2×2 cells of the one below, down to (1, 1)."""
    H, W = z.shape
    S = 1 << int(math.ceil(math.log2(max(H, W, 1))))
    d = np.zeros((S, S), np.float32)
    with np.errstate(divide="ignore"):
        d[:H, :W] = np.where(z < FAR_Z, -1.0 / np.maximum(z, 1e-30), 0.0)
    out = [d]
    while out[-1].shape[0] > 1:
        a = out[-1]
        out.append(np.minimum.reduce([a[0::2, 0::2], a[1::2, 0::2], a[0::2, 1::2], a[1::2, 1::2]]))
    return out


class HiZ:
    """:func:`hiz_levels` on a backend: one flat array of rows of ``size`` (S) cells, level m (side S/2^m, cell
    2^m px) in rows 2S − 2·S/2^m onwards (2S² cells in all), so a cell's index needs only the level's 1/2^m: no
    table of offsets read before the cell (the march's reads in a row, one after the other)."""

    def __init__(self, z: np.ndarray, B):
        levels = hiz_levels(z)
        S = levels[0].shape[0]
        self.B, self.size, self.top = B, S, float(len(levels) - 1)
        flat = np.zeros((2 * S, S), np.float32)
        for a in levels:
            r0 = 2 * S - 2 * a.shape[0]
            flat[r0 : r0 + a.shape[0], : a.shape[0]] = a
        self.data = B.array(flat.ravel())

    def cell(self, inv, cx, cy):
        """d of cell (cx, cy) of the level of cell size 1/``inv`` (2^−m per ray; cx, cy within the level): one
        lookup. Exact: the row base (a multiple of S below 2S²) and cx become integers before they are added."""
        S = float(self.size)
        return self.B.gather_at(self.data, ((2.0 * S - (2.0 * S) * inv) + cy) * S, cx)

    def read(self, inv, cx, cy):
        """:meth:`cell` with (cx, cy) clamped into the level (non-finite: 0), for cells off it or lanes where it
        does not matter."""
        B = self.B
        side = inv * float(self.size)
        cx, cy = B.select(B.isfinite(cx), cx, side * 0.0), B.select(B.isfinite(cy), cy, side * 0.0)
        cx = B.minimum(B.maximum(cx, 0.0), side - 1.0)
        cy = B.minimum(B.maximum(cy, 0.0), side - 1.0)
        return self.cell(inv, cx, cy)


_HIZ: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def screen_depth(scr) -> np.ndarray:
    """The (H, W) z-depth of a :class:`~study.impostor.screen.ScreenView` (its texture's fourth channel)."""
    t = scr.tex
    a = np.asarray(t.tensor() if hasattr(t, "tensor") else t, np.float32)
    return a.reshape(-1, scr.side, scr.side, 4)[0, : scr.height, : scr.width, 3]


def hiz_of(scr) -> HiZ:
    """The pyramid of a screen view, built once and kept while the view lives."""
    if scr not in _HIZ:
        _HIZ[scr] = HiZ(screen_depth(scr), scr.B)
    return _HIZ[scr]


def smoothstep(B, a: float, b: float, x):
    s = B.minimum(B.maximum((x - a) / (b - a), 0.0), 1.0)
    return s * s * (3.0 - 2.0 * s)


@dataclass
class ScreenRay:
    """A ray in screen space: P(t) = (px0, py0, d0) + t (Dx, Dy, Dd), with what maps t back to the ray."""

    px0: Any
    py0: Any
    d0: Any
    Dx: Any
    Dy: Any
    Dd: Any
    z0: Any
    Rf: Any  # R along the view axis
    Rc: tuple  # R in camera axes (right, up, forward)
    start: Any  # x on screen, in front of the near plane

    def at(self, t):
        return self.px0 + t * self.Dx, self.py0 + t * self.Dy, self.d0 + t * self.Dd


def screen_ray(B, scr, x: V3, R: V3) -> ScreenRay:
    """The screen-space line of the rays x + R s (module docstring); non-finite lanes made safe (not started)."""
    X0, Y0, z0 = scr.camera_space(x)
    Rc = tuple(
        R.x * float(a[0]) + R.y * float(a[1]) + R.z * float(a[2]) for a in (scr.right, scr.up, scr.forward)
    )
    W, H, T, Ty = float(scr.width), float(scr.height), scr.tan_x, scr.tan_y
    px0 = (X0 / (z0 * T) + 1.0) * (0.5 * W)
    py0 = (1.0 - Y0 / (z0 * Ty)) * (0.5 * H)
    Dx = (0.5 * W / T) * (Rc[0] * z0 - X0 * Rc[2])
    Dy = -(0.5 * H / Ty) * (Rc[1] * z0 - Y0 * Rc[2])
    ok = (z0 > NEAR) & B.isfinite(px0) & B.isfinite(py0) & B.isfinite(Dx) & B.isfinite(Dy) & B.isfinite(Rc[2])
    start = ok & scr.on_screen(px0, py0)
    safe = lambda a, v=0.0: B.select(ok, a, a * 0.0 + v)  # noqa: E731
    return ScreenRay(safe(px0), safe(py0), safe(-1.0 / z0, -1.0), safe(Dx), safe(Dy), safe(Rc[2]), safe(z0, 1.0),
                safe(Rc[2]), tuple(safe(c) for c in Rc), start)  # fmt: skip


def _planes(B, r: ScreenRay):
    """Per axis: (1/D or 0 where D = 0, floor offset, nudge) as SSSR's inv_direction, floor_offset, uv_offset."""
    out = []
    for D in (r.Dx, r.Dy):
        zero = D == 0.0
        inv = B.select(zero, D * 0.0, 1.0 / B.select(zero, D * 0.0 + 1.0, D))
        floor_off = B.select(D < 0.0, D * 0.0, D * 0.0 + 1.0)
        out.append((inv, zero, floor_off, B.select(D < 0.0, D * 0.0 - NUDGE, D * 0.0 + NUDGE)))
    return out


def _exit_t(B, plane, p0, inv, zero):
    return B.select(zero, plane * 0.0 + BIG, (plane - p0) * inv)


def hiz_march(B, scr, hz: HiZ, r: ScreenRay, max_iterations: int, min_occupancy: int = 0):
    """(t, level, reads, on_screen) at the march's end, per ray (module docstring).

    The level is carried as its cell size 2^m and 1/2^m (the exit planes, the cell under the ray: products, exact,
    where m and a table of offsets, sizes and sides read before the cell were a dependent read more per step); a
    ray that does not start stands below level 0 (m = −1) from the first test. The loop's test: above level 0 and
    on screen (the read budget is the loop's limit); in the test's lanes the cell under the ray lies in the level,
    so the read needs no clamp where the loop runs only the lanes that test true (Dr.Jit's symbolic loop; numpy's
    loop and the occupancy exit's host loop run every lane: clamped there)."""
    (ix, zx, fx, ux), (iy, zy, fy, uy) = _planes(B, r)
    zero = r.px0 * 0.0
    # InitialAdvanceRay: out of x's pixel at level 0
    t = B.minimum(
        _exit_t(B, B.floor(r.px0) + fx + ux, r.px0, ix, zx),
        _exit_t(B, B.floor(r.py0) + fy + uy, r.py0, iy, zy),
    )
    t = B.select(r.start, t, zero)
    away = r.Dd > 0.0
    iz = 1.0 / B.select(away, r.Dd, zero + 1.0)
    clamp = B.name == "numpy" or min_occupancy > 0  # the body runs on lanes off the screen or below level 0

    def on(t):
        px, py, _ = r.at(t)
        return scr.on_screen(px, py)

    def cond(t, px, py, size, inv, i):
        return (size >= 1.0) & scr.on_screen(px, py)

    def body(t, px, py, size, inv, i):
        pd = r.d0 + t * r.Dd
        cx, cy = B.floor(px * inv), B.floor(py * inv)
        ds = hz.read(B.minimum(inv, 1.0), cx, cy) if clamp else hz.cell(inv, cx, cy)
        tx = _exit_t(B, (cx + fx) * size + ux, r.px0, ix, zx)
        ty = _exit_t(B, (cy + fy) * size + uy, r.py0, iy, zy)
        tz = B.select(away, (ds - r.d0) * iz, zero + BIG)
        tmin = B.minimum(B.minimum(tx, ty), tz)
        above = ds > pd
        skipped = (tmin != tz) & above
        t = B.select(above, tmin, t)
        # one level up where it skipped the cell, else one down; at the top (one cell, the padded square) a skip
        # leaves the screen (the cell's exit, nudged, lies off it), so no test of the top here: m is capped after
        size = size * B.select(skipped, zero + 2.0, zero + 0.5)
        inv = inv * B.select(skipped, zero + 0.5, zero + 2.0)
        px, py, _ = r.at(t)
        return t, px, py, size, inv, i + 1.0

    size0 = B.select(r.start, zero + 1.0, zero + 0.5)
    px, py, _ = r.at(t)
    state = (t, px, py, size0, B.select(r.start, zero + 1.0, zero + 2.0), zero)
    if min_occupancy <= 0:
        t, _, _, size, _, i = B.while_loop(state, cond, body, limit=max_iterations)
    else:  # the wave exit needs the count of each wave's marching rays: a host loop
        quit = r.start & ~r.start
        for _ in range(max_iterations):
            act = cond(*state) & ~quit
            a = B.numpy(act).astype(bool)
            if not a.any():
                break
            new = body(*state)
            state = tuple(B.select(act, p, q) for p, q in zip(new, state))
            n = len(a)
            per = np.pad(a, (0, -n % WAVE)).reshape(-1, WAVE).sum(1)
            low = B.array(np.repeat(per, WAVE)[:n].astype(np.float32)) <= float(min_occupancy)
            quit = quit | (act & low)
        t, _, _, size, _, i = state
    m = B.select(r.start, B.minimum(B.exponent(size), hz.top), zero)  # 2^m = size; −1 below level 0
    return t, m, i, on(t) & r.start


def depth_normal(B, scr, j, i, zs) -> V3:
    """The normal of pixel (column j, row i) at depth zs, camera axes, turned towards the camera: reconstructed from
    the depth buffer (a buffer without a G-buffer's normals) by the neighbour in each axis whose depth is nearer to
    the pixel's, four reads of level 0 of the pyramid."""
    W, H, T, Ty = float(scr.width), float(scr.height), scr.tan_x, scr.tan_y
    hz = hiz_of(scr)

    def view_point(jj, ii, z):  # camera-space point of pixel (jj, ii) at depth z
        return V3(z * ((2.0 * (jj + 0.5) / W - 1.0) * T), z * ((1.0 - 2.0 * (ii + 0.5) / H) * Ty), z)

    c = view_point(j, i, zs)
    tangents = []
    for dj, di, last in ((1.0, 0.0, W - 1.0), (0.0, 1.0, H - 1.0)):
        k = j if dj else i
        pts = []
        for sgn in (-1.0, 1.0):
            jj, ii = j + sgn * dj, i + sgn * di
            dn = hz.read(zs * 0.0 + 1.0, jj, ii)  # level 0
            zn = -1.0 / B.select(dn < 0.0, dn, zs * 0.0 - 1.0)
            inside = (k + sgn >= 0.0) & (k + sgn <= last) & (dn < 0.0)
            pts.append((view_point(jj, ii, zn), B.select(inside, B.abs(zn - zs), zs * 0.0 + BIG)))
        (pa, ga), (pb, gb) = pts
        use_b = gb <= ga
        other = V3(*(B.select(use_b, u, v) for u, v in zip((pb.x, pb.y, pb.z), (pa.x, pa.y, pa.z))))
        sgn = B.select(use_b, zs * 0.0 + 1.0, zs * 0.0 - 1.0)
        ok = B.minimum(ga, gb) < BIG
        tangents.append((other - c) * B.select(ok, sgn, sgn * 0.0))
    (ax, ay) = tangents
    n = V3(ax.y * ay.z - ax.z * ay.y, ax.z * ay.x - ax.x * ay.z, ax.x * ay.y - ax.y * ay.x)
    n = n * B.select(n.dot(c) > 0.0, zs * 0.0 - 1.0, zs * 0.0 + 1.0)  # a surface on screen faces the camera
    return n


@register
class SSRHiZ(TracingMethod):
    name = "ssr_hiz"
    Params = Params
    ratio_where_valid = True
    knob = Knob("max_iterations", (16, 32, 64, 128, 256))

    def _fallback(self) -> Method | None:
        return REGISTRY[self.params.fallback]() if self.params.fallback != "none" else None

    def views_needed(self) -> Views:
        fb = self._fallback()
        return Views.merge(Views(screen=True), *([fb.views_needed()] if fb else []))

    def confidence(self, B, scr, r: ScreenRay, t, on_screen):
        """(c, hit pixel column j, row i, the hit's rgbz) of SSSR's validation (module docstring)."""
        p = self.params
        W, H, T, Ty = float(scr.width), float(scr.height), scr.tan_x, scr.tan_y
        px, py, pd = r.at(t)
        j = B.minimum(B.maximum(B.floor(px), 0.0), W - 1.0)
        i = B.minimum(B.maximum(B.floor(py), 0.0), H - 1.0)
        rgbz = scr.fetch(j, i)
        zs = rgbz[3]
        far = zs >= FAR_Z
        zs = B.select(far, zs * 0.0 + 1.0, zs)
        # ------------------------------------------------------------- the normal: the G-buffer's, or from depth
        if getattr(scr, "has_normals", False):
            nw = scr.fetch_normal(j, i)
            n = V3(
                *(
                    nw[0] * float(a[0]) + nw[1] * float(a[1]) + nw[2] * float(a[2])
                    for a in (scr.right, scr.up, scr.forward)
                )
            )
        else:
            n = depth_normal(B, scr, j, i, zs)
        back = (n.x * r.Rc[0] + n.y * r.Rc[1] + n.z * r.Rc[2]) > 1e-6 * B.length(n)
        # ------------------------------------------------------------- distance to the surface, border fade
        zh = -1.0 / B.select(pd < 0.0, pd, pd * 0.0 - 1e-30)
        v = V3((2.0 * px / W - 1.0) * T, (1.0 - 2.0 * py / H) * Ty, px * 0.0 + 1.0)
        delta = B.abs(zs - zh) * B.length(v)
        fx, fy = 0.05 * H / W, 0.05
        u, w = px / W, py / H
        vignette = (smoothstep(B, 0.0, fx, u) * (1.0 - smoothstep(B, 1.0 - fx, 1.0, u))
                    * smoothstep(B, 0.0, fy, w) * (1.0 - smoothstep(B, 1.0 - fy, 1.0, w)))  # fmt: skip
        keep = 1.0 - smoothstep(B, 0.0, p.thickness, delta)
        near = (B.abs(px - r.px0) < 2.0) & (B.abs(py - r.py0) < 2.0)
        ok = on_screen & ~near & ~far & ~back & (pd < 0.0) & B.isfinite(delta)
        return B.select(ok, vignette * keep * keep, zs * 0.0), rgbz

    def search(self, B: Backend, env: Captured, x: V3, R: V3) -> Found:
        p = self.params
        scr = env.need_screen(self.name)
        zero = x.x * 0.0
        nan = float("nan")
        if scr is not None:
            r = screen_ray(B, scr, x, R)
            t, _, reads, on_screen = hiz_march(B, scr, hiz_of(scr), r, p.max_iterations, p.min_occupancy)
            c, rgbz = self.confidence(B, scr, r, t, on_screen)
            den = 1.0 - t * r.z0 * r.Rf
            s = t * r.z0 * r.z0 / B.select(den > 0.0, den, zero + 1.0)
            c = B.select((den > 0.0) & B.isfinite(s), c, zero)
            shown = x + R * B.select(c > 0.0, s, zero)
            rgb = rgbz[:3]
            checks = (
                2.0 if getattr(scr, "has_normals", False) else 5.0
            )  # the hit's rgbz, its normal (or 4 depths)
            spent = reads + B.select(r.start, zero + checks, zero)
        else:  # no camera buffer: nothing on screen
            c, shown, rgb, spent = zero, x * 0.0, [zero] * 3, zero
        screen = c >= 0.5
        rad = V3(*rgb)
        valid, l = screen, shown
        fb = self._fallback()
        if fb is not None:  # the environment, blended in by 1 − c

            def sel(m, a: V3, b: V3) -> V3:
                return V3(*(B.select(m, p, q) for p, q in zip((a.x, a.y, a.z), (b.x, b.y, b.z))))

            tr = fb.trace(B, env, x, R, check_origin=False)
            blend = rad * c + V3(
                *(B.select(tr.valid, a, zero) for a in (tr.radiance.x, tr.radiance.y, tr.radiance.z))
            ) * (1.0 - c)
            rad = sel(tr.valid, blend, rad)
            shown, l = sel(screen, shown, tr.shown), sel(screen, l, tr.l)
            spent = spent + B.select(c < 1.0, tr.lookups, zero)
            valid = screen | tr.valid
        shown = V3(*(B.select(valid, a, nan) for a in (shown.x, shown.y, shown.z)))
        safe = V3(*(B.select(valid, a, b) for a, b in zip((shown.x, shown.y, shown.z), (R.x, R.y, R.z))))
        ratio = B.length(safe) / env.distance(safe)  # diagnostic: 1 on the impostor
        return Found(l, shown, rad, ratio, valid, spent)

    def lookups_per_ray(self, res: int | None = None) -> float:
        fb = self._fallback()
        return self.params.max_iterations + 5 + (fb.lookup_bound(res) if fb else 0)

    def volume_lookups(self, res: int | None = None) -> float:
        fb = self._fallback()
        return fb.volume_lookups(res) if fb else 0.0

    def host_steps(self, res: int | None = None) -> float:
        # the occupancy exit marches on the host, one step over all rays per iteration; and the fallback's steps
        fb = self._fallback()
        own = float(self.params.max_iterations) if self.params.min_occupancy > 0 else 0.0
        return own + (fb.host_steps(res) if fb else 0.0)


def hiz_march_ref(depth: np.ndarray, P0, D, max_iterations: int) -> tuple[float, int, int]:
    """Slow twin of :func:`hiz_march` for one ray (P0, D: (px, py, d) and its direction, floats): SSSR's loop in
    plain Python, each cell's minimum taken over its pixels of level 0 (so the pyramid is checked too), the ray
    stopping where it leaves the screen. Returns (t, level, reads)."""
    d0 = hiz_levels(depth)[0].astype(np.float64)
    H, W = depth.shape
    top = int(math.log2(d0.shape[0]))
    inv = [1.0 / a if a != 0 else None for a in D[:2]]
    fo = [0.0 if a < 0 else 1.0 for a in D[:2]]
    uo = [-NUDGE if a < 0 else NUDGE for a in D[:2]]
    exits = lambda cell, size: [  # noqa: E731
        BIG if inv[k] is None else ((cell[k] + fo[k]) * size + uo[k] - P0[k]) * inv[k] for k in (0, 1)
    ]
    t = min(exits([math.floor(P0[0]), math.floor(P0[1])], 1.0))
    m = reads = 0
    while reads < max_iterations and m >= 0:
        p = [P0[k] + t * D[k] for k in range(3)]
        if not (0 <= p[0] < W and 0 <= p[1] < H):
            break
        size = 2**m
        cell = [math.floor(p[0] / size), math.floor(p[1] / size)]
        ds = float(d0[cell[1] * size : (cell[1] + 1) * size, cell[0] * size : (cell[0] + 1) * size].min())
        tz = (ds - P0[2]) / D[2] if D[2] > 0 else BIG
        tmin = min(*exits(cell, float(size)), tz)
        above = ds > p[2]
        skipped = tmin != tz and above
        t = tmin if above else t
        if not (skipped and m >= top):
            m += 1 if skipped else -1
        reads += 1
    return t, m, reads
