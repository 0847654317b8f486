"""The time guard (``--max-minutes``) stops what it estimated wrong: a command that runs past its limit stops at
the next stage boundary or inside a long stage (a method's samples), exit 3, one line, the outputs of earlier runs
untouched; and the estimate sees what the stochastic method costs from its parameters (samples × iterations,
each an array step over every ray: ``stochastic(samples=4096, iterations=1000)`` was estimated at 43 s and ran
past ``--max-minutes 1`` for more than 100 s)."""

import time

import pytest
from conftest import digest, error_output, run_cli, scene_toml, small_scene_dict

from study import methods, progress
from study.errors import StudyError
from study.harness import budget
from study.scene import scene_from_dict

HOSTILE = "stochastic(samples=4096, iterations=1000)"


def _tiny() -> dict:
    d = small_scene_dict()
    d["object"]["alpha"] = 0.2  # rough: the glossy methods' lobe
    d["render"].update(cube_res=16, cube_spp=2, spp=2)
    d["camera"].update(width=24, height=24)
    return d


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    root = tmp_path_factory.mktemp("time-guard")
    (root / "tiny.toml").write_text(scene_toml(_tiny()))
    return root


def test_the_estimate_learns_the_stochastic_cost_from_its_parameters():
    """Its array steps grow with samples × iterations whatever the rays: the hostile case is now estimated at
    tens of minutes and refused before it runs, naming the method."""
    scene = scene_from_dict(_tiny())
    est = budget.estimate(scene, [methods.make("stochastic", samples=4096, iterations=1000)])
    assert est.time["methods"] > 20 * 60, est.time
    assert est.time["methods"] >= 4096 * 1003 * budget.SECONDS_PER_STEP  # samples × (iterations + 3) steps
    with pytest.raises(
        StudyError, match=r"methods: .*over the limit of 1 min .*the costliest " + HOSTILE[:10]
    ):
        budget.check_cases(
            [("c", scene)],
            [methods.make("stochastic", samples=4096, iterations=1000)],
            limits=budget.Limits(max_minutes=1),
        )


def test_the_estimate_bounds_a_measured_stochastic_run(tiny):
    """The other side: a small stochastic run measured here takes less than its estimate (3× leeway for a
    machine shared with other work; the estimate of before was 100× short)."""
    import study

    scene = study.load_scene(str(tiny / "tiny.toml"))
    label = "stochastic(samples=32, iterations=30)"
    m = methods.make("stochastic", samples=32, iterations=30)
    res = study.evaluate(scene, methods=[label], cache=str(tiny / "cache"))
    row = res.table[res.table.label == label].iloc[0]
    rays = row["rays"]
    estimated = (
        rays * m.lookup_bound(16) * budget.SECONDS_PER_LOOKUP + m.host_steps(16) * budget.SECONDS_PER_STEP
    )
    assert row["seconds"] < 3 * estimated, (row["seconds"], estimated)


def test_a_stage_boundary_past_the_deadline_stops():
    """progress's checkpoints: a stage, a unit, an item past the deadline raise its error; none before it."""
    mark = progress.Stages()
    with progress.deadline(time.time() + 60, lambda: AssertionError("early")):
        mark("load")
        progress.advance()
    for call in (lambda: mark("capture"), progress.advance, lambda: progress.item("c").__enter__()):
        with progress.deadline(time.time() - 1, lambda: budget.over_time(1)):
            with pytest.raises(StudyError, match="ran past its limit of 1 min") as err:
                call()
            assert err.value.code == 3
    mark.end()


def test_a_run_past_max_minutes_stops_inside_its_long_stage(tiny, monkeypatch):
    """An estimator that gets the methods wholly wrong (no cost per lookup or step) lets the hostile stochastic
    run start under --max-minutes 0.1 (6 s); the run stops inside its methods stage, soon after, with exit 3 and
    the old outputs as they were (a full run takes half an hour)."""
    monkeypatch.setattr(budget, "SECONDS_PER_STEP", 0.0)
    monkeypatch.setattr(budget, "SECONDS_PER_LOOKUP", 0.0)
    out = tiny / "out"
    out.mkdir(exist_ok=True)
    (out / "table.csv").write_text("label\nold\n")
    before = digest(out)
    t0 = time.perf_counter()
    res = run_cli(
        *["--max-minutes", "0.1", "run", str(tiny / "tiny.toml"), "-m", HOSTILE, "--out", str(out)]
        + ["--cache", str(tiny / "cache")],
    )
    took = time.perf_counter() - t0
    text = error_output(res)
    assert res.exit_code == 3, res.output
    assert text.startswith("error: --max-minutes: stopped: the command ran past its limit of 0.1 min"), text
    assert "\n" not in text and "Traceback" not in text
    assert took < 40, took  # 6 s of budget, then at most one sample's steps
    assert digest(out) == before
    assert "STUDY_DEADLINE" not in __import__("os").environ  # the command's deadline ends with it


@pytest.mark.slow
def test_a_sweep_past_max_minutes_stops_in_its_workers(tiny, monkeypatch):
    """With --jobs 2 the worker processes carry the deadline: the sweep stops with exit 3, its old table kept."""
    monkeypatch.setattr(budget, "SECONDS_PER_STEP", 0.0)
    monkeypatch.setattr(budget, "SECONDS_PER_LOOKUP", 0.0)
    (tiny / "sweep.toml").write_text(
        'scene = "tiny.toml"\nmethods = [{ name = "stochastic", samples = 4096, iterations = 1000 }]\n'
        '[axes]\n"object.center" = [[0.6, 1.2, 0.3], [0.5, 1.2, 0.3]]\n'
    )
    out = tiny / "sweep-out"
    out.mkdir(exist_ok=True)
    (out / "results.csv").write_text("case,label\nc0,old\n")
    before = digest(out)
    t0 = time.perf_counter()
    res = run_cli(
        *["--max-minutes", "0.4", "sweep", str(tiny / "sweep.toml"), "--jobs", "2", "--out", str(out)]
        + ["--cache", str(tiny / "cache")],
    )
    assert res.exit_code == 3, res.output
    assert "ran past its limit of 0.4 min" in error_output(res)
    assert time.perf_counter() - t0 < 90
    assert digest(out) == before


def test_a_nan_host_steps_is_refused_naming_the_method():
    """As a NaN lookup bound (tests/robustness/test_budget_guards.py): NaN > limit is False, so it would pass every
    limit."""

    class NanSteps(methods.base.Method):
        name = "nan_steps_probe"

        def localize(self, B, env, x, R):  # never called here
            raise AssertionError

        def lookups_per_ray(self, res=None):
            return 1

        def host_steps(self, res=None):
            return float("nan")

    with pytest.raises(StudyError, match=r"host_steps\(\) of 'nan_steps_probe' gave nan"):
        budget.estimate(scene_from_dict(_tiny()), [NanSteps()])
