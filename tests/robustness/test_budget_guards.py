"""The budget sees what drives a case's cost: a plug-in's lookup bound must be a finite number (a NaN once passed
every --max-minutes, since NaN > limit is False), and the environment's triangles count in memory and time (a
2,007,372-triangle room was estimated at 0.50 GiB / 5 s and took 1.16 GiB / 181 s)."""

import numpy as np
import pytest

from study import methods
from study.errors import StudyError
from study.harness import budget
from study.scene import load_scene_file


class NanBound(methods.base.Method):
    name = "nan_bound_probe"

    def localize(self, B, env, x, R):  # never called here
        raise AssertionError

    def lookups_per_ray(self, res=None):
        return float("nan")


def test_a_nan_lookup_bound_is_refused_naming_the_method():
    scene = load_scene_file("scenes/room.toml")
    with pytest.raises(StudyError, match="lookups_per_ray\\(\\) of 'nan_bound_probe' gave nan"):
        budget.estimate(scene, [NanBound()])


def test_environment_triangles_count_in_the_estimate(monkeypatch):
    scene = load_scene_file("scenes/room.toml")
    ms = [methods.make("classical")]
    small = budget.estimate(scene, ms)
    monkeypatch.setattr(budget, "_triangles", lambda sc: 2_007_372.0)
    big = budget.estimate(scene, ms)
    assert big.memory["environment"] == pytest.approx(2_007_372 * budget.BYTES_PER_TRIANGLE)
    assert big.bytes - small.bytes > 0.6 * (1 << 30)  # the 2 M-triangle room's extra 0.66 GiB
    assert big.seconds - small.seconds > 50
    with pytest.raises(StudyError, match="environment: .*the environment's 2,007,372 triangles"):
        budget.check_cases([("c", scene)], ms, limits=budget.Limits(max_memory_gib=0.9, max_minutes=np.inf))


def test_a_distance_field_counts_in_the_estimate_and_its_resolution_is_named():
    """sdf's field costs res³ nodes while built: at 512³ (134 M nodes, about 10 GiB at 80 B a node) a 4 GiB limit
    refuses the case, naming method.res; at the default 128³ it adds 168 MB."""
    scene = load_scene_file("scenes/room.toml")
    small = budget.estimate(scene, [methods.make("sdf")])
    assert small.memory["method.res"] == 128**3 * budget.BYTES_PER_SDF_NODE
    big = [methods.make("sdf", res=512)]
    assert budget.estimate(scene, big).memory["method.res"] > 10e9
    with pytest.raises(StudyError, match="method.res: .*distance fields' grid nodes"):
        budget.check_cases([("c", scene)], big, limits=budget.Limits(max_memory_gib=4.0, max_minutes=np.inf))
