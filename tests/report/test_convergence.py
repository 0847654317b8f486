"""Convergence as curves (``study convergence``, study/outputs/convergence.py, study/measure/convergence.py).

One small real case (Figure 4's farthest position, camera 48², cube 64², 4 spp), run through the command line: the
files are written, each rung's row is the row the same method gets in a plain case, the breakdown's groups add up to
the rung's wrong rays, and the rays it calls "undershoot, never bracketed" are those of an independent twin of the
paper's listing (per ray, in Python floats, on the same impostor: no guess before the last overshot)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from study.errors import StudyError
from study.outputs.convergence import load_convergence, to_reach
from study.tables import read_csv
from tests.conftest import error_output, run_cli

ROOT = Path(__file__).resolve().parents[2]
POSITION = [1.5, 0.6, 1.0]  # fig4's farthest: rays that need several steps
SMALL = {"camera.width": 48, "camera.height": 48, "render.supersample": 1, "render.cube_res": 64,
         "render.cube_spp": 4, "render.spp": 4, "render.flip_against": []}  # fmt: skip
K = 3  # the localized rung explained


def _toml(d: dict) -> str:
    return "\n".join(f'"{k}" = {v!r}' for k, v in d.items())


def _write(tmp: Path, ladders: str) -> Path:
    (tmp / "fig.toml").write_text(
        f'scene = "{ROOT / "scenes/room.toml"}"\npositions = [{POSITION}]\nmethods = ["classical"]\n'
    )
    p = tmp / "conv.toml"
    p.write_text(f'figures = ["fig.toml"]\n[overrides]\n{_toml(SMALL)}\n{ladders}')
    return p


LADDERS = f"""
[[ladders]]
method = "localized"
param = "iterations"
values = [0, 1, 2, 3, 4, 6]
breakdown = [{K}]
[[ladders]]
method = "linear_secant"
param = "secant_steps"
values = [0, 4]
breakdown = [4]
"""


@pytest.fixture(scope="module")
def made(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("conv")
    cfg = _write(tmp, LADDERS)
    res = run_cli("convergence", str(cfg), "--out", str(tmp / "out"), "--cache", str(tmp / "c"))
    assert res.exit_code == 0, res.output
    return tmp


def test_to_reach_is_where_the_curve_stays_below():
    v = [0, 1, 2, 3]
    assert to_reach(v, [0.5, 0.04, 0.06, 0.03], 0.05) == 3  # dips below at 1, back above at 2
    assert to_reach(v, [0.5, 0.04, 0.03, 0.02], 0.05) == 1
    assert to_reach(v, [0.01, 0.0, 0.0, 0.0], 0.05) == 0
    assert math.isnan(to_reach(v, [0.5, 0.04, 0.03, 0.06], 0.05))  # above at the last rung: not reached


def test_files_and_rows(made):
    out = made / "out"
    for f in ("curves.csv", "reach.csv", "breakdown.csv", "convergence.png", "index.md", "metadata.json"):
        assert (out / f).stat().st_size > 0, f
    rows = read_csv(out / "curves.csv")
    assert [r["value"] for r in rows if r["ladder"] == "localized vs iterations"] == [0, 1, 2, 3, 4, 6]
    assert {r["label"] for r in rows} >= {
        "localized(iterations=3)",
        "linear_secant(steps_per_texel=1.0, secant_steps=4)",
    }
    assert (
        "not reached" in (out / "index.md").read_text()
        or "localized vs iterations" in (out / "index.md").read_text()
    )


def test_a_rung_is_the_method_of_a_plain_case(made):
    """The rung's columns are those of the same method run alone on the same case (no ladder effect)."""
    from study import methods as registry
    from study.cache import Cache
    from study.harness.config import load_figure_config

    _, scene, _ = load_figure_config(made / "fig.toml")
    sc = scene.with_updates({"object.center": POSITION, **SMALL})
    from study.measure.case import run_case

    alone = run_case(
        sc, [registry.make("localized", iterations=K)], cache=Cache(made / "c"), keep_images=False
    )
    want = next(r for r in alone.rows if r["label"] == f"localized(iterations={K})")
    got = next(r for r in read_csv(made / "out/curves.csv") if r["label"] == want["label"])
    for c in (
        "wrong_fraction_texel",
        "wrong_fraction_1cm",
        "wrong_fraction_10cm",
        "angle_p95_deg",
        "rmse_truth",
    ):
        assert got[c] == pytest.approx(want[c], rel=1e-9, nan_ok=True), c


