"""Wavefront OBJ and its MTL materials, read as the format defines them (not through trimesh).

* Face indices start at 1; a negative index counts back from the end of the vertex (or texture-coordinate) list
  read so far (−1 is the last one); index 0 or one past the end is refused, naming the line.
* Polygons are split into fans of triangles; ``l`` and ``p`` elements are ignored (counted).
* One part per material (``usemtl``); MTL ``Kd`` is a linear albedo, ``map_Kd`` an sRGB texture (multiplied by
  ``Kd``, as the MTL spec says), ``Ke`` a linear emitted radiance (an area light). ``d`` < 1 / ``Tr`` > 0 (alpha),
  transmission (``illum`` 4, 6, 7, ``Tf`` other than 1) and the other maps are not rendered: counted as ignored.
"""

from __future__ import annotations

from collections import Counter
from pathlib import Path

import numpy as np

from study.errors import StudyError
from study.scene.parts import Loaded, Piece, image_linear

_OTHER_MAPS = ("map_ks", "map_ns", "map_d", "map_bump", "bump", "disp", "decal", "refl", "norm", "map_ke")


def read_mtl(path: Path, ignored: Counter) -> dict[str, dict]:
    """Materials of an MTL file: name → {"Kd", "Ke", "map_Kd" (Path), "ignored" (kinds)}."""
    mats: dict[str, dict] = {}
    cur: dict | None = None
    for line in path.read_text(errors="replace").splitlines():
        tok = line.split()
        if not tok or tok[0].startswith("#"):
            continue
        key = tok[0].lower()
        if key == "newmtl":
            cur = mats.setdefault(" ".join(tok[1:]), {"ignored": set()})
        elif cur is None:
            continue
        elif key in ("kd", "ke") and len(tok) >= 2:
            vals = [float(x) for x in tok[1:4]]
            cur[tok[0].capitalize()] = tuple(vals * 3 if len(vals) == 1 else vals)
        elif key == "map_kd" and len(tok) >= 2:
            cur["map_Kd"] = path.parent / tok[-1]
        elif key == "d" and len(tok) >= 2 and float(tok[-1]) < 1:
            cur["ignored"].add("alpha")
        elif key == "tr" and len(tok) >= 2 and float(tok[-1]) > 0:
            cur["ignored"].add("alpha")
        elif key == "illum" and len(tok) >= 2 and tok[1] in ("4", "6", "7"):
            cur["ignored"].add("transmission")
        elif key == "tf" and len(tok) >= 2 and any(float(x) != 1 for x in tok[1:4] if x[0] in "0123456789.-"):
            cur["ignored"].add("transmission")
        elif key in _OTHER_MAPS:
            cur["ignored"].add(tok[0])
    return mats


def _index(tok: str, n: int, line_no: int, what: str, src: str) -> int:
    i = int(tok)
    if i == 0:
        raise StudyError(f"line {line_no}: {what} index 0 (OBJ indices start at 1; −1 is the last)", key=src)
    j = i - 1 if i > 0 else n + i
    if not 0 <= j < n:
        raise StudyError(
            f"line {line_no}: {what} index {i} refers past the end of the list ({n} defined so far)", key=src
        )
    return j


def read_obj(path: Path, src: str, default_color: tuple) -> Loaded:
    """The OBJ at ``path`` as parts (one per material), with their MTL colours, textures and emission."""
    V: list[list[float]] = []
    VT: list[list[float]] = []
    faces: dict[str, list] = {}  # material → [(v0, t0), (v1, t1), (v2, t2)] per triangle
    mtllibs: list[Path] = []
    ignored: Counter = Counter()
    mat = ""
    text = path.read_text(errors="replace").replace("\\\n", " ")
    for no, line in enumerate(text.splitlines(), 1):
        if not line or line[0] == "#":
            continue
        tok = line.split()
        if not tok:
            continue
        k = tok[0]
        if k == "v":
            if len(tok) < 4:
                raise StudyError(f"line {no}: a vertex needs x y z", key=src)
            V.append([float(x) for x in tok[1:4]])
            if len(tok) >= 7:
                ignored["vertex colour"] += 1
        elif k == "vt":
            VT.append([float(tok[1]), float(tok[2]) if len(tok) > 2 else 0.0])
        elif k == "f":
            corners = []
            for c in tok[1:]:
                parts = c.split("/")
                vi = _index(parts[0], len(V), no, "vertex", src)
                ti = (
                    _index(parts[1], len(VT), no, "texture coordinate", src)
                    if len(parts) > 1 and parts[1]
                    else -1
                )
                corners.append((vi, ti))
            if len(corners) < 3:
                raise StudyError(f"line {no}: a face needs at least 3 vertices", key=src)
            lst = faces.setdefault(mat, [])
            for a in range(1, len(corners) - 1):
                lst.append((corners[0], corners[a], corners[a + 1]))
        elif k == "usemtl":
            mat = " ".join(tok[1:])
        elif k == "mtllib":
            mtllibs += [path.parent / n for n in tok[1:]]
        elif k in ("l", "p"):
            ignored["line" if k == "l" else "point"] += 1
    mats: dict[str, dict] = {}
    for lib in mtllibs:
        if not lib.is_file():
            ignored[f"missing material library {lib.name}"] += 1
            continue
        mats.update(read_mtl(lib, ignored))
    Va = np.asarray(V, float).reshape(-1, 3)
    VTa = np.asarray(VT, float).reshape(-1, 2)
    out = Loaded([], ignored=ignored)
    textures = set()
    for name, tris in faces.items():
        c = np.asarray(tris, np.int64).reshape(-1, 3, 2)
        m = mats.get(name)
        if name and m is None:
            ignored["undefined material"] += 1
        m = m or {"ignored": set()}
        for kind in m["ignored"]:
            ignored[kind] += 1
        tex = m.get("map_Kd")
        albedo = None
        if tex is not None and (c[..., 1] >= 0).all():
            try:
                from PIL import Image

                albedo = image_linear(Image.open(tex)) * np.asarray(m.get("Kd", (1, 1, 1)), np.float32)
                textures.add(tex)
            except OSError:
                ignored[f"unreadable texture {tex.name}"] += 1
        elif tex is not None:
            ignored["texture without uv"] += 1
        if albedo is not None:  # unshare (vertex, uv) pairs: uv per vertex, v running down (Mitsuba's)
            pairs, inv = np.unique(c.reshape(-1, 2), axis=0, return_inverse=True)
            uv = VTa[pairs[:, 1]]
            piece = Piece(
                name or "default", Va[pairs[:, 0]], inv.reshape(-1, 3), uv=np.c_[uv[:, 0], 1 - uv[:, 1]]
            )
            piece.albedo = albedo.astype(np.float32)
        else:
            used, inv = np.unique(c[..., 0], return_inverse=True)
            piece = Piece(
                name or "default", Va[used], inv.reshape(-1, 3), color=tuple(m.get("Kd", default_color))
            )
        ke = m.get("Ke")
        if ke is not None and max(ke) > 0:
            piece.emission = tuple(float(x) for x in ke)
        out.pieces.append(piece)
    out.materials = len([n for n in faces if n in mats])
    out.textures = len(textures)
    return out
