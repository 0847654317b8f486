"""Wavefront OBJ and its MTL materials, read as the format defines them (not through trimesh).

* Whitespace: any run of spaces and tabs separates tokens, lines may be indented, end in CR LF, and continue on
  the next line after a ``\\``; ``o``, ``g``, ``s``, ``vn``, ``vp`` and unknown statements are skipped.
* ``v`` takes 3 numbers, or 4 (``w``, ignored: study's vertices are points) or 6 (x y z r g b: vertex colours,
  counted as ignored: the MTL's colours are used).
* Face indices start at 1; a negative index counts back from the end of the vertex (or texture-coordinate) list
  read so far (−1 is the last one); index 0 or one past the end is refused, naming the line. Corners may be
  ``v``, ``v/t``, ``v//n`` or ``v/t/n``, mixed freely.
* Polygons of any size are split into fans of triangles; ``l`` and ``p`` elements are ignored (counted).
* ``mtllib`` names one or more libraries (a name with spaces is taken whole where that file exists); every file the
  OBJ or its MTL names must lie in the OBJ's (or the MTL's) folder (:func:`study.scene.paths.named_file`).
* One part per material (``usemtl``); MTL ``Kd`` is a linear albedo in [0, 1], ``map_Kd`` an sRGB texture
  (multiplied by ``Kd``, as the MTL spec says; its options ``-o``, ``-s``, ``-clamp`` … are skipped, counted),
  ``Ke`` (≥ 0) a linear emitted radiance (an area light). ``d`` < 1 / ``Tr`` > 0 (alpha), transmission (``illum``
  4, 6, 7, ``Tf`` other than 1), specular ``Ks`` > 0 and the other maps are not rendered (two-sided diffuse):
  counted as ignored, once per material.
"""

from __future__ import annotations

import operator
import re
from collections import Counter
from pathlib import Path

import numpy as np

from study.errors import StudyError
from study.scene.parts import Loaded, Piece, read_image
from study.scene.paths import named_file

_OTHER_MAPS = ("map_ks", "map_ns", "map_d", "map_bump", "bump", "disp", "decal", "refl", "norm", "map_ke")


#: map statement options and how many arguments each takes at most (the MTL spec; numbers are counted as read)
_MAP_OPTIONS = {"-blendu": 1, "-blendv": 1, "-boost": 1, "-cc": 1, "-clamp": 1, "-imfchan": 1, "-mm": 2,
                "-o": 3, "-s": 3, "-t": 3, "-texres": 1, "-bm": 1, "-type": 1}  # fmt: skip


def _num(x: str) -> float:
    """A number of an MTL statement; a word (``spectral``, ``xyz``) counts as 1 (neutral)."""
    try:
        return float(x)
    except ValueError:
        return 1.0


def _map_file(tok: list[str]) -> tuple[str, bool]:
    """(file name, whether options were given) of a map statement's arguments: options first, each with its
    arguments (numbers, or one word), then the name, which may hold spaces."""
    i, opts = 0, False
    while i < len(tok) and tok[i].lower() in _MAP_OPTIONS:
        n, i, opts = _MAP_OPTIONS[tok[i].lower()], i + 1, True
        for _ in range(n):
            if i < len(tok) - 1 and (
                tok[i].lower() in ("on", "off", "r", "g", "b", "m", "l", "z") or _isnum(tok[i])
            ):
                i += 1
    return " ".join(tok[i:]), opts


def _isnum(x: str) -> bool:
    try:
        float(x)
        return True
    except ValueError:
        return False


def _colour(tok: list[str], what: str, hi: float | None) -> tuple | None:
    """An MTL colour statement's r g b (one number: grey); ``spectral`` / ``xyz`` forms: None (not read)."""
    if tok[1].lower() in ("spectral", "xyz"):
        return None
    try:
        vals = [float(x) for x in tok[1:4]]
    except ValueError:
        raise StudyError(f"{what}: {' '.join(tok[1:4])!r} is not a colour") from None
    vals = vals * 3 if len(vals) == 1 else vals
    if len(vals) != 3 or not all(np.isfinite(vals)) or min(vals) < 0 or (hi is not None and max(vals) > hi):
        rng = f"[0, {hi:g}]" if hi is not None else "≥ 0"
        raise StudyError(f"{what}: {' '.join(tok[1:4])!r} must be 1 or 3 numbers in {rng}")
    return tuple(vals)


