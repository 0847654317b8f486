"""The time estimate per backend (study.harness.estimate: a table per backend in stage_costs.json, numpy's where a
backend has none) and its calibration from real runs' metadata (study.harness.estimate_fit)."""

import hashlib
import json
import os

import numpy as np
import pytest

from study.cache import Cache
from study.harness import estimate, estimate_fit
from study.harness.config import load_figure_config
from study.harness.sweep import load_sweep

REPO = estimate.REPO
#: the planted seconds per unit (llvm), and numpy's (another backend's runs must not leak into llvm's table)
LLVM = {"inputs": 2e-7, "renders": 1.5e-6, "probes": 9e-7, "exact": 3e-5, "traces": 4e-9, "columns": 6e-5,
        "columns_method": 0.02}  # fmt: skip
NUMPY = {k: 10 * v for k, v in LLVM.items()}
ONES = {**{k: 1.0 for k in estimate.DEFAULT_RATES}, "columns_method": 0.0, "case": 0.0}


def _sha(rel):
    return hashlib.sha256((REPO / rel).read_bytes()).hexdigest()[:16]


def _units_of_figure(name):
    """Each stage's units of a figure's cases, through forecast with every rate 1 (not estimate_fit's code); its
    method rows as ``columns_method``."""
    cfg, scene, methods = load_figure_config(REPO / "configs" / f"{name}.toml")
    scenes = [scene.with_updates(over) for _, _, over in cfg.case_list()]
    units = estimate.forecast(scenes, methods, cache=Cache(None), table=ONES).stages
    rows = {**ONES, "columns": 0.0, "columns_method": 1.0}
    units["columns_method"] = estimate.forecast(scenes, methods, cache=Cache(None), table=rows).stages[
        "columns"
    ]
    return units, len(scenes)


def _plant_figure(root, name, backend, rates, *, case=0.5, cached=False, cpus=2):
    units, n = _units_of_figure(name)
    split = {k: rates[k] * units[k] for k in rates}
    split["columns"] += split.pop("columns_method", 0.0)  # a cost per pixel and one per method row
    if cached:  # the impostors were in the cache: read in a trifle of the time
        split["renders"], split["probes"] = 1e-3 * split["renders"], 1e-3 * split["probes"]
    meta = {"figure": name, "config": f"configs/{name}.toml", "config_sha256": _sha(f"configs/{name}.toml"),
            "backend": backend, "cpus": cpus, "cases": n, "quality": "preview", "git_commit": "abcdef0123",
            "command": f"study figure {name} --backend {backend}", "seconds": sum(split.values()) + case * n,
            "time_split": {**split, "outputs": 0.0}}  # fmt: skip
    (root / name).mkdir(parents=True, exist_ok=True)
    (root / name / "metadata.json").write_text(json.dumps(meta))
    return meta


def test_planted_runs_give_back_their_rates_per_backend(tmp_path):
    """Figures and a sweep whose seconds are known rates × their units: the fit gives the rates back, llvm's from
    llvm's runs alone (numpy's 10× slower runs beside them), a run whose impostors were cached not lowering the
    renders' rate, the sweep's columns share and the per-case seconds."""
    _plant_figure(tmp_path, "fig_attic", "llvm", LLVM)
    _plant_figure(tmp_path, "fig_probes", "llvm", LLVM)  # the one with probes
    _plant_figure(tmp_path, "fig_hitcache", "llvm", LLVM, cached=True)
    _plant_figure(tmp_path, "fig_glossy", "numpy", NUMPY, case=3.0)
    sw = load_sweep(REPO / "configs" / "sweep_glossy.toml", backend="llvm")
    units = estimate.forecast([c.scene for c in sw.cases], sw.methods, cache=Cache(None), intervals=False,
                              table=ONES).stages  # fmt: skip
    split = {k: LLVM[k] * units[k] for k in LLVM if k != "columns_method"}
    split["columns"] += LLVM["columns_method"] * sum(len(sw.methods) for _ in sw.cases)
    split["columns"] *= 0.25  # a sweep's columns (no pixel intervals): a quarter of a figure's per unit
    (tmp_path / "sweep-sweep_glossy").mkdir()
    record = estimate.run_record(100.0, [c.id for c in sw.cases], [{}] * len(sw.cases))
    meta = {"config": "configs/sweep_glossy.toml", "config_sha256": _sha("configs/sweep_glossy.toml"),
            "backend": "llvm", "cpus": 2, "command": "study sweep configs/sweep_glossy.toml --backend llvm",
            **record, "time_split": split}  # fmt: skip
    (tmp_path / "sweep-sweep_glossy" / "metadata.json").write_text(json.dumps(meta))
    # a figure whose config changed since its run: not counted (its units today are not what ran)
    stale = _plant_figure(tmp_path, "fig4", "llvm", {k: 100 * v for k, v in LLVM.items()})
    (tmp_path / "fig4" / "metadata.json").write_text(json.dumps({**stale, "config_sha256": "0" * 16}))

    runs, totals = estimate_fit.collect(tmp_path)
    names = sorted(r["command"].split()[2] for r in runs)
    assert names == ["configs/sweep_glossy.toml", "fig_attic", "fig_glossy", "fig_hitcache", "fig_probes"]
    fitted = estimate_fit.fit(runs, totals, "llvm", dict(estimate.DEFAULT_RATES))
    got = fitted["seconds_per_unit"]
    assert fitted["kept"] == []
    for stage, rate in LLVM.items():
        assert np.isclose(got[stage], rate, rtol=1e-3), (stage, got[stage], rate)
    assert np.isclose(got["sweep_share"], 0.25, rtol=1e-3) and np.isclose(got["case"], 0.5, rtol=1e-3)
    numpy = estimate_fit.fit(runs, totals, "numpy", dict(estimate.DEFAULT_RATES))
    assert np.isclose(numpy["seconds_per_unit"]["traces"], NUMPY["traces"], rtol=1e-3)
    assert "sweep_share" in numpy["kept"]  # no numpy sweep: its share is the base table's

    # the script writes llvm's table beside the others, with the runs it came from
    out = tmp_path / "costs.json"
    out.write_text((REPO / "study" / "harness" / "stage_costs.json").read_text())
    tab = estimate_fit.fitted_table(tmp_path, "llvm", made_by="test")
    estimate_fit.write(out, "llvm", tab)
    tables = json.loads(out.read_text())["backends"]
    assert {"numpy", "llvm"} <= set(tables) and len(tables["llvm"]["runs"]) == 4
    assert np.isclose(estimate.rates(out, "llvm")["traces"], LLVM["traces"], rtol=1e-3)


