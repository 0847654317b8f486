"""study: measure how close GPU-friendly approximations of ray tracing come to real ray tracing.

Importing the package chooses a libLLVM for Dr.Jit's LLVM backend (see :mod:`study.runtime`) before anything
imports drjit or mitsuba, so that Debian 12's libLLVM 15 (which crashes Dr.Jit 1.5) is never picked.

The Python API (:mod:`study.api`) is reached from here and imported on first use, so ``import study`` stays
light: ``study.load_scene(...)``, ``study.evaluate(...)`` → ``study.Result``. One case end to end, the layer
under the API, is :mod:`study.measure`.
"""

import importlib

from study import runtime as _llvm

_llvm.configure()

__version__ = "0.1.0"

#: names served by study.api, imported when first asked for
_API = ("load_scene", "evaluate", "Result", "method_list")
__all__ = ["__version__", *_API]


def __getattr__(name: str):
    if name in _API:
        return getattr(importlib.import_module("study.api"), name)
    if name == "methods":  # `import study` then `@study.methods.register`, as the README shows
        return importlib.import_module("study.methods")
    raise AttributeError(f"module 'study' has no attribute {name!r}")


def __dir__():
    return sorted([*globals(), *_API, "methods"])