def test_breakdown_adds_up(made):
    curves = {(r["ladder"], r["value"]): r for r in read_csv(made / "out/curves.csv")}
    parts = read_csv(made / "out/breakdown.csv")
    for (ladder, value), r in curves.items():
        sel = [p for p in parts if p["ladder"] == ladder and p["value"] == value]
        if not sel:
            continue
        wrong = round(r["wrong_fraction_texel"] * r["n_rays"])
        for by in ("cause", "length", "surface"):
            g = [p for p in sel if p["by"] == by]
            assert sum(p["n_wrong"] for p in g) == wrong, (ladder, value, by)
            if by != "cause":
                assert sum(p["n_rays"] for p in g) == r["n_rays"], (ladder, value, by)


def _twin(env_dist, x, R, k, lo=0.999, hi=1.001):
    """The listing of ``localized`` for one ray, in Python floats: (final point, an overshoot was seen)."""
    r_len = env_dist(R)
    pun = np.linalg.norm(x) / env_dist(x)
    dl, dun, dov, pov, seen = r_len * (1 - pun), 0.0, 0.0, 0.0, False
    for _ in range(k):
        l = x + R * dl
        llp = np.linalg.norm(l) / env_dist(l)
        if llp < lo:
            step = r_len * (1 - llp) if dov == 0 else (dl - dov) * (1 - llp) / (llp - pov)
            dun, pun = dl, llp
            dl += step
        elif llp > hi:
            seen = True
            step = (dl - dun) * (1 - llp) / (llp - pun)
            dov, pov = dl, llp
            dl += step
    return x + R * dl, seen


def test_never_bracketed_is_what_the_listing_does(made):
    from study import backend as backends
    from study.cache import Cache
    from study.harness.config import load_figure_config
    from study.impostor.envmap import EnvMap
    from study.measure import outcomes, split
    from study.measure.inputs import impostor
    from study.optics import shading
    from study.reference.tracer import make_tracer

    _, scene, _ = load_figure_config(made / "fig.toml")
    sc = scene.with_updates({"object.center": POSITION, **SMALL})
    tracer = make_tracer(sc.mesh())
    rays = shading.object_rays(sc, occluder=tracer.distance)
    o = np.asarray(sc.reference.point, float)
    nb = backends.get("numpy")
    env = EnvMap(impostor(sc, Cache(made / "c"), tracer).texels(), nb)

    def dist(v):
        return float(np.asarray(env.distance(nb.vec(np.asarray(v, float)[None])))[0])

    shown, seen = zip(*(_twin(dist, x - o, R, K) for x, R in zip(rays.x, rays.R)))
    shown = np.array(shown) + o
    point, escapes, hidden = split.exact_hits(tracer, rays.x, rays.R, o)
    eps = outcomes.tolerance(o, point, sc.render.cube_res)
    wrong = outcomes.classify(rays.x, rays.R, shown, point, eps=eps).cls != outcomes.CORRECT
    held = split.held(hidden, escapes)
    never = int((wrong & held & ~np.array(seen)).sum())
    parts = read_csv(made / "out/breakdown.csv")
    got = {p["group"]: p["n_wrong"] for p in parts if p["value"] == K and p["by"] == "cause"
           and p["ladder"] == "localized vs iterations"}  # fmt: skip
    assert got["undershoot, never bracketed"] == never
    assert got["bracketed, not converged"] == int((wrong & held & np.array(seen)).sum())
    assert never > 0  # the case has such rays: the test can fail


