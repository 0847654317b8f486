"""Measured floors: what the hardware allows the methods at best, timed in the same run as the methods.

Fetch rate
    bilinear fetches per second of a 1-channel and a 4-channel 6·R×R texture (``Backend.texture``: a Dr.Jit
    ``Texture2f``, hardware-accelerated on CUDA), ``n_lanes`` lanes each fetching ``fetches`` times in one kernel
    (a recorded loop), in two patterns: **coherent** (neighbouring lanes read neighbouring texels, each step one
    texel further along u) and **random** (a hashed, uniform start per lane, then one texel further along u per
    step: no locality between lanes, the locality along one ray of a search); **scattered** (a new random position
    for every lane and step, no locality at all: shown for reference, used in no floor). The rate is the
    difference quotient between ``fetches`` and ``fetches / 4`` fetches per lane, so launch, tracing and the one
    output per lane cancel.
3D fetch rate
    trilinear fetches per second of a 1-channel :data:`VOLUME_RES`³ ``Texture3f`` (a distance field), coherent and
    random as above (:func:`fetch3d_rate`).
Bandwidth
    bytes read + written per second by ``y = x + 1`` over ``copy_floats`` float32s (one read, one write each).
Floor of a method (:func:`method_floor`)
    f₁ · (1-channel fetch cost) + f₄ · (4-channel fetch cost) + bytes per ray / bandwidth, per ray, with
    f₁ = the mean lookups per ray measured in the method's timed calls (``Trace.lookups``; ``lookups_per_ray(res)``,
    the bound, where none is given) + 1 − f₃ (every counted lookup reads the distance texture, plus the origin
    check of ``Method.trace``), f₃ = ``volume_lookups(res)`` scaled by measured / bound (its 3D fetches, priced
    at the 3D fetch rate: f₃ · (3D fetch cost) is added), f₄ = 1 (the colour at the shown point; a 3-channel
    texture is stored as 4 on CUDA), or ``colour_lookups(res)`` scaled as f₃ where the method reads more colours
    (a blend of probes reads the colour of every probe it weighs), and :data:`BYTES_PER_RAY` (origin and direction
    read, the bench's outputs written). The pattern's fetch cost is taken for the batch: coherent for the scene's rays,
    random for synthetic ones.
"""

from __future__ import annotations

import numpy as np

from study.bench.timing import median_time

#: Nodes per axis of the 3D texture whose fetch rate is measured (the default distance field of ``sdf``).
VOLUME_RES = 64

#: float32 x, R read (24 B); shown point, radiance, ratio (28 B) and the valid mask (1 B) written.
BYTES_PER_RAY = 24 + 28 + 1


def _hash01(dr, m, i):
    """A float in [0, 1) from a UInt32 ``i`` (a 32-bit integer hash, lowbias32)."""
    x = m.UInt32(i)
    x = x ^ (x >> 16)
    x = x * 0x7FEB352D
    x = x ^ (x >> 15)
    x = x * 0x846CA68B
    x = x ^ (x >> 16)
    return m.Float(x >> 8) * (1.0 / (1 << 24))


