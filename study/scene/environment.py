"""The environment as one thing behind one interface, whatever its source (:mod:`study.scene.sources`):
triangles with surface ids (the very ones Embree intersects and Mitsuba renders), each surface's material, the
emitters, and the bounds (an :class:`~study.scene.sources.base.EnvGeometry`, re-exported here).

:func:`geometry` turns a scene into an :class:`EnvGeometry`; the result is memoized by content (files by their
bytes), so every caller of one case shares one load of a mesh file or a Mitsuba scene.
"""

from __future__ import annotations

import json
from collections import OrderedDict
from typing import TYPE_CHECKING, Any

from study.errors import StudyError
from study.scene.sources import EnvGeometry, key_fields
from study.scene.sources.base import checked_build, source_call

if TYPE_CHECKING:
    from study.scene.schema import Scene


# ---------------------------------------------------------------------------------------------- one per content
_MEMO: OrderedDict[str, EnvGeometry] = OrderedDict()


def env_key(scene: Scene) -> str:
    """Content key of what :func:`geometry` returns: the environment source (files by their bytes), and for the
    box the room and columns."""
    env = scene.environment
    extra = source_call(env, "key_extra()", lambda: env.key_extra(scene))
    if not isinstance(extra, dict):
        raise StudyError(
            f"environment {env.type!r}: key_extra() returned a {type(extra).__name__}, not a dict"
        )
    return json.dumps({"environment": key_fields(env), **extra}, sort_keys=True, default=str)


def geometry(scene: Scene | Any) -> EnvGeometry:
    """The environment of ``scene`` (memoized: the last few loaded environments are kept). ``scene`` may also be
    a mesh or Mitsuba environment on its own (a :mod:`study.scene.sources` model or its dict)."""
    if not hasattr(scene, "environment"):  # an environment alone (not the box: that needs its room)
        from pydantic import TypeAdapter

        from study.scene.sources import Environment

        env = scene if hasattr(scene, "type") else TypeAdapter(Environment).validate_python(scene)
        scene = type("_EnvOnly", (), {"environment": env, "room": None, "columns": ()})()
    key = env_key(scene)
    if key not in _MEMO:
        _MEMO[key] = checked_build(scene.environment, scene)
        while len(_MEMO) > 8:
            _MEMO.popitem(last=False)
    _MEMO.move_to_end(key)
    return _MEMO[key]


def describe_source(env) -> str:
    """The source of an environment in a few words (its file name, builtin or "scene dict")."""
    return env.label()


def describe(scene: Scene) -> str:
    """A short name of the environment for titles: "(-2, 0, -2)..(2, 3, 2) room", "mesh l_room.ply", "Mitsuba
    cornell_box"."""
    return scene.environment.describe(scene)
