"""The oracle knows where the reference point o looks (study/measure/split.py): unit rays built by hand in a small
open scene, one of each class — held, hidden, escaping-visible, escaping-hidden and off-screen — classified by the
very functions a case uses (:func:`split.exact_hits`, :func:`split.view_class`, :func:`outcomes.off_screen`)."""

from __future__ import annotations

import numpy as np
import pytest

from study.measure import outcomes, split
from study.reference.embree import Tracer
from study.scene.models import Camera

O = np.array([0.0, 1.0, 0.0])  # the reference point


def _quad(c, u, v):
    """Two triangles of the rectangle c ± u ± v."""
    c, u, v = (np.asarray(a, float) for a in (c, u, v))
    return [c - u - v, c + u - v, c + u + v, c - u + v]


@pytest.fixture(scope="module")
def tracer():
    """A floor (y = 0), one wall (x = 3, up to y = 3), no ceiling, and a small screen at x = 1 between o and the
    wall's point (3, 1, 0): everything else is open (rays escape)."""
    quads = [
        _quad((0, 0, 0), (5, 0, 0), (0, 0, 5)),  # floor
        _quad((3, 1.5, 0), (0, 1.5, 0), (0, 0, 5)),  # wall, y ∈ [0, 3]
        _quad((1, 1, 0), (0, 0.5, 0), (0, 0, 0.5)),  # screen, y ∈ [0.5, 1.5], z ∈ [−0.5, 0.5]
    ]
    V = np.array([p for q in quads for p in q])
    F = np.array(
        [[4 * i, 4 * i + 1, 4 * i + 2] for i in range(3)] + [[4 * i, 4 * i + 2, 4 * i + 3] for i in range(3)]
    )
    return Tracer.from_triangles(V, F, threads=1)


def _unit(v):
    v = np.asarray(v, float)
    return v / np.linalg.norm(v)


#: name → (origin x, direction): each ray built so that its class is what its name says.
RAYS = {
    "held": ((0.0, 1.0, 1.0), (0, -1, 0)),  # down to the floor at (0, 0, 1), in plain view of o
    "hidden": ((2.0, 1.0, 0.0), (1, 0, 0)),  # to the wall at (3, 1, 0), which the screen hides from o
    "escaping-visible": ((0.0, 1.0, 1.0), (0, 1, 0)),  # up, no ceiling; o looking up sees nothing either
    "escaping-hidden": (
        (2.8, 2.95, 0.0),
        (1, 0.5, 0),
    ),  # over the wall's top; o in that direction sees the wall
    "off-screen": (
        (0.0, 0.5, 4.5),
        (0, -1, 0),
    ),  # to the floor at (0, 0, 4.5): o sees it, the camera does not
}
#: The camera: from (0, 1, 5) towards −z; sees the held ray's floor point, not the off-screen one's.
CAMERA = Camera(eye=(0.0, 1.0, 5.0), target=(0.0, 1.0, 0.0), fov=90.0, width=64, height=64)


@pytest.fixture(scope="module")
def classified(tracer):
    x = np.array([r[0] for r in RAYS.values()])
    d = np.array([_unit(r[1]) for r in RAYS.values()])
    point, escapes, hidden = split.exact_hits(tracer, x, d, O)
    names = list(RAYS)
    return {
        n: (split.VIEW_NAMES[c], bool(h), bool(off), point[i])
        for i, (n, c, h, off) in enumerate(
            zip(
                names,
                split.view_class(hidden, escapes),
                split.held(hidden, escapes),
                outcomes.off_screen(CAMERA, point),
            )
        )
    }


@pytest.mark.parametrize("name", ["held", "hidden", "escaping-visible", "escaping-hidden"])
def test_each_ray_is_the_class_its_name_says(classified, name):
    assert classified[name][0] == name


def test_held_is_exactly_what_o_sees(classified):
    """The oracle has a value for held and escaping-visible rays only: an escaping ray whose direction o sees a
    wall in is not held (the impostor's texel holds the wall, not the background)."""
    held = {n: h for n, (_, h, _, _) in classified.items()}
    assert held == {"held": True, "hidden": False, "escaping-visible": True, "escaping-hidden": False,
                    "off-screen": True}  # fmt: skip


def test_off_screen_is_asked_of_the_camera_not_of_o(classified):
    cls, held, off, point = classified["off-screen"]
    assert off and held and cls == "held"
    np.testing.assert_allclose(point, (0.0, 0.0, 4.5), atol=1e-5)
    assert not classified["held"][2] and not classified["hidden"][2]  # the finite hits the frame shows


def test_exact_hits_where_the_geometry_says(classified):
    np.testing.assert_allclose(classified["held"][3], (0, 0, 1), atol=1e-5)
    np.testing.assert_allclose(classified["hidden"][3], (3, 1, 0), atol=1e-5)
    for n in ("escaping-visible", "escaping-hidden"):
        x, d = RAYS[n]
        assert np.linalg.norm(classified[n][3] - x) == pytest.approx(split.FAR, rel=1e-9)


def test_oracle_radiance_follows_the_classes():
    """Per class the oracle's radiance: the map towards the hit (held), the background along the ray (escaping-
    visible), no value (hidden, escaping-hidden)."""
    hidden = np.array([False, True, False, True])
    escapes = np.array([False, False, True, True])
    assert list(split.view_class(hidden, escapes)) == [
        split.HELD,
        split.HIDDEN,
        split.ESC_VISIBLE,
        split.ESC_HIDDEN,
    ]
    looked, along = np.full((4, 3), 0.5), np.full((4, 3), 2.0)
    rad = split.oracle_radiance(looked, along, split.held(hidden, escapes), escapes)
    assert np.all(rad[0] == 0.5) and np.all(rad[2] == 2.0)
    assert np.isnan(rad[1]).all() and np.isnan(rad[3]).all()
