"""`study figure --quality`: a preset's scene keys reach every case after the config's own (the paper preset
renders 1024²; here a stand-in preset of 20² keeps the test small), the metadata says which preset, the outputs go
to reports/<preset>/<name>/ by default, and an unknown preset is one line naming the allowed ones."""

import json

from conftest import run_cli

from study.harness import config
from study.io import read_exr_layers
from tests.robustness.test_bad_inputs import DEFAULT, FIG


def test_paper_preset_is_1024_squared():
    assert config.QUALITY["paper"]["camera.width"] == config.QUALITY["paper"]["camera.height"] == 1024
    assert config.QUALITY["preview"] == {}


def test_a_preset_reaches_every_case(tmp_path, monkeypatch):
    monkeypatch.setitem(config.QUALITY, "tiny", {"camera.width": 20, "camera.height": 20})
    cfg = tmp_path / "f.toml"
    cfg.write_text(FIG.format(**DEFAULT))
    res = run_cli("figure", "--config", str(cfg), "--out", str(tmp_path / "o"), "--quality", "tiny")
    assert res.exit_code == 0, res.output
    meta = json.loads((tmp_path / "o" / "metadata.json").read_text())
    assert meta["quality"] == "tiny"
    exr = next((tmp_path / "o" / "exr").glob("*.exr"))
    assert next(iter(read_exr_layers(exr).values())).shape[:2] == (20, 20)


def test_unknown_preset_is_one_line(tmp_path):
    res = run_cli("figure", "fig4", "--quality", "ultra", "--out", str(tmp_path / "o"))
    assert res.exit_code == 2 and res.output.strip() == (
        "error: --quality: unknown quality 'ultra'; allowed: preview, paper"
    ), res.output
    assert not (tmp_path / "o").exists()


def test_report_shows_the_paper_resolution_figures(tmp_path):
    """Found by their metadata's quality (as `study figure --quality paper` writes it), not by the folder's name."""
    d = tmp_path / "paper" / "fig9"
    d.mkdir(parents=True)
    (d / "metadata.json").write_text(json.dumps({"command": "study figure fig9", "seconds": 12.5}))
    (d / "fig9.png").write_bytes(b"\x89PNG")
    assert run_cli("report", "--reports", str(tmp_path)).exit_code == 0
    assert not (tmp_path / "index.md").exists()  # a preview figure there is not one: nothing to report
    (d / "metadata.json").write_text(
        json.dumps({"command": "study figure fig9 --quality paper", "seconds": 12.5, "quality": "paper"})
    )
    (d / "fig9.png").write_bytes(b"\x89PNG")
    res = run_cli("report", "--reports", str(tmp_path))
    assert res.exit_code == 0, res.output
    md = (tmp_path / "index.md").read_text()
    assert (
        "## Paper resolution (1024², made on a GPU)" in md and "![fig9 at 1024²](paper/fig9/fig9.png)" in md
    )
    assert "`study figure fig9 --quality paper`, 12.5 s" in md
