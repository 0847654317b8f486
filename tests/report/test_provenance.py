"""Provenance written by code (issue 55): every table's metadata names its commit, whether the tree was dirty, the
command, the device, versions (study's own included) and the hash of the code that made it; a copy without
``.git`` reads the stamp ``scripts/device_run.sh stamp`` writes; every committed table is either made by the code
of its commit (checked here from git's own files, independently of study.harness.provenance) or marked stale in
the report."""

import hashlib
import json
import shutil
import subprocess
from pathlib import Path

import pytest

import study
from study.codehash import code_hash, code_record, file_module
from study.harness import provenance
from study.harness.runner import metadata
from study.outputs.markup import md_esc
from study.report import sections
from tests.report.test_report_html import small_report

ROOT = Path(__file__).resolve().parents[2]


def _git(repo: Path, *args: str) -> str:
    return subprocess.run(["git", *args], cwd=repo, capture_output=True, text=True, check=True).stdout.strip()


def _repo_with(tmp_path: Path, files: list[str]) -> Path:
    """A git repository holding copies of study's ``files`` (paths relative to the repository root)."""
    repo = tmp_path / "repo"
    for f in files:
        (repo / f).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy(ROOT / f, repo / f)
    _git(repo.parent, "init", "-q", str(repo))
    _git(repo, "add", "-A")
    _git(repo, "-c", "user.name=t", "-c", "user.email=t@t", "commit", "-qm", "code")
    return repo


def test_code_status_current_changed_unknown_and_missing(tmp_path):
    from study.measure import outcomes

    rec = code_record(outcomes)
    assert rec["code_hash"] == code_hash(outcomes) and not rec["code_outside"]
    assert "study/measure/outcomes.py" in rec["code_files"] and "study/__init__.py" in rec["code_files"]
    repo = _repo_with(tmp_path, rec["code_files"])
    first = _git(repo, "rev-parse", "HEAD")
    meta = {"git_commit": first, **rec}
    assert provenance.code_status(meta, repo=repo) is None
    # one file the table depends on changes in a later commit: the table made at the later commit is stale
    with open(repo / "study/measure/outcomes.py", "a") as f:
        f.write("\n# changed\n")
    _git(repo, "-c", "user.name=t", "-c", "user.email=t@t", "commit", "-qam", "change")
    later = _git(repo, "rev-parse", "HEAD")
    assert "differs" in provenance.code_status({**meta, "git_commit": later}, repo=repo)
    assert provenance.code_status(meta, repo=repo) is None  # the first commit still holds its code
    assert "not in this repository" in provenance.code_status({**meta, "git_commit": "d" * 40}, repo=repo)
    assert "no code hash" in provenance.code_status({"git_commit": first}, repo=repo)
    assert "unknown" in provenance.code_status({**meta, "git_commit": "unknown"}, repo=repo)
    missing = {**meta, "code_files": [*rec["code_files"], "study/nowhere.py"]}
    assert "missing" in provenance.code_status(missing, repo=repo)


def test_git_state_dirty_and_the_stamp_of_a_copy_without_git(tmp_path):
    repo = _repo_with(tmp_path, ["study/errors.py"])
    head = _git(repo, "rev-parse", "HEAD")
    assert provenance.git_state(repo) == {"commit": head, "dirty": False, "diff_sha256": None, "from": "git"}
    (repo / "reports").mkdir()
    (repo / "reports" / "x.csv").write_text("a\n")  # outputs do not make the tree dirty
    assert provenance.git_state(repo)["dirty"] is False
    with open(repo / "study/errors.py", "a") as f:
        f.write("\n# local change\n")
    diff = subprocess.run(["git", "diff", "HEAD", "--binary", "--", *provenance.CODE_PATHS], cwd=repo,
                          capture_output=True, check=True).stdout  # fmt: skip
    state = provenance.git_state(repo)
    assert state["dirty"] is True and state["diff_sha256"] == hashlib.sha256(diff).hexdigest()[:16]
    stamp = provenance.write_stamp(repo)
    want = {k: stamp[k] for k in ("commit", "dirty", "diff_sha256")}
    assert provenance.git_state(repo) == {**want, "from": "stamp"}  # the stamp is of exactly these files
    # the copy that travels to the GPU machine holds a .git of another commit (the session's first): the stamp wins
    _git(repo, "-c", "user.email=a@b", "-c", "user.name=a", "commit", "-qam", "another")
    assert provenance.git_state(repo) == {**want, "from": "stamp"}
    shutil.rmtree(repo / ".git")  # or none at all
    assert provenance.git_state(repo) == {**want, "from": "stamp"}
    with open(repo / "study/errors.py", "a") as f:  # a stale stamp: its commit, dirty
        f.write("\n# another change\n")
    assert provenance.git_state(repo) == {**want, "dirty": True, "from": "stamp"}
    (repo / provenance.STAMP).unlink()
    assert provenance.git_state(repo) == {
        "commit": "unknown",
        "dirty": None,
        "diff_sha256": None,
        "from": "none",
    }


