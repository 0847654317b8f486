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
        q = subprocess.run(
            ["nvidia-smi", "--query-gpu=name,driver_version,memory.total", "--format=csv,noheader"],
            capture_output=True,
            text=True,
            timeout=20,
        )
    except (OSError, subprocess.SubprocessError):
        return ""
    return q.stdout.strip().splitlines()[0] if q.returncode == 0 and q.stdout.strip() else ""


#: Data-centre GPUs without RT cores: OptiX traverses BVHs in software (CUDA cores) on them.
NO_RT_CORES = ("H100", "H200", "H800", "GH200", "A100", "A800", "A30", "V100", "B100", "B200", "GB200")


def rt_cores_line(gpu: str) -> str:
    """Whether the GPU named ``gpu`` has RT cores, and what that means for the exact side of the ratios."""
    if not gpu:
        return "no GPU: the exact tracers run on the CPU (Embree; Mitsuba llvm_ad_rgb uses Embree too)"
    if any(k in gpu for k in NO_RT_CORES):
        return (
            f"{gpu.split(',')[0]} has no RT cores: OptiX traverses in software here; on an RT-core GPU the "
            "exact side would be faster"
        )
    return f"{gpu.split(',')[0]}: RT cores assumed present (OptiX traverses in hardware)"


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
    info["rt_cores"] = rt_cores_line(info["gpu"])
    return info
