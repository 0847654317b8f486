"""Files written and read the one way study does it: atomically, with one clear error per problem.

* :func:`output_set`: a command's whole output set as a transaction: written into a fresh directory beside the
  target and swapped in at the end, so a failed or killed command leaves the previous outputs as they were
  (:func:`locked`: one command at a time per output directory). Study removes or replaces only what it wrote
  itself: each output folder lists the files study wrote there (:data:`OUTPUTS`); a file study did not write is
  never removed (a user's ``exr/mine.txt`` stays), and an empty output path is refused (:func:`out_dir`).
* :func:`atomic_write` / :func:`atomic_savefig` / :func:`write_exr`: a temporary file beside the target, renamed
  over it at the end, so a reader (or a killed run) never sees half a file, and no temporary file is left behind.
* :func:`read_toml`: a TOML file, or a :class:`~study.errors.StudyError` naming the file.
* :func:`json_text`: strict JSON (NaN and ±inf as null), the one way study writes JSON files.
* :func:`write_exr` / :func:`read_exr`: float32 EXR through Mitsuba's ``Bitmap`` (:func:`study.runtime.mitsuba`);
  :func:`exr_bytes` / :func:`layers_exr_bytes` the same in memory (for :func:`write_set`), one file of named
  layers read back by :func:`read_exr_layers`.
* :func:`file_stem` / :func:`file_stems`: the one way a label becomes a file or layer name (no shell syntax).
"""

from __future__ import annotations

import contextlib
import ctypes
import errno
import fcntl
import glob
import os
import re
import shutil
import stat
import sys
import tempfile
import tomllib
from collections.abc import Iterable
from pathlib import Path

import numpy as np

from study import runtime
from study.errors import EnvironmentProblem, StudyError, os_problem
from study.owned import OUTPUTS, carry, in_the_way, out_dir, owned, written_here

__all__ = ["OUTPUTS", "out_dir", "written_here"]  # study.owned's, where output sets are: study.io.OUTPUTS

LOCK = ".lock"
_UMASK = os.umask(0)
os.umask(_UMASK)
_FILE_MODE = 0o666 & ~_UMASK


