"""The oracle with one meaning, and the split of a method's image error over every object pixel.

**Which hits the views hold.** The views are what the reference point o captured (the impostor). Each secondary
ray's exact hit falls in one of four classes (:func:`view_class`, from :func:`exact_hits`):

====================  ====  ===============================================================================
class                 code  the exact hit …
====================  ====  ===============================================================================
:data:`HELD`          0     is a surface point o sees (nothing nearer on the segment o → hit)
:data:`HIDDEN`        1     is a surface point something nearer hides from o
:data:`ESC_VISIBLE`   2     is at infinity (the ray leaves the scene) and o, looking in the ray's direction,
                            sees no surface either: the impostor's open texel holds the background there
:data:`ESC_HIDDEN`    3     is at infinity, but o sees a surface in the ray's direction (a wall behind the
                            opening, seen from o): the texel holds that wall, not the background
====================  ====  ===============================================================================

The hit is *held* (:func:`held`) in the classes HELD and ESC_VISIBLE, i.e. exactly where o sees it: for an
escaping ray "seeing it" means seeing the background in its direction (the point ``x + d·FAR`` is not occluded
from o). No search on o's views can show a hit of the other two classes. Whether the camera's frame shows the
hit (:func:`study.measure.outcomes.off_screen`) is another question, asked of screen-space views only: an
off-screen hit is held or not by o's views like any other.

**oracle_map** (:func:`oracle_radiance`) = the exact hit shaded with what the views hold:

* a held hit seen from o: the impostor's radiance read in the direction o → exact hit;
* an escaping ray whose direction o sees open (ESC_VISIBLE): the background in the ray's *own* direction (the
  environment's radiance along the exact ray, which for a ray that meets nothing is the emitter's value:
  Mitsuba's ``truth_at_hit`` there);
* a hit the views do not hold: no value. Its pixels are marked (:data:`MARK`, magenta) in the image and left out
  of every ``*_oracle`` column (``held_pixels`` says how many pixels are left).

**The error split** (:func:`split_columns`), in mean squared error (linear radiance², per pixel the mean over
channels), over *all* the object's pixels (``mask``); T = truth_at_hit (two seeds), n = its noise image (half the
seeds' difference, so n² estimates the noise variance of T per pixel), O = oracle_map, h = the pixel's rays are all
held, u = 1 − h:

============================  ===========================================================================
``dec_total``                 mean |img − T|²
``dec_search``                mean h·|img − O|²: what a better search on the same views could fix
``dec_visibility``            mean u·(|img − T|² − n²): the error on pixels whose hits the views do not hold
``dec_representation``        mean h·(capture + resolution), measured *without* T: capture = |O − O₂|²/(1 + k)
                              (O₂: the oracle from a second capture seed with 1/k of the samples, k =
                              :data:`SEED_SPP_DIVISOR`: its noise variance is k times O's), resolution =
                              |O − O_c|² − ¾·capture (O_c: from the map at half the resolution, its 2 × 2 texel
                              means; first-order extrapolation, box-filtered texels err ∝ texel size, so O_c errs
                              twice as much as O and O − O_c is O's own error; ¾·capture: the noise of O − O_c,
                              O_c averaging four texels one of which O reads)
``dec_noise``                 mean n²: the reference's own noise (two seeds)
``dec_cross``                 mean h·2(img − O)·(O − T): the search × (representation + noise) cross term
``dec_residual``              total − (search + visibility + representation + noise + cross) = mean
                              h·(|O − T|² − n² − representation): what the map misses that neither seed nor
                              resolution explains (view-dependent radiance, bounce budget, …)
============================  ===========================================================================

**Each term from its own experiment.** Besides the split above, whose representation is measured without T, the
representation is also measured directly: ``dec_representation_direct`` = mean h·(|O − T|² − n²), the exact hit
shaded from the impostor against the same hit shaded from the scene, the truth's noise removed. Then every part is
an experiment of its own: search = the method against the oracle on the same views (img vs O), visibility = the
pixels whose hits the views do not hold against the truth there, representation = O against T, noise = the two
seeds. ``dec_sums_direct`` is 1 when search + visibility + representation_direct + noise meets the total within
their intervals: what is left is the cross term 2(img − O)(O − T) (:data:`TERMS`' ``cross``), so the check asks
whether the search's error and the map's are unrelated. ``tests/measure/test_split_planted.py`` plants each kind of
error in a cube map of a known room (shifted views, a wall hidden, a blurred impostor, noisy truth): each lands in
its own term.

Each term has a 95 % interval over the object's spatially correlated pixels (the mean ± t·√variance, the variance
from the term's own autocovariance over a lag window sized by its correlation length:
:func:`study.stats.spatial.mean_intervals`), written ``dec_<term>_lo``/``_hi``. ``dec_sums`` is 1 when the
parts add up to the total within their intervals: the parts'
summed interval [Σ lo, Σ hi] meets the total's. ``dec_residual``'s own interval is the stricter, paired check (it
excludes 0 where the map misses more than seed and resolution explain, e.g. at the edge of an emitter, where texel
filtering errs more than first order). No term is defined from another: the representation is measured against O₂ and
O_c, not against T, so the sum is a test, not an identity.
"""

