"""Bad caustics configs (issue: the caustics sweep had no guard): each is one line naming the file and the key,
exit 2, before any work, with the earlier outputs byte-identical — a splatting window or light maps that would
not fit in memory (res 2048 with a 4096² light map grew to 24 GB and was killed), references that would run for
days, an infinite eps (relMSE 0 for every method), equal seeds (noise 0), duplicate resolutions (duplicate rows)."""

import tomllib
from pathlib import Path

import pytest
import tomli_w
from conftest import assert_one_line_error, digest, run_cli

ROOT = Path(__file__).resolve().parents[2]

# (id, changes to configs/caustics_sweep.toml as {table: {key: value}}, expected words)
CASES = [
    ("res-too-big", {"caustic": {"res": 2048, "lightmap_res": 4096}}, "caustic.res"),
    ("lightmap-too-big", {"caustic": {"lightmap_res": 4096, "sigma": 0.5}}, "--max-memory"),
    (
        "spp-huge",
        {"mitsuba": {"spp": 2**31 - 1}},
        "mitsuba.spp: Input should be less than or equal to 1048576",
    ),
    ("spp-days", {"mitsuba": {"spp": 1 << 20}}, "mitsuba.spp: the Mitsuba references would take about"),
    ("seeds-2000", {"mitsuba": {"seeds": list(range(2000))}}, "mitsuba.seeds: List should have at most 16"),
    ("seeds-equal", {"mitsuba": {"seeds": [1, 1]}}, "mitsuba.seeds: Value error, seeds must differ"),
    ("eps-inf", {"caustic": {"eps": float("inf")}}, "caustic.eps: Input should be a finite number"),
    ("eps-nan", {"caustic": {"eps": float("nan")}}, "caustic.eps: Input should be a finite number"),
    ("sigma-inf", {"caustic": {"sigma": float("inf")}}, "caustic.sigma: Input should be a finite number"),
    ("resolutions-dup", {"": {"resolutions": [16, 16]}}, "resolutions: Value error, resolutions must differ"),
    (
        "resolutions-huge",
        {"": {"resolutions": [16, 4096]}},
        "resolutions.1: Input should be less than or equal to",
    ),
    ("resolutions-empty", {"": {"resolutions": []}}, "resolutions: List should have at least 1 item"),
]


@pytest.mark.parametrize("case_id, changes, words", CASES, ids=[c[0] for c in CASES])
def test_bad_caustics_config(tmp_path, case_id, changes, words):
    cfg = tomllib.loads((ROOT / "configs" / "caustics_sweep.toml").read_text())
    cfg["scene"] = str(ROOT / "scenes" / "room.toml")
    for table, kv in changes.items():
        (cfg.setdefault(table, {}) if table else cfg).update(kv)
    path = tmp_path / "bad.toml"
    path.write_bytes(tomli_w.dumps(cfg).encode())
    out = tmp_path / "out"
    out.mkdir()
    (out / "fig8.csv").write_text("old\n")
    before = digest(out)
    res = run_cli("caustics-sweep", "--config", str(path), "--out", str(out))
    assert_one_line_error(res, words, before, out)
    assert "bad.toml" in res.output