def read_mtl(path: Path, ignored: Counter, src: str = "", root: Path | None = None) -> dict[str, dict]:
    """Materials of an MTL file: name → {"Kd", "Ke", "map_Kd" (Path), "ignored" (kinds)}; the maps it names must
    lie in ``root`` (the OBJ's folder; default: the MTL's)."""
    mats: dict[str, dict] = {}
    cur: dict | None = None
    text = path.read_text(errors="replace").replace("\\\r\n", " ").replace("\\\n", " ")
    for no, line in enumerate(text.splitlines(), 1):
        tok = line.split()
        if not tok or tok[0].startswith("#"):
            continue
        key = tok[0].lower()
        what = f"{path.name} line {no}: {tok[0]}"
        if key == "newmtl":
            cur = mats.setdefault(" ".join(tok[1:]), {"ignored": set()})
        elif cur is None:
            continue
        elif key in ("kd", "ke") and len(tok) >= 2:
            try:
                c = _colour(tok, what, 1.0 if key == "kd" else None)
            except StudyError as err:
                raise StudyError(err.detail, key=src) from None
            if c is None:
                cur["ignored"].add(f"{tok[1].lower()} {tok[0]}")
            else:
                cur[tok[0].capitalize()] = c
        elif key == "map_kd" and len(tok) >= 2:
            name, opts = _map_file(tok[1:])
            cur["map_Kd"] = named_file(path.parent, name, what=what, src=src, root=root)
            if opts:
                cur["ignored"].add("texture option")  # -s, -o, -clamp, …: the texture is used plain
        elif key == "ks" and len(tok) >= 2 and any(_num(x) > 0 for x in tok[1:4]):
            cur["ignored"].add("specular (Ks)")
        elif key == "d" and len(tok) >= 2 and _num(tok[-1]) < 1:
            cur["ignored"].add("alpha")
        elif key == "tr" and len(tok) >= 2 and _num(tok[-1]) > 0:
            cur["ignored"].add("alpha")
        elif key == "illum" and len(tok) >= 2 and tok[1] in ("4", "6", "7"):
            cur["ignored"].add("transmission")
        elif key == "tf" and len(tok) >= 2 and any(_num(x) != 1 for x in tok[1:4]):
            cur["ignored"].add("transmission")
        elif key in _OTHER_MAPS:
            cur["ignored"].add(tok[0])
    return mats


def _resolve(raw: np.ndarray, n_before: np.ndarray, lines: np.ndarray, what: str, src: str) -> np.ndarray:
    """0-based indices of OBJ indices ``raw`` (1-based; negative: counted back from ``n_before``, the length of
    the list when the face was read); index 0 or past the end: a StudyError naming the line."""
    j = np.where(raw > 0, raw - 1, n_before + raw)
    bad = (raw == 0) | (j < 0) | (j >= n_before)
    if bad.any():
        k = int(np.flatnonzero(bad)[0])
        i, n = int(raw[k]), int(n_before[k])
        why = (
            "index 0 (OBJ indices start at 1; -1 is the last)"
            if i == 0
            else (f"index {i} refers past the end of the list ({n} defined so far)")
        )
        raise StudyError(f"line {int(lines[k])}: {what} {why}", key=src)
    return j


def _corners(body: bytes, ntok: int, line_of: np.ndarray, src: str) -> tuple[np.ndarray, np.ndarray]:
    """(vertex, texture coordinate) OBJ indices of the face corners in ``body`` (the faces' bodies, one per line,
    single-spaced): ``v``, ``v/t``, ``v//n`` or ``v/t/n`` (t = 0 where none is given). One layout throughout is
    parsed at once; anything else, corner by corner (naming the line of a bad one)."""
    a = np.frombuffer(body, np.uint8)
    first = np.r_[0, np.flatnonzero((a == 32) | (a == 10)) + 1]  # where each token starts
    slashes = np.add.reduceat(a == 47, first, dtype=np.int64) if len(a) and len(first) == ntok else None
    k = int(slashes[0]) if slashes is not None and ntok else 0
    longest = int(np.diff(np.r_[first, len(a) + 1]).max()) - 1 if ntok else 0
    if slashes is not None and ntok and (slashes == k).all() and k <= 2 and longest <= 18 + 2 * k:
        try:
            ints = np.fromstring(body.replace(b"//", b"/0/").replace(b"/", b" "), np.int64, sep=" ")
        except ValueError:
            ints = None
        if ints is not None and len(ints) == ntok * (k + 1):
            ints = ints.reshape(ntok, k + 1)
            return ints[:, 0], ints[:, 1] if k >= 1 else np.zeros(ntok, np.int64)
    tokens = body.decode("utf-8", "replace").split()
    v, t = np.zeros(len(tokens), np.int64), np.zeros(len(tokens), np.int64)
    for i, tok in enumerate(tokens):
        parts = tok.split("/")
        try:
            v[i] = int(parts[0])
            t[i] = int(parts[1]) if len(parts) > 1 and parts[1] else 0
        except ValueError:
            raise StudyError(f"line {int(line_of[i])}: not a face corner: {tok!r}", key=src) from None
        except OverflowError:
            raise StudyError(f"line {int(line_of[i])}: index {tok!r} is too large", key=src) from None
    return v, t


