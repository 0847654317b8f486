"""What a source's keys are worth in a content key: ``file`` fields resolved against the scene file's directory
(:func:`resolve`) and hashed by their bytes and the bytes of every file they reference (:func:`key_fields`).

A relative ``file`` is resolved against the directory of the scene file that names it (the validation context's
``"base"``; the working directory otherwise) and stored absolute. Cache keys hash the file's bytes, not its path,
and the bytes of every file it references (:mod:`study.scene.references`).
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path
from typing import Any

from pydantic import BaseModel

from study.scene.paths import resolve, strict_resolve  # noqa: F401  (resolve: re-exported)


# ---------------------------------------------------------------------------------------------- content keys
def file_digest(path: str) -> str:
    """sha256 of a file's bytes and of every file it references (:func:`study.scene.references.referenced`: an
    OBJ's materials and textures, a glTF's buffers and images, a Mitsuba XML's includes, meshes, textures and
    envmaps): a change to any of them changes the key. A referenced file that is missing counts by its name."""
    from study.scene.references import referenced

    p = Path(path)
    h = hashlib.sha256(p.read_bytes())
    for ref in referenced(p):
        h.update(b"\0" + str(ref.name).encode() + b"\0")
        h.update(ref.read_bytes() if ref.is_file() else b"<missing>")
    return "sha256:" + h.hexdigest()


def _canon(v: Any) -> Any:
    """A JSON-able stand-in for any value of a scene: files by content, Mitsuba objects by their repr."""
    if isinstance(v, dict):
        return {str(k): _canon(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [_canon(x) for x in v]
    if isinstance(v, (str, int, float, bool)) or v is None:
        return v
    return repr(v)


#: Camera keys that only set others (``target``, ``fov``) on validation: content keys leave them out, so a framed
#: camera and the same camera given by hand share their results, and older keys stay valid.
FRAMING_KEYS = ("frame_object", "frame_fill")
#: Object keys added later, left out of content keys at their default (the object's GGX ``alpha`` = 0: a mirror),
#: so that every result made before they existed keeps its key.
LATER_DEFAULTS = {"alpha": 0.0}


def key_fields(model: BaseModel | dict) -> dict:
    """``model_dump`` of a scene (or part of one) for content keys: every field called ``file`` (or ``filename``,
    in a Mitsuba scene dict) replaced by the digest of the file's bytes (and of the files it references), Python
    objects (Mitsuba transforms in a scene dict) by their repr; the framing keys (:data:`FRAMING_KEYS`) left
    out, and the object's later keys at their defaults (:data:`LATER_DEFAULTS`); a plug-in source's code
    (:func:`plugin_code`) is added to the source's fields."""
    data = model.model_dump(mode="python") if isinstance(model, BaseModel) else model

    def walk(v):
        if isinstance(v, dict):
            return {
                k: (
                    file_digest(x)
                    if k in ("file", "filename", "sky") and isinstance(x, str) and Path(x).is_file()
                    else walk(x)
                )
                for k, x in v.items()
                if k not in FRAMING_KEYS
                and not ("material" in v and LATER_DEFAULTS.get(k, ()) == x)
                and not (
                    "type" in v and k == "sky" and x is None
                )  # an environment without a sky: keys as before
            }
        if isinstance(v, (list, tuple)):
            return [walk(x) for x in v]
        return v

    out = json.loads(json.dumps(_canon(walk(data)), sort_keys=True))
    env = model if hasattr(model, "build") else getattr(model, "environment", None)
    code = plugin_code(env)
    if code is not None:  # a plug-in source's code, as the methods' code is in the sweep's keys
        (out if env is model else out["environment"])[PLUGIN_CODE] = code
    return out


#: The key under which a plug-in source's code hash joins its content key (:func:`key_fields`).
PLUGIN_CODE = "plugin_code"


def plugin_code(source: Any) -> str | None:
    """The hash of a plug-in source's code (:func:`study.codehash.code_hash` of its class: its module's file, read
    now, so an edited ``build()`` changes every key that holds the source), or None for study's own sources (their
    code is in the keys of the study code that builds them) and for anything that is not a source."""
    from study.scene.sources.base import is_source_plugin

    if not hasattr(source, "build") or not hasattr(source, "type") or not is_source_plugin(type(source)):
        return None
    from study.codehash import code_hash

    return code_hash(type(source))