@contextlib.contextmanager
def _temp_beside(path: Path, suffix: str):
    """A temporary file name beside ``path``; renamed over ``path`` if the block succeeds, removed otherwise."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.stem}.", suffix=suffix)
    os.close(fd)
    os.chmod(tmp, _FILE_MODE)  # mkstemp's 0600 → what open() would have made (umask)
    try:
        yield tmp
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)


def text_bytes(data: bytes | str) -> bytes:
    """``data`` as bytes: text as UTF-8, where a file name that is not UTF-8 (Python's surrogate escapes) shows
    as ``\\udcff`` instead of making the file unwritable."""
    return data.encode("utf-8", "backslashreplace") if isinstance(data, str) else data


def atomic_write(path: str | Path, data: bytes | str) -> None:
    """Write ``data`` to ``path`` atomically (temporary file + rename)."""
    path = Path(path)
    with _temp_beside(path, ".tmp") as tmp:
        Path(tmp).write_bytes(text_bytes(data))


def atomic_savefig(fig, path: str | Path, *, dpi: int = 110) -> None:
    """Save a matplotlib figure as PNG atomically (:func:`png_bytes`), then close it."""
    data = png_bytes(fig, dpi=dpi)
    with _temp_beside(Path(path), ".png") as tmp:
        Path(tmp).write_bytes(data)


def png_bytes(fig, *, dpi: int = 110) -> bytes:
    """A matplotlib figure as PNG bytes (then closed): matplotlib's RGBA stored as RGB where every pixel is opaque
    (a figure on its white face: the same pixels), deflated by PIL's optimizer (the tracked figures 10 % lighter)."""
    import io

    import matplotlib.pyplot as plt
    from PIL import Image

    buf, out = io.BytesIO(), io.BytesIO()
    try:
        fig.savefig(buf, dpi=dpi, format="png")
    finally:
        plt.close(fig)
    im = Image.open(buf)
    if im.mode == "RGBA" and im.getchannel("A").getextrema() == (255, 255):
        im = im.convert("RGB")
    im.save(out, format="png", optimize=True)
    return out.getvalue()


def read_toml(path: str | Path, *, what: str = "config file") -> dict:
    """The TOML file at ``path`` as a dict; a missing, unreadable or invalid file is one StudyError that calls
    the file ``what``."""
    path = Path(path)
    try:
        return tomllib.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise StudyError(f"{what} not found", file=str(path)) from None
    except IsADirectoryError:
        raise StudyError(f"is a directory, expected a {what} (TOML)", file=str(path)) from None
    except UnicodeDecodeError:
        raise StudyError(f"not UTF-8 text, expected a {what} (TOML)", file=str(path)) from None
    except tomllib.TOMLDecodeError as err:
        raise StudyError(f"not valid TOML ({err})", file=str(path)) from None


def read_json(path: str | Path, *, what: str = "JSON file"):
    """The JSON file at ``path``: an OSError or ValueError (invalid JSON, not UTF-8) as the caller handles it, but
    one nested too deeply for Python's parser (``[[[[…]]]]`` 10⁵ deep: RecursionError, a bug's exit 4) is one
    StudyError naming the file (bad input, exit 2)."""
    import json

    text = Path(path).read_text(encoding="utf-8")
    try:
        return json.loads(text)
    except RecursionError:
        raise StudyError(
            f"malformed {what}: its arrays or objects nest too deeply to read; not a file study wrote",
            file=str(path),
        ) from None


def json_text(obj, *, nonfinite: str = "null", **kw) -> str:
    """``obj`` as strict JSON (``allow_nan=False``: no ``NaN``/``Infinity`` tokens, which most parsers refuse): NaN
    and ±inf become null (``nonfinite="text"``: the strings "NaN", "Infinity", "-Infinity", which ``float()`` reads
    back), numpy scalars and arrays plain numbers and lists. ``kw`` goes to :func:`json.dumps`."""
    import json

    def plain(v):
        if isinstance(v, dict):
            return {k: plain(x) for k, x in v.items()}
        if isinstance(v, (list, tuple, np.ndarray)):
            return [plain(x) for x in (v.tolist() if isinstance(v, np.ndarray) else v)]
        if isinstance(v, np.generic):
            v = v.item()
        if isinstance(v, float) and not np.isfinite(v):
            return None if nonfinite == "null" else "NaN" if v != v else "Infinity" if v > 0 else "-Infinity"
        return v

    return json.dumps(plain(obj), allow_nan=False, **kw)


def write_exr(path: str | Path, array: np.ndarray) -> None:
    """Write an (H, W, C) float32 array as EXR through Mitsuba's Bitmap, atomically."""
    mi = runtime.mitsuba()
    with _temp_beside(Path(path), ".exr") as tmp:
        mi.Bitmap(np.ascontiguousarray(array, np.float32)).write(tmp)


def exr_bytes(array: np.ndarray, channels: list[str] | None = None) -> bytes:
    """An (H, W, C) float32 array as the bytes of an EXR file (made in memory: an output set then only writes
    them). ``channels``: the channels' names (``["classical.R", "classical.G", …, "mask.Y"]``: layers as
    name prefixes, as tev and OpenEXR's tools group them); without it, Y / RGB / RGBA by C."""
    mi = runtime.mitsuba()
    a = np.ascontiguousarray(array, np.float32)
    if channels is None:
        bmp = mi.Bitmap(a)
    else:
        if len(channels) != a.shape[-1]:
            raise ValueError(f"{len(channels)} channel names for {a.shape[-1]} channels")
        bmp = mi.Bitmap(a, pixel_format=mi.Bitmap.PixelFormat.MultiChannel, channel_names=list(channels))
    s = mi.MemoryStream()
    bmp.write(s, mi.Bitmap.FileFormat.OpenEXR)
    # the stream's buffer, its first size() bytes: read() took 2.2 s for a 1024² case's 486 MB, raw_buffer 0.3 s
    n, buf = s.size(), s.raw_buffer()
    return buf if len(buf) == n else buf[:n]


def layers_exr_bytes(layers: dict[str, np.ndarray]) -> bytes:
    """One multi-layer EXR of named images (layer name → (H, W) or (H, W, 1 | 3) array): channels
    ``<layer>.Y`` or ``<layer>.R/.G/.B``; :func:`read_exr_layers` reads it back."""
    arrays, names = [], []
    for name, a in layers.items():
        a = np.asarray(a)
        a = a[..., None] if a.ndim == 2 else a
        if a.shape[-1] not in (1, 3):
            raise ValueError(f"layer {name!r} has {a.shape[-1]} channels; 1 or 3 allowed")
        arrays.append(a)
        names += [f"{name}.Y"] if a.shape[-1] == 1 else [f"{name}.{c}" for c in "RGB"]
    if len(sizes := {a.shape[:-1] for a in arrays}) != 1:
        raise ValueError(f"layers of different sizes, or none: {sorted(sizes)}")
    # each layer cast into its channels of one buffer: one copy, not two
    out = np.empty((*sizes.pop(), len(names)), np.float32)
    for a, k in zip(arrays, np.cumsum([0] + [a.shape[-1] for a in arrays])):
        out[..., k : k + a.shape[-1]] = a
    return exr_bytes(out, names)


def read_exr_layers(path: str | Path) -> dict[str, np.ndarray]:
    """The layers of a multi-layer EXR (:func:`layers_exr_bytes`) as name → (H, W, C) float32; a missing or
    damaged file is a StudyError."""
    mi = runtime.mitsuba()
    if not Path(path).is_file():
        raise StudyError("EXR file not found", file=str(path))
    try:
        out = {}
        for name, bmp in mi.Bitmap(str(path)).split():
            a = np.array(bmp, dtype=np.float32)
            out[name] = a if a.ndim == 3 else a[..., None]
        return out
    except Exception as err:
        raise StudyError(f"unreadable EXR ({str(err).splitlines()[0][:120]})", file=str(path)) from None


def file_stem(label: str) -> str:
    """The one file (and EXR layer) name study gives a method label or case: letters, digits and ``.``, ``_``,
    ``-`` kept, every other run of characters one ``-`` (``localized(iterations=10)`` →
    ``localized-iterations-10``): nothing a shell would read as syntax."""
    return re.sub(r"[^A-Za-z0-9._-]+", "-", str(label)).strip("-.") or "_"


def file_stems(labels: Iterable[str]) -> dict[str, str]:
    """:func:`file_stem` of each distinct label, made distinct where two labels give one stem (``a b`` and
    ``a-b``: the later one gets ``-2``, ``-3``, …), compared without case (case-insensitive file systems)."""
    out: dict[str, str] = {}
    taken: set[str] = set()
    for lab in labels:
        if lab in out:
            continue
        stem, k = file_stem(lab), 2
        name = stem
        while name.lower() in taken:
            name, k = f"{stem}-{k}", k + 1
        out[lab] = name
        taken.add(name.lower())
    return out


def read_exr(path: str | Path) -> np.ndarray:
    """Read an EXR as an (H, W, C) float32 array; a missing or damaged file is a StudyError."""
    mi = runtime.mitsuba()
    if not Path(path).is_file():
        raise StudyError("EXR file not found", file=str(path))
    try:
        a = np.array(mi.Bitmap(str(path)), dtype=np.float32)
    except Exception as err:
        raise StudyError(f"unreadable EXR ({str(err).splitlines()[0][:120]})", file=str(path)) from None
    return a if a.ndim == 3 else a[..., None]


# ---------------------------------------------------------------------------------------------- output sets
@contextlib.contextmanager
def locked(out: str | Path):
    """Hold ``<out>/.lock`` (created, and removed again at the end) so that one study command at a time writes to
    ``out``; a second one stops at once with a clear message. ``out`` is created if needed (and removed again if
    the block fails and leaves it empty); an empty path is refused (:func:`out_dir`)."""
    out = out_dir(out)
    top = _make_dir(out)
    try:
        if not os.access(out, os.W_OK | os.X_OK):
            raise EnvironmentProblem("the output directory is not writable", file=str(out))
        path, f = out / LOCK, None
        try:  # an interrupt anywhere after the lock file is opened still removes it (if no one else holds it)
            while True:
                try:
                    f = open(path, "a+")
                except OSError as err:
                    raise os_problem(err, "cannot lock the output directory", out) from None
                try:
                    fcntl.flock(f, fcntl.LOCK_EX | fcntl.LOCK_NB)
                except BlockingIOError:
                    f.close()
                    f = None
                    raise EnvironmentProblem(
                        "another study command is writing to this directory; wait for it or choose another --out",
                        file=str(out),
                    ) from None
                if _same_file(path, f):  # not a lock file that its last holder removed meanwhile
                    break
                f.close()
                f = None
            yield
        finally:
            # interrupted between creating the lock file and holding it: remove it if no one holds it
            if f is None:
                with contextlib.suppress(OSError):
                    f = open(path)
            if f is not None:
                with contextlib.suppress(OSError):
                    fcntl.flock(f, fcntl.LOCK_EX | fcntl.LOCK_NB)  # a no-op if held; if free, ours now
                    if _same_file(path, f):
                        os.unlink(path)
                f.close()
    except BaseException:
        _remove_created(out, top)
        raise


def _same_file(path: Path, f) -> bool:
    try:
        a, b = os.stat(path), os.fstat(f.fileno())
    except OSError:
        return False
    return (a.st_dev, a.st_ino) == (b.st_dev, b.st_ino)


def _make_dir(out: Path) -> Path | None:
    """Create ``out`` (and its parents); the topmost directory created, or None if it existed."""
    top = None
    for p in [out, *out.parents]:
        if p.exists():
            break
        top = p
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise os_problem(err, "cannot create the output directory", out) from None
    return top


def _remove_created(out: Path, top: Path | None) -> None:
    """Remove the empty directories :func:`_make_dir` created, from ``out`` up to ``top``."""
    if top is None:
        return
    for p in [out, *out.parents]:
        try:
            p.rmdir()
        except OSError:
            return
        if p == top:
            return


@contextlib.contextmanager
def output_set(
    out: str | Path,
    owns: Iterable[str] = (),
    *,
    keeps: Iterable[str] = (),
    lock: bool = True,
    swap: bool = True,
):
    """A command's outputs as one transaction: ``with output_set(out, owns) as tmp:`` write every output into the
    fresh directory ``tmp`` (beside ``out``); when the block succeeds they replace the command's outputs in ``out``
    together, when it fails (or the process is killed) ``out`` is left as it was and ``tmp`` goes.

    ``owns``: paths relative to ``out`` (files or directories) that belong to the command even if this run does
    not write them: the files under them that study wrote there before (:data:`OUTPUTS`) are removed (no stale
    plot beside a new table); whatever ``tmp`` holds replaces the file of its name. Everything else in ``out`` is
    kept: a file study did not write is never removed, even inside an owned directory (``exr/mine.txt``), and a
    folder or file of the user's where an output would go is one StudyError before anything changes. The swap is
    one ``renameat2(RENAME_EXCHANGE)`` of the two directories after the kept entries are hard-linked into ``tmp``,
    so a reader sees all old or all new outputs; it is used when every kept entry is a file or a directory named
    in ``keeps`` (e.g. a sweep's ``cases``); otherwise, or where the platform cannot exchange, or with
    ``swap=False`` (a directory others write into, e.g. ``reports/``), the outputs are renamed into place one by
    one. ``out`` is locked for the block (:func:`locked`) unless ``lock`` is False (the caller holds the lock)."""
    out = out_dir(out).absolute()
    if out.is_symlink():
        out = out.resolve()  # swap the directory it names, not the link
    with contextlib.suppress(OSError):  # never exchange the working directory away from under us
        if Path.cwd().is_relative_to(out.resolve()):
            swap = False
    with locked(out) if lock else contextlib.nullcontext():
        for stale in _stale_temps(out):  # left by a killed run (the lock is held)
            shutil.rmtree(stale, ignore_errors=True)
        try:
            tmp = Path(tempfile.mkdtemp(dir=out.parent, prefix=f".{out.name}.new-"))
            os.chmod(tmp, 0o777 & ~_UMASK)  # mkdtemp's 0700 → a directory as mkdir would make it
        except OSError as err:
            raise os_problem(err, "cannot write beside the output directory", out.parent) from None
        try:
            yield tmp
            (c := sys.modules.get("study.cache")) and c.flush()  # cache writes done: a failed one fails here
            try:
                _commit(tmp, out, set(owns), set(keeps), swap)
            except OSError as err:
                raise os_problem(err, "cannot put the outputs in place", out) from None
        finally:
            shutil.rmtree(tmp, ignore_errors=True)


def write_set(
    out: str | Path,
    files: dict[str, bytes | str],
    owns: Iterable[str] = (),
    *,
    keeps: Iterable[str] = (),
    lock: bool = True,
    swap: bool = True,
) -> list[Path]:
    """:func:`output_set` of outputs made beforehand (relative path → content): the temporary directory then
    lives only while they are written and swapped in (milliseconds), so even a SIGKILL almost never leaves it
    behind, and the next command on ``out`` removes one it left. Returns the paths written."""
    with output_set(out, [*owns, *files], keeps=keeps, lock=lock, swap=swap) as tmp:
        for rel, data in files.items():
            (tmp / rel).parent.mkdir(parents=True, exist_ok=True)
            (tmp / rel).write_bytes(text_bytes(data))
    return [Path(out) / rel for rel in files]


def _stale_temps(out: Path) -> list[Path]:
    """The temporary directories an earlier run on ``out`` left (``.<name>.new-`` and mkdtemp's characters, no
    dot), and no others: a sibling output named ``<name>.new-x`` has temporaries ``.<name>.new-x.new-…``, alive."""
    pat = re.compile(re.escape(f".{out.name}.new-") + r"[A-Za-z0-9_]+")
    return [p for p in out.parent.glob(f".{glob.escape(out.name)}.new-*") if pat.fullmatch(p.name)]


_RENAME_EXCHANGE = 2


def _exchange(a: Path, b: Path) -> bool:
    """Swap two directories atomically (Linux renameat2); False where the platform or file system cannot."""
    try:
        fn = ctypes.CDLL(None, use_errno=True).renameat2
    except (OSError, AttributeError):
        return False
    if fn(-100, os.fsencode(a), -100, os.fsencode(b), _RENAME_EXCHANGE) == 0:  # AT_FDCWD = -100
        return True
    e = ctypes.get_errno()
    if e in (errno.EINVAL, errno.ENOSYS, errno.EOPNOTSUPP, errno.EXDEV):
        return False
    raise OSError(e, os.strerror(e), str(b))


def _commit(tmp: Path, out: Path, owns: set[str], keeps: set[str], swap: bool = True) -> None:
    """Put the outputs in ``tmp`` in place in ``out`` (see :func:`output_set`): the files of ``tmp`` replace those
    of their names, the files study wrote before under ``owns`` (:func:`written_here`) and does not write again
    go, and the list :data:`OUTPUTS` is brought up to date. Nothing study did not write is removed."""
    new = {p.relative_to(tmp).as_posix() for p in tmp.rglob("*") if not p.is_dir()} - {OUTPUTS}
    listed = written_here(out)
    in_the_way(out, new, listed)
    stale = {r for r in listed if owned(r, owns) and r not in new and r != OUTPUTS}
    (tmp / OUTPUTS).write_bytes(
        text_bytes(json_text({"written_by": "study", "files": sorted((listed - stale) | new)}, indent=1))
    )
    owns = new | stale | {OUTPUTS}  # files only: a directory is never replaced whole
    os.chmod(tmp, stat.S_IMODE(os.stat(out).st_mode))
    if swap and carry(out, tmp, "", owns, keeps) and _exchange(tmp, out):
        return  # tmp now holds the old outputs; the caller removes it
    for rel in sorted(owns):  # one by one: each rename is atomic, the set is not
        new_file, old = tmp / rel, out / rel
        if new_file.exists() or new_file.is_symlink():
            for parent in reversed(Path(rel).parents):  # an earlier output file where a folder now goes
                q = out / parent
                if parent.name and (q.is_symlink() or q.exists()) and not q.is_dir():
                    os.unlink(q)
            old.parent.mkdir(parents=True, exist_ok=True)
            os.replace(new_file, old)
        elif (old.is_symlink() or old.exists()) and not old.is_dir():
            os.unlink(old)
            for parent in Path(rel).parents:  # folders emptied by it go too (up to out)
                if not parent.name:
                    break
                try:
                    (out / parent).rmdir()
                except OSError:
                    break