@pytest.mark.parametrize(
    "ladder, key",
    [
        ('method = "nosuch"\nparam = "iterations"\nvalues = [1]', "ladders[0].method"),
        ('method = "localized"\nparam = "nosuch"\nvalues = [1]', "ladders[0].param"),
        ('method = "localized"\nparam = "iterations"\nvalues = [1]\nbreakdown = [2]', "ladders[0].breakdown"),
    ],
)
def test_bad_ladders_are_one_line(tmp_path, ladder, key):
    cfg = _write(tmp_path, f"[[ladders]]\n{ladder}\n")
    with pytest.raises(StudyError) as e:
        load_convergence(cfg)
    assert e.value.key == key
    res = run_cli("convergence", str(cfg), "--out", str(tmp_path / "o"))
    assert res.exit_code == 2 and key in error_output(res), res.output


def test_causes_read_the_guesses_before_the_last():
    """Hand-made rays: the shown points of rungs 0 … 3 carry their |l|/|l'| in x (a fake impostor): an overshoot at
    rung 1 brackets the ray for rung 3, one at rung 3 itself does not (rung 3's guess is never tested)."""
    from types import SimpleNamespace

    from study.measure import convergence, outcomes

    W, C = outcomes.WRONG_DEPTH, outcomes.CORRECT
    ratios = {  # per rung: the ratio of rays a … f
        0: [0.5, 0.5, 0.5, 0.5, 0.5, 0.5],
        1: [1.2, 0.7, 0.7, 0.7, 0.7, 0.7],  # a overshoots at rung 1
        2: [0.9, 0.8, 0.8, 0.8, 0.8, 0.8],
        3: [0.95, 1.3, 0.9, np.nan, 0.9, 1.0],  # b overshoots only at rung 3
    }

    def ctx(j):
        shown = np.zeros((6, 3))
        shown[:, 0] = ratios[j]
        return SimpleNamespace(
            shown=shown,
            classes=outcomes.Outcomes(
                np.array([W, W, W, outcomes.NO_HIT, W, C], np.int8), *(np.zeros(6),) * 3
            ),
            occluded=np.array([0, 0, 0, 0, 1, 0], bool),
        )

    seen = {f"r{j}": ctx(j) for j in ratios}
    geo = SimpleNamespace(ratio=lambda s: np.asarray(s)[:, 0])
    ld = convergence.Ladder("localized", "iterations", (0, 1, 2, 3))
    got = convergence.causes(seen["r3"], np.zeros(6, bool), {j: f"r{j}" for j in ratios}, 3, ld, geo, seen)
    names = [convergence.CAUSES[i] if i >= 0 else "correct" for i in got]
    assert names == ["bracketed, not converged", "undershoot, never bracketed", "undershoot, never bracketed",
                     "no hit", "hidden from o", "correct"]  # fmt: skip
    other = convergence.Ladder("linear_secant", "secant_steps", (0, 1, 2, 3))
    got = convergence.causes(seen["r3"], np.zeros(6, bool), {j: f"r{j}" for j in ratios}, 3, other, geo, seen)
    assert [convergence.CAUSES[i] for i in got[:3]] == ["missed (held)"] * 3


def test_convergence_is_a_figure_kind_with_its_report_section(tmp_path):
    """configs/convergence.toml names its kind; a folder with curves.csv and reach.csv is found as it, and its
    section shows the curves and the reach table (the report places it among the figures)."""
    from study.report import kinds

    assert kinds.config_kind("configs/convergence.toml").name == "convergence"
    d = tmp_path / "convergence"
    d.mkdir()
    (d / "curves.csv").write_text("scene,case,ladder,param,value\nfig4,fig4-p0,localized,iterations,3\n")
    (d / "reach.csv").write_text(
        "scene,ladder,column,target,value_to_reach\nfig4,localized,wrong_fraction_texel,0.05,3\n"
    )
    (d / "convergence.png").write_bytes(b"png")
    ((k, found),) = kinds.found(tmp_path)
    assert k.name == "convergence" and found == d
    blocks = k.section(tmp_path, d, [], [])
    assert ("img", "convergence/convergence.png", "convergence") in blocks
    assert blocks[-1][0] == "table" and blocks[-1][1][0]["value_to_reach"] == 3