def test_a_sweep_without_a_time_split_fits_its_share_from_its_case_files(tmp_path):
    """A sweep written before its metadata held a time split: its case files' case_seconds, less the other
    stages at the fitted rates, give the share of the columns."""
    _plant_figure(tmp_path, "fig_attic", "llvm", LLVM, case=0.0)
    _plant_figure(tmp_path, "fig_probes", "llvm", LLVM, case=0.0)  # two figures: per pixel and per row apart
    sw = load_sweep(REPO / "configs" / "sweep_tiny.toml", backend="llvm")
    d = tmp_path / "sweep-sweep_tiny"
    (d / "cases").mkdir(parents=True)
    (d / "metadata.json").write_text(json.dumps({"config": "configs/sweep_tiny.toml", "backend": "llvm"}))
    seen = set()
    for c in sw.cases:
        from study.impostor.capture import impostor_key

        n = estimate.units(c.scene, sw.methods, rendered=impostor_key(c.scene) not in seen, intervals=False)
        seen.add(impostor_key(c.scene))
        cols = LLVM["columns"] * n["columns"] + LLVM["columns_method"] * n["columns_method"]
        sec = sum(LLVM[k] * n[k] for k in LLVM if not k.startswith("columns")) + 0.4 * cols
        rows = [{"case": c.id, "backend": "llvm", "case_seconds": sec}]
        (d / "cases" / f"{c.key}.json").write_text(json.dumps({"key": c.key, "rows": rows}))
    runs, totals = estimate_fit.collect(tmp_path)
    assert len(totals) == len(sw.cases)
    got = estimate_fit.fit(runs, totals, "llvm", dict(estimate.DEFAULT_RATES))["seconds_per_unit"]
    assert np.isclose(got["sweep_share"], 0.4, rtol=1e-3)


def _costs(path):
    tables = {"numpy": {"seconds_per_unit": {"traces": 1e-7, "columns": 1e-4, "columns_method": 0.0}},
              "llvm": {"seconds_per_unit": {"traces": 1e-9, "columns": 2e-5, "columns_method": 0.0}}}  # fmt: skip
    path.write_text(json.dumps({"backends": tables}))
    return path


def test_the_backends_table_is_used_and_an_unknown_backend_falls_back_to_numpys_saying_so(
    tmp_path, monkeypatch
):
    monkeypatch.setattr(estimate, "COSTS", _costs(tmp_path / "costs.json"))
    cfg = REPO / "configs" / "fig_attic.toml"
    none = Cache(None)
    numpy = estimate.config_estimate(cfg, backend="numpy", cache=none)
    llvm = estimate.config_estimate(cfg, backend="llvm", cache=none)
    cuda = estimate.config_estimate(cfg, backend="cuda", cache=none)
    assert np.isclose(llvm.stages["traces"], numpy.stages["traces"] / 100)
    assert np.isclose(llvm.stages["columns"], numpy.stages["columns"] / 5)
    assert llvm.stages["renders"] == numpy.stages["renders"]  # both from the defaults: neither table has one
    assert cuda.stages == numpy.stages
    assert estimate.told(llvm).endswith("from costs.json's llvm table")
    assert estimate.told(cuda).endswith("from costs.json's numpy table: none for cuda")
    # the reproduce's list: --backend reaches every command (or a command's own --backend wins); the second
    # command finds the impostors the first captured in the shared cache: no renders
    steps = estimate.step_estimates(["figure fig_attic", "figure fig_attic --backend numpy"], cache=none,
                                    reports=tmp_path, backend="llvm")  # fmt: skip
    assert steps[0][1] == llvm.seconds and "llvm table" in steps[0][2] and numpy.stages["renders"] > 0
    assert np.isclose(steps[1][1], numpy.seconds - numpy.stages["renders"] - numpy.stages["probes"])
    # an older file of one table: its backend's (numpy)
    old = tmp_path / "old.json"
    old.write_text(json.dumps({"backend": "numpy", "seconds_per_unit": {"traces": 3e-8}}))
    assert estimate.table_for("llvm", old) == ({**estimate.DEFAULT_RATES, "traces": 3e-8},
                                               "old.json's numpy table: none for llvm")  # fmt: skip


