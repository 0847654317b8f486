"""A file whose only light is weak gets study's point light, said in one line, the table and index.json; a picture
of fireflies is labelled; a truth too noisy to rank by says which render.spp would do (study.scene.lights,
study.measure.lighting, study.measure.exposure).

The scene: the McGuire Cornell box (tests/assets/corpus/) with its ceiling light (Ke 17 12 4, 0.47 m × 0.38 m) ×
1e-3. Its power is checked against the quad's area from the file's own vertices, by hand."""

import json
import math
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from study.api import load_scene
from study.cli import app
from study.measure import exposure, lighting
from study.scene import lights
from study.scene.autoplace import light_intensity
from study.scene.environment import geometry
from study.tables import read_csv

ROOT = Path(__file__).resolve().parents[2]
CORNELL = ROOT / "tests/assets/corpus/obj/mcguire-cornell"
SMALL = {
    "camera.width": 40,
    "camera.height": 40,
    "render.spp": 8,
    "render.cube_spp": 8,
    "render.cube_res": 32,
}


def dim_cornell(tmp: Path, factor: float = 1e-3) -> Path:
    """The Cornell box with its light's emission × ``factor`` (the MTL's Ke; the OBJ names the new MTL)."""
    ke = " ".join(f"{v * factor:g}" for v in (17, 12, 4))
    (tmp / "dim.mtl").write_text(
        (CORNELL / "CornellBox-Original.mtl").read_text().replace("Ke 17 12 4", f"Ke {ke}")
    )
    obj = (CORNELL / "CornellBox-Original.obj").read_text().replace("CornellBox-Original.mtl", "dim.mtl")
    (tmp / "dim.obj").write_text(obj)
    return tmp / "dim.obj"


def light_quad_power(factor: float = 1.0) -> float:
    """π · L · A of the box's light, A from the four vertices under the file's "## Object light" line."""
    lines = (CORNELL / "CornellBox-Original.obj").read_text().splitlines()
    i = next(k for k, ln in enumerate(lines) if ln.startswith("## Object light"))
    v = np.array([[float(x) for x in ln.split()[1:]] for ln in lines[i + 1 : i + 5]])
    area = np.linalg.norm(np.cross(v[1] - v[0], v[3] - v[0]))  # a rectangle
    assert area == pytest.approx(0.47 * 0.38, rel=1e-6)
    lum = 0.2126 * 17 + 0.7152 * 12 + 0.0722 * 4
    return math.pi * lum * factor * area


def test_the_files_light_power_is_its_quads():
    env = geometry(load_scene(CORNELL / "CornellBox-Original.obj"))
    assert lights.own_power(env) == pytest.approx(light_quad_power(), rel=1e-5)
    study = 4 * math.pi * light_intensity(*env.bounds)
    assert lights.own_share(env, light_intensity(*env.bounds)) == pytest.approx(
        light_quad_power() / study, rel=1e-5
    )
    assert 0.2 < lights.own_share(env, light_intensity(*env.bounds)) < 0.5  # the box as shipped: not weak


def test_a_weak_light_turns_studys_light_on_and_a_given_key_wins(tmp_path):
    assert not load_scene(CORNELL / "CornellBox-Original.obj").lamp()  # its own light, as before
    dim = dim_cornell(tmp_path)
    assert load_scene(dim).lamp()  # × 1e-3: under 5 % of study's light, which is added
    assert not load_scene(dim, {"light.enabled": False}).lamp()  # the user's word stands
    # the threshold: the box's light is 31 % of study's; × 0.2 leaves 6 % (not weak), × 0.1 leaves 3 % (weak)
    (tmp_path / "a").mkdir(), (tmp_path / "b").mkdir()
    assert not load_scene(dim_cornell(tmp_path / "a", 0.2)).lamp()
    assert load_scene(dim_cornell(tmp_path / "b", 0.1)).lamp()


