"""Camera rays: the pinhole camera of a scene, matching Mitsuba's perspective sensor."""

from __future__ import annotations

import math

import numpy as np

from study.scene.models import Camera


def look_at_basis(eye, target, up) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(forward, right, up) unit vectors of a camera; right = forward × up, as Mitsuba's look_at."""
    f = np.asarray(target, float) - np.asarray(eye, float)
    f /= np.linalg.norm(f)
    r = np.cross(f, up)
    r /= np.linalg.norm(r)
    return f, r, np.cross(r, f)


def camera_rays(cam: Camera, supersample: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """Primary rays through stratified sub-pixel centres, matching Mitsuba's perspective sensor.

    Returns origins (H, W, s*s, 3) and unit directions (H, W, s*s, 3), float64; fov is horizontal.
    """
    f, r, u = look_at_basis(cam.eye, cam.target, cam.up)
    s, W, H = supersample, cam.width, cam.height
    sub = (np.arange(s) + 0.5) / s
    j = (np.arange(W)[:, None] + sub[None, :]).ravel()  # continuous column coordinates
    i = (np.arange(H)[:, None] + sub[None, :]).ravel()
    tan = math.tan(math.radians(cam.fov) / 2)
    xs = (2 * j / W - 1) * tan
    ys = (1 - 2 * i / H) * tan * H / W
    d = f + xs[None, :, None] * r + ys[:, None, None] * u  # (H*s, W*s, 3)
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    d = d.reshape(H, s, W, s, 3).transpose(0, 2, 1, 3, 4).reshape(H, W, s * s, 3)
    o = np.broadcast_to(np.asarray(cam.eye, float), d.shape)
    return np.ascontiguousarray(o), d
