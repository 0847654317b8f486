"""Where a table came from, written by code: the commit and whether the tree was dirty, the command line, the
device, versions, and whether the code that made it is the code of its commit.

The commit comes from ``git`` where the repository has one. A copy without ``.git`` (the lent GPU machine's)
carries a stamp, ``.study-stamp.json`` at the repository root, written before the copy travels by
``bash scripts/device_run.sh stamp`` (:func:`write_stamp`): the same commit, dirty flag and diff hash that ``git``
gives here. Without either, the commit is ``"unknown"``.

:func:`code_status` checks a table's metadata against the repository: its commit is in the history and its
``code_hash`` equals the hash of the files it lists (``code_files``) as that commit holds them. The report marks
every table for which it returns a reason as stale.
"""

from __future__ import annotations

import hashlib
import json
import os
import platform
import subprocess
import sys
from pathlib import Path

from study.codehash import PACKAGE_DIR, hash_of_sources

REPO = PACKAGE_DIR.parent  # the repository root (the folder that holds study/)
STAMP = ".study-stamp.json"
#: what counts for "dirty": the code, the configs and the scenes (reports/ is written while tables are made)
CODE_PATHS = ("study", "configs", "scenes", "pyproject.toml")


def config_sha(path: str | Path) -> str:
    """The ``config_sha256`` of a run's metadata: the config file's SHA-256, its first 16 hex digits."""
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()[:16]


def _git(*args: str, repo: Path = REPO, data: bytes | None = None) -> bytes | None:
    """``git args`` in ``repo``: its stdout, or None where git or the repository is absent or the call fails."""
    try:
        r = subprocess.run(["git", *args], cwd=repo, input=data, capture_output=True, check=True, timeout=60)
    except (OSError, subprocess.SubprocessError):
        return None
    return r.stdout


def tree_sha256(repo: Path = REPO) -> str:
    """SHA-256 (16 hex digits) of the files under :data:`CODE_PATHS` as they lie on disk (relative paths and
    contents, sorted; compiled files left out): what a stamp was written for."""
    h = hashlib.sha256()
    for top in CODE_PATHS:
        root = repo / top
        files = [root] if root.is_file() else sorted(root.rglob("*")) if root.is_dir() else []
        for f in files:
            if f.is_file() and "__pycache__" not in f.parts and f.suffix != ".pyc":
                h.update(str(f.relative_to(repo)).encode() + b"\0" + f.read_bytes() + b"\0")
    return h.hexdigest()[:16]


def _stamp(repo: Path) -> dict | None:
    try:
        stamp = json.loads((repo / STAMP).read_text())
        return {"commit": str(stamp["commit"]), "dirty": bool(stamp["dirty"]),
                "diff_sha256": stamp.get("diff_sha256"), "tree": stamp.get("tree_sha256")}  # fmt: skip
    except (OSError, ValueError, KeyError, TypeError):
        return None


def git_state(repo: Path = REPO) -> dict:
    """``{"commit", "dirty", "diff_sha256", "from"}``: the commit checked out, whether the code paths
    (:data:`CODE_PATHS`) differ from it (tracked changes or untracked files), the SHA-256 (16 hex digits) of
    ``git diff HEAD`` over those paths (None when clean), and where this came from (``git``, ``stamp`` or
    ``none``). A stamp (:data:`STAMP`) written for exactly these files (its ``tree_sha256``, :func:`tree_sha256`)
    is read first: a copy that travels may hold a ``.git`` of another commit (the lent GPU machine's does), and a
    stale stamp of other files is never taken. Without a matching stamp, ``git``; without a repository, a stamp
    of other files gives its commit, dirty."""
    stamp = _stamp(repo)
    if stamp is not None and stamp.pop("tree") == tree_sha256(repo):
        return {**stamp, "from": "stamp"}
    head = _git("rev-parse", "HEAD", repo=repo)
    if head is not None:
        diff = _git("diff", "HEAD", "--binary", "--", *CODE_PATHS, repo=repo) or b""
        others = _git("ls-files", "--others", "--exclude-standard", "--", *CODE_PATHS, repo=repo) or b""
        dirty = bool(diff.strip() or others.strip())
        return {
            "commit": head.decode().strip(),
            "dirty": dirty,
            "diff_sha256": hashlib.sha256(diff + others).hexdigest()[:16] if dirty else None,
            "from": "git",
        }
    if stamp is not None:  # a stamp of other files than these: its commit, and the tree differs from it
        return {**stamp, "dirty": True, "from": "stamp"}
    return {"commit": "unknown", "dirty": None, "diff_sha256": None, "from": "none"}