from __future__ import annotations

import math

import numpy as np

from study.impostor.cubemap import FAR
from study.measure.metrics import masked_rows
from study.stats import LEVEL
from study.stats.spatial import grouped_intervals

#: The colour of oracle_map pixels whose hits the views do not hold (linear RGB).
MARK = (1.0, 0.0, 1.0)
#: The second capture seed takes 1/k of the capture's samples per texel (its cost), k = this.
SEED_SPP_DIVISOR = 8
#: The split's terms, in the order the parts add up (``dec_residual`` closes the sum).
TERMS = ("search", "visibility", "representation", "noise", "cross")
#: The parts measured each by its own experiment (module docstring): their sum is checked against the total.
DIRECT = ("search", "visibility", "representation_direct", "noise")


#: Where a secondary ray's exact hit stands with o's views (module docstring), codes of :func:`view_class`.
HELD, HIDDEN, ESC_VISIBLE, ESC_HIDDEN = 0, 1, 2, 3
#: Names of the view classes, indexed by code (tables, legends).
VIEW_NAMES = ("held", "hidden", "escaping-visible", "escaping-hidden")


def hidden_from(tracer, o, points) -> np.ndarray:
    """(N,) bool: something nearer than each of ``points`` (N, 3) lies on the segment from ``o`` (3,) to it, by
    the exact ``tracer`` (a relative slack of 1e-4 and 1e-5 m keeps a point on a surface seen). For a point at
    :data:`~study.impostor.cubemap.FAR` along an escaping ray this asks whether o sees a surface in that
    direction."""
    to_hit = np.asarray(points, float) - np.asarray(o, float)
    dist = np.linalg.norm(to_hit, axis=-1)
    seen = tracer.distance(np.broadcast_to(np.asarray(o, float), to_hit.shape), to_hit / dist[:, None])
    return seen < dist * (1 - 1e-4) - 1e-5


