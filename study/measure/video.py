"""Video quality of a method's motion sequence: ColorVideoVDP (``cvvdp``, pinned in the optional extra
``study[video]``) of the method's frames against Mitsuba's, in JOD.

JOD (just-objectionable differences): 10 means no visible difference from the reference; each unit less means
that about 75 % of viewers would prefer the reference. The frames are the animation's own (sRGB, 8 bit after
:func:`study.measure.metrics.to_ldr`), shown on ColorVideoVDP's display model :data:`CVVDP_DISPLAY` — a 24-inch Full HD
SDR monitor, 200 cd/m² peak, contrast 1000:1, 250 lux office light, seen from 0.6 m (its ``standard_fhd``) — at
the animation's frame rate. The interval comes from the sequence's ``segments`` equal runs of consecutive frames
(:func:`segment_interval`: the whole sequence's JOD ± Student's t over the segments' standard error; a percentile
bootstrap over 4 segments covered 74 % of the time): it says how much the verdict depends on which part of the
motion is watched, not how observers scatter. The noise floor is the JOD of ``truth_at_hit`` (every ray's
exact hit shaded by Mitsuba) against Mitsuba's render: what Monte Carlo noise alone costs.
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


def jod_with_interval(
    test: np.ndarray, ref: np.ndarray, *, fps: float, segments: int = 4, metric=None
) -> tuple[float, float, float]:
    """(JOD of the whole sequence, 95 % interval low, high) — the interval from ``segments`` runs of
    consecutive frames (see the module docstring); (jod, nan, nan) when the sequence is too short to split."""
    m = metric or _metric()
    whole = jod(test, ref, fps=fps, metric=m)
    F = len(test)
    if F < 2 * segments:
        return whole, float("nan"), float("nan")
    edges = np.linspace(0, F, segments + 1).astype(int)
    parts = np.array([jod(test[a:b], ref[a:b], fps=fps, metric=m) for a, b in zip(edges[:-1], edges[1:])])
    return (whole, *segment_interval(whole, parts))


def segment_interval(whole: float, parts, level: float = 0.95) -> tuple[float, float]:
    """(lo, hi): the ``level`` interval of a whole sequence's score from its k segments' scores ``parts``: ``whole``
    ± t₍ₖ₋₁₎ · sd(parts) / √k (the segments as independent draws of the score, the whole as their mean; it
    contains ``whole``). Equal parts: (whole, whole)."""
    from scipy.stats import t

    p = np.asarray(parts, float)
    if p.size < 2 or np.ptp(p) == 0:
        return float(whole), float(whole)
    half = float(t.ppf(0.5 + level / 2, p.size - 1) * p.std(ddof=1) / np.sqrt(p.size))
    return float(whole) - half, float(whole) + half


def motion_rows(sequences: dict[str, np.ndarray], reference: np.ndarray, *, fps: float) -> list[dict]:
    """One row per sequence (label → frames) against ``reference``: label, jod, jod_lo, jod_hi, frames, display."""
    m = _metric()
    rows = []
    for label, frames in sequences.items():
        q, lo, hi = jod_with_interval(frames, reference, fps=fps, metric=m)
        rows.append({"label": label, "jod": q, "jod_lo": lo, "jod_hi": hi, "frames": len(frames),
                     "display": CVVDP_DISPLAY, "cvvdp": VERSION})  # fmt: skip
    return rows


def motion_claim(
    rows: list[dict], *, floor_label: str = "truth_at_hit", within: float = 0.5, quiet_floor: float = 9.0
) -> list[str]:
    """The paper's claim for moving curved objects — localization errors "can hardly be recognized visually" —
    judged per method: holds where the method's JOD is no more than ``within`` JOD below the noise floor's (what
    Monte Carlo noise alone costs), its interval included. Where the floor itself lies below ``quiet_floor`` JOD the
    references' noise would hide any error of that size, and every verdict is "undecided" (a claim tested where
    it cannot fail is not tested). One sentence per method."""
    floor = next((r for r in rows if r["label"] == floor_label), None)
    if floor is None:
        return []
    out = []
    for r in rows:
        if r["label"] == floor_label:
            continue
        gap = floor["jod"] - r["jod"]
        lo_gap = floor["jod"] - (r["jod_hi"] if np.isfinite(r["jod_hi"]) else r["jod"])
        verdict = "holds" if gap <= within else ("fails" if lo_gap > within else "undecided")
        if floor["jod"] < quiet_floor:
            verdict = f"is undecided: the references' own noise already costs {10 - floor['jod']:.1f} JOD"
        out.append(
            f"{r['label']}: {r['jod']:.2f} JOD (95 % CI over segments {r['jod_lo']:.2f}–{r['jod_hi']:.2f}) "
            f"against the noise floor's {floor['jod']:.2f}: {gap:+.2f} below it, the claim {verdict} "
            f"(bound {within} JOD)"
        )
    return out