def write_stamp(repo: Path = REPO) -> dict:
    """Write :data:`STAMP` from ``git`` (what :func:`git_state` gives here), for a copy that travels without
    ``.git``; returns it. Raises RuntimeError where there is no repository to read."""
    if (repo / STAMP).exists():
        (repo / STAMP).unlink()  # not read back by git_state below
    state = git_state(repo)
    if state["from"] != "git":
        raise RuntimeError(f"no git repository at {repo}: nothing to stamp")
    stamp = {**{k: state[k] for k in ("commit", "dirty", "diff_sha256")}, "tree_sha256": tree_sha256(repo)}
    (repo / STAMP).write_text(json.dumps(stamp, indent=1) + "\n")
    return stamp


def device(backend: str) -> dict:
    """The machine: its CPU's model and core count, and on the ``cuda`` backend the GPU's name (first line of
    ``nvidia-smi``; Dr.Jit's device list where that is absent)."""
    cpu = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.partition(":")[2].strip()
                break
    except OSError:
        pass
    out = {"cpu": cpu, "cores": os.cpu_count(), "gpu": None}
    if backend == "cuda":
        try:
            r = subprocess.run(["nvidia-smi", "--query-gpu=name", "--format=csv,noheader"],
                               capture_output=True, text=True, check=True, timeout=30)  # fmt: skip
            out["gpu"] = r.stdout.strip().splitlines()[0] if r.stdout.strip() else None
        except (OSError, subprocess.SubprocessError):
            out["gpu"] = None
    return out


def versions() -> dict:
    """The versions of study (its ``__version__``) and of the libraries that make its numbers."""
    from importlib.metadata import PackageNotFoundError, version

    import study

    vers: dict = {"study": study.__version__}
    for p in ("mitsuba", "drjit", "embreex", "numpy", "scikit-image", "flip-evaluator"):
        try:
            vers[p] = version(p)
        except PackageNotFoundError:
            vers[p] = None
    return vers


def command(argv: list[str] | None = None) -> str:
    """The command line: ``study …`` for the study command (its script, ``python -m study`` or ``python -m
    study.cli``), else the interpreter's arguments as given."""
    argv = sys.argv if argv is None else argv
    p = Path(argv[0]) if argv else Path("")
    if p.name in ("study", "cli.py") or (p.name == "__main__.py" and p.parent.name in ("cli", "study")):
        return " ".join(["study", *argv[1:]])
    return " ".join(["python", *argv]) if argv else "python"


def code_status(meta: dict, repo: Path = REPO) -> str | None:
    """None when the table described by ``meta`` (its metadata.json) was made by the code of its commit: the
    commit is in ``repo``'s history and ``code_hash`` equals the hash of ``code_files`` as that commit holds them.
    Else why not, in a few words (no code hash, an unknown commit, code changed, no git here)."""
    commit, want, files = meta.get("git_commit"), meta.get("code_hash"), meta.get("code_files")
    if not want or not files:
        return "no code hash in its metadata"
    if meta.get("code_outside"):
        return f"made with code outside study ({', '.join(meta['code_outside'])})"
    if not commit or commit == "unknown":
        return "its commit is unknown"
    if _git("rev-parse", "--git-dir", repo=repo) is None:
        return "no git repository here to check its commit"
    if _git("cat-file", "-e", f"{commit}^{{commit}}", repo=repo) is None:
        return f"commit {str(commit)[:10]} is not in this repository's history"
    sources = _blobs(commit, files, repo)
    if sources is None:
        return f"a file it lists is missing at commit {commit[:10]}"
    if hash_of_sources(sources) != want:
        return f"its code hash differs from the code at commit {commit[:10]}"
    return None


def _blobs(commit: str, files: list[str], repo: Path) -> dict[str, bytes] | None:
    """The bytes of ``files`` at ``commit`` (one ``git cat-file --batch``), None if any is missing."""
    out = _git("cat-file", "--batch", repo=repo, data="".join(f"{commit}:{f}\n" for f in files).encode())
    if out is None:
        return None
    got, pos = {}, 0
    for f in files:
        end = out.index(b"\n", pos)
        head = out[pos:end].split()
        if len(head) < 3 or head[1] != b"blob":
            return None
        size = int(head[2])
        got[f] = out[end + 1 : end + 1 + size]
        pos = end + 1 + size + 1
    return got
