"""glTF 2.0's document and bytes, checked before use (:mod:`study.scene.gltf` reads the scene from them).

* The JSON's top-level members are checked for their types (arrays of objects, ``asset`` an object, ``scene`` an
  index) and every index for its range (:meth:`GltfFile.get`); a GLB's header and chunks against the file's
  length; a buffer against its ``byteLength``, a buffer view against its buffer, an accessor against its buffer
  view (a truncated file is one line).
* Buffer and image URIs are relative to the file and must stay in its folder
  (:func:`study.scene.paths.named_file`); ``data:`` URIs are the file's own bytes, base64 or percent-encoded.
* Accessors of any component type, normalized integers scaled as the spec says, sparse accessors (their values
  written over the base, or over zeros: glTF 2.0 § 3.6.2.3); ``EXT_meshopt_compression`` buffer views decoded by
  meshoptimizer's decoder (the package ``meshopt``), filters undone (a fallback buffer without data is not read).
"""

from __future__ import annotations

import base64
import binascii
import json
import struct
from pathlib import Path
from urllib.parse import unquote_to_bytes

import numpy as np

from study.errors import StudyError
from study.scene.parts import read_image
from study.scene.paths import named_file

_CT = {5120: np.int8, 5121: np.uint8, 5122: np.int16, 5123: np.uint16, 5125: np.uint32, 5126: np.float32}
_NC = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT2": 4, "MAT3": 9, "MAT4": 16}
#: top-level members that are arrays of objects (glTF 2.0 schema, glTF.schema.json)
_ARRAYS = ("accessors", "animations", "buffers", "bufferViews", "cameras", "images", "materials", "meshes",
           "nodes", "samplers", "scenes", "skins", "textures")  # fmt: skip
_GLB_JSON, _GLB_BIN = 0x4E4F534A, 0x004E4942


def is_index(i) -> bool:
    return isinstance(i, int) and not isinstance(i, bool)


