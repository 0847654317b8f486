"""Stale results never come back silently (issue 12): keys follow the code, resume follows today's config, cache
entries are bound to their key, ``study cache`` shows and clears the cache, and ``--jobs`` workers die with the
sweep's process."""

import importlib
import json
import os
import shutil
import signal
import subprocess
import sys
import time
import types
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from study import codehash, methods
from study.cache import Cache, content_key
from study.cache import flush as cache_flush
from study.cli import app
from study.codehash import code_hash
from study.harness.runner import run_sweep
from study.harness.sweep import load_sweep
from study.tables import read_csv
from tests.conftest import scene_toml, small_scene_dict

ROOT = Path(__file__).resolve().parents[2]


def write_sweep(d: Path, axes: str, methods_: str = '[{ name = "classical" }]', name: str = "s.toml") -> Path:
    """A tiny sweep (camera 24², cube 16², 2 samples) over ``axes`` (TOML lines of the [axes] table)."""
    scene = small_scene_dict()
    scene["camera"].update(width=24, height=24)
    scene["render"].update(cube_res=16, cube_spp=2, spp=2)
    (d / "scene.toml").write_text(scene_toml(scene))
    p = d / name
    p.write_text(f'scene = "scene.toml"\nmethods = {methods_}\n\n[axes]\n{axes}\n')
    return p


def by_case(rows):
    return {(r["case"], r["label"]): r for r in rows}


# ---------------------------------------------------------------------------------------------- code_hash
@pytest.fixture
def fake_study(tmp_path, monkeypatch):
    """A throwaway package standing in for study's directory, so code_hash can be watched as files change."""
    root = tmp_path / "study"
    (root / "sub").mkdir(parents=True)
    files = {
        "__init__.py": "",
        "a.py": "def f():\n    from study.sub import b\n    return b.g()\n",
        "sub/__init__.py": "X = 1\n",
        "sub/b.py": "from . import c\n\ndef g():\n    return c.h()\n",
        "sub/c.py": "def h():\n    return 1\n",
        "lone.py": "def k():\n    return 2\n",
    }
    for name, text in files.items():
        (root / name).write_text(text)

    def clear():
        for fn in (codehash._source, codehash._imports, codehash._study_closure):
            fn.cache_clear()

    monkeypatch.setattr(codehash, "PACKAGE_DIR", root)
    clear()
    yield root, clear
    monkeypatch.undo()
    clear()


def test_code_hash_follows_imports_transitively(fake_study):
    """Imports inside functions, relative imports and packages' __init__ count; an unrelated module does not."""
    root, clear = fake_study
    mod = types.ModuleType("study.a")
    assert set(codehash._study_closure("study.a")) == {
        "study",
        "study.a",
        "study.sub",
        "study.sub.b",
        "study.sub.c",
    }
    before, lone = code_hash(mod), code_hash(types.ModuleType("study.lone"))
    for name, text in [("sub/c.py", "def h():\n    return 2\n"), ("sub/__init__.py", "X = 2\n")]:
        (root / name).write_text(text)
        clear()
        after = code_hash(mod)
        assert after != before, name  # a module imported two steps away, a package's init
        before = after
    assert code_hash(types.ModuleType("study.lone")) == lone  # imports none of them
    (root / "__init__.py").write_text("Y = 1\n")
    clear()
    assert code_hash(types.ModuleType("study.lone")) != lone  # but the package it lives in counts


