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
from urllib.parse import unquote

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
    except (ValueError, struct.error, UnicodeDecodeError):
        return []  # not readable: the loader says so; the key still hashes the bytes
    uris = [b.get("uri") for b in g.get("buffers", [])] + [i.get("uri") for i in g.get("images", [])]
    return [path.parent / unquote(u) for u in uris if isinstance(u, str) and not u.startswith("data:")]


def _mtl_file(line: str) -> str:
    """The file name of an MTL map statement: the last token (options such as ``-s 1 1 1`` come first)."""
    return line.split()[-1]


def _obj(path: Path) -> list[Path]:
    import re

    out = []
    for line in re.findall(r"^mtllib[ \t]+(.*)$", path.read_text(errors="replace"), re.M):
        for name in line.split():
            mtl = path.parent / name
            out.append(mtl)
            if mtl.is_file():
                for ml in mtl.read_text(errors="replace").splitlines():
                    ml = ml.strip()
                    if ml.lower().startswith(MTL_MAPS) and len(ml.split()) > 1:
                        out.append(mtl.parent / _mtl_file(ml))
    return out


def _xml(path: Path, seen: set, top: Path, defaults: dict) -> list[Path]:
    """Files a Mitsuba XML names: relative to the naming file and, where that differs, to the top scene file's
    folder (Mitsuba's file resolver), both hashed where both exist; ``$name`` takes its ``<default>`` value."""
    import xml.etree.ElementTree as ET

    try:
        root = ET.parse(path).getroot()
    except (ET.ParseError, OSError):
        return []
    defaults = {**defaults, **{d.get("name"): d.get("value") for d in root.iter("default") if d.get("name")}}
    out = []
    for el in root.iter():
        names = [el.get("filename")]
        if el.get("name") == "filename":
            names.append(el.get("value"))
        for n in names:
            if n and n.startswith("$"):
                n = defaults.get(n[1:])
            if not n:
                continue
            cands = list(dict.fromkeys([(path.parent / n).resolve(), (top / n).resolve()]))
            found = [c for c in cands if c.is_file()] or cands[:1]
            for p in found:
                out.append(p)
                if p.suffix.lower() == ".xml" and p.is_file() and p not in seen:
                    seen.add(p)
                    out += _xml(p, seen, top, defaults)
                elif p.suffix.lower() in (".obj", ".gltf", ".glb") and p.is_file():
                    out += referenced(p)
    return out


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
