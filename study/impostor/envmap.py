"""A cube map bound to an array backend: what methods search (:class:`EnvMap`)."""

from __future__ import annotations

import numpy as np

from study.backend import V3, Backend
from study.impostor import cubemap
from study.impostor.pyramid import MinPyramid


class EnvMap:
    """A cube map bound to a backend: ``lookup(v)`` returns the C channels in the direction of ``v``.

    The channels of a distance impostor are (R, G, B, distance). The last channel (distance) is kept in a texture
    of its own, ``dist``: the search reads only distances, so each of its lookups fetches one float per texel
    instead of four (a quarter of the texture traffic); ``tex`` holds the other channels. Every channel is
    filtered on its own, so the values are the same as from one texture. What methods know besides the impostor
    (other views, the scene) comes with it in a :class:`study.impostor.views.Captured`.
    """

    def __init__(self, texels: np.ndarray, B: Backend):
        self.B, self.res, self.channels = B, texels.shape[1], texels.shape[-1]
        self.tex = B.texture(texels[..., :-1]) if self.channels > 1 else None  # colour channels
        self.dist = B.texture(texels[..., -1:])  # distance |v'|
        self._dist_np, self._pyramid = texels[..., -1], None

    @property
    def pyramid(self) -> MinPyramid:
        """The min pyramid of the distances (:mod:`study.impostor.pyramid`), built on first use and kept."""
        if self._pyramid is None:
            self._pyramid = MinPyramid(self._dist_np, self.B)
        return self._pyramid

    def lookup(self, v: V3) -> list:
        face, u, w = cubemap.face_uv(self.B, v.x, v.y, v.z)
        colour = self.B.sample(self.tex, face, u, w) if self.tex is not None else []
        return colour + self.B.sample(self.dist, face, u, w)

    def distance(self, v: V3):
        """|v'|: the stored distance of the environment point seen from the reference point towards v."""
        face, u, w = cubemap.face_uv(self.B, v.x, v.y, v.z)
        return self.B.sample(self.dist, face, u, w)[0]
