"""Localization methods, one file each, registered by name. Every module of this package is imported here, so
adding a method means adding a file and nothing else."""
from __future__ import annotations

import importlib
import pkgutil

from study.errors import StudyError
from study.methods.base import REGISTRY, Localization, Method, Trace, register

for _m in pkgutil.iter_modules(__path__):
    if _m.name != "base":
        importlib.import_module(f"{__name__}.{_m.name}")


def names() -> list[str]:
    return sorted(REGISTRY)


def make(name: str, **params) -> Method:
    """Instantiate the method called ``name`` with its parameters (unknown names and parameters are errors)."""
    if name not in REGISTRY:
        raise StudyError(f"unknown method {name!r}; allowed: {', '.join(names())}", key="method")
    return REGISTRY[name](**params)


__all__ = ["Localization", "Method", "Trace", "make", "names", "register", "REGISTRY"]
