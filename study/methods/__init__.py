"""Localization methods: the contract (``base``) and one file per method, registered by name.

Every module of this package is imported here, so adding a method to study means adding a file and nothing else.
Methods from outside the package register the same way (``@register``) from a module that study imports at start:
one named by ``--plugin MODULE`` on the command line or in the environment variable ``STUDY_PLUGINS``
(comma-separated; worker processes inherit it), or one advertised under the entry-point group ``study.methods``.
"""

from __future__ import annotations

import importlib
import importlib.metadata
import os
import pkgutil

from study.errors import StudyError
from study.methods.base import (
    REGISTRY,
    RESERVED,
    Found,
    Knob,
    Localization,
    Method,
    Trace,
    TracingMethod,
    register,
)

for _m in pkgutil.iter_modules(__path__):
    if _m.name != "base":
        importlib.import_module(f"{__name__}.{_m.name}")

PLUGIN_ENV = "STUDY_PLUGINS"


def load_plugins(modules: list[str] | tuple[str, ...] = ()) -> list[str]:
    """Import the plugin modules named in ``modules``, in ``$STUDY_PLUGINS`` and under the entry-point group
    ``study.methods``; their ``@register`` calls add methods. The named modules are added to ``$STUDY_PLUGINS``
    so that worker processes load them too. Returns the modules loaded."""
    names = [m for m in os.environ.get(PLUGIN_ENV, "").split(",") if m.strip()] + list(modules)
    names = list(dict.fromkeys(n.strip() for n in names))
    for n in names:
        _import_plugin(n, lambda n=n: importlib.import_module(n))
    if names:
        os.environ[PLUGIN_ENV] = ",".join(names)
    for ep in importlib.metadata.entry_points(group="study.methods"):
        _import_plugin(ep.value, ep.load)
    return names


def _import_plugin(name: str, load) -> None:
    """``load()`` a plug-in module; whatever goes wrong (it cannot be found, has a syntax error, raises or exits
    while imported, registers a taken or reserved name) is one StudyError line naming the module."""
    try:
        load()
    except StudyError as err:
        raise StudyError(err.detail, key=name) from None
    except SyntaxError as err:
        where = f"{err.filename}, line {err.lineno}" if err.filename else f"line {err.lineno}"
        raise StudyError(f"syntax error in the plugin module ({where}: {err.msg})", key=name) from None
    except ImportError as err:
        raise StudyError(f"cannot import the plugin module ({err})", key=name) from None
    except SystemExit as err:
        raise StudyError(
            f"the plugin module called sys.exit({err.code!r}) while imported", key=name
        ) from None
    except Exception as err:
        first = (str(err).strip().splitlines() or [""])[0][:160]
        raise StudyError(
            f"the plugin module raised {type(err).__name__} while imported: {first}", key=name
        ) from None


def names() -> list[str]:
    return sorted(REGISTRY)


def make(name: str, **params) -> Method:
    """Instantiate the method called ``name`` with its parameters (unknown names and parameters are errors)."""
    if name not in REGISTRY:
        raise StudyError(f"unknown method {name!r}; allowed: {', '.join(names())}", key="method")
    return REGISTRY[name](**params)


def all_methods() -> list[Method]:
    """Every registered mirror method (not ``glossy``) with its default parameters, in name order, but those that
    are an experiment of their own (``in_all`` False: ``hit_cache``, measured in fig_hitcache)."""
    return [
        make(n)
        for n in names()
        if not getattr(REGISTRY[n], "glossy", False) and getattr(REGISTRY[n], "in_all", True)
    ]


def glossy_methods() -> list[Method]:
    """Every registered glossy method (``Method.glossy``, :mod:`study.methods.glossy`), defaults, name order."""
    return [make(n) for n in names() if getattr(REGISTRY[n], "glossy", False)]


__all__ = [
    "Found",
    "RESERVED",
    "Knob",
    "Localization",
    "Method",
    "Trace",
    "TracingMethod",
    "all_methods",
    "glossy_methods",
    "load_plugins",
    "make",
    "names",
    "register",
    "REGISTRY",
]