def _normalised(raw: bytes) -> bytes:
    """The file with one kind of line end and one kind of blank, continuations joined and indentation removed."""
    if b"\r" in raw:
        raw = raw.replace(b"\r\n", b"\n").replace(b"\r", b"\n")
    raw = raw.replace(b"\\\n", b" ")  # a line continued on the next
    if b"\t" in raw or b"\v" in raw or b"\f" in raw:  # any run of blanks separates: one kind of blank
        raw = raw.replace(b"\t", b" ").replace(b"\v", b" ").replace(b"\f", b" ")
    if b"\n " in raw or raw.startswith(b" "):
        raw = re.sub(rb"(?m)^ +", b"", raw)
    return raw


def _bodies(lines: list[bytes], idx: np.ndarray, head: bytes) -> tuple[bytes, np.ndarray]:
    """The statements ``head`` (``b"v"``, ``b"f"`` …) at line indices ``idx``: their bodies, single-spaced, one per
    line, and the number of tokens of each (in file order)."""
    if not len(idx):
        return b"", np.zeros(0, np.int64)
    picked = operator.itemgetter(*idx)(lines)
    body = b"\n".join(picked) if len(idx) > 1 else picked
    body = body.replace(b"\n" + head + b" ", b"\n")[len(head) + 1 :]
    if b"  " in body:
        body = re.sub(rb" +", b" ", body)
    if body.startswith(b" ") or body.endswith(b" ") or b"\n " in body or b" \n" in body:
        body = re.sub(rb"(?m)^ | $", b"", body)
    a = np.frombuffer(body, np.uint8)
    nl = np.flatnonzero(a == 10)
    lo, hi = np.r_[0, nl + 1], np.r_[nl, len(a)]
    spaces = (
        np.add.reduceat(a == 32, np.minimum(lo, len(a) - 1), dtype=np.int64) if len(a) else np.zeros(len(lo))
    )
    return body, np.where(hi > lo, spaces + 1, 0).astype(np.int64)


def _numbers(body: bytes, n: np.ndarray, cols: int, lines_no: np.ndarray, what: str, src: str) -> np.ndarray:
    """The first ``cols`` numbers of each line of ``body`` (float64; pandas' C parser), missing ones 0."""
    import io

    import pandas as pd

    if not len(n):
        return np.zeros((0, cols))
    try:
        df = pd.read_csv(io.BytesIO(body), sep=" ", header=None, names=range(max(int(n.max()), cols)),
                         dtype=np.float64, engine="c", skip_blank_lines=False)  # fmt: skip
    except ValueError:
        for i, ln in enumerate(body.split(b"\n")):  # name the line
            for x in ln.split()[:cols]:
                try:
                    float(x)
                except ValueError:
                    raise StudyError(f"line {int(lines_no[i])}: {what} {x.decode(errors='replace')!r} is not a "
                                     "number", key=src) from None  # fmt: skip
        raise StudyError(f"a {what} is not a number", key=src) from None
    out = df.to_numpy()[:, :cols]
    out[np.arange(cols)[None, :] >= n[:, None]] = 0.0
    return out


def _lines(raw: bytes) -> dict[str, np.ndarray]:
    """Each line's start and end offset in ``raw`` and what it holds (``v``, ``vt``, ``f``, or ``other``), from its
    first bytes, for the whole file at once."""
    a = np.frombuffer(raw, np.uint8)
    nl = np.flatnonzero(a == 10)
    start, end = np.r_[0, nl + 1], np.r_[nl, len(a)]
    p = np.r_[a, np.zeros(3, np.uint8)]
    c0, c1, c2 = p[start], p[start + 1], p[start + 2]
    v, f = (c0 == ord("v")) & (c1 == 32), (c0 == ord("f")) & (c1 == 32)
    vt = (c0 == ord("v")) & (c1 == ord("t")) & (c2 == 32)
    quiet = (c0 == ord("#")) | (start == end) | ((c0 == ord("v")) & (c1 == ord("n")))  # normals: not used
    return {"start": start, "end": end, "v": v, "vt": vt, "f": f, "other": ~(v | vt | f | quiet)}


