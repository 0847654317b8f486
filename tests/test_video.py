"""ColorVideoVDP (optional extra study[video]) on short sequences with a known perturbation: identical videos score
10 JOD, a visible perturbation scores clearly less, a larger one less still (skipped, saying so, without the extra);
the motion claim's verdicts follow."""

import numpy as np
import pytest

from study.measure import video

needs_cvvdp = pytest.mark.skipif(
    not video.available(),
    reason="needs the extra study[video] (cvvdp, PyTorch): bash scripts/setup.sh --video",
)


def sequence(frames=8, size=48, seed=0):
    """A textured square moving right across a grey background, sRGB floats in [0, 1]."""
    rng = np.random.default_rng(seed)
    tex = rng.uniform(0.2, 0.8, (12, 12, 3))
    out = np.full((frames, size, size, 3), 0.5, np.float32)
    for f in range(frames):
        x = 4 + 3 * f
        out[f, 18:30, x : x + 12] = tex
    return out


@needs_cvvdp
def test_identical_is_10_and_a_perturbation_is_seen():
    ref = sequence()
    m = video._metric()
    same = video.jod(ref, ref, fps=8, metric=m)
    small = ref.copy()
    small[:, 18:30] = np.clip(small[:, 18:30] + 0.08, 0, 1)  # a brighter band through the moving square
    big = ref.copy()
    big[:, 18:30] = np.clip(big[:, 18:30] + 0.3, 0, 1)
    q_small, q_big = video.jod(small, ref, fps=8, metric=m), video.jod(big, ref, fps=8, metric=m)
    assert same == pytest.approx(10.0, abs=1e-3)
    assert q_small < 9.8 and q_big < q_small - 0.3, (q_small, q_big)


def test_motion_claim_verdicts():  # the verdicts' logic: no cvvdp needed
    rows = [
        {"label": "truth_at_hit", "jod": 9.6, "jod_lo": 9.5, "jod_hi": 9.7},
        {"label": "good", "jod": 9.4, "jod_lo": 9.3, "jod_hi": 9.5},
        {"label": "bad", "jod": 7.0, "jod_lo": 6.5, "jod_hi": 7.5},
    ]
    s = video.motion_claim(rows)
    assert "good" in s[0] and "the claim holds" in s[0]
    assert "bad" in s[1] and "the claim fails" in s[1]
    noisy = [{**r, "jod": r["jod"] - 3, "jod_lo": r["jod_lo"] - 3, "jod_hi": r["jod_hi"] - 3} for r in rows]
    assert all(
        "is undecided: the references' own noise already costs 3.4 JOD" in t
        for t in video.motion_claim(noisy)
    )
