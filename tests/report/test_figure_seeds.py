"""Figures have enough cases for intervals over cases (issues 41 item 5, 42 item 3, 53 item 1): every shipped grid
figure has ≥ 12 distinct geometries (seeds do not count), read through the real config loader; the seeds axis
draws the stochastic parts anew (Mitsuba's references differ between seeds) while the grid's picture keeps the
first seed's rows; and a figure states where its time went (``time_split`` in metadata.json, one line printed)."""

import json
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from study import progress
from study.cli import app
from study.harness.config import load_figure_config
from study.report.kinds import config_kind
from tests.conftest import error_output, scene_toml, small_scene_dict

ROOT = Path(__file__).resolve().parents[2]
#: fewest distinct geometries per figure: calibrated case intervals (the median's order-statistic CI from 10 cases on,
#: study.stats.case_interval) and paired tests with power
MIN_CASES = 12
#: figure configs whose kind has no positions or cases (one scene measured another way), and why
NOT_CASES = {
    "fig8": "caustics: one caustic scene (no positions), its intervals from two Mitsuba seeds and the sweep"
}


def _geometries(cfg) -> int:
    """Distinct geometries of a figure config: its cases' scene overrides without ``render.seed`` (the seed redraws
    the Monte Carlo parts only: its replicates are copies for every geometric column; issue 53)."""
    return len({json.dumps({k: v for k, v in o.items() if k != "render.seed"}, sort_keys=True)
                for _, _, o in cfg.case_list()})  # fmt: skip


@pytest.mark.parametrize("path", sorted((ROOT / "configs").glob("fig*.toml")), ids=lambda p: p.stem)
def test_every_figure_has_at_least_12_distinct_geometries(path):
    """≥ 12 distinct geometries (object position, scene, object), not positions × seeds: before issue 53 fig5,
    fig6, fig_glossy and fig_hitcache had 6 (× 2 seeds), fig_atrium, fig_attic and fig_lroom 3 (× 4), fig_cornell
    and fig_probes 2 (× 6)."""
    if path.stem in NOT_CASES:
        assert config_kind(path).name not in ("grid", "glossy"), f"{path.stem} became a grid figure: count it"
        return
    cfg, _, _ = load_figure_config(path)
    n = cfg.case_count()
    assert n == len(cfg.case_list()) and len({cid for cid, _, _ in cfg.case_list()}) == n
    g = _geometries(cfg)
    assert g >= MIN_CASES, f"{path.name}: {g} distinct geometries ({n} cases with seeds), want ≥ {MIN_CASES}"


def _write(tmp: Path, seeds: str) -> Path:
    """``<tmp>/<n>/fig_seeds.toml``: one position, ``seeds`` as given (its length names the folder)."""
    tmp = tmp / str(len(seeds))
    tmp.mkdir(exist_ok=True)
    scene = small_scene_dict()
    scene["render"].update(cube_res=16, cube_spp=4, spp=4)
    (tmp / "scene.toml").write_text(scene_toml(scene))
    cfg = tmp / "fig_seeds.toml"  # one name: the pictures' titles are the same
    cfg.write_text(
        f'scene = "scene.toml"\npositions = [[0.6, 1.2, 0.3]]\nmethods = ["classical", "localized"]\n{seeds}\n'
    )
    return cfg


