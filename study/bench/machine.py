"""The machine a bench ran on: CPU, GPU (``nvidia-smi``), package versions, and the backends available here."""
from __future__ import annotations

import importlib.metadata
import os
import platform
import subprocess

from study import backend as backends


def available_backends() -> list[str]:
    """numpy, and llvm / cuda where Dr.Jit can start them on this machine."""
    out = ["numpy"]
    for name in ("llvm", "cuda"):
        try:
            backends.get(name)
            out.append(name)
        except Exception:
            pass
    return out


def gpu_name() -> str:
    """'name, driver, memory' of the first GPU ``nvidia-smi`` lists; '' without one."""
    try:
        q = subprocess.run(["nvidia-smi", "--query-gpu=name,driver_version,memory.total", "--format=csv,noheader"],
                           capture_output=True, text=True, timeout=20)
    except (OSError, subprocess.SubprocessError):
        return ""
    return q.stdout.strip().splitlines()[0] if q.returncode == 0 and q.stdout.strip() else ""


def machine_info() -> dict:
    """cpu, cores, gpu, python, the versions of numpy / drjit / mitsuba / embreex ('-' if missing), libllvm."""
    cpu = platform.processor() or "?"
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    cpu = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    info = {"cpu": cpu, "cores": os.cpu_count(), "python": platform.python_version(), "gpu": gpu_name()}
    for pkg in ("numpy", "drjit", "mitsuba", "embreex"):
        try:
            info[pkg] = importlib.metadata.version(pkg)
        except importlib.metadata.PackageNotFoundError:
            info[pkg] = "-"
    info["libllvm"] = os.environ.get("DRJIT_LIBLLVM_PATH", "")
    return info
