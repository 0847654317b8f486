"""The native runtimes as study loads them: a libLLVM that Dr.Jit's LLVM backend (and Mitsuba's ``llvm_ad_rgb``)
can use, the render device (CPU or CUDA: which Mitsuba variant renders and traces exact hits) and the mitsuba
module with its variant set (:func:`mitsuba`).

Dr.Jit 1.5 on Debian 12 picks the system's libLLVM 15 and aborts the process ("LLVM ERROR: Cannot select ...
fminimum") — an abort no Python code can catch. :func:`configure` runs when :mod:`study` is imported and points
``DRJIT_LIBLLVM_PATH`` at the newest libLLVM >= 16 it finds: Debian's ``libllvm19`` or the PyPI wheel
``karellen-llvm-core`` (its library lies in the environment's ``lib/``). :func:`require` is called before
anything touches the LLVM backend and raises one clear :class:`~study.errors.EnvironmentProblem` (exit 3) when
none was found, or when the one ``DRJIT_LIBLLVM_PATH`` names cannot be used: it must load (ctypes) and be LLVM 16 or
newer by its file name or, failing that, its exported symbols (``LLVMGetVersion`` exists from LLVM 16 on). Checked
here because Dr.Jit would abort the process on it.
"""

from __future__ import annotations

import contextlib
import ctypes
import functools
import glob
import os
import re
import sys

from study.errors import EnvironmentProblem

MIN_VERSION = 16  # LLVM 15 and older crash Dr.Jit 1.5 on Debian 12
_FIX = (
    "no usable libLLVM (>= 16) found for Dr.Jit's LLVM backend (Debian 12's libLLVM 15 crashes it); "
    "fix: `apt-get install libllvm19` or `pip install karellen-llvm-core`, "
    "or set DRJIT_LIBLLVM_PATH to a libLLVM >= 16"
)


def _version(path: str) -> int:
    m = re.search(r"libLLVM[-.]?(?:so\.)?(\d+)", os.path.basename(path))
    return int(m.group(1)) if m else -1


def candidates() -> list[str]:
    """Usable libLLVM files, best first: the environment's own (karellen-llvm-core), then the system's."""
    found = []
    for root in dict.fromkeys([sys.prefix, sys.base_prefix]):
        # lib/ and one level below (karellen-llvm-core's place), not the whole tree: a recursive walk of /usr/lib
        # took 1 s of every start on the GPU machine
        here = glob.glob(os.path.join(root, "lib", "libLLVM*.so*"))
        here += glob.glob(os.path.join(root, "lib", "*", "libLLVM*.so*"))
        found += sorted(here, key=_version, reverse=True)
    found += sorted(
        glob.glob("/usr/lib/*/libLLVM*.so*") + glob.glob("/usr/lib/llvm-*/lib/libLLVM*.so*"),
        key=_version,
        reverse=True,
    )
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


@functools.cache
def problem(lib: str) -> str | None:
    """Why the libLLVM file ``lib`` cannot serve Dr.Jit (None if it can): missing, not loadable, not LLVM, or
    older than :data:`MIN_VERSION` (by its name, else by its symbols; a named old one is never loaded)."""
    if not os.path.isfile(lib):
        return "no such file"
    named = _version(lib)
    if 0 <= named < MIN_VERSION:
        return f"it is libLLVM {named}, Dr.Jit needs >= {MIN_VERSION}"
    try:
        dll = ctypes.CDLL(lib)
    except OSError as err:
        return f"not a loadable library ({str(err).split(': ')[-1][:80]})"
    if named >= MIN_VERSION:
        return None
    if hasattr(dll, "LLVMGetVersion"):  # LLVM >= 16
        v = [ctypes.c_uint() for _ in range(3)]
        dll.LLVMGetVersion(*[ctypes.byref(x) for x in v])
        return (
            None
            if v[0].value >= MIN_VERSION
            else f"it is libLLVM {v[0].value}, Dr.Jit needs >= {MIN_VERSION}"
        )
    if hasattr(dll, "LLVMContextCreate"):
        return f"it is a libLLVM older than {MIN_VERSION} (no LLVMGetVersion), Dr.Jit needs >= {MIN_VERSION}"
    return "not a libLLVM (no LLVM C API symbols)"


def require() -> str:
    """Return the libLLVM in use, or raise EnvironmentProblem with the fix if none usable was found."""
    p = configure()
    if not p:
        raise EnvironmentProblem(_FIX)
    why = problem(p)
    if why:
        raise EnvironmentProblem(
            f"cannot use it for Dr.Jit's LLVM backend: {why}; unset it or point it at a "
            f"libLLVM >= {MIN_VERSION} (e.g. `apt-get install libllvm19`)",
            key=f"DRJIT_LIBLLVM_PATH={p}",
        )
    if "drjit" in sys.modules and os.environ.get("DRJIT_LIBLLVM_PATH") != p:
        raise EnvironmentProblem("drjit was imported before study chose a libLLVM; import study first")
    return p


# ---------------------------------------------------------------------------------------------- render device
#: Render device → the Mitsuba variant that renders there (and whose ray queries give the exact hits on the GPU).
VARIANTS = {"cpu": "llvm_ad_rgb", "cuda": "cuda_ad_rgb"}
_ENV = "STUDY_RENDER_DEVICE"  # inherited by worker processes (``--jobs``, local Dask workers)


def set_render_device(device: str) -> None:
    """Where Mitsuba renders and exact hits are computed: ``"cpu"`` (``llvm_ad_rgb`` + Embree, the default) or
    ``"cuda"`` (``cuda_ad_rgb`` + OptiX through Mitsuba). Process-wide; worker processes started later inherit it
    (environment variable ``STUDY_RENDER_DEVICE``). The CLI sets it from ``--backend cuda``."""
    if device not in VARIANTS:
        raise ValueError(f"render device must be one of {', '.join(VARIANTS)}, got {device!r}")
    os.environ[_ENV] = device


@contextlib.contextmanager
def using_render_device(device: str | None):
    """:func:`set_render_device` for the duration of a ``with`` block (a command run in-process, e.g. by a test),
    the previous setting restored after it; ``None`` changes nothing."""
    before = os.environ.get(_ENV)
    if device is not None:
        set_render_device(device)
    try:
        yield
    finally:
        if device is not None:
            if before is None:
                os.environ.pop(_ENV, None)
            else:
                os.environ[_ENV] = before


def render_device() -> str:
    d = os.environ.get(_ENV, "cpu")
    return d if d in VARIANTS else "cpu"


def current_variant() -> str:
    """The Mitsuba variant of the render device (what :func:`mitsuba` sets when no variant is named)."""
    return VARIANTS[render_device()]


# ---------------------------------------------------------------------------------------------- Mitsuba
_variant: str | None = None


def mitsuba(variant: str | None = None):
    """The mitsuba module with ``variant`` (default :func:`current_variant`) set (libLLVM checked first for LLVM
    variants, so Dr.Jit never loads Debian's libLLVM 15). The one place study imports mitsuba: every renderer and
    the EXR I/O go through it."""
    global _variant
    variant = variant or current_variant()
    if variant.startswith("llvm"):
        require()
    import mitsuba as mi

    if _variant != variant:
        mi.set_variant(variant)
        _variant = variant
    return mi