def read_obj(path: Path, src: str, default_color: tuple) -> Loaded:
    """The OBJ at ``path`` as parts (one per material), with their MTL colours, textures and emission."""
    mtllibs: list[Path] = []
    ignored: Counter = Counter()
    raw = _normalised(path.read_bytes())
    L = _lines(raw)
    lines = raw.split(b"\n")
    materials: list[str] = [""]
    mat_at = [(0, 0)]  # (line index, material) from that line on
    for i in np.flatnonzero(L["other"]):
        line = raw[L["start"][i] : L["end"][i]].decode("utf-8", "replace")
        tok = line.split()
        if not tok or tok[0].startswith("#"):
            continue
        k = tok[0]
        if k in ("v", "vt", "f"):  # a statement without its numbers
            raise StudyError(
                f"line {i + 1}: {k} without its {'x y z' if k == 'v' else 'u v' if k == 'vt' else 'vertices'}",
                key=src,
            )
        if k == "usemtl":
            name = " ".join(tok[1:])
            if name not in materials:
                materials.append(name)
            mat_at.append((i, materials.index(name)))
        elif k == "mtllib":
            rest = line.split(None, 1)[1].strip() if len(tok) > 1 else ""
            whole = named_file(path.parent, rest, what=f"line {i + 1}: mtllib", src=src) if rest else None
            names = [rest] if whole is not None and whole.is_file() else tok[1:]
            mtllibs += [named_file(path.parent, n, what=f"line {i + 1}: mtllib", src=src) for n in names]
        elif k in ("l", "p"):
            ignored["line" if k == "l" else "point"] += 1
    # ------------------------------------------------------------------ vertices and texture coordinates
    vbody, vn = _bodies(lines, np.flatnonzero(L["v"]), b"v")
    vlines_no = np.flatnonzero(L["v"]) + 1
    if len(vn) and vn.min() < 3:
        raise StudyError(f"line {int(vlines_no[np.argmin(vn)])}: a vertex needs x y z", key=src)
    if (vn >= 6).any():
        ignored["vertex colour"] += int((vn >= 6).sum())
    Va = _numbers(vbody, vn, 3, vlines_no, "vertex coordinate", src)
    tbody, tn = _bodies(lines, np.flatnonzero(L["vt"]), b"vt")
    VTa = _numbers(tbody, tn, 2, np.flatnonzero(L["vt"]) + 1, "texture coordinate", src)
    # ------------------------------------------------------------------ faces
    fidx = np.flatnonzero(L["f"])
    fbody, counts_a = _bodies(lines, fidx, b"f")
    if len(counts_a) and counts_a.min() < 3:
        raise StudyError(
            f"line {int(fidx[np.argmin(counts_a)]) + 1}: a face needs at least 3 vertices", key=src
        )
    nv = np.cumsum(L["v"])[fidx]  # vertices defined before each face
    nvt = np.cumsum(L["vt"])[fidx]
    starts = np.array([m[0] for m in mat_at])
    fmat = np.array([m[1] for m in mat_at])[np.searchsorted(starts, fidx, side="right") - 1]
    counts_a = counts_a.astype(np.int64)
    per_corner = lambda a: np.repeat(np.asarray(a, np.int64), counts_a)  # noqa: E731
    line_of = per_corner(fidx + 1)
    rv, rt = _corners(fbody, int(counts_a.sum()), line_of, src)
    vi = _resolve(rv, per_corner(nv), line_of, "vertex", src)
    has_t = rt != 0
    ti = np.full(len(rt), -1, np.int64)
    if has_t.any():
        ti[has_t] = _resolve(rt[has_t], per_corner(nvt)[has_t], line_of[has_t], "texture coordinate", src)
    start = np.concatenate([[0], np.cumsum(counts_a)[:-1]]).astype(np.int64)
    faces: dict[str, list] = {}
    tri_mat = []
    tris = []
    for c in np.unique(counts_a):  # fans: (0, a, a + 1) of every polygon of c corners
        sel = np.flatnonzero(counts_a == c)
        for a in range(1, int(c) - 1):
            idx = np.stack([start[sel], start[sel] + a, start[sel] + a + 1], 1)
            tris.append(idx)
            tri_mat.append(np.asarray(fmat, np.int64)[sel])
    if tris:
        T, M = np.concatenate(tris), np.concatenate(tri_mat)
        order = np.argsort(M, kind="stable")
        T, M = T[order], M[order]
        for m in np.unique(M):
            t = T[M == m]
            faces[materials[m]] = np.stack([vi[t], ti[t]], -1)  # (n, 3, 2)
    mats: dict[str, dict] = {}
    for lib in mtllibs:
        if not lib.is_file():
            ignored[f"missing material library {lib.name}"] += 1
            continue
        mats.update(read_mtl(lib, ignored, src, root=path.parent))
    out = Loaded([], ignored=ignored)
    textures = set()
    for name, c in faces.items():
        m = mats.get(name)
        if name and m is None:
            ignored["undefined material"] += 1
        m = m or {"ignored": set()}
        for kind in m["ignored"]:
            ignored[kind] += 1
        tex = m.get("map_Kd")
        albedo = None
        if tex is not None and (c[..., 1] >= 0).all():
            if tex.is_file():
                albedo = read_image(tex, what=f"map_Kd {tex.name}", src=src)
                albedo = albedo * np.asarray(m.get("Kd", (1, 1, 1)), np.float32)
                textures.add(tex)
            else:
                ignored[f"missing texture {tex.name}"] += 1
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