class GltfFile:
    """A glTF's JSON (type-checked at the top level) and its buffers, read on demand."""

    def __init__(self, path: Path, src: str):
        self.path, self.src = path, src
        data = path.read_bytes()
        self.bin = None
        try:
            if data[:4] == b"glTF":
                text = self._glb(data)
            else:
                text = data
            self.g = json.loads(text)
        except RecursionError:
            self.fail("not a glTF 2.0 file (its JSON is nested too deeply)")
        except (ValueError, UnicodeDecodeError) as err:
            self.fail(f"not a glTF 2.0 file ({' '.join(str(err).split())[:120]})")
        self._check_types()
        self._buffers: dict[int, bytes] = {}
        self._decoded: dict[int, bytes] = {}  # meshopt-compressed buffer views, decoded
        self.images_used: set[int] = set()

    def fail(self, msg: str):
        raise StudyError(msg, key=self.src)

    def _glb(self, data: bytes) -> bytes:
        """The JSON chunk of a GLB (and its BIN chunk in ``self.bin``), checked against the file's length."""
        if len(data) < 20:
            self.fail(f"a GLB of {len(data)} bytes is shorter than its 20-byte header (truncated?)")
        version, length = struct.unpack_from("<II", data, 4)
        if version != 2:
            self.fail(f"GLB version {version}; study reads glTF 2.0")
        if length > len(data):
            self.fail(f"the GLB header says {length} bytes, the file has {len(data)} (truncated?)")
        n, kind = struct.unpack_from("<II", data, 12)
        if kind != _GLB_JSON or 20 + n > len(data):
            self.fail("the GLB's first chunk is not a whole JSON chunk (truncated or not a GLB)")
        off = 20 + n + (-n % 4 if 20 + n + (-n % 4) + 8 <= len(data) else 0)
        if off + 8 <= len(data):
            m, kind = struct.unpack_from("<II", data, off)
            if kind == _GLB_BIN:
                if off + 8 + m > len(data):
                    self.fail(f"the GLB's binary chunk says {m} bytes, the file holds {len(data) - off - 8} "
                              "(truncated?)")  # fmt: skip
                self.bin = data[off + 8 : off + 8 + m]
        return data[20 : 20 + n]

    def _check_types(self) -> None:
        g = self.g
        if not isinstance(g, dict):
            self.fail(f"not a glTF 2.0 file (its JSON is a {type(g).__name__}, not an object)")
        for k in _ARRAYS:
            v = g.get(k, [])
            if not isinstance(v, list) or not all(isinstance(x, dict) for x in v):
                self.fail(f"'{k}' must be an array of objects (glTF 2.0), got {kind_of(v)}")
        for k in ("asset", "extensions", "extras"):
            if not isinstance(g.get(k, {}), dict):
                self.fail(f"'{k}' must be an object (glTF 2.0), got {kind_of(g[k])}")
        for k in ("extensionsUsed", "extensionsRequired"):
            v = g.get(k, [])
            if not isinstance(v, list) or not all(isinstance(x, str) for x in v):
                self.fail(f"'{k}' must be an array of strings (glTF 2.0), got {kind_of(v)}")
        if "scene" in g and not is_index(g["scene"]):
            self.fail(f"'scene' must be an index, got {kind_of(g['scene'])}")

    def get(self, kind: str, i, where: str) -> dict:
        """Element ``i`` of the top-level array ``kind``; an index that is not one: a StudyError naming ``where``."""
        arr = self.g.get(kind, [])
        if not is_index(i) or not 0 <= i < len(arr):
            self.fail(f"{where}: {kind} index {i!r} is out of range ({len(arr)} {kind})")
        return arr[i]

    # ------------------------------------------------------------------------------------------ bytes
    def buffer(self, i: int, where: str) -> bytes:
        if i not in self._buffers:
            b = self.get("buffers", i, where)
            uri = b.get("uri")
            if uri is None:
                if self.bin is None:
                    self.fail(f"buffer {i} has no uri and the file has no binary chunk")
                data = self.bin
            else:
                data = self._uri(uri, f"buffer {i}")
            need = b.get("byteLength", 0)
            if not is_index(need) or need > len(data):
                self.fail(
                    f"buffer {i} holds {len(data)} bytes, fewer than its byteLength {need!r} (truncated?)"
                )
            self._buffers[i] = data
        return self._buffers[i]

    def _uri(self, uri, what: str) -> bytes:
        if not isinstance(uri, str):
            self.fail(f"{what}: uri must be a string, got {kind_of(uri)}")
        if uri.startswith("data:"):
            head, _, body = uri.partition(",")
            try:
                return (
                    base64.b64decode(body, validate=True)
                    if head.endswith(";base64")
                    else unquote_to_bytes(body)
                )
            except (binascii.Error, ValueError):
                self.fail(f"{what}: its data URI is not valid base64")
        p = named_file(self.path.parent, uri, what=what, src=self.src, uri=True)
        if not p.is_file():
            self.fail(f"{what}: the file it references is missing: {p}")
        return p.read_bytes()

    def view(self, i: int, where: str) -> tuple[bytes, int, int, int | None]:
        """(buffer, start, end, byteStride) of buffer view ``i``, checked against its buffer."""
        v = self.get("bufferViews", i, where)
        ext = (
            v.get("extensions", {}).get("EXT_meshopt_compression")
            if isinstance(v.get("extensions"), dict)
            else None
        )
        if isinstance(ext, dict):
            data = self._meshopt(i, ext)
            return data, 0, len(data), v.get("byteStride")
        buf = self.buffer(v.get("buffer"), f"bufferView {i}")
        off, n = v.get("byteOffset", 0), v.get("byteLength")
        if not (is_index(off) and is_index(n)) or off + n > len(buf):
            self.fail(f"bufferView {i} (bytes {off!r}..+{n!r}) lies outside its buffer of {len(buf)} bytes")
        return buf, off, off + n, v.get("byteStride")

    def _meshopt(self, i: int, ext: dict) -> bytes:
        """Buffer view ``i`` decoded from its EXT_meshopt_compression stream (meshoptimizer's decoder through the
        package meshopt): ``count`` elements of ``byteStride`` bytes, the ``filter`` undone."""
        if i not in self._decoded:
            what = f"bufferView {i} (EXT_meshopt_compression)"
            try:
                import meshopt
            except ImportError:
                self.fail(
                    f"{what}: the package meshopt, which decodes it, is not installed (pip install meshopt)"
                )
            buf = self.buffer(ext.get("buffer"), what)
            off, n = ext.get("byteOffset", 0), ext.get("byteLength")
            count, stride = ext.get("count"), ext.get("byteStride")
            mode, filt = ext.get("mode"), ext.get("filter", "NONE")
            if not all(is_index(x) for x in (off, n, count, stride)) or off + n > len(buf):
                self.fail(f"{what}: byteOffset, byteLength, count and byteStride must be indices inside buffer "
                          f"{ext.get('buffer')!r}")  # fmt: skip
            try:
                rows = meshopt.decode_gltf_buffer(bytes(buf[off : off + n]), count, stride, mode, filt)
            except Exception as err:  # noqa: BLE001 - the decoder's own errors are bad input
                self.fail(f"{what}: its stream does not decode ({type(err).__name__}: {err})")
            self._decoded[i] = np.ascontiguousarray(rows).astype(rows.dtype.newbyteorder("<")).tobytes()
        return self._decoded[i]

    def _rows(self, view: int, offset, dt: np.dtype, nc: int, count: int, where: str) -> np.ndarray:
        """``count`` elements of ``nc`` components of type ``dt`` from buffer view ``view`` at ``offset``."""
        buf, start, end, stride = self.view(view, where)
        if not is_index(offset) or offset < 0:
            self.fail(f"{where}: byteOffset {offset!r} is not an offset")
        off = start + offset
        size = dt.itemsize * nc
        stride = stride or size
        if count and off + (count - 1) * stride + size > end:
            self.fail(f"{where}: {count} elements read past the end of bufferView {view} (truncated?)")
        raw = np.frombuffer(buf, np.uint8, count=(count - 1) * stride + size if count else 0, offset=off)
        rows = (
            np.lib.stride_tricks.as_strided(raw, (count, size), (stride, 1))
            if count
            else raw.reshape(0, size)
        )
        return np.ascontiguousarray(rows).view(dt).reshape(count, nc)

    def accessor(self, i: int, where: str, draco: np.ndarray | None = None) -> np.ndarray:
        """Accessor ``i`` as (count, components), sparse values applied and normalized integers scaled;
        ``draco``: the decoded attribute that stands for its data (KHR_draco_mesh_compression)."""
        a = self.get("accessors", i, where)
        where = f"accessor {i}"
        if a.get("componentType") not in _CT or a.get("type") not in _NC:
            self.fail(f"{where}: componentType {a.get('componentType')!r} / type {a.get('type')!r} is not "
                      f"one of glTF's ({sorted(_CT)} / {sorted(_NC)})")  # fmt: skip
        dt, nc, count = np.dtype(_CT[a["componentType"]]).newbyteorder("<"), _NC[a["type"]], a.get("count")
        if not is_index(count) or count < 0:
            self.fail(f"{where}: count {count!r} is not a count")
        if draco is not None:
            out = np.asarray(draco).reshape(len(draco), -1)[:, :nc].astype(dt)
        elif "bufferView" not in a:
            out = np.zeros((count, nc), dt)
        else:
            out = self._rows(a["bufferView"], a.get("byteOffset", 0), dt, nc, count, where)
        if "sparse" in a:
            out = self._sparse(a["sparse"], out, dt, nc, where)
        if a.get("normalized") and dt.kind in "iu":
            out = np.maximum(out / np.iinfo(dt).max, -1.0)
        return out

    def _sparse(self, s: dict, base: np.ndarray, dt: np.dtype, nc: int, where: str) -> np.ndarray:
        """The base with ``s["count"]`` elements replaced, at ``s["indices"]``, by ``s["values"]`` (spec 3.6.2.3)."""
        try:
            n, ind, val = s["count"], s["indices"], s["values"]
            it = np.dtype(_CT[ind["componentType"]]).newbyteorder("<")
        except (KeyError, TypeError):
            self.fail(
                f"{where}: sparse needs count, indices (bufferView, componentType) and values (bufferView)"
            )
        if not is_index(n) or n < 1 or it.kind != "u":
            self.fail(f"{where}: sparse count {n!r} / index type {ind.get('componentType')!r} is not valid")
        idx = self._rows(ind.get("bufferView"), ind.get("byteOffset", 0), it, 1, n, f"{where} sparse indices")
        idx = idx.ravel().astype(np.int64)
        if idx.max() >= len(base):
            self.fail(f"{where}: sparse index {int(idx.max())} is past the accessor's count ({len(base)})")
        vals = self._rows(
            val.get("bufferView"), val.get("byteOffset", 0), dt, nc, n, f"{where} sparse values"
        )
        out = base.copy()
        out[idx] = vals
        return out

    def image(self, i: int, where: str) -> np.ndarray:
        """Image ``i`` as linear RGB (sRGB decoded)."""
        im = self.get("images", i, where)
        what = f"image {i}"
        if "uri" in im:
            data = self._uri(im["uri"], what)
        elif "bufferView" in im:
            buf, start, end, _ = self.view(im["bufferView"], what)
            data = buf[start:end]
        else:
            self.fail(f"{what} has neither a uri nor a bufferView")
        return read_image(data, what=what, src=self.src)


def kind_of(v) -> str:
    return {list: "an array", dict: "an object", str: "a string", bool: "a boolean", type(None): "null"}.get(
        type(v), "a number"
    )