@pytest.fixture(scope="module")
def seeded(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("seeds")
    runs = {}
    for seeds in ("", "seeds = [0, 5]"):
        cfg = _write(tmp, seeds)
        out = tmp / f"out{len(seeds)}"
        res = CliRunner().invoke(
            app,
            [
                "figure",
                "--config",
                str(cfg),
                "--out",
                str(out),
                "--cache",
                str(tmp / "c"),
                "--images",
                "all" if seeds else "none",
            ],
        )
        assert res.exit_code == 0, res.output
        runs[seeds] = (res, out, cfg)
    return runs


def test_seeds_give_other_reference_noise_and_the_same_picture(seeded):
    _, one, _ = seeded[""]
    res, two, cfg = seeded["seeds = [0, 5]"]
    import pandas as pd

    a, b = pd.read_csv(one / "metrics.csv"), pd.read_csv(two / "metrics.csv")
    assert sorted(b["case"].unique()) == ["fig_seeds-p0", "fig_seeds-p0-s5"]
    first = b[b["case"] == "fig_seeds-p0"].reset_index(drop=True)
    other = b[b["case"] == "fig_seeds-p0-s5"].reset_index(drop=True)
    col = "truth_noise_rmse"  # the references' own noise, from their two Mitsuba seeds
    # the first seed is the case without seeds (seed 0): the same numbers; the other seed draws them anew
    np.testing.assert_allclose(first[col], a[col], rtol=1e-9)
    assert not np.allclose(first[col], other[col], rtol=1e-6), (first[col], other[col])
    own = first["label"] != "truth_at_hit"  # the truth against itself is 0 at every seed
    assert (first["rmse_truth"] != other["rmse_truth"])[own].all()
    # the picture: the first seed's rows only, the same bytes as the figure without seeds
    assert (two / "fig_seeds.png").read_bytes() == (one / "fig_seeds.png").read_bytes() or _same_pixels(
        one / "fig_seeds.png", two / "fig_seeds.png"
    )
    assert json.loads((two / "metadata.json").read_text())["cases"] == 2


def test_the_viewer_shows_the_picture_and_every_case_keeps_its_exr(seeded):
    """The viewer holds the picture's cases (the first seed's); ``--images all`` writes every case's EXR, which
    the glossy split reads. Planted: a viewer for every case lists two; EXRs for the picture alone miss one."""
    _, two, _ = seeded["seeds = [0, 5]"]
    shown = json.loads((two / "viewer" / "index.json").read_text())["cases"]
    assert [c["id"] for c in shown] == ["fig_seeds-p0"]
    assert sorted(p.name for p in (two / "exr").glob("*.exr")) == ["fig_seeds-p0-s5.exr", "fig_seeds-p0.exr"]


def _same_pixels(a: Path, b: Path) -> bool:
    from PIL import Image

    x, y = np.asarray(Image.open(a)), np.asarray(Image.open(b))
    return x.shape == y.shape and bool((x == y).all())


def test_repeated_or_negative_seeds_are_one_line_naming_the_key(tmp_path):
    for seeds, want in (("seeds = [1, 1]", "seeds repeat"), ("seeds = [-1]", "greater than or equal to 0"),
                        ("seeds = []", "at least 1"), ('seeds = ["a"]', "valid integer")):  # fmt: skip
        cfg = _write(tmp_path, seeds)
        res = CliRunner().invoke(app, ["figure", "--config", str(cfg), "--out", str(tmp_path / "o")])
        text = error_output(res)
        assert res.exit_code == 2 and len(text.splitlines()) == 1, text
        assert want in text and "seeds" in text and cfg.name in text, text
        assert not (tmp_path / "o").exists()


def test_a_figure_states_its_time_split(seeded):
    res, out, _ = seeded["seeds = [0, 5]"]
    meta = json.loads((out / "metadata.json").read_text())
    split = meta["time_split"]
    assert list(split) == [*progress.CASE_PARTS, "outputs"]
    # cold: Mitsuba rendered the references (both seeds), the methods traced; the parts add up to the cases' time
    assert split["renders"] > 0 and split["traces"] > 0 and split["exact"] > 0, split
    cases = sum(v for k, v in split.items() if k != "outputs")
    assert cases <= meta["seconds"] + 0.5 and cases >= 0.8 * meta["seconds"] - 0.5, (split, meta["seconds"])
    line = next(ln for ln in res.stdout.splitlines() if "time split" in ln)
    assert "renders" in line and "without renders and probes" in line, line


def test_a_run_keeps_its_time_split(tmp_path):
    """``study run``'s result (the API's evaluate) carries the case's split and writes it into index.json."""
    from study.api import evaluate

    scene = small_scene_dict()
    scene["render"].update(cube_res=16, cube_spp=4, spp=4)
    (tmp_path / "s.toml").write_text(scene_toml(scene))
    res = evaluate(tmp_path / "s.toml", ["classical"], cache=None)
    assert list(res.times) == list(progress.CASE_PARTS) and res.times["renders"] > 0, res.times
    res.save(tmp_path / "out")
    assert json.loads((tmp_path / "out" / "index.json").read_text())["time_split"] == res.times
    assert "without renders and probes" in progress.split_line(res.times)


def test_seeds_multiply_the_cases_and_convergence_reads_the_first_seed_only():
    from pathlib import Path as P

    from study.harness.config import FigureConfig
    from study.outputs.convergence import convergence_cases, load_convergence

    cfg = FigureConfig(scene="room.toml", positions=[[0.0, 1.5, 0.0], [0.6, 1.2, 0.3]], seeds=[0, 3])
    every, first = cfg.case_list(), cfg.case_list(replicates=False)
    assert len(every) == len(first) * len(cfg.seeds) and [c[0] for c in first] == [
        c[0] for c in every[: len(first)]
    ]
    assert {o["render.seed"] for _, _, o in first} == {cfg.seeds[0]}
    assert {o["render.seed"] for _, _, o in every} == set(cfg.seeds)
    conv, _ = load_convergence(ROOT / "configs" / "convergence.toml")
    ids = [cid for _, cid, _ in convergence_cases(conv, P(ROOT / "configs" / "convergence.toml"))]
    assert len(ids) == len(set(ids)) and not any("-s" in i for i in ids) and "fig5-p5" in ids
