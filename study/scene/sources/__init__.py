"""Where the environment comes from (the ``[environment]`` table of a scene): one file per source type, registered
by name — the box room (``box``, the default), a mesh file (``mesh``), a Mitsuba scene (``mitsuba``) — on the
contract of ``base`` (a pydantic model that builds an :class:`~study.scene.sources.base.EnvGeometry`), with the
content keys of their files (``keys``).

Every module of this package is imported here, so adding a source type means adding a file and nothing else;
from outside the package a module that study imports at start (``study --plugin MODULE``, ``$STUDY_PLUGINS``)
registers one the same way (``@register_source``).
"""

from __future__ import annotations

import importlib
import pkgutil
from typing import Annotated

from pydantic import PlainValidator, SerializeAsAny

from study.scene.sources.base import SOURCES, EnvGeometry, Source, register_source, validate_source
from study.scene.sources.keys import FRAMING_KEYS, file_digest, key_fields, resolve

for _m in pkgutil.iter_modules(__path__):
    if _m.name not in ("base", "keys"):
        importlib.import_module(f"{__name__}.{_m.name}")

from study.scene.sources.box import BoxEnv  # noqa: E402 - the default environment, for the schema

#: The type of a scene's ``environment`` field: any registered source, chosen by its ``type`` key.
Environment = Annotated[SerializeAsAny[Source], PlainValidator(validate_source)]

__all__ = [
    "BoxEnv",
    "EnvGeometry",
    "Environment",
    "FRAMING_KEYS",
    "SOURCES",
    "Source",
    "file_digest",
    "key_fields",
    "register_source",
    "resolve",
]
