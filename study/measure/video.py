"""Video quality of a method's motion sequence on the object's pixels: ColorVideoVDP (``cvvdp``, pinned in the
optional extra ``study[video]``) of the method's frames against ``truth_at_hit``'s (every ray's exact hit shaded by
Mitsuba), in JOD.

JOD (just-objectionable differences): 10 means no visible difference from the reference; on ColorVideoVDP's scale
a difference of 1 JOD between two conditions means that 75 % of observers choose the one with the higher score,
i.e. one JND (Mantiuk et al., "ColorVideoVDP: A visual difference predictor for image, video and display
distortions", SIGGRAPH 2024, and the cvvdp README). That is the bound of the motion claim (:data:`BOUND_JOD`): an
error less than one JND beyond what the references' own noise already costs can "hardly be recognized visually".
The paper itself gives no number.

Only the object is judged (:func:`on_object`): outside the pixels fully on the object the method's frames take the
reference's values (no difference there), and every frame is cut to one square around the object's pixels in every
frame (the view stays still while the object moves) — frame-wide, 93–98 % of each frame is the room, whose
path-tracing noise would set the score. The frames are sRGB, 8 bit after :func:`study.measure.metrics.to_ldr`,
shown on ColorVideoVDP's display model :data:`CVVDP_DISPLAY` — a 24-inch Full HD SDR monitor, 200 cd/m² peak, contrast
1000:1, 250 lux office light, seen from 0.6 m (its ``standard_fhd``) — at the animation's frame rate.

Intervals come from seed replicates (the whole sequence rendered again with another ``render.seed``: impostor
captures, truth_at_hit and Mitsuba all drawn anew): a 95 % Student-t interval of the mean over the seeds
(:func:`seed_interval`). The noise floor is the JOD of truth_at_hit of the next seed against truth_at_hit of this
one: what Monte Carlo noise alone costs.
"""

from __future__ import annotations

import contextlib
import io
import os

import numpy as np

#: ColorVideoVDP's display model (see the module docstring).
CVVDP_DISPLAY = "standard_fhd"
#: cvvdp's version the numbers were made with (v0.6 retrained the model: pin it).
VERSION = "0.5.7"
#: the motion claim's bound: 1 JOD, the difference 75 % of observers notice (one JND on ColorVideoVDP's scale)
BOUND_JOD = 1.0
#: the label of the noise floor's row (truth_at_hit of another seed against truth_at_hit)
FLOOR = "truth_at_hit"


def available() -> bool:
    """True where the optional extra ``study[video]`` (cvvdp and PyTorch) is installed."""
    try:
        import pycvvdp  # noqa: F401
    except ImportError:
        return False
    return True


def _metric():
    os.environ.setdefault("HF_HUB_OFFLINE", "1")  # everything it needs ships in the package
    import pycvvdp
    import torch

    torch.manual_seed(0)
    with contextlib.redirect_stderr(io.StringIO()):
        return pycvvdp.cvvdp(display_name=CVVDP_DISPLAY, quiet=True, device=torch.device("cpu"))


def jod(test: np.ndarray, ref: np.ndarray, *, fps: float, metric=None) -> float:
    """ColorVideoVDP's JOD of ``test`` against ``ref``: (F, H, W, 3) sRGB frames, uint8 or float in [0, 1]."""
    import torch

    def prep(a):
        a = np.asarray(a)
        a = a.astype(np.float32) / 255.0 if a.dtype == np.uint8 else np.clip(a, 0.0, 1.0).astype(np.float32)
        return torch.from_numpy(np.ascontiguousarray(a))

    m = metric or _metric()
    with torch.no_grad(), contextlib.redirect_stderr(io.StringIO()):
        q, _ = m.predict(prep(test), prep(ref), dim_order="FHWC", frames_per_second=float(fps))
    return float(q)


def on_object(
    test: np.ndarray, ref: np.ndarray, masks: np.ndarray, crop: tuple[slice, slice]
) -> tuple[np.ndarray, np.ndarray]:
    """(test, ref) of (F, H, W, 3) frames judged on the object only: ``test`` keeps its pixels where ``masks``
    (F, H, W) is set and takes ``ref``'s elsewhere; both cut to ``crop`` (rows, columns)."""
    t = np.where(np.asarray(masks, bool)[..., None], test, ref)
    return t[:, crop[0], crop[1]], np.asarray(ref)[:, crop[0], crop[1]]