def exact_hits(tracer, origins, dirs, o) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The exact answer for rays ``origins + t·dirs`` (N, 3 each, unit dirs) seen against o's views:
    (point (N, 3): the first hit, escaping rays at ``FAR`` in their direction; escapes (N,) bool; hidden (N,)
    bool: :func:`hidden_from` o)."""
    origins, dirs = np.asarray(origins, float), np.asarray(dirs, float)
    point = tracer.intersect(origins, dirs)["point"]
    escapes = ~np.all(np.isfinite(point), axis=-1)  # open environments: the ray leaves the scene
    point[escapes] = origins[escapes] + dirs[escapes] * FAR  # "no surface": at infinity (cubemap.FAR)
    return point, escapes, hidden_from(tracer, o, point)


def view_class(hidden, escapes) -> np.ndarray:
    """(N,) int8 class of each exact hit (module docstring) from ``hidden`` (:func:`hidden_from`: for an escaping
    ray, o sees a surface in its direction) and ``escapes``."""
    hidden, escapes = np.asarray(hidden, bool), np.asarray(escapes, bool)
    return np.where(
        escapes, np.where(hidden, ESC_HIDDEN, ESC_VISIBLE), np.where(hidden, HIDDEN, HELD)
    ).astype(np.int8)


def held(hidden, escapes) -> np.ndarray:
    """(N,) bool: the exact hit is held by o's views: class HELD or ESC_VISIBLE of :func:`view_class` (seen from
    o; an escaping ray only where o sees the background in its direction, not a wall)."""
    return np.isin(view_class(hidden, escapes), (HELD, ESC_VISIBLE))


def oracle_radiance(looked_up, background_along, held_rays, escapes) -> np.ndarray:
    """(N, 3) oracle radiance per ray (module docstring): ``looked_up`` (the map read towards the exact hit) where
    the hit is held and finite, ``background_along`` (radiance along the ray itself) where the ray escapes, NaN
    where the views do not hold the hit."""
    escapes = np.asarray(escapes, bool)[:, None]
    out = np.where(escapes, background_along, looked_up)
    return np.where(np.asarray(held_rays, bool)[:, None], out, np.nan)


def measures_the_map(col: str) -> bool:
    """Whether ``col`` is measured against the cube map at the exact hit (the oracle_map, the split's terms): what
    the row of a method that reads no cube map leaves out (``Method.reads_views`` False: the exact query)."""
    return "oracle" in col or col.startswith("dec_")


def unread_blank(cols: dict) -> dict:
    """``cols`` with every column :func:`measures_the_map` NaN: the row of a method that reads no cube map."""
    return {k: (np.nan if measures_the_map(k) else v) for k, v in cols.items()}


def held_pixels(rays, held_rays) -> np.ndarray:
    """(H, W) bool: pixels none of whose object rays has a hit the views do not hold."""
    return rays.per_pixel((~np.asarray(held_rays, bool)).astype(float), fill=0.0) == 0


def mark(img: np.ndarray, keep: np.ndarray) -> np.ndarray:
    """``img`` with the pixels not in ``keep`` painted :data:`MARK`."""
    out = np.array(img, np.float32, copy=True)
    out[~np.asarray(keep, bool)] = MARK
    return out


def coarser(radiance: np.ndarray) -> np.ndarray:
    """(6, R, R, C) cube-map texels → (6, R/2, R/2, C): the means of 2 × 2 texels (R even)."""
    f, r, _, c = radiance.shape
    return radiance.reshape(f, r // 2, 2, r // 2, 2, c).mean(axis=(2, 4))


def _sq(a, b=None) -> np.ndarray:
    """Per pixel, the mean over channels of a² (or a·b)."""
    return np.mean(a * (a if b is None else b), axis=-1)


def pixel_terms(img, truth, noise, oracle, oracle_seed, oracle_coarse, held_px) -> dict[str, np.ndarray]:
    """The per-pixel values whose means are the split's terms (module docstring), for P pixels.

    Parameters
    ----------
    img, truth, noise, oracle, oracle_seed, oracle_coarse : (P, 3) arrays
        The method's image, truth_at_hit, its noise image, oracle_map, the oracle from a second capture seed (1/k
        of the samples) and from the map at half the resolution, on the object's pixels (oracles may be NaN where
        not held). ``img`` may be a stack (M, P, 3): each term that the image enters is then (M, P).
    held_px : (P,) bool
        The pixel's hits are all held.

    Returns
    -------
    dict of (P,) float arrays: ``total`` and every name of :data:`TERMS`, ``residual`` and
    ``representation_direct``.
    """
    img, truth, noise = (np.asarray(a, float) for a in (img, truth, noise))
    h = np.asarray(held_px, bool)
    O, O2, Oc = (
        np.where(h[:, None], np.asarray(a, float), 0.0) for a in (oracle, oracle_seed, oracle_coarse)
    )
    e = img - truth
    capture = _sq(O - O2) / (1 + SEED_SPP_DIVISOR)
    t = {
        "total": _sq(e),
        "search": np.where(h, _sq(img - O), 0.0),
        "visibility": np.where(h, 0.0, _sq(e) - _sq(noise)),
        "representation": np.where(h, capture + _sq(O - Oc) - 0.75 * capture, 0.0),
        "noise": _sq(noise),
        "cross": np.where(h, 2 * _sq(img - O, O - truth), 0.0),
    }
    t["residual"] = t["total"] - sum(t[k] for k in TERMS)
    t["representation_direct"] = np.where(h, _sq(O - truth) - _sq(noise), 0.0)  # O against T itself
    return t


def split_columns(
    img, truth, noise, oracle, oracle_seed, oracle_coarse, *, mask, held_px, intervals: bool = True
) -> dict[str, float]:
    """The ``dec_*`` columns of one image (module docstring) over the object's pixels ``mask`` (H, W), with
    intervals; also ``rmse_truth_held`` / ``rmse_truth_unheld`` (RMSE against T on the pixels whose hits the views
    hold / do not hold, with ``_lo``/``_hi``: the interval of the mean of se·[held] over all pixels, divided by the
    held share, i.e. given the number of held pixels), ``held_pixels`` and ``unheld_pixels``. ``intervals`` False
    (sweeps: about 1 s of CPU per method and case saved at 10⁴ pixels) leaves every ``_lo``/``_hi`` and
    ``dec_sums`` NaN."""
    return split_stack(np.asarray(img)[None], truth, noise, oracle, oracle_seed, oracle_coarse, mask=mask,
                       held_px=held_px, intervals=intervals)[0]  # fmt: skip


def split_stack(
    images, truth, noise, oracle, oracle_seed, oracle_coarse, *, mask, held_px, intervals: bool = True
) -> list[dict[str, float]]:
    """:func:`split_columns` of each image of ``images`` (M, H, W, 3): the references' masked pixels once, the
    per-pixel terms (:func:`pixel_terms`) over the stack, the intervals per image."""
    mask = np.asarray(mask, bool)
    h = np.asarray(held_px, bool)[mask]
    refs = [np.asarray(a)[mask] for a in (truth, noise, oracle, oracle_seed, oracle_coarse)]
    terms = pixel_terms(masked_rows(images, mask), *refs, h)  # (M, P), or (P,) where the image plays no part
    terms = {k: np.broadcast_to(v, (len(images), h.size)) for k, v in terms.items()}
    each = [{k: v[i] for k, v in terms.items()} for i in range(len(images))]
    parts = [_parts(t, h) for t in each]
    measured = (  # every image's intervals in one pass over the mask (a term no image changes: measured once)
        [ci for ci, _ in grouped_intervals([list(p.values()) for p in parts], mask, LEVEL)]
        if intervals and h.size
        else [None] * len(each)
    )
    return [_split_of(t, h, dict(zip(p, ci)) if ci else None) for t, p, ci in zip(each, parts, measured)]


def _parts(t: dict, h: np.ndarray) -> dict[str, np.ndarray]:
    """The per-pixel samples whose means get an interval: each term, and the total on held and on unheld
    pixels."""
    names = ["total", *TERMS, "residual", "representation_direct"]
    return {**{f"dec_{k}": t[k] for k in names}, "held": t["total"] * h, "unheld": t["total"] * ~h}


def _split_of(t: dict, h: np.ndarray, cis: dict | None) -> dict[str, float]:
    """The columns of :func:`split_columns` from one image's per-pixel terms ``t`` and the intervals ``cis`` of
    its :func:`_parts` (None: without intervals)."""
    names = ["total", *TERMS, "residual", "representation_direct"]
    out: dict[str, float] = {"held_pixels": int(h.sum()), "unheld_pixels": int((~h).sum())}
    nan2 = (math.nan, math.nan)
    if not h.size:
        return (
            out
            | {f"dec_{k}{s}": math.nan for k in names for s in ("", "_lo", "_hi")}
            | {"dec_sums": math.nan, "dec_sums_direct": math.nan}
        )
    intervals = cis is not None
    cis = cis if intervals else dict.fromkeys(_parts(t, h), nan2)
    for k in names:
        out[f"dec_{k}"], (out[f"dec_{k}_lo"], out[f"dec_{k}_hi"]) = float(t[k].mean()), cis[f"dec_{k}"]
    for name, parts_of in (("dec_sums", TERMS), ("dec_sums_direct", DIRECT)):
        lo, hi = sum(out[f"dec_{k}_lo"] for k in parts_of), sum(out[f"dec_{k}_hi"] for k in parts_of)
        out[name] = float(lo <= out["dec_total_hi"] and out["dec_total_lo"] <= hi) if intervals else math.nan
    for name, sel in (("held", h), ("unheld", ~h)):
        share = sel.mean()
        out[f"rmse_truth_{name}"] = math.sqrt(t["total"][sel].mean()) if sel.any() else math.nan
        lo, hi = (math.sqrt(max(b, 0.0) / share) for b in cis[name]) if sel.any() else nan2
        out[f"rmse_truth_{name}_lo"], out[f"rmse_truth_{name}_hi"] = lo, hi
    return out
