"""Per-ray outcome classes: did a method show the exact hit, the right ray at the wrong depth, another
surface, or nothing.

The angular error (:func:`study.measure.metrics.angular_error`) is blind to a wrong depth on the same ray: a
shown point anywhere on the ray x + t R, t > 0, has angle 0 at x. The classes here are not:

========================  ====  ==============================================================================
class                     code  the shown point …
========================  ====  ==============================================================================
:data:`CORRECT`           0     lies within ε of the exact hit: ``|shown − exact| ≤ ε``
:data:`WRONG_DEPTH`       1     lies within ε of the exact ray's line, ahead of its origin (t > 0), but > ε
                                from the exact hit (e.g. the floor behind a column top hidden from o)
:data:`WRONG_SURFACE`     2     lies anywhere else, > ε from the exact hit and > ε off the ray
:data:`NO_HIT`            3     is NaN: the method found nothing (``Trace.valid`` False)
========================  ====  ==============================================================================

**Rays that leave the scene** (open environments): an exact ray that hits nothing has its "hit" at infinity,
given as a point at distance ≥ :data:`~study.impostor.cubemap.FAR_MIN` along it (``x + d·FAR``), and a method's
shown point that far away means "no surface, at infinity in that direction". Where either is at infinity the
comparison is by direction: the shown point is *correct* when both are at infinity and the directions differ by
at most ε/|exact − x| (one texel's angle); *wrong depth* when it lies on the exact ray (within that angle, or
within max(ε_fixed, that angle × its distance) of the line for a finite point) but at the other depth (finite
against infinite); else *wrong surface*. ``dist`` and ``depth_error`` are NaN there (no finite distance).

The tolerance is per ray, ``ε = max(EPS_FIXED, texel_footprint(o, exact, res))`` with ``EPS_FIXED = 0.01`` m:
one centimetre, or the world-space size of one cube-map texel at the exact hit seen from the reference point o,
whichever is larger — a method that reads a cube map cannot be asked to be finer than one of its texels. This
tolerance is *texel-relative*: it changes with the cube resolution (about 6 cm at 64², 1 cm at 512²), so a finer
map can make a method look worse; :mod:`study.stats` adds wrong fractions at fixed distances
(``wrong_fraction_1cm``, ``_3cm``, ``_10cm``, …) and at a fixed angle, which keep one meaning.

Which ray: the exact ray is the one Embree traced, from its origin (``exact_origin``, by default the method's
ray origin x) through the exact hit; its direction is R when ``exact_origin`` is not given (the method's ray is
the exact ray) and ``(exact − exact_origin)/|…|`` otherwise (dielectric objects whose outgoing ray the methods
get from the object's own distance map: :meth:`study.optics.shading.ObjectRays.exact_rays`). Shown points on
the method's own, slightly wrong ray then count as WRONG_SURFACE unless they are also on the exact ray.

:func:`classify` is vectorised (numpy); :func:`classify_on` the same on a Dr.Jit backend (LLVM, CUDA: where the
rays are); :func:`classify_ref` is their slow, obvious twin (one ray at a time) for tests.
:func:`outcome_columns` turns the classes into the columns of a results table.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from study.impostor import cubemap
from study.impostor.cubemap import FAR_MIN

#: Outcome class codes, in order of severity (a pixel's map shows its most frequent class, ties to the worse).
CORRECT, WRONG_DEPTH, WRONG_SURFACE, NO_HIT = 0, 1, 2, 3
#: Human names of the classes, indexed by code (legends, tables).
NAMES = ("correct", "wrong depth", "wrong surface", "no hit")
#: The fixed part of the per-ray tolerance ε, metres.
EPS_FIXED = 0.01


@dataclass(frozen=True)
class Outcomes:
    """Per-ray results of :func:`classify` (N rays)."""

    cls: np.ndarray  # (N,) int8: CORRECT, WRONG_DEPTH, WRONG_SURFACE or NO_HIT
    dist: np.ndarray  # (N,) |shown − exact|, m (NaN for NO_HIT)
    depth_error: np.ndarray  # (N,) signed depth error along the exact ray, m: > 0 behind the exact hit
    eps: np.ndarray  # (N,) the tolerance used, m


class _np:  # the numpy "backend" that cubemap.face_uv needs
    abs, maximum = staticmethod(np.abs), staticmethod(np.maximum)
    select = staticmethod(np.where)


def texel_footprint(o, hit, res: int) -> np.ndarray:
    """World-space size of one cube-map texel at ``hit``, seen from the reference point ``o``.

    A texel spans Δs = Δt = 2/res in face coordinates (:mod:`study.impostor.cubemap`: direction
    ``forward + s·right + t·up``). Under this gnomonic projection the angle a texel subtends is
    Δs·√(1 + t²)/(1 + s² + t²) along s and Δt·√(1 + s²)/(1 + s² + t²) along t; the footprint is
    ``|hit − o|`` times the larger of the two. It is 2/res·|hit − o| at a face centre and falls to
    about 0.47 of that at a face corner. The obliquity of the surface at the hit is not taken into account
    (a texel seen at grazing incidence covers a longer strip).

    Parameters
    ----------
    o : (3,) array
        The reference point, world space.
    hit : (N, 3) array
        Points, world space (NaN rows give NaN).
    res : int
        The cube map's resolution (texels along a face edge).

    Returns
    -------
    (N,) float64 array, metres.
    """
    v = np.asarray(hit, float) - np.asarray(o, float)
    with np.errstate(invalid="ignore"):
        _, u, w = cubemap.face_uv(_np, v[:, 0], v[:, 1], v[:, 2])
    s, t = 2 * u - 1, 1 - 2 * w
    q = 1 + s * s + t * t
    ang = (2.0 / res) * np.maximum(np.sqrt(1 + t * t), np.sqrt(1 + s * s)) / q
    return np.linalg.norm(v, axis=-1) * ang


def tolerance(o, exact, res: int) -> np.ndarray:
    """The per-ray tolerance ε = max(:data:`EPS_FIXED`, :func:`texel_footprint`) (N,), metres (NaN-safe)."""
    return np.fmax(EPS_FIXED, texel_footprint(o, exact, res))


def _exact_ray(x, R, exact, exact_origin):
    if exact_origin is None:
        return np.asarray(x, float), np.asarray(R, float)
    e0 = np.asarray(exact_origin, float)
    d = np.asarray(exact, float) - e0
    with np.errstate(invalid="ignore", divide="ignore"):
        return e0, d / np.linalg.norm(d, axis=-1, keepdims=True)


def classify(x, R, shown, exact, *, eps, exact_origin=None) -> Outcomes:
    """Outcome class of every ray (module docstring), with the distance and the signed depth error.

    Parameters
    ----------
    x, R : (N, 3) arrays
        The method's secondary rays: origins and unit directions, world space.
    shown : (N, 3) array
        The points the method shows, world space; NaN where it found nothing.
    exact : (N, 3) array
        The exact (Embree) hits, world space.
    eps : float or (N,) array
        Tolerance per ray, metres (usually :func:`tolerance`).
    exact_origin : (N, 3) array, optional
        Origins of the exactly traced rays where they differ from x (their direction is then taken through
        ``exact``); by default the method's ray is the exact ray.

    Returns
    -------
    Outcomes
        ``cls`` (N,) int8, ``dist`` (N,) = |shown − exact|, ``depth_error`` (N,) =
        (shown − x₀)·d − (exact − x₀)·d along the exact ray (x₀, d), > 0 where the shown point lies beyond the
        exact hit, and ``eps`` (N,).
    """
    shown, exact = np.asarray(shown, float), np.asarray(exact, float)
    x0, d = _exact_ray(x, R, exact, exact_origin)
    eps = np.broadcast_to(np.asarray(eps, float), (len(shown),)).copy()
    rel = shown - x0
    t_shown = np.sum(rel * d, axis=-1)
    t_exact = np.sum((exact - x0) * d, axis=-1)
    off_line = np.linalg.norm(rel - t_shown[:, None] * d, axis=-1)
    dist = np.linalg.norm(shown - exact, axis=-1)
    missing = ~np.all(np.isfinite(shown), axis=-1)
    with np.errstate(invalid="ignore", divide="ignore"):
        cls = np.where(
            dist <= eps, CORRECT, np.where((off_line <= eps) & (t_shown > 0), WRONG_DEPTH, WRONG_SURFACE)
        )
        # ------------------------------------------------------- at infinity (open environments): by direction
        r_shown, r_exact = np.linalg.norm(rel, axis=-1), np.linalg.norm(exact - x0, axis=-1)
        far_e, far_s = r_exact >= FAR_MIN, ~missing & (r_shown >= FAR_MIN)
        tol = eps / r_exact  # the tolerance as an angle, radians
        along = np.arccos(np.clip(t_shown / r_shown, -1, 1)) <= tol  # shown direction within it of the ray's
        near_line = (off_line <= np.fmax(EPS_FIXED, tol * r_shown)) & (t_shown > 0)
        cls = np.where(far_e & far_s, np.where(along, CORRECT, WRONG_SURFACE), cls)
        cls = np.where(far_e & ~far_s, np.where(near_line, WRONG_DEPTH, WRONG_SURFACE), cls)
        cls = np.where(~far_e & far_s, np.where(along, WRONG_DEPTH, WRONG_SURFACE), cls)
    finite = ~missing & ~far_e & ~far_s
    cls = np.where(missing, NO_HIT, cls).astype(np.int8)
    return Outcomes(cls, np.where(finite, dist, np.nan), np.where(finite, t_shown - t_exact, np.nan), eps)


def classify_on(B, x, R, shown, exact, *, eps, exact_origin=None) -> Outcomes:
    """:func:`classify` on the backend ``B`` (Dr.Jit's LLVM or CUDA: one kernel over the rays, in float64 so that
    the classes are numpy's to rounding; ``tests/measure/test_outcomes.py`` compares them). Same parameters and result;
    on the numpy backend it is :func:`classify`."""
    if B.name == "numpy":  # numpy's select is float32 (as the methods compute): classify is the numpy path
        return classify(x, R, shown, exact, eps=eps, exact_origin=exact_origin)
    shown, exact = np.asarray(shown, float), np.asarray(exact, float)
    x0, d = _exact_ray(x, R, exact, exact_origin)
    n = len(shown)
    S, E, X0, D = ([B.array64(a[:, k]) for k in range(3)] for a in (shown, exact, x0, d))
    ep = B.array64(np.broadcast_to(np.asarray(eps, float), (n,)))
    rel = [S[k] - X0[k] for k in range(3)]
    t_shown = rel[0] * D[0] + rel[1] * D[1] + rel[2] * D[2]
    to_e = [E[k] - X0[k] for k in range(3)]
    t_exact = to_e[0] * D[0] + to_e[1] * D[1] + to_e[2] * D[2]
    off = [rel[k] - t_shown * D[k] for k in range(3)]
    off_line = B.sqrt(off[0] * off[0] + off[1] * off[1] + off[2] * off[2])
    de = [S[k] - E[k] for k in range(3)]
    dist = B.sqrt(de[0] * de[0] + de[1] * de[1] + de[2] * de[2])
    missing = ~(B.isfinite(S[0]) & B.isfinite(S[1]) & B.isfinite(S[2]))
    c = B.select(
        dist <= ep,
        float(CORRECT),
        B.select((off_line <= ep) & (t_shown > 0), float(WRONG_DEPTH), float(WRONG_SURFACE)),
    )
    # ------------------------------------------------------- at infinity (open environments): by direction
    r_shown = B.sqrt(rel[0] * rel[0] + rel[1] * rel[1] + rel[2] * rel[2])
    r_exact = B.sqrt(to_e[0] * to_e[0] + to_e[1] * to_e[1] + to_e[2] * to_e[2])
    far_e, far_s = r_exact >= FAR_MIN, ~missing & (r_shown >= FAR_MIN)
    tol = ep / r_exact
    along = B.acos(B.minimum(B.maximum(t_shown / r_shown, -1.0), 1.0)) <= tol
    reach = tol * r_shown
    near_line = (off_line <= B.select(reach > EPS_FIXED, reach, EPS_FIXED)) & (t_shown > 0)  # fmax: NaN → ε
    good, bad = float(CORRECT), float(WRONG_SURFACE)
    c = B.select(far_e & far_s, B.select(along, good, bad), c)
    c = B.select(far_e & ~far_s, B.select(near_line, float(WRONG_DEPTH), bad), c)
    c = B.select(~far_e & far_s, B.select(along, float(WRONG_DEPTH), bad), c)
    finite = ~missing & ~far_e & ~far_s
    c = B.select(missing, float(NO_HIT), c)
    nan = float("nan")
    dist, depth = B.select(finite, dist, nan), B.select(finite, t_shown - t_exact, nan)
    B.eval(c, dist, depth)
    out = [np.asarray(B.numpy(a), np.float64) for a in (c, dist, depth)]
    return Outcomes(
        out[0].astype(np.int8), out[1], out[2], np.broadcast_to(np.asarray(eps, float), (n,)).copy()
    )


def classify_ref(x, R, shown, exact, *, eps, exact_origin=None) -> Outcomes:
    """Slow, obvious twin of :func:`classify`: one ray at a time, in plain Python floats."""
    n = len(shown)
    eps = np.broadcast_to(np.asarray(eps, float), (n,))
    cls, dist, depth = np.empty(n, np.int8), np.empty(n), np.empty(n)
    for i in range(n):
        s, e = [float(a) for a in shown[i]], [float(a) for a in exact[i]]
        if exact_origin is None:
            o, d = [float(a) for a in x[i]], [float(a) for a in R[i]]
        else:
            o = [float(a) for a in exact_origin[i]]
            d = [e[k] - o[k] for k in range(3)]
            ln = sum(c * c for c in d) ** 0.5
            d = [c / ln for c in d]
        if not all(math.isfinite(c) for c in s):
            cls[i], dist[i], depth[i] = NO_HIT, np.nan, np.nan
            continue
        rs = sum((s[k] - o[k]) ** 2 for k in range(3)) ** 0.5
        re = sum((e[k] - o[k]) ** 2 for k in range(3)) ** 0.5
        if rs >= FAR_MIN or re >= FAR_MIN:  # at infinity: compared by direction
            tol = eps[i] / re
            cos = sum((s[k] - o[k]) * d[k] for k in range(3)) / rs
            along = math.acos(max(-1.0, min(1.0, cos))) <= tol
            ts = sum((s[k] - o[k]) * d[k] for k in range(3))
            off = sum((s[k] - o[k] - ts * d[k]) ** 2 for k in range(3)) ** 0.5
            if rs >= FAR_MIN and re >= FAR_MIN:
                cls[i] = CORRECT if along else WRONG_SURFACE
            elif re >= FAR_MIN:
                cls[i] = WRONG_DEPTH if off <= max(EPS_FIXED, tol * rs) and ts > 0 else WRONG_SURFACE
            else:
                cls[i] = WRONG_DEPTH if along else WRONG_SURFACE
            dist[i], depth[i] = np.nan, np.nan
            continue
        dist[i] = sum((s[k] - e[k]) ** 2 for k in range(3)) ** 0.5
        ts = sum((s[k] - o[k]) * d[k] for k in range(3))
        te = sum((e[k] - o[k]) * d[k] for k in range(3))
        depth[i] = ts - te
        foot = [o[k] + ts * d[k] for k in range(3)]  # the nearest point of the ray's line
        off = sum((s[k] - foot[k]) ** 2 for k in range(3)) ** 0.5
        if dist[i] <= eps[i]:
            cls[i] = CORRECT
        elif off <= eps[i] and ts > 0:
            cls[i] = WRONG_DEPTH
        else:
            cls[i] = WRONG_SURFACE
    return Outcomes(cls, dist, depth, np.array(eps, float))


def _frac(mask, sel=None) -> float:
    m = mask if sel is None else mask[sel]
    return float(m.mean()) if m.size else np.nan


def _pct(v, q) -> float:
    v = np.asarray(v, float)
    v = v[np.isfinite(v)]
    return float(np.percentile(v, q)) if v.size else np.nan


def outcome_columns(outcomes: Outcomes, hidden, angle) -> dict[str, float]:
    """The columns of a results table that the outcome classes give, one value each.

    Parameters
    ----------
    outcomes : Outcomes
        :func:`classify` of N rays.
    hidden : (N,) bool array
        The exact hit is hidden from the reference point (``occluded`` in :func:`study.measure.case.run_case`).
    angle : (N,) array
        The angular error of each ray, degrees (NaN where nothing is shown).

    Returns
    -------
    dict
        ``correct_fraction``, ``wrong_fraction`` (= 1 − correct; NO_HIT counts as wrong),
        ``wrong_depth_fraction``, ``wrong_surface_fraction``, ``no_hit_fraction`` (over all rays);
        ``wrong_fraction_visible`` / ``wrong_fraction_hidden`` (over the rays whose exact hit is visible / hidden
        from o; NaN where there are none) and ``hidden_fraction``; ``dist_p50``, ``dist_p95``, ``dist_p99``
        (|shown − exact| over the rays with a shown point, m); ``depth_error_p95``: the 95th percentile of the
        *absolute* signed depth error over the rays shown on the exact ray (CORRECT or WRONG_DEPTH), m;
        ``angle_p95_visible_deg`` / ``angle_p95_hidden_deg``. Every fraction counts secondary rays, unweighted.
        ``wrong_fraction`` uses the texel-relative ε of :func:`tolerance` (also written as
        ``wrong_fraction_texel``); the dist/angle percentiles leave out the rays without a finite value, and
        :func:`study.measure.case_columns.ray_columns` writes how many (``dist_dropped``, ``angle_dropped``) beside the
        counts, intervals and fixed-tolerance fractions.
    """
    c = np.asarray(outcomes.cls)
    hidden = np.asarray(hidden, bool)
    wrong = c != CORRECT
    on_ray = (c == CORRECT) | (c == WRONG_DEPTH)
    return {
        "correct_fraction": _frac(c == CORRECT),
        "wrong_fraction": _frac(wrong),
        "wrong_depth_fraction": _frac(c == WRONG_DEPTH),
        "wrong_surface_fraction": _frac(c == WRONG_SURFACE),
        "no_hit_fraction": _frac(c == NO_HIT),
        "wrong_fraction_visible": _frac(wrong, ~hidden),
        "wrong_fraction_hidden": _frac(wrong, hidden),
        "hidden_fraction": _frac(hidden),
        "dist_p50": _pct(outcomes.dist, 50),
        "dist_p95": _pct(outcomes.dist, 95),
        "dist_p99": _pct(outcomes.dist, 99),
        "depth_error_p95": _pct(np.abs(outcomes.depth_error[on_ray]), 95),
        "angle_p95_visible_deg": _pct(np.asarray(angle)[~hidden], 95),
        "angle_p95_hidden_deg": _pct(np.asarray(angle)[hidden], 95),
    }


def class_fractions(outcomes: Outcomes) -> np.ndarray:
    """One-hot (N, 4) float of the classes: per-pixel averages of it (``ObjectRays.per_pixel``) give each
    pixel's fraction of rays in each class."""
    return (np.asarray(outcomes.cls)[:, None] == np.arange(4)[None, :]).astype(float)


def majority(fractions: np.ndarray) -> np.ndarray:
    """(H, W, 4) class fractions → (H, W) float: the most frequent class (ties to the worse, i.e. the
    higher code), NaN where a pixel has no rays (all fractions NaN or zero)."""
    f = np.asarray(fractions, float)
    best, top = np.full(f.shape[:-1], 3.0), np.nan_to_num(f[..., 3])
    for c in (2, 1, 0):  # a better class must be strictly more frequent: ties stay with the worse
        v = np.nan_to_num(f[..., c])
        np.copyto(best, c, where=v > top)
        np.maximum(top, v, out=top)
    return np.where(top > 0, best, np.nan)  # fractions are ≥ 0: none > 0 means no rays


def off_screen(camera, points) -> np.ndarray:
    """Which points the camera does not see in its frame: (N,) bool, True where a point projects outside the
    image (or lies behind the camera's eye plane, or is not finite). The projection is the pinhole camera of
    :mod:`study.scene.camera` (horizontal ``fov``); whether something nearer hides the point is not asked.

    Parameters
    ----------
    camera : study.scene.schema.Camera
        eye, target, up, fov (degrees, horizontal), width, height.
    points : (N, 3) array
        World points (the exact hits).
    """
    from study.scene.camera import look_at_basis

    f, r, u = look_at_basis(camera.eye, camera.target, camera.up)
    c = np.asarray(points, float) - np.asarray(camera.eye, float)
    z = c @ f
    tan = math.tan(math.radians(camera.fov) / 2)
    with np.errstate(divide="ignore", invalid="ignore"):
        sx, sy = (c @ r) / (z * tan), (c @ u) / (z * tan * camera.height / camera.width)
        inside = (z > 0) & (np.abs(sx) < 1) & (np.abs(sy) < 1)
    return ~inside


def offscreen_columns(outcomes: Outcomes, offscreen) -> dict[str, float]:
    """The screen-space columns of a results table: ``offscreen_fraction`` (rays whose exact hit projects off the
    camera's screen, :func:`off_screen`) and ``wrong_fraction_offscreen`` (the fraction of those rays the method
    got wrong, NaN where there are none), as ``wrong_fraction_hidden`` is for the rays hidden from o."""
    offscreen = np.asarray(offscreen, bool)
    return {
        "offscreen_fraction": _frac(offscreen),
        "wrong_fraction_offscreen": _frac(np.asarray(outcomes.cls) != CORRECT, offscreen),
    }
