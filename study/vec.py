"""Structure-of-arrays 3-vectors (:class:`V3`) of any array type with arithmetic (numpy or Dr.Jit): the vectors the
methods and the array backend (:mod:`study.backend`, which re-exports it) compute with."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any


@dataclass
class V3:
    """A 3-vector of equally long 1-D arrays (numpy or Dr.Jit)."""

    x: Any
    y: Any
    z: Any

    def __add__(s, o):
        return V3(s.x + o.x, s.y + o.y, s.z + o.z)

    def __sub__(s, o):
        return V3(s.x - o.x, s.y - o.y, s.z - o.z)

    def __mul__(s, a):
        return V3(s.x * a, s.y * a, s.z * a)

    __rmul__ = __mul__

    def __truediv__(s, a):
        return V3(s.x / a, s.y / a, s.z / a)

    def __neg__(s):
        return V3(-s.x, -s.y, -s.z)

    def dot(s, o):
        return s.x * o.x + s.y * o.y + s.z * o.z