def test_a_figures_last_run_on_the_same_backend_is_preferred(tmp_path, monkeypatch, capsys):
    """reports/NAME/metadata.json of the same config, backend and CPU count: its measured seconds, renders and
    probes as the cache stands now (measured where it rendered and nothing is cached, none where all is cached,
    the model's where it read them from a cache and nothing is cached now); another backend's run or --fresh:
    the stage model."""
    monkeypatch.setattr(estimate, "COSTS", _costs(tmp_path / "costs.json"))
    meta = _plant_figure(tmp_path, "fig_attic", "llvm", LLVM, cpus=os.cpu_count())
    none = Cache(None)
    model = estimate.config_estimate(REPO / "configs" / "fig_attic.toml", backend="llvm", cache=none)
    split = meta["time_split"]
    drawn = split["renders"] + split["probes"]

    def step(backend="llvm", **kw):
        return estimate.step_estimates(
            ["figure fig_attic"], cache=none, reports=tmp_path, backend=backend, **kw
        )[0]

    (cmd, sec, how) = step()
    assert np.isclose(sec, meta["seconds"]) and f"its last run, llvm on {os.cpu_count()} cores" in how
    assert not np.isclose(sec, model.seconds)
    with monkeypatch.context() as m:  # every impostor in the cache now
        m.setattr(estimate, "cached_impostor", lambda sc, cache: cache is not None)
        assert np.isclose(step()[1], meta["seconds"] - drawn)
    _plant_figure(tmp_path, "fig_attic", "llvm", LLVM, cpus=os.cpu_count(), cached=True)  # it read them
    thin = json.loads((tmp_path / "fig_attic" / "metadata.json").read_text())
    got = thin["seconds"] - thin["time_split"]["renders"] - thin["time_split"]["probes"]
    assert np.isclose(step()[1], got + model.stages["renders"] + model.stages["probes"])
    (_, sec, how) = step("numpy")
    assert "stage model" in how and "last run" not in how
    assert step(fresh=True)[1] == model.seconds
    estimate.main(["--backend", "cuda", "--jobs", "2", "--cache", str(tmp_path / "c"), "--reports", str(tmp_path),
                   "figure fig_attic"])  # fmt: skip
    out = capsys.readouterr().out.splitlines()
    assert "stage model, costs.json's numpy table: none for cuda" in out[0]
    assert "on 2 cores, cuda" in out[1] and "from costs.json's numpy table: none for cuda" in out[1]


@pytest.mark.parametrize(
    "times", [[{"traces": 1.0, "columns": 2.0}, {"traces": 0.5}], [{"traces": 1.0}, None]]
)
def test_a_sweeps_metadata_records_its_run_and_time_split(times):
    rec = estimate.run_record(12.34, ["c0000", "c0001"], times)
    assert rec["seconds"] == 12.3 and rec["computed"] == 2 and rec["computed_cases"] == ["c0000", "c0001"]
    if None in times:  # a case without its times: no split rather than a short one
        assert "time_split" not in rec
    else:
        assert rec["time_split"]["traces"] == 1.5 and rec["time_split"]["columns"] == 2.0


def _rows(case_id):
    return [{"label": "classical", "method": "classical", estimate.TIMES: {"traces": 2.0, "exact": 1.0}}]


def test_the_runner_sums_the_cases_stage_times_into_the_metadata_and_keeps_them_out_of_the_rows(tmp_path):
    from study.harness.runner import run_cases

    sw = load_sweep(REPO / "configs" / "sweep_tiny.toml")
    rows, stats = run_cases(sw.cases[:2], tmp_path / "out", {"config": "x"}, lambda c: (_rows, (c.id,)))
    meta = json.loads((tmp_path / "out" / "metadata.json").read_text())
    assert meta["time_split"]["traces"] == 4.0 and meta["time_split"]["exact"] == 2.0
    assert meta["computed"] == 2 and meta["computed_cases"] == ["c0000", "c0001"] and "seconds" in meta
    assert all(estimate.TIMES not in r for r in rows)
    case_files = [json.loads(p.read_text()) for p in (tmp_path / "out" / "cases").glob("*.json")]
    assert case_files and all(estimate.TIMES not in r for f in case_files for r in f["rows"])