def test_code_hash_of_study_and_of_outside_modules(tmp_path, monkeypatch):
    """Study's own closure (a method class adds its module), and a module outside study by its file, re-read."""
    from study.measure.case import run_case
    from study.methods.localized import Localized

    assert "study.methods.base" in codehash._study_closure("study.measure.case")
    assert "study.methods.localized" not in codehash._study_closure("study.measure.case")  # dynamic import
    assert code_hash(run_case) != code_hash(run_case, Localized) == code_hash(Localized, run_case)
    (tmp_path / "outside_mod_ch.py").write_text("def f():\n    return 1\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    m = importlib.import_module("outside_mod_ch")
    try:
        h = code_hash(m.f)
        (tmp_path / "outside_mod_ch.py").write_text("def f():\n    return 22\n")
        assert code_hash(m.f) != h  # read again: the file on disk decides
    finally:
        sys.modules.pop("outside_mod_ch", None)


# ---------------------------------------------------------------------------------------------- cache entries
def test_cache_entry_is_bound_to_its_key_and_code(tmp_path, monkeypatch):
    (tmp_path / "producer_ch.py").write_text("def make():\n    return 1\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    prod = importlib.import_module("producer_ch")
    cache, calls = Cache(tmp_path / "c"), []

    def make(v):
        calls.append(v)
        return np.full((2, 3), v, np.float32)

    try:
        assert cache.get("k", "a", lambda: make(1), code=prod.make)[0, 0] == 1
        assert cache.get("k", "a", lambda: make(9), code=prod.make)[0, 0] == 1 and calls == [1]  # a hit
        cache_flush()  # the entry on disk (written off this thread)
        entry = next((tmp_path / "c" / "k").glob("*.json"))
        assert json.loads(entry.read_text())["key"] == entry.stem
        # the entry copied under the key of "b": checksum fine, stored key wrong → recomputed
        other = content_key("b", code_hash(prod.make))
        shutil.copy(entry, entry.with_name(f"{other}.json"))
        shutil.copy(entry.with_suffix(".npy"), entry.with_name(f"{other}.npy"))
        assert cache.load("k", other) is None
        assert cache.get("k", "b", lambda: make(2), code=prod.make)[0, 0] == 2 and calls == [1, 2]
        # the producing code changes: a new key, recomputed; the old entry is left alone
        (tmp_path / "producer_ch.py").write_text("def make():\n    return 2  # changed\n")
        assert cache.get("k", "a", lambda: make(3), code=prod.make)[0, 0] == 3 and calls == [1, 2, 3]
        # an entry of the old format (no key in its JSON) is not trusted
        entry.write_text(json.dumps({k: v for k, v in json.loads(entry.read_text()).items() if k != "key"}))
        assert cache.load("k", entry.stem) is None
    finally:
        sys.modules.pop("producer_ch", None)


def test_cache_info_and_clear(tmp_path):
    root = tmp_path / "c"
    cache = Cache(root)
    for kind, n in (("radiance", 2), ("mitsuba", 3)):
        for i in range(n):
            cache.get(kind, f"k{i}", lambda: np.ones((4, 4), np.float32), code=test_cache_info_and_clear)
    cache_flush()  # the entries on disk (written off this thread)
    (root / "mitsuba" / "notes.txt").write_text("mine")  # not the cache's: never counted, never removed
    (root / "mitsuba" / "metadata.json").write_text('{"a": 1}')
    (root / "radiance" / ".x.abc.tmp").write_text("leftover")  # an interrupted write: the cache's
    os.utime(root / "radiance" / ".x.abc.tmp", (1e9, 1e9))  # left long ago (a young one may be in flight)
    run = CliRunner().invoke
    r = run(app, ["cache", "info", "--cache", str(root)])
    assert r.exit_code == 0, r.output
    assert (
        "mitsuba: 3 entries" in r.output and "radiance: 2 entries" in r.output and ": 5 entries" in r.output
    )
    r = run(app, ["cache", "clear", "--cache", str(root), "--kind", "nope"])
    assert r.exit_code == 2 and "error: " in r.output and "--kind: no entries of kind 'nope'" in r.output
    r = run(app, ["cache", "clear", "--cache", str(root), "--kind", "radiance"])
    assert r.exit_code == 0 and "radiance: removed 2 entries" in r.output, r.output
    assert not (root / "radiance").exists() and Cache(root).info()["mitsuba"][0] == 3
    r = run(app, ["cache", "clear", "--cache", str(root)])
    assert r.exit_code == 0 and "removed 3 entries" in r.output, r.output
    assert sorted(p.name for p in (root / "mitsuba").iterdir()) == ["metadata.json", "notes.txt"]
    assert Cache(root).info() == {}
    r = run(app, ["cache", "info", "--cache", str(tmp_path / "none")])
    assert r.exit_code == 0 and "0 entries" in r.output
    (tmp_path / "file").write_text("x")
    r = run(app, ["cache", "info", "--cache", str(tmp_path / "file")])
    assert r.exit_code == 2 and "the cache is not a directory" in r.output


# ---------------------------------------------------------------------------------------------- method code
PROBE = '''
"""A throwaway method: {what}."""
from study.methods import Localization, Method, register


@register
class Probe(Method):
    name = "integrity_probe"

    def localize(self, B, env, x, R):
        return Localization(l=R * {sign}, valid=B.isfinite(B.length(R)))

    def lookups_per_ray(self):
        return 1
'''


@pytest.fixture
def probe(tmp_path, monkeypatch):
    """Write (and re-import) the plugin module ``integrity_probe_mod`` in one of two versions."""
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.delenv(methods.PLUGIN_ENV, raising=False)
    monkeypatch.setattr(sys, "dont_write_bytecode", True)

    def version(right: bool):
        (tmp_path / "integrity_probe_mod.py").write_text(
            PROBE.format(
                what="the ray direction (classical)" if right else "the wrong direction, -R",
                sign="1.0" if right else "-1.0",
            )
        )
        methods.REGISTRY.pop("integrity_probe", None)
        sys.modules.pop("integrity_probe_mod", None)
        importlib.invalidate_caches()
        methods.load_plugins(["integrity_probe_mod"])

    yield version
    methods.REGISTRY.pop("integrity_probe", None)
    sys.modules.pop("integrity_probe_mod", None)
    os.environ.pop(methods.PLUGIN_ENV, None)


def test_changed_method_code_is_recomputed_and_changed_back_is_reused(tmp_path, probe):
    """The issue's story: a method changed (a wrong lookup direction), run, changed back. Each version's numbers
    are its own: the wrong one is computed, never reused for the right one, and the right one comes back."""
    cfg = write_sweep(
        tmp_path,
        '"render.cube_res" = [16, 12]',
        methods_='[{ name = "classical" }, { name = "integrity_probe" }]',
    )
    out, cache = tmp_path / "out", tmp_path / "cache"

    def probe_median(rows):
        return [r["angle_median_deg"] for r in rows if r["method"] == "integrity_probe"]

    probe(right=True)
    rows, stats = run_sweep(cfg, out, cache=cache)
    right = probe_median(rows)
    assert stats["computed"] == 2 and right == [
        r["angle_median_deg"] for r in rows if r["method"] == "classical"
    ]
    probe(right=False)
    rows, stats = run_sweep(cfg, out, cache=cache)
    assert stats["computed"] == 2 and stats["cached"] == 0
    assert all(w > 90 for w in probe_median(rows)), probe_median(rows)
    assert all(w > 90 for w in probe_median(read_csv(out / "results.csv")))
    probe(right=True)
    rows, stats = run_sweep(cfg, out, cache=cache)
    assert stats["computed"] == 0 and stats["cached"] == 2 and probe_median(rows) == right
    assert probe_median(read_csv(out / "results.csv")) == pytest.approx(right)


# ---------------------------------------------------------------------------------------------- resume identity
@pytest.fixture(scope="module")
def shared_cache(tmp_path_factory):
    return tmp_path_factory.mktemp("cache")


def test_added_axis_value_and_added_axis_follow_the_config(tmp_path, shared_cache):
    out = tmp_path / "out"
    _, stats = run_sweep(write_sweep(tmp_path, '"render.cube_res" = [16, 24]'), out, cache=shared_cache)
    assert stats["computed"] == 2
    # a value added in front: every later case moves to another id; the two finished ones are reused
    rows, stats = run_sweep(
        write_sweep(tmp_path, '"render.cube_res" = [12, 16, 24]'), out, cache=shared_cache
    )
    assert stats == {**stats, "cached": 2, "computed": 1}
    assert [(r["case"], r["axis:render.cube_res"]) for r in rows if r["label"] == "classical"] == [
        ("c0000", "12"),
        ("c0001", "16"),
        ("c0002", "24"),
    ]
    per_case = len(rows) // 3
    for table in (rows, read_csv(out / "results.csv")):
        assert [r["case"] for r in table] == [f"c000{i}" for i in range(3) for _ in range(per_case)]
        assert all(float(r["axis:render.cube_res"]) == float(r["cube_res"]) for r in table)
        assert len(by_case(table)) == len(table) == 3 * per_case
    # an axis added later (its value is the scene's own, so nothing changes but the column): reused, labelled
    rows, stats = run_sweep(
        write_sweep(tmp_path, '"render.cube_res" = [12, 16, 24]\n"object.radius" = [0.4]'),
        out,
        cache=shared_cache,
    )
    assert stats["cached"] == 3 and stats["computed"] == 0
    assert all(r["axis:object.radius"] == "0.4" for r in rows)
    assert all(r["axis:object.radius"] == 0.4 for r in read_csv(out / "results.csv"))
    # and dropped again: the column goes
    rows, _ = run_sweep(write_sweep(tmp_path, '"render.cube_res" = [24, 16]'), out, cache=shared_cache)
    assert not any(k.startswith("axis:object") for r in rows for k in r)
    assert [(r["case"], r["cube_res"]) for r in rows if r["label"] == "classical"] == [
        ("c0000", 24),
        ("c0001", 16),
    ]


def test_int_and_float_spellings_do_not_collide(tmp_path, shared_cache):
    cfg = write_sweep(tmp_path, '"render.cube_res" = [16, 16.0]')
    sw = load_sweep(cfg)
    assert [c.labels["render.cube_res"] for c in sw.cases] == ["16", "16.0"]
    assert sw.cases[0].key == sw.cases[1].key  # the same scene: the same content, shared result
    for _ in range(2):  # computed, then resumed: both cases, once each
        rows, _ = run_sweep(cfg, tmp_path / "out", cache=shared_cache)
        got = [(r["case"], r["axis:render.cube_res"]) for r in rows if r["label"] == "classical"]
        assert got == [("c0000", "16"), ("c0001", "16.0")]
        table = read_csv(tmp_path / "out" / "results.csv")
        assert [r["case"] for r in table] == [r["case"] for r in rows] and len(table) == len(by_case(table))
        assert sorted({r["case"] for r in table}) == ["c0000", "c0001"]


@pytest.mark.parametrize(
    "damage",
    [
        "empty rows",
        "copied under another key",
        "wrong labels",
        "a row missing",
        "rows not a list",
        "not JSON",
    ],
)
def test_damaged_or_forged_case_files_are_recomputed(tmp_path, shared_cache, damage):
    cfg = write_sweep(tmp_path, '"render.cube_res" = [16, 24]')
    out = tmp_path / "out"
    ref, _ = run_sweep(cfg, out, cache=shared_cache)
    a, b = (out / "cases" / f"{c.key}.json" for c in load_sweep(cfg).cases)
    data = json.loads(b.read_text())
    if damage == "empty rows":
        data["rows"] = []
    elif damage == "copied under another key":
        data = json.loads(a.read_text())  # case c0000's file, key and all, as c0001's
    elif damage == "wrong labels":
        data["rows"][-1]["label"] = "localized(iterations=3)"  # the method's row (the last)
    elif damage == "a row missing":
        data["rows"] = data["rows"][:1]
    elif damage == "rows not a list":
        data["rows"] = {"oracle": 1}
    b.write_text("{not json" if damage == "not JSON" else json.dumps(data))
    rows, stats = run_sweep(cfg, out, cache=shared_cache)
    assert stats["cached"] == 1 and stats["computed"] == 1
    assert [(r["case"], r["label"], r["cube_res"]) for r in rows] == [
        (r["case"], r["label"], r["cube_res"]) for r in ref
    ]
    assert [r["case"] for r in read_csv(out / "results.csv")] == [r["case"] for r in ref]


@pytest.mark.slow
def test_caustics_sweep_resumes_with_the_same_checks(tmp_path):
    """The caustics sweep runs on the same runner: a re-run reuses its cases; an empty or relabelled case file is
    recomputed; a resolution added later shifts nothing (ids and keys from the config as it is now)."""
    from study.caustics.figure import fig8
    from tests.report.test_caustics import SMALL_CAUSTICS

    cfg = tmp_path / "c.toml"
    cfg.write_text(SMALL_CAUSTICS.replace('"MATERIAL"', '"dielectric", ior = 1.3'))
    out, cache = tmp_path / "o", tmp_path / "cache"
    fig8(cfg, out, cache=cache, sweep=True)
    files = sorted(
        (out / "sweep" / "cases").glob("*.json"),
        key=lambda p: json.loads(p.read_text())["rows"][0]["caustic_res"],
    )
    assert len(files) == 2
    first = read_csv(out / "sweep" / "results.csv")
    stamp = files[0].stat().st_mtime_ns
    data = json.loads(files[1].read_text())
    data["rows"][-1]["label"] = "something else"
    files[1].write_text(json.dumps(data))
    fig8(cfg, out, cache=cache, sweep=True)
    assert files[0].stat().st_mtime_ns == stamp  # reused
    assert json.loads(files[1].read_text())["rows"][-1]["label"] != "something else"  # recomputed
    again = read_csv(out / "sweep" / "results.csv")
    assert [(r["case"], r["label"]) for r in again] == [(r["case"], r["label"]) for r in first]
    cfg.write_text(cfg.read_text().replace("resolutions = [16, 32]", "resolutions = [8, 16, 32]"))
    fig8(cfg, out, cache=cache, sweep=True)
    assert files[0].stat().st_mtime_ns == stamp
    table = read_csv(out / "sweep" / "results.csv")
    assert sorted({(r["case"], r["caustic_res"]) for r in table}) == [
        ("r0008", 8),
        ("r0016", 16),
        ("r0032", 32),
    ]


# ---------------------------------------------------------------------------------------------- orphans
@pytest.mark.slow
def test_workers_die_with_the_sweep_process(tmp_path):
    """SIGKILL the parent of a --jobs 2 sweep while its workers run: none of its processes is left after a few
    seconds (before: the workers waited forever on a queue nobody would write to)."""
    psutil = pytest.importorskip("psutil")
    cfg = write_sweep(
        tmp_path,
        '"render.cube_res" = [48, 64, 80]\n"camera.width" = [96]\n"camera.height" = [96]'
        '\n"render.spp" = [16]',
    )
    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "study.cli",
            "sweep",
            str(cfg),
            "--out",
            str(tmp_path / "out"),
            "--cache",
            str(tmp_path / "cache"),
            "--jobs",
            "2",
            "--no-plots",
        ],
        cwd=ROOT,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    kids: list = []
    try:
        parent = psutil.Process(proc.pid)
        deadline = time.time() + 120
        while time.time() < deadline:
            kids = parent.children(recursive=True)
            if sum("spawn_main" in " ".join(_cmdline(k)) for k in kids) >= 2:
                break
            time.sleep(0.05)
        assert sum("spawn_main" in " ".join(_cmdline(k)) for k in kids) >= 2, "the sweep started no workers"
        while time.time() < deadline and not list((tmp_path / "cache").glob("*/*.json")):
            time.sleep(0.05)  # a worker is inside a case: past start-up and its initializer
        kids = parent.children(recursive=True)
        assert not list((tmp_path / "out").glob("cases/*.json")), "the sweep got too far to test anything"
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait()
        deadline = time.time() + 10
        while time.time() < deadline and any(_alive(k) for k in kids):
            time.sleep(0.1)
        left = [(k.pid, _cmdline(k)) for k in kids if _alive(k)]
        assert not left, f"orphans: {left}"
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        for k in kids:  # never leave anything behind on a shared machine
            if _alive(k):
                k.kill()


def _cmdline(p) -> list[str]:
    import psutil

    try:
        return p.cmdline()
    except psutil.Error:
        return []


def _alive(p) -> bool:
    import psutil

    try:
        return p.is_running() and p.status() != psutil.STATUS_ZOMBIE
    except psutil.NoSuchProcess:
        return False
