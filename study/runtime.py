"""The native runtimes as study loads them: a libLLVM that Dr.Jit's LLVM backend (and Mitsuba's ``llvm_ad_rgb``)
can use, and the mitsuba module with its variant set (:func:`mitsuba`).

Dr.Jit 1.5 on Debian 12 picks the system's libLLVM 15 and aborts the process ("LLVM ERROR: Cannot select ...
fminimum") — an abort no Python code can catch. :func:`configure` runs when :mod:`study` is imported and points
``DRJIT_LIBLLVM_PATH`` at the newest libLLVM >= 16 it finds: Debian's ``libllvm19`` or the PyPI wheel
``karellen-llvm-core`` (its library lies in the environment's ``lib/``). :func:`require` is called before
anything touches the LLVM backend and raises one clear :class:`~study.errors.StudyError` when none was found.
"""
from __future__ import annotations

import glob
import os
import re
import sys

from study.errors import StudyError

MIN_VERSION = 16  # LLVM 15 and older crash Dr.Jit 1.5 on Debian 12
_FIX = ("no usable libLLVM (>= 16) found for Dr.Jit's LLVM backend (Debian 12's libLLVM 15 crashes it); "
        "fix: `apt-get install libllvm19` or `pip install karellen-llvm-core`, "
        "or set DRJIT_LIBLLVM_PATH to a libLLVM >= 16")


def _version(path: str) -> int:
    m = re.search(r"libLLVM[-.]?(?:so\.)?(\d+)", os.path.basename(path))
    return int(m.group(1)) if m else -1


def candidates() -> list[str]:
    """Usable libLLVM files, best first: the environment's own (karellen-llvm-core), then the system's."""
    found = []
    for root in dict.fromkeys([sys.prefix, sys.base_prefix]):
        found += sorted(glob.glob(os.path.join(root, "lib", "**", "libLLVM*.so*"), recursive=True),
                        key=_version, reverse=True)
    found += sorted(glob.glob("/usr/lib/*/libLLVM*.so*") + glob.glob("/usr/lib/llvm-*/lib/libLLVM*.so*"),
                    key=_version, reverse=True)
    return [p for p in dict.fromkeys(found) if _version(p) >= MIN_VERSION and os.path.isfile(p)]


def configure() -> str | None:
    """Set ``DRJIT_LIBLLVM_PATH`` (unless the user already did) and return the chosen path, or None."""
    chosen = os.environ.get("DRJIT_LIBLLVM_PATH")
    if chosen:
        return chosen
    found = candidates()
    if found:
        os.environ["DRJIT_LIBLLVM_PATH"] = found[0]
        return found[0]
    return None


def path() -> str | None:
    return os.environ.get("DRJIT_LIBLLVM_PATH")


def require() -> str:
    """Return the libLLVM in use, or raise StudyError with the fix if none usable was found."""
    p = configure()
    if not p or not os.path.exists(p):
        raise StudyError(_FIX)
    if "drjit" in sys.modules and os.environ.get("DRJIT_LIBLLVM_PATH") != p:
        raise StudyError("drjit was imported before study chose a libLLVM; import study first")
    return p


# ---------------------------------------------------------------------------------------------- Mitsuba
_variant: str | None = None


def mitsuba(variant: str = "llvm_ad_rgb"):
    """The mitsuba module with ``variant`` set (libLLVM checked first for LLVM variants, so Dr.Jit never loads
    Debian's libLLVM 15). The one place study imports mitsuba: every renderer and the EXR I/O go through it."""
    global _variant
    if variant.startswith("llvm"):
        require()
    import mitsuba as mi
    if _variant != variant:
        mi.set_variant(variant)
        _variant = variant
    return mi
