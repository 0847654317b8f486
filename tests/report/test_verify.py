"""``study verify`` (issue 55.2): fresh tables against committed ones, row by row, within the committed intervals;
deterministic columns within float tolerance on the same backend only. Planted disagreements are found, agreeing
tables pass, bad input is one line (exit 2)."""

import json
import subprocess
from pathlib import Path

import numpy as np
from conftest import run_cli

from study.report.verify import compare_tables as verify
from study.tables import write_csv


def _table(d: Path, rows: list[dict], backend: str) -> None:
    d.mkdir(parents=True, exist_ok=True)
    write_csv(rows, d / "metrics.csv")
    (d / "metadata.json").write_text(json.dumps({"backend": backend, "config": "x.toml"}))


def _rows(rng, n=6, shift=0.0, det=1.0):
    """Rows of a figure: wrong_fraction with its interval (binomial: the estimate ± 2 σ), and a deterministic
    column (lookups per ray)."""
    out = []
    for i in range(n):
        for lab in ("classical", "localized(iterations=10)"):
            p = 0.2 + 0.05 * i + shift
            s = np.sqrt(p * (1 - p) / 4000)
            row = {"case": f"c{i}", "label": lab, "wrong_fraction": p, "wrong_fraction_lo": p - 2 * s}
            row.update(wrong_fraction_hi=p + 2 * s, lookups_per_ray=13.0 * det, seconds=rng.random())
            out.append(row)
    return out


def test_agreeing_tables_pass_and_a_planted_value_outside_its_interval_is_found(tmp_path):
    rng = np.random.default_rng(0)
    committed = _rows(rng)
    _table(tmp_path / "committed" / "figA", committed, "cuda")
    fresh = [dict(r) for r in committed]
    for r in fresh:  # another run: within the committed intervals (and other timings)
        r["wrong_fraction"] += 0.5 * (r["wrong_fraction_hi"] - r["wrong_fraction"])
        r["seconds"] += 5
    _table(tmp_path / "fresh" / "figA", fresh, "cuda")
    (res,) = verify(tmp_path / "fresh", tmp_path / "committed")
    assert (res.rows, res.interval_values, res.outside, res.det_differ) == (12, 12, 0, 0)
    fresh[3]["wrong_fraction"] = fresh[3]["wrong_fraction_hi"] + 0.01  # planted
    _table(tmp_path / "fresh" / "figA", fresh, "cuda")
    (res,) = verify(tmp_path / "fresh", tmp_path / "committed")
    assert res.outside == 1 and res.worst[0][1:4] == ("c1", "localized(iterations=10)", "wrong_fraction")
    out = tmp_path / "v.md"
    r = run_cli(
        "verify", str(tmp_path / "fresh"), "--against", str(tmp_path / "committed"), "--out", str(out)
    )
    assert r.exit_code == 1, r.output
    text = out.read_text()
    assert "| figA | cuda vs cuda | 12 | 0 | 1 | 12 | 1 |" in text and "localized(iterations=10)" in text


def test_deterministic_columns_are_judged_on_the_same_backend_only(tmp_path):
    rng = np.random.default_rng(1)
    _table(tmp_path / "committed" / "figB", _rows(rng), "cuda")
    _table(tmp_path / "fresh" / "figB", _rows(rng, det=1.001), "cuda")
    (res,) = verify(tmp_path / "fresh", tmp_path / "committed")
    assert res.det_judged and res.det_differ == 12 and res.outside == 0
    assert run_cli("verify", str(tmp_path / "fresh"), "--against", str(tmp_path / "committed")).exit_code == 1
    _table(tmp_path / "fresh" / "figB", _rows(rng, det=1.001), "llvm")  # another backend: counted, not judged
    (res,) = verify(tmp_path / "fresh", tmp_path / "committed")
    assert not res.det_judged and res.det_differ == 12
    r = run_cli("verify", str(tmp_path / "fresh"), "--against", str(tmp_path / "committed"))
    assert r.exit_code == 0 and "not judged" in r.output


def test_bad_input_is_one_line(tmp_path):
    (tmp_path / "empty").mkdir()
    _table(tmp_path / "committed" / "figA", _rows(np.random.default_rng(2)), "cuda")
    r = run_cli("verify", str(tmp_path / "empty"), "--against", str(tmp_path / "committed"))
    assert r.exit_code == 2 and "holds no results table" in r.output and str(tmp_path / "empty") in r.output
    _table(tmp_path / "fresh" / "figZ", _rows(np.random.default_rng(2)), "cuda")
    r = run_cli("verify", str(tmp_path / "fresh"), "--against", str(tmp_path / "committed"))
    assert r.exit_code == 2 and "no committed table to compare figZ with (allowed: figA)" in r.output
    r = run_cli("verify", str(tmp_path / "nowhere"), "--against", str(tmp_path / "committed"))
    assert r.exit_code == 2 and "no such directory" in r.output


def test_reproduce_sh_has_a_verify_step():
    """`scripts/reproduce.sh --verify` keeps the committed tables aside before it runs, and ends with study verify
    against them (the script's own text: running it takes the whole reproduction)."""
    root = Path(__file__).resolve().parents[2]
    text = (root / "scripts/reproduce.sh").read_text()
    assert "--verify" in text and "verify reports --against" in text
    assert subprocess.run(["bash", "-n", str(root / "scripts/reproduce.sh")]).returncode == 0