def test_the_stamp_script_writes_what_study_reads(tmp_path):
    """``bash scripts/device_run.sh stamp`` (run where .git is, before the copy travels) writes the stamp."""
    repo = _repo_with(tmp_path, ["study/errors.py"])
    (repo / "scripts").mkdir()
    shutil.copy(ROOT / "scripts/device_run.sh", repo / "scripts/device_run.sh")
    (repo / "study" / "__init__.py").write_text("")
    shutil.copy(ROOT / "study/codehash.py", repo / "study/codehash.py")
    (repo / "study/harness").mkdir()
    (repo / "study/harness/__init__.py").write_text("")
    shutil.copy(ROOT / "study/harness/provenance.py", repo / "study/harness/provenance.py")
    _git(repo, "add", "-A")
    _git(repo, "-c", "user.name=t", "-c", "user.email=t@t", "commit", "-qm", "more")
    r = subprocess.run(["bash", "scripts/device_run.sh", "stamp"], cwd=repo, capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    got = json.loads((repo / ".study-stamp.json").read_text())
    assert got == {"commit": _git(repo, "rev-parse", "HEAD"), "dirty": False, "diff_sha256": None,
                   "tree_sha256": provenance.tree_sha256(repo)}  # fmt: skip


def test_metadata_is_written_by_code(tmp_path, monkeypatch):
    from study.measure.case import run_case

    cfg = tmp_path / "c.toml"
    cfg.write_text("x = 1\n")
    monkeypatch.setattr("sys.argv", ["/x/study/__main__.py", "figure", "fig4", "--backend", "llvm"])
    m = metadata(cfg, backend="llvm", seed=3, methods=["classical"], cases=1, code=(run_case,))
    assert m["command"] == "study figure fig4 --backend llvm"
    assert m["versions"]["study"] == study.__version__
    assert m["device"]["cores"] >= 1 and m["device"]["cpu"] and m["device"]["gpu"] is None
    assert m["code_hash"] == code_hash(run_case) and "study/measure/case.py" in m["code_files"]
    assert m["git_commit"] == _git(ROOT, "rev-parse", "HEAD") and m["git_from"] == "git"
    assert isinstance(m["git_dirty"], bool)


def test_a_figure_writes_its_code_hash_and_the_report_says_whether_it_is_current(tmp_path_factory):
    reports = small_report(tmp_path_factory)
    m = json.loads((reports / "fig4" / "metadata.json").read_text())
    assert m["code_hash"] and m["code_files"] and m["versions"]["study"] == study.__version__
    assert "study/outputs/figures.py" in m["code_files"] and "study/methods/localized.py" in m["code_files"]
    mark = sections.code_mark(m)
    assert mark == ("current" if _independent_check(m) else mark) and (
        mark == "current"
    ) == _independent_check(m)
    page = (reports / "index.md").read_text()
    assert md_esc(mark) in page and "| device |" in page


def _independent_check(m: dict) -> bool:
    """The table's commit is in the history and the SHA-256 of each file it lists, as ``git show`` gives it at
    that commit, combined as study.codehash combines module digests, equals its code hash."""
    commit = m.get("git_commit")
    if not m.get("code_hash") or not m.get("code_files") or not commit or m.get("code_outside"):
        return False
    if subprocess.run(
        ["git", "cat-file", "-e", f"{commit}^{{commit}}"], cwd=ROOT, capture_output=True
    ).returncode:
        return False
    parts = {}
    for f in m["code_files"]:
        r = subprocess.run(["git", "show", f"{commit}:{f}"], cwd=ROOT, capture_output=True)
        if r.returncode:
            return False
        parts[file_module(f)] = hashlib.sha256(r.stdout).hexdigest()
    blob = "\n".join(f"{k} {v}" for k, v in sorted(parts.items()))
    return hashlib.sha256(blob.encode()).hexdigest()[:16] == m["code_hash"]


def _committed_metadata() -> list[Path]:
    out = _git(ROOT, "ls-files", "reports/*metadata*.json", "reports/**/metadata*.json")
    return sorted({ROOT / p for p in out.splitlines()})


@pytest.mark.parametrize("path", _committed_metadata(), ids=lambda p: str(p.relative_to(ROOT / "reports")))
def test_every_committed_table_is_current_or_marked_stale(path):
    """Each committed table: its commit is in the history and its code hash matches the code at that commit, or the
    report's Versions section marks it stale (those made before study wrote a code hash, until regenerated)."""
    m = json.loads(path.read_text())
    if not isinstance(m, dict) or "config" not in m:
        pytest.skip("not a table's metadata")
    ok = _independent_check(m)
    mark = sections.code_mark(m)
    assert (mark == "current") == ok, (mark, ok)
    if not ok:
        assert mark.startswith("stale: ")
        rows = sections.versions_section([path.parent])[2][1]
        assert rows[0]["code"] == mark


def test_a_planted_code_change_marks_a_table_stale():
    """A committed-looking table whose code hash was made from other code: stale, though its commit is real."""
    from study.measure import outcomes

    rec = code_record(outcomes)
    head = _git(ROOT, "rev-parse", "HEAD")
    assert sections.code_mark({"git_commit": head, **rec, "code_hash": "0123456789abcdef"}).startswith(
        "stale"
    )
