"""study: measure how close GPU-friendly approximations of ray tracing come to real ray tracing.

Importing the package chooses a libLLVM for Dr.Jit's LLVM backend (see :mod:`study.runtime`) before anything
imports drjit or mitsuba, so that Debian 12's libLLVM 15 (which crashes Dr.Jit 1.5) is never picked.
"""
from study import runtime as _llvm

_llvm.configure()

__version__ = "0.1.0"
