"""The one exception type users see: a single line naming the file, the key and what is allowed.

Each error carries the exit code the CLI ends with: 2 for bad input (:class:`StudyError`), 3 for a problem of the
environment (:class:`EnvironmentProblem`: libLLVM, GPU, disk full, permissions, memory). ``study check`` ends
with 1 for a regression it found (not an error), and an unexpected exception (a bug) with 4
(:func:`user_error` turns any exception into its one line).
"""

import errno
import os

BAD_INPUT, REGRESSION, ENVIRONMENT, INTERNAL = 2, 1, 3, 4


class StudyError(Exception):
    """Bad input or environment. ``str(err)`` is one line meant for the user; the CLI prints it and exits with
    ``err.code`` (2: bad input)."""

    code = BAD_INPUT

    def __init__(
        self, message: str, *, file: str | None = None, key: str | None = None, code: int | None = None
    ):
        self.file, self.key, self.detail = file, key, message
        if code is not None:
            self.code = code
        where = ": ".join(str(p) for p in (file, key) if p)
        super().__init__(f"{where}: {message}" if where else message)

    def __reduce__(self):  # keeps file, key and code across processes (worker → sweep)
        return _rebuild, (type(self), self.detail, self.file, self.key, self.code)


class EnvironmentProblem(StudyError):
    """The machine, not the input: no usable libLLVM, no GPU, a full or read-only disk, too little memory
    (exit code 3)."""

    code = ENVIRONMENT


def _rebuild(cls, detail, file, key, code):
    return cls(detail, file=file, key=key, code=code)


def plugin_guard(call, *, plugin: bool, exited, failed: str):
    """``call()`` with what a plug-in may do wrong turned into one StudyError line (bad input, exit 2):
    ``sys.exit`` always (``exited(code)`` is the line), an exception where ``plugin`` (``failed``, then the
    exception's type and first line); a StudyError passes as it is, and an exception of study's own code stays a
    bug (exit 4)."""
    try:
        return call()
    except StudyError:
        raise
    except SystemExit as err:
        raise StudyError(exited(err.code)) from None
    except Exception as err:
        if not plugin:
            raise
        first = (str(err).strip().splitlines() or [""])[0][:160]
        raise StudyError(f"{failed}: {type(err).__name__}: {first}") from None


#: errno values that say the path given is wrong (bad input, exit 2); any other OSError is the machine's (exit 3).
_BAD_PATH = {errno.ENOTDIR, errno.EEXIST, errno.EISDIR, errno.ENOENT, errno.ENAMETOOLONG, errno.ELOOP}


def os_problem(err: OSError, what: str, path=None) -> StudyError:
    """An OSError as the one line a user sees: a wrong path is bad input (exit 2), anything else — a full or
    read-only disk, permissions, I/O — a problem of the environment (exit 3)."""
    path = path if path is not None else err.filename
    reason = os.strerror(err.errno) if err.errno else str(err)
    cls = StudyError if err.errno in _BAD_PATH else EnvironmentProblem
    return cls(f"{what} ({reason})", file=str(path) if path is not None else None)


def user_error(err: BaseException) -> StudyError:
    """Any exception as the StudyError a user sees, with its exit code: OSError → :func:`os_problem` (and a
    StudyError raised while handling one of the machine's), out of memory → 3, anything unexpected → an internal
    error (4) naming the exception."""
    if isinstance(err, StudyError):
        ctx = err.__context__  # raised while handling a full disk, a permission, … (e.g. the cache's)
        if err.code == BAD_INPUT and isinstance(ctx, OSError) and ctx.errno and ctx.errno not in _BAD_PATH:
            return EnvironmentProblem(err.detail, file=err.file, key=err.key)
        return err
    if isinstance(err, OSError):
        return os_problem(err, "cannot read or write a file")
    if isinstance(err, UnicodeError):  # a file or directory name (or a file) that is not UTF-8
        bad, a, b = getattr(err, "object", b""), getattr(err, "start", 0), getattr(err, "end", 0)
        near = bad[max(a - 30, 0) : b + 30]  # the name around the offending character
        where = near.decode("utf-8", "backslashreplace") if isinstance(near, bytes) else near
        return EnvironmentProblem(
            f"a file or directory name is not valid UTF-8 (…{where!r}…); rename it or choose another --out"
        )
    if isinstance(err, ModuleNotFoundError):
        return EnvironmentProblem(
            f"a Python package is missing: {err.name} (run `bash scripts/setup.sh`, or pip install it)"
        )
    if _full_disk(err):  # Mitsuba's Bitmap and other C++ writers report these as RuntimeError
        return EnvironmentProblem(f"cannot write a file ({_first(err)})")
    if type(err).__name__ == "KilledWorker":
        return EnvironmentProblem(
            f"a Dask worker died repeatedly ({_first(err)}); too little memory per worker?"
        )
    if isinstance(err, MemoryError):
        return EnvironmentProblem(
            "out of memory; lower the resolution, supersampling or samples, or --max-memory"
        )
    first = _first(err)
    return StudyError(
        f"internal error ({type(err).__name__}: {first}); please report it, `study --debug …` "
        "shows the traceback",
        code=INTERNAL,
    )


_MACHINE_WORDS = (
    "no space left on device",
    "disk quota exceeded",
    "read-only file system",
    "input/output error",
)


def _first(err: BaseException) -> str:
    return (str(err).strip().splitlines() or [""])[0][:200]


def _full_disk(err: BaseException) -> bool:
    text = str(err).lower()
    return isinstance(err, RuntimeError) and any(w in text for w in _MACHINE_WORDS)
