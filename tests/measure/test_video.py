"""ColorVideoVDP (optional extra study[video]) on short sequences with a known perturbation: identical videos score
10 JOD, a visible perturbation scores clearly less, a larger one less still (skipped, saying so, without the extra);
the motion claim's verdicts follow."""

import numpy as np
import pytest

from study import stats
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


def _rows(floor, methods, seq="ball"):
    """motion.csv rows: the floor (jod, its interval) and methods as (label, jod, gap interval)."""
    f, flo, fhi = floor
    out = [{"sequence": seq, "label": "truth_at_hit", "jod": f, "jod_lo": flo, "jod_hi": fhi, "seeds": 3}]
    for lab, q, glo, ghi in methods:
        out.append({"sequence": seq, "label": lab, "jod": q, "jod_lo": q - 0.1, "jod_hi": q + 0.1,
                    "gap": f - q, "gap_lo": glo, "gap_hi": ghi})  # fmt: skip
    return out


def test_motion_claim_verdicts():  # the verdicts' logic: no cvvdp needed
    rows = _rows(
        (9.8, 9.75, 9.85), [("good", 9.6, 0.1, 0.3), ("bad", 7.0, 2.5, 3.1), ("edge", 8.9, 0.7, 1.2)]
    )
    s = video.motion_claim(rows)
    assert s[0].startswith("ball: noise floor 9.80 JOD") and "within a third of the 1-JOD bound" in s[0]
    assert (
        "smallest difference between two methods beyond it is 0.70 JOD (good vs edge), the floor at most"
        in s[0]
    )
    assert "within the floor of each other" not in s[0]
    tie = video.motion_claim(rows + _rows((9.8, 9.75, 9.85), [("twin", 9.59, 0.1, 0.3)])[1:])[0]
    assert "good, twin lie within the floor of each other (at most 0.01 JOD apart" in tie
    assert "good:" in s[1] and "the claim holds" in s[1] and "1 JND" in s[1]
    assert "bad:" in s[2] and "the claim fails" in s[2]
    assert "edge:" in s[3] and "straddles the 1-JOD bound" in s[3]
    noisy = _rows((9.5, 9.4, 9.6), [("good", 9.4, 0.0, 0.2)])  # the floor costs 0.5 JOD > 1/3
    t = video.motion_claim(noisy)
    assert (
        "more than a third" in t[0] and "undecided: the references' own noise already costs 0.50 JOD" in t[1]
    )
    one = _rows((np.nan, np.nan, np.nan), [("good", 9.4, np.nan, np.nan)])
    assert "no noise floor" in video.motion_claim(one)[0] and "undecided" in video.motion_claim(one)[1]
    both = video.motion_claim(rows + _rows((9.8, 9.7, 9.9), [("good", 9.6, 0.1, 0.3)], seq="ring"))
    assert len(both) == 6 and both[4].startswith("ring: noise floor")


def test_seed_interval_is_students_t():
    from scipy.stats import t

    v = [1.0, 2.0, 4.0]
    mean, lo, hi = stats.seed_interval(v)
    half = t.ppf(0.975, 2) * np.std(v, ddof=1) / np.sqrt(3)  # 4.303 × 1.528 / 1.732
    assert (
        mean == pytest.approx(7 / 3) and hi - mean == pytest.approx(half) and mean - lo == pytest.approx(half)
    )
    assert half == pytest.approx(3.7953, abs=1e-3)
    assert np.isnan(stats.seed_interval([5.0])[1]) and stats.seed_interval([5.0, np.nan])[0] == 5.0


def test_on_object_keeps_only_the_object_and_crops():
    rng = np.random.default_rng(1)
    ref, test = rng.uniform(size=(2, 4, 10, 12, 3))
    masks = np.zeros((4, 10, 12), bool)
    masks[:, 3:5, 4:7] = True
    t, r = video.on_object(test, ref, masks, (slice(2, 8), slice(3, 9)))
    assert t.shape == r.shape == (4, 6, 6, 3)
    np.testing.assert_array_equal(r, ref[:, 2:8, 3:9])
    inside = masks[:, 2:8, 3:9]
    np.testing.assert_array_equal(t[inside], test[:, 2:8, 3:9][inside])  # the object: the test's
    np.testing.assert_array_equal(t[~inside], r[~inside])  # the rest: the reference's


@needs_cvvdp
def test_object_jod_sees_only_the_object():
    """A change outside the object costs nothing (10 JOD); the same change on it is seen."""
    ref = sequence()
    masks = np.zeros(ref.shape[:3], bool)
    for f in range(len(ref)):
        masks[f, 18:30, 4 + 3 * f : 16 + 3 * f] = True  # the moving square
    off = ref.copy()
    off[:, 2:14] = np.clip(off[:, 2:14] + 0.3, 0, 1)  # a band above the square
    on = ref.copy()
    on[:, 18:30] = np.clip(on[:, 18:30] + 0.3, 0, 1)
    crop = (slice(8, 40), slice(0, 48))
    m = video._metric()
    assert video.object_jod(off, ref, masks, crop, fps=8, metric=m) == pytest.approx(10.0, abs=1e-3)
    assert video.jod(off, ref, fps=8, metric=m) < 9.5  # frame-wide it would count
    assert video.object_jod(on, ref, masks, crop, fps=8, metric=m) < 9.5