def test_the_run_says_its_light_was_added_in_one_line_the_table_and_index_json(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    dim = dim_cornell(tmp_path)
    args = ["run", str(dim), "-m", "classical", "-m", "localized", "--out", str(tmp_path / "out"),
            "--cache", str(tmp_path / "c")] + [a for k, v in SMALL.items() for a in ("--set", f"{k}={v}")]  # fmt: skip
    res = CliRunner().invoke(app, args)
    assert res.exit_code == 0, res.output
    said = [ln for ln in res.output.splitlines() if ln.startswith("note: the file's own lights are weak")]
    assert len(said) == 1 and "study's point light is added" in said[0], res.output
    rows = read_csv(tmp_path / "out/table.csv")
    share = float(rows[0]["own_light_share"])
    env = geometry(load_scene(dim))
    assert share == pytest.approx(
        light_quad_power(1e-3) / (4 * math.pi * light_intensity(*env.bounds)), rel=1e-4
    )
    index = json.loads((tmp_path / "out/index.json").read_text())
    assert any("study's point light is added" in n for n in index["notes"])
    page = (tmp_path / "out/index.html").read_text().replace("&#x27;", "'")
    assert (
        "Note:</strong> the file's own lights are weak" in page
        or "Note: the file's own lights are weak" in page
    )
    # this render (40², 8 spp, study's light beside the dim quad, the mirror sphere's caustics) has fireflies:
    # labelled in the printed notes, index.json and the viewer's title; the viewer of the shipped box is not
    f = float(rows[0]["firefly_fraction"])
    assert f > exposure.FIREFLY_LIMIT, f
    assert any(ln.startswith("note: the picture shows fireflies") for ln in res.output.splitlines())
    assert any("fireflies" in n for n in index["notes"])
    assert "FIREFLIES" in (tmp_path / "out/viewer/index.json").read_text()
    # the box as shipped: no such line
    args[1] = str(CORNELL / "CornellBox-Original.obj")
    args[7] = str(tmp_path / "out2")
    res = CliRunner().invoke(app, args)
    assert res.exit_code == 0 and "lights are weak" not in res.output, res.output
    shipped = read_csv(tmp_path / "out2/table.csv")[0]
    assert float(shipped["own_light_share"]) == pytest.approx(0.31, abs=0.01)
    labelled = "FIREFLIES" in (tmp_path / "out2/viewer/index.json").read_text()
    assert labelled == (float(shipped["firefly_fraction"]) > exposure.FIREFLY_LIMIT)


def seeds(rng, fireflies: float, scale: float = 1.0):
    """Two seeds of a smooth 64² picture with 1 % Gaussian noise, and in the first ``fireflies`` of its pixels
    a value 50× the picture's."""
    base = np.linspace(0.05, 0.5, 64 * 64).reshape(64, 64, 1) * np.ones(3)
    a, b = (base * (1 + 0.01 * rng.standard_normal(base.shape)) for _ in range(2))
    idx = rng.permutation(64 * 64)[: int(fireflies * 64 * 64)]
    a.reshape(-1, 3)[idx] *= 50
    return (a + b) / 2 * scale, (a - b) / 2 * scale


def test_the_firefly_fraction_counts_planted_fireflies_at_any_brightness():
    rng = np.random.default_rng(0)
    clean, noise = seeds(rng, 0.0)
    assert exposure.firefly_fraction(clean, noise) == 0.0
    for share in (0.01, 0.05, 0.2):
        pic, noise = seeds(np.random.default_rng(1), share)
        f = exposure.firefly_fraction(pic, noise)
        assert f == pytest.approx(share, abs=0.2 * share)  # the planted pixels, some already clipped in both
        dark = exposure.firefly_fraction(*seeds(np.random.default_rng(1), share, scale=1e-3))
        assert dark == pytest.approx(f, abs=1e-9)  # the picture's own exposure: brightness does not matter
        rows = [{"label": "classical", "firefly_fraction": f}]
        assert bool(lighting.picture_label(rows)) == (f > exposure.FIREFLY_LIMIT)
        assert bool(lighting.firefly_note(rows, 16)) == (f > exposure.FIREFLY_LIMIT)


def test_a_truth_too_noisy_to_rank_by_names_the_spp_that_would_do():
    noise = {"truth_noise_relmse": 0.01}
    rows = [{"label": "truth_at_hit", "relmse_truth_exposed": 0.0, **noise},
            {"label": "classical", "relmse_truth_exposed": 0.5, **noise},
            {"label": "localized(iterations=10)", "relmse_truth_exposed": 0.02, **noise}]  # fmt: skip
    line = lighting.noise_note(rows, 16)
    # 0.01 / 0.02 = 50 % of the best method's error; 1/spp: 16 × 0.5 / (1/9) = 72 spp brings it to 1/9 (σ to 1/3)
    assert "50%" in line and "render.spp ≥ 72" in line
    rows[2]["relmse_truth_exposed"] = 0.1  # 10 % < 1/9: under the limit
    assert lighting.noise_note(rows, 16) == ""
