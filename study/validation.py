"""Validation errors of pydantic models as the one line a user sees (:class:`~study.errors.StudyError`).

Every config, scene and method-parameter model is validated through :func:`validate`, so every bad value reads
alike: ``<file>: <dotted key>: <what is wrong>; allowed: <keys>`` where the key is unknown.
"""

from __future__ import annotations

from typing import Any

from pydantic import BaseModel, ValidationError

from study.errors import StudyError
from study.io import read_toml


class KeyedError(ValueError):
    """Raised inside a model validator to blame a key other than the one being validated (e.g. a placement
    check of the whole scene that blames ``object.center``); :func:`first_error` reports that key."""

    def __init__(self, key: str, msg: str):
        super().__init__(msg)
        self.key = key


def allowed_keys(model: type[BaseModel], loc: tuple) -> str:
    """The keys allowed beside the last element of ``loc`` (a pydantic error location) in ``model``."""
    node: Any = model
    for part in loc[:-1]:
        if isinstance(part, int) or (isinstance(part, str) and part.isdigit()):
            continue
        field = (
            node.model_fields.get(part) if isinstance(node, type) and issubclass(node, BaseModel) else None
        )
        if field is None:
            return ""
        ann = field.annotation
        args = getattr(ann, "__args__", ())
        node = next((a for a in (ann, *args) if isinstance(a, type) and issubclass(a, BaseModel)), None)
        if node is None:
            return ""
    if isinstance(node, type) and issubclass(node, BaseModel):
        return ", ".join(node.model_fields)
    return ""


def first_error(
    err: ValidationError, model: type[BaseModel], *, skip: tuple[str, ...] = ()
) -> tuple[str, str]:
    """(dotted key, message) of the first error; ``skip``: location parts left out of the key (union tags)."""
    e = err.errors()[0]
    inner = (e.get("ctx") or {}).get("error")
    if isinstance(inner, KeyedError):
        return inner.key, str(inner)
    loc = tuple(p for p in e["loc"] if p not in skip and not str(p).startswith("<"))  # "<tag>": union tags
    key = ".".join(str(p) for p in loc)
    if e["type"] == "extra_forbidden":
        allowed = allowed_keys(model, loc)
        return key, "unknown key" + (f"; allowed: {allowed}" if allowed else "")
    return key, e["msg"]


def validate(model: type[BaseModel], data: Any, *, file: str | None = None, prefix: str = ""):
    """``model.model_validate(data)``; the first problem becomes one StudyError naming ``file`` and the key
    (``prefix`` + the dotted location)."""
    try:
        return model.model_validate(data)
    except ValidationError as err:
        key, msg = first_error(err, model)
        raise StudyError(
            msg, file=file, key=(prefix + key) if key else (prefix.rstrip(".") or None)
        ) from None


def validate_file(model: type[BaseModel], path):
    """Read the TOML file at ``path`` into ``model`` (:func:`study.io.read_toml`, then :func:`validate`)."""
    return validate(model, read_toml(path), file=str(path))