def fetch_rate(
    B, res: int, channels: int, pattern: str, *, n_lanes: int = 1 << 22, fetches: int = 64, repeats: int = 5
) -> float:
    """Bilinear fetches per second of a (6·res)×res texture of ``channels`` channels in ``pattern``
    (``"coherent"``, ``"random"`` or ``"scattered"``) on the Dr.Jit backend ``B``."""
    dr, m = B.dr, B.m
    rng = np.random.default_rng(0)
    tex = B.texture(rng.uniform(0.5, 2.0, (6, res, res, channels)).astype(np.float32))
    lane = dr.arange(m.UInt32, n_lanes)
    H = 6 * res

    u0, v0 = _hash01(dr, m, 2 * lane) * 0.5, _hash01(dr, m, 2 * lane + 1)  # random starts (u0 + k/res < 1)

    def kernel(k: int):
        def body(j, acc):
            if pattern == "coherent":
                t = m.UInt32(lane % res + j) % res, (lane // res) % H
                pos = m.Array2f((m.Float(t[0]) + 0.5) / res, (m.Float(t[1]) + 0.5) / H)
            elif pattern == "random":  # a random start per lane, then one texel further per step
                pos = m.Array2f(u0 + m.Float(j) / res, v0)
            else:  # scattered: a new random position for every lane and step
                pos = m.Array2f(
                    _hash01(dr, m, lane * 2 * k + 2 * j), _hash01(dr, m, lane * 2 * k + 2 * j + 1)
                )
            return j + 1, acc + tex.eval(pos)[0]

        _, acc = dr.while_loop((m.UInt32(0), m.Float(0.0)), lambda j, acc: j < k, body)
        return acc

    return _per_second(dr, kernel, n_lanes, fetches, repeats)


def fetch3d_rate(
    B, res: int, pattern: str, *, n_lanes: int = 1 << 22, fetches: int = 64, repeats: int = 5
) -> float:
    """Trilinear fetches per second of a 1-channel res³ ``Texture3f`` (a distance field, as
    :class:`study.impostor.sdf.SdfGrid` stores it) in ``pattern``: ``"coherent"`` (neighbouring lanes read
    neighbouring voxels, each step one voxel further along x) or ``"random"`` (a hashed start per lane, then one
    voxel further along x per step), on the Dr.Jit backend ``B``; the same difference quotient as :func:`fetch_rate`."""
    dr, m = B.dr, B.m
    rng = np.random.default_rng(0)
    grid = rng.uniform(0.5, 2.0, (res, res, res, 1)).astype(np.float32)
    tex = m.Texture3f(
        m.TensorXf(grid),
        filter_mode=dr.FilterMode.Linear,
        wrap_mode=dr.WrapMode.Clamp,
        use_accel=B.name == "cuda",
    )
    lane = dr.arange(m.UInt32, n_lanes)
    u0 = _hash01(dr, m, 3 * lane) * 0.5
    v0, w0 = _hash01(dr, m, 3 * lane + 1), _hash01(dr, m, 3 * lane + 2)

    def kernel(k: int):
        def body(j, acc):
            if pattern == "coherent":
                x = m.UInt32(lane % res + j) % res
                y, z = (lane // res) % res, (lane // (res * res)) % res
                pos = m.Array3f(*((m.Float(c) + 0.5) / res for c in (x, y, z)))
            else:
                pos = m.Array3f(u0 + m.Float(j) / res, v0, w0)
            return j + 1, acc + tex.eval(pos)[0]

        _, acc = dr.while_loop((m.UInt32(0), m.Float(0.0)), lambda j, acc: j < k, body)
        return acc

    return _per_second(dr, kernel, n_lanes, fetches, repeats)


def _per_second(dr, kernel, n_lanes: int, fetches: int, repeats: int) -> float:
    """Fetches per second of ``kernel(k)`` (each of ``n_lanes`` lanes fetching k times): the difference quotient
    between k = ``fetches`` and k = ``fetches``/4, so the launch and the output write cancel."""

    def timed(k):
        return median_time(
            lambda: kernel(k),
            lambda out: dr.sync_thread() if out is None else dr.eval(out),
            repeats=repeats,
            warmup=2,
        )

    lo, hi = max(1, fetches // 4), fetches
    t_lo, t_hi = timed(lo), timed(hi)
    return n_lanes * (hi - lo) / max(t_hi - t_lo, 1e-9)


def copy_bandwidth(B, *, copy_floats: int = 1 << 27, repeats: int = 5) -> float:
    """Bytes per second read + written by ``y = x + 1`` over ``copy_floats`` float32s on backend ``B``."""
    dr, m = B.dr, B.m
    x = dr.arange(m.Float, copy_floats)  # a stored array (zeros would be a literal, never read)
    dr.eval(x)
    t = median_time(
        lambda: x + 1.0,
        lambda out: dr.sync_thread() if out is None else dr.eval(out),
        repeats=repeats,
        warmup=2,
    )
    return 8.0 * copy_floats / t


def measure(
    B, res: int, *, n_lanes: int = 1 << 22, fetches: int = 64, copy_floats: int = 1 << 27, repeats: int = 5
) -> dict:
    """All floors of backend ``B`` at cube resolution ``res``: fetch rates (fetches/s) ``fetch_<c>ch_<pattern>``
    for c in 1, 4 and each pattern, ``fetch_3d_<pattern>`` (trilinear, a :data:`VOLUME_RES`³ grid; coherent and
    random) and ``bandwidth`` (bytes/s)."""
    out = {}
    for c in (1, 4):
        for pattern in ("coherent", "random", "scattered"):
            out[f"fetch_{c}ch_{pattern}"] = fetch_rate(
                B, res, c, pattern, n_lanes=n_lanes, fetches=fetches, repeats=repeats
            )
    for pattern in ("coherent", "random"):
        out[f"fetch_3d_{pattern}"] = fetch3d_rate(
            B, VOLUME_RES, pattern, n_lanes=n_lanes, fetches=fetches, repeats=repeats
        )
    out["bandwidth"] = copy_bandwidth(B, copy_floats=copy_floats, repeats=repeats)
    return out


def method_floor(
    method, floors: dict, pattern: str, rays: int, res: int | None = None, lookups: float | None = None
) -> float:
    """The floor (seconds) of ``method`` on ``rays`` rays at cube resolution ``res``: fetches × fetch cost + bytes /
    bandwidth (see the module docstring); ``pattern`` is ``"coherent"`` or ``"random"``; ``lookups``: the mean
    lookups per ray measured (a search that skips or stops early spends fewer than its bound), else the bound."""
    bound = float(method.lookup_bound(res))
    spent = bound if lookups is None else float(lookups)
    f3 = float(method.volume_lookups(res)) * (spent / bound if bound > 0 else 1.0)  # its 3D share
    f1 = spent + 1 - f3
    f4 = max(1.0, float(method.colour_lookups(res)) * (spent / bound if bound > 0 else 1.0))  # colours read
    rate3 = floors.get(
        f"fetch_3d_{pattern}", floors[f"fetch_1ch_{pattern}"]
    )  # floors measured before: 2D rate
    per_ray = (
        f1 / floors[f"fetch_1ch_{pattern}"]
        + f3 / rate3
        + f4 / floors[f"fetch_4ch_{pattern}"]
        + BYTES_PER_RAY / floors["bandwidth"]
    )
    return per_ray * rays


def floor_rows(floors: dict, res: int, backend: str) -> list[dict]:
    """The floors as table rows (quantity, value, unit)."""
    rows = [
        {
            "backend": backend,
            "cube_res": res,
            "quantity": (
                f"trilinear fetch, 1ch {VOLUME_RES}³, {k.split('_')[2]}"
                if k.startswith("fetch_3d")
                else f"bilinear fetch, {k.split('_')[1]}, {k.split('_')[2]}"
            ),
            "value": v / 1e9,
            "unit": "Gfetch/s",
        }
        for k, v in floors.items()
        if k.startswith("fetch_")
    ]
    rows.append(
        {
            "backend": backend,
            "cube_res": res,
            "quantity": "copy bandwidth (read + write)",
            "value": floors["bandwidth"] / 1e9,
            "unit": "GB/s",
        }
    )
    return rows
