"""The files a scene file references, resolved as the loaders resolve them, for content keys
(:func:`study.scene.sources.file_digest`): change a texture, a buffer, an included XML or an envmap, and the key of
every result made from the scene changes.

=============  ===============================================================================================
file           references (each relative to the file that names it)
=============  ===============================================================================================
``.gltf``      ``buffers[].uri`` and ``images[].uri`` (not ``data:`` URIs: those are the file's own bytes)
``.glb``       the same, read from the JSON chunk
``.obj``       ``mtllib`` libraries, and in them every ``map_*``, ``bump``, ``disp``, ``decal``, ``refl`` texture
``.xml``       every ``filename`` (an attribute, as ``<include filename>``, or ``<string name="filename">``) of
               Mitsuba 3: meshes, textures, envmaps, included XML (whose references are followed in turn);
               ``$name`` through its ``<default>``; also relative to the top scene file, as Mitsuba resolves
=============  ===============================================================================================
"""

from __future__ import annotations

import json
import struct
from pathlib import Path

from study.scene.paths import inside

MTL_MAPS = ("map_", "bump", "disp", "decal", "refl", "norm")


def gltf_json(path: Path) -> dict:
    """The JSON of a ``.gltf`` or the JSON chunk of a ``.glb`` (ValueError if it is neither)."""
    data = path.read_bytes()
    if data[:4] == b"glTF":
        n, kind = struct.unpack_from("<II", data, 12)
        if kind != 0x4E4F534A:
            raise ValueError("the GLB's first chunk is not JSON")
        return json.loads(data[20 : 20 + n])
    return json.loads(data)


def _gltf(path: Path) -> list[Path]:
    try:
        g = gltf_json(path)
    except (ValueError, struct.error, UnicodeDecodeError, RecursionError):
        return []  # not readable: the loader says so; the key still hashes the bytes
    if not isinstance(g, dict):
        return []
    items = [
        x for k in ("buffers", "images") if isinstance(g.get(k), list) for x in g[k] if isinstance(x, dict)
    ]
    uris = [x.get("uri") for x in items]
    found = [
        inside(path.parent, u, uri=True) for u in uris if isinstance(u, str) and not u.startswith("data:")
    ]
    return [p for p in found if p is not None]


def _obj(path: Path) -> list[Path]:
    import re

    from study.scene.obj import _map_file

    out = []
    for line in re.findall(r"^[ \t]*mtllib[ \t]+(.*?)[ \t]*\r?$", path.read_text(errors="replace"), re.M):
        whole = inside(path.parent, line)
        names = [line] if whole is not None and whole.is_file() else line.split()
        for mtl in (inside(path.parent, n) for n in names):
            if mtl is None:
                continue  # outside the folder: the loader refuses it, nothing is read for the key either
            out.append(mtl)
            if mtl.is_file():
                for ml in mtl.read_text(errors="replace").splitlines():
                    tok = ml.split()
                    if tok and tok[0].lower().startswith(MTL_MAPS) and len(tok) > 1:
                        tex = inside(mtl.parent, _map_file(tok[1:])[0], root=path.parent)
                        if tex is not None:
                            out.append(tex)
    return out


def _xml_names(path: Path, defaults: dict):
    """(element, file name) of every ``filename`` a Mitsuba XML names (an attribute, as ``<include filename>``,
    or ``<string name="filename">``), ``$name`` through its ``<default>``; and the defaults in force."""
    import xml.etree.ElementTree as ET

    try:
        root = ET.parse(path).getroot()
    except (ET.ParseError, OSError, RecursionError):
        return [], defaults
    defaults = {**defaults, **{d.get("name"): d.get("value") for d in root.iter("default") if d.get("name")}}
    out = []
    for el in root.iter():
        names = [el.get("filename")]
        if el.get("name") == "filename":
            names.append(el.get("value"))
        for n in names:
            if n and n.startswith("$"):
                n = defaults.get(n[1:])
            if n:
                out.append((el, n))
    return out, defaults


def _xml(path: Path, seen: set, top: Path, defaults: dict) -> list[Path]:
    """Files a Mitsuba XML names: relative to the naming file and, where that differs, to the top scene file's
    folder (Mitsuba's file resolver), both hashed where both exist; names outside the top folder are skipped (the
    loader refuses them: :func:`xml_outside`)."""
    names, defaults = _xml_names(path, defaults)
    out = []
    for _, n in names:
        cands = [c for c in dict.fromkeys([inside(path.parent, n, root=top), inside(top, n, root=top)]) if c]
        found = [c for c in cands if c.is_file()] or cands[:1]
        for p in found:
            out.append(p)
            if p.suffix.lower() == ".xml" and p.is_file() and p.resolve() not in seen:
                seen.add(p.resolve())
                out += _xml(p, seen, top, defaults)
            elif p.suffix.lower() in (".obj", ".gltf", ".glb") and p.is_file():
                out += referenced(p)
    return out


def xml_outside(path: str | Path) -> str | None:
    """The first file name a Mitsuba XML (or an XML it includes) names that lies outside the scene file's folder,
    or is missing from it (Mitsuba would then search the folders of ``<path>`` elements, which may lie outside), as
    one line naming the file and the element; None if every name stays inside. Nothing outside is read."""
    top = Path(path).resolve().parent
    todo, seen, defaults = [Path(path).resolve()], set(), {}
    while todo:
        f = todo.pop()
        seen.add(f)
        names, defaults = _xml_names(f, defaults)
        for el, n in names:
            cands = [c for c in (inside(f.parent, n, root=top), inside(top, n, root=top)) if c is not None]
            if not cands:
                return (f"{f.name}: <{el.tag}> names {n!r}, which lies outside the scene's folder ({top}); "
                        "files a scene names must lie in it")  # fmt: skip
            c = next((c for c in cands if c.exists()), None)
            if c is None:  # Mitsuba would search its <path> folders, which may lie outside: refused here
                return f"{f.name}: <{el.tag}> names {n!r}, which is not in the scene's folder ({top})"
            if c.suffix.lower() == ".xml" and c.is_file() and c.resolve() not in seen:
                todo.append(c.resolve())
    return None


def referenced(path: str | Path) -> list[Path]:
    """Every file ``path`` references (recursively, in the order named; missing ones included: creating one
    changes the key too)."""
    p = Path(path)
    suffix = p.suffix.lower()
    if suffix in (".gltf", ".glb"):
        return _gltf(p)
    if suffix == ".obj":
        return _obj(p)
    if suffix == ".xml":
        return _xml(p, {p.resolve()}, p.resolve().parent, {})
    return []