def object_jod(test, ref, masks, crop, *, fps: float, metric=None) -> float:
    """:func:`jod` of ``test`` against ``ref`` on the object's pixels (:func:`on_object`)."""
    t, r = on_object(test, ref, masks, crop)
    return jod(t, r, fps=fps, metric=metric)


def motion_claim(rows: list[dict], *, bound: float = BOUND_JOD) -> list[str]:
    """The paper's claim for moving curved objects — localization errors "can hardly be recognized visually" —
    judged per sequence (object) and method on the object's pixels, from ``motion.csv``'s rows (``sequence``,
    ``label``, ``jod`` and ``gap``, the floor's JOD minus the method's, each with its seed interval ``_lo``/``_hi``;
    the floor's row is :data:`FLOOR`). Per method: holds where the gap's interval lies below ``bound`` (one JND),
    fails where it lies above, undecided where it straddles the bound or no interval exists (one seed). Where the
    floor itself costs more than a third of the bound (10 − floor > bound / 3) the references' noise would hide an
    error of that size and every verdict is undecided. Per sequence first a sentence on the floor: the methods
    closer to each other than the floor costs (tied), and the smallest difference between two methods beyond it
    (the floor should be at most a third of it to order them)."""
    out = []
    for seq in dict.fromkeys(r.get("sequence", "") for r in rows):
        mine = [r for r in rows if r.get("sequence", "") == seq]
        floor = next((r for r in mine if r["label"] == FLOOR), None)
        methods = [r for r in mine if r["label"] != FLOOR and np.isfinite(_f(r.get("jod")))]
        if floor is None or not methods:
            continue
        f, loss = _f(floor["jod"]), 10 - _f(floor["jod"])
        name = f"{seq}: " if seq else ""
        gaps = sorted(
            (abs(_f(a["jod"]) - _f(b["jod"])), a["label"], b["label"])
            for i, a in enumerate(methods)
            for b in methods[i + 1 :]
        )
        head = (
            f"{name}noise floor {f:.2f} JOD (truth_at_hit of another seed; {_f(floor.get('seeds')):.0f} seeds, 95 % CI "
            f"{_f(floor['jod_lo']):.2f}–{_f(floor['jod_hi']):.2f}): the references' noise costs {loss:.2f} JOD, "
            + ("within" if loss <= bound / 3 else "more than")
            + f" a third of the {bound:g}-JOD bound"
        )
        tied = [(d, a, b) for d, a, b in gaps if d <= loss]  # closer than the noise floor: not to be ordered
        apart = [(d, a, b) for d, a, b in gaps if d > loss]
        if tied:
            names = sorted({x for _, a, b in tied for x in (a, b)})
            head += (
                f"; {', '.join(names)} lie within the floor of each other (at most {tied[-1][0]:.2f} JOD apart, "
                "less than the references' noise costs: not ordered)"
            )
        if apart:
            d, a, b = apart[0]
            head += (
                f"; the smallest difference between two methods beyond it is {d:.2f} JOD ({a} vs {b}), the floor "
                + ("at most a third of it" if loss <= d / 3 else "more than a third of it: raise render.spp")
            )
        if not np.isfinite(f):
            head = f"{name}no noise floor: one seed (give two seeds or more)"
        out.append(head)
        for r in methods:
            gap, lo, hi = _f(r["gap"]), _f(r.get("gap_lo")), _f(r.get("gap_hi"))
            if not np.isfinite(loss):
                verdict = "is undecided: one seed gives no noise floor"
            elif loss > bound / 3:
                verdict = f"is undecided: the references' own noise already costs {loss:.2f} JOD"
            elif not (np.isfinite(lo) and np.isfinite(hi)):
                verdict = "is undecided: one seed gives no interval"
            elif hi < bound:
                verdict = "holds"
            elif lo > bound:
                verdict = "fails"
            else:
                verdict = f"is undecided: its interval straddles the {bound:g}-JOD bound"
            out.append(
                f"{name}{r['label']}: {_f(r['jod']):.2f} JOD on the object against truth_at_hit (95 % CI over seeds "
                f"{_f(r['jod_lo']):.2f}–{_f(r['jod_hi']):.2f}), {gap:+.2f} JOD below the noise floor (CI "
                f"{lo:+.2f}–{hi:+.2f}): the claim {verdict} (bound {bound:g} JOD = 1 JND, the difference 75 % of "
                "observers notice)"
            )
    return out


def _f(x) -> float:
    try:
        return float(x)
    except (TypeError, ValueError):
        return float("nan")
