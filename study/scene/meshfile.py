"""A mesh file as the environment: read by the reader of its format (:mod:`study.scene.obj`,
:mod:`study.scene.gltf`; trimesh for PLY, STL, OFF), checked (:func:`study.scene.parts.clean`), moved by the
environment's ``scale``, ``rotation`` and ``translate``, and told in one summary line."""

from __future__ import annotations

from collections import Counter
from pathlib import Path

import numpy as np

from study.errors import StudyError
from study.scene.parts import (
    Loaded,
    Part,
    Piece,
    clean,
    load_summary_line,
    srgb_to_linear,
    transform_lights,
    transform_sensor,
)
from study.scene.room import RoomMesh


def _trimesh(path: Path, src: str, default_color: tuple) -> Loaded:
    """PLY / STL / OFF through trimesh (unprocessed, so that nothing is dropped unseen); vertex and face
    colours are 8-bit sRGB (converted to linear)."""
    import trimesh

    try:
        sc = trimesh.load(str(path), force="scene", process=False)
        meshes = [g for g in sc.dump(concatenate=False) if isinstance(g, trimesh.Trimesh)]
    except Exception as err:  # noqa: BLE001 - any reader failure is bad input
        raise StudyError(f"cannot read the mesh file ({type(err).__name__}: {err})", key=src) from None
    out = Loaded([], ignored=Counter())
    for g in meshes:
        V, F = np.asarray(g.vertices, float), np.asarray(g.faces, np.int64).reshape(-1, 3)
        vis = g.visual
        kind = getattr(vis, "kind", None)
        p = Piece("", V, F)
        if kind == "face":  # one colour per face: unshare the vertices
            p.V, p.F = V[F].reshape(-1, 3), np.arange(3 * len(F)).reshape(-1, 3)
            p.colors = srgb_to_linear(np.repeat(np.asarray(vis.face_colors)[:, :3], 3, axis=0) / 255)
        elif kind == "vertex":
            p.colors = srgb_to_linear(np.asarray(vis.vertex_colors)[:, :3] / 255)
        else:
            p.color = tuple(default_color)
        out.pieces.append(p)
    return out


def _read(path: Path, src: str, color: tuple) -> Loaded:
    from study.scene.gltf import read_gltf
    from study.scene.obj import read_obj

    suffix = path.suffix.lower()
    try:
        if suffix == ".obj":
            loaded = read_obj(path, src, color)
        elif suffix in (".gltf", ".glb"):
            loaded = read_gltf(path, src, color)
        else:
            loaded = _trimesh(path, src, color)
    except (
        ValueError,
        KeyError,
        IndexError,
        TypeError,
        AttributeError,
    ) as err:  # structure the reader did not name
        detail = " ".join(str(err).split())[:200]
        raise StudyError(f"cannot read {path.name} ({type(err).__name__}: {detail})", key=src) from None
    return clean(loaded, src)


def triangles(path: str | Path, key: str) -> tuple[np.ndarray, np.ndarray]:
    """(V, F) of every part of a mesh file joined, read as :func:`load` reads it (an object's mesh file); a
    problem is a StudyError naming the file and ``key``."""
    try:
        loaded = _read(Path(path), key, (0.6, 0.6, 0.6))
    except StudyError as err:
        raise StudyError(err.detail, file=str(path), key=key) from None
    V, F, n = [], [], 0
    for p in loaded.pieces:
        V.append(p.V)
        F.append(p.F + n)
        n += len(p.V)
    return np.concatenate(V), np.concatenate(F)


def load(env) -> tuple[RoomMesh, tuple[Part, ...], list[dict], str, dict | None]:
    """(mesh, parts, lights, summary line, camera or None) of a ``type = "mesh"`` environment."""
    from trimesh.transformations import euler_matrix

    src = "environment.file"
    path = Path(env.file)
    color = tuple(env.color)
    loaded = _read(path, src, color)
    M = euler_matrix(*np.radians(env.rotation), "sxyz")[:3, :3] * env.scale
    t = np.asarray(env.translate, float)
    V, F, UV, S, C, parts = [], [], [], [], [], []
    n = 0
    for i, p in enumerate(loaded.pieces):
        name = f"part{i}:{p.name}" if p.name else f"part{i}"
        part = Part(
            name,
            albedo=p.albedo if p.uv is not None else None,
            color=None if p.colors is not None or (p.uv is not None and p.albedo is not None) else p.color,
            vertex_colors=p.colors is not None,
            emission=p.emission,
        )
        col = (
            p.colors
            if p.colors is not None
            else np.broadcast_to(np.asarray(p.color or color, float), (len(p.V), 3))
        )
        V.append(p.V @ M.T + t)
        F.append(p.F + n)
        UV.append(p.uv if p.uv is not None else np.zeros((len(p.V), 2)))
        S.append(np.full(len(p.F), i))
        C.append(col)
        parts.append(part)
        n += len(p.V)
    mesh = RoomMesh(
        np.concatenate(V).astype(np.float32),
        np.concatenate(F).astype(np.int32),
        np.concatenate(UV).astype(np.float32),
        np.concatenate(S).astype(np.int32),
        tuple(p.name for p in parts),
        np.concatenate(C).astype(np.float32),
    )
    return (
        mesh,
        tuple(parts),
        transform_lights(loaded.lights, M, t),
        load_summary_line(path.name, loaded),
        (transform_sensor(loaded.sensor, M, t)),
    )
