"""The ``study`` application: global options, one-line errors and exit codes, and the executable's ``main``.

Commands live beside this module (one module per group) and register themselves on :data:`app`.

Every error prints one line (``error: <file>: <key>: <what is allowed>``), never a traceback (``study --debug``
shows it), and ends with a distinct exit code: 2 bad input, 3 a problem of the environment (libLLVM, GPU, disk
full, permissions, memory, another command writing to the same directory), 1 a regression found by ``check``,
4 an internal error (a bug), 130 interrupted.
"""

from __future__ import annotations

import functools
import signal
import sys
from pathlib import Path

import typer
from rich.console import Console

from study import __version__, methods, progress, runtime
from study.errors import StudyError, user_error
from study.harness import budget
from study.harness.config import shipped

app = typer.Typer(
    add_completion=False,
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    help="Measure how close GPU-friendly approximations of ray tracing come to ray tracing.",
)
#: Markup off: names, labels and paths are printed as they are (a ``[/x]`` in a case name is text, not a style).
err_console = Console(stderr=True, markup=False)
console = Console(markup=False)
#: Where the output is no terminal (a log, a pipe), lines and tables are never cut to fit 80 columns.
LOG_WIDTH = 100_000


def _wide_when_logged() -> None:
    for c in (console, err_console):
        if not c.is_terminal:
            c.width = LOG_WIDTH


def _version(value: bool) -> None:
    if value:
        console.print(f"study {__version__}", highlight=False)
        raise typer.Exit()


#: Global options of this run (set by the callback before the command).
DEBUG = {"on": False}
QUIET = {"on": False}


@app.callback()
def _options(
    ctx: typer.Context,
    plugin: list[str] = typer.Option(
        [],
        "--plugin",
        metavar="MODULE",
        help="import MODULE first: methods it registers join every command (repeatable; also $STUDY_PLUGINS)",
    ),
    debug: bool = typer.Option(False, "--debug", help="show the traceback of an error"),
    quiet: bool = typer.Option(
        False,
        "--quiet",
        "-q",
        help="no progress lines on stderr (stages, times, ETA); tables and errors stay",
    ),
    max_memory: float = typer.Option(
        budget.DEFAULT_MAX_MEMORY_GIB,
        "--max-memory",
        metavar="GIB",
        help="refuse a case estimated to need more memory (GiB)",
    ),
    max_minutes: float = typer.Option(
        budget.DEFAULT_MAX_MINUTES,
        "--max-minutes",
        metavar="MIN",
        help="refuse a command estimated to take longer, and stop one that runs longer (minutes)",
    ),
    version: bool = typer.Option(
        False, "--version", callback=_version, is_eager=True, help="print the version and exit"
    ),
):
    """Measure how close GPU-friendly approximations of ray tracing come to ray tracing."""
    DEBUG["on"] = debug
    QUIET["on"] = quiet
    _wide_when_logged()
    try:
        budget.set_limits(max_memory, max_minutes)
        ctx.call_on_close(budget.set_limits)  # this command's limits end with it (one process, many commands)
        methods.load_plugins(plugin)
    except StudyError as err:
        _fail(err)


def figures() -> dict[str, str]:
    """The figures ``study figure NAME`` makes: every ``configs/fig*.toml`` (name: the file's stem), shipped with
    study or in ``configs/`` under the working directory (that one wins, :func:`shipped`) → its config path."""
    from study.harness.config import ROOT

    names = {p.stem for d in (ROOT / "configs", Path("configs")) for p in d.glob("fig*.toml")}
    return {n: str(shipped(Path("configs") / f"{n}.toml")) for n in sorted(names)}


def _line(text: str) -> str:
    return " ".join(str(text).split()) or "(no message)"


def _fail(err: StudyError) -> None:
    from rich.text import Text

    err_console.print(
        Text("error: ", style="bold red") + Text(_line(str(err))), highlight=False, soft_wrap=True
    )
    raise typer.Exit(err.code)


def guarded(llvm: bool = False):
    """A command whose errors are one line each (:func:`study.errors.user_error`) and whose progress goes to
    stderr by stage (:mod:`study.cli.progress`, unless ``--quiet``); ``llvm``: it renders, so the libLLVM that
    Mitsuba and Dr.Jit will load is checked first (exit 3 where it would abort the process)."""

    def wrap(fn):
        @functools.wraps(fn)
        def run(*args, **kwargs):
            try:
                if llvm:
                    runtime.require()
                cuda = (
                    "cuda" if kwargs.get("backend") == "cuda" else None
                )  # renders and exact hits on the GPU too
                with runtime.using_render_device(cuda), progress.reporting(_reporter()), budget.time_limit():
                    out = fn(*args, **kwargs)  # past --max-minutes: stopped at a checkpoint, exit 3
                    if "study.cache" in sys.modules:  # its entries on disk: a failed write is this command's
                        sys.modules["study.cache"].flush()
                    return out
            except (typer.Exit, typer.Abort, typer.TyperException):
                raise
            except KeyboardInterrupt:
                if DEBUG["on"]:
                    raise
                raise typer.Exit(130) from None  # main() says so: Typer turns an interrupt anywhere into 130
            except Exception as err:
                if DEBUG["on"]:
                    raise
                _fail(user_error(err))

        return run

    return wrap


def _reporter():
    """Progress by stage on stderr (:mod:`study.cli.progress`), or none with ``--quiet``."""
    from study.cli.progress import reporter

    return None if QUIET["on"] else reporter(err_console)


def _interrupt(signum, frame):
    raise KeyboardInterrupt


def main() -> None:
    """The ``study`` executable: like ``app()``, but usage errors too are one line (exit 2), and SIGTERM
    interrupts like Ctrl-C (the output sets of :mod:`study.io` then clean up)."""
    signal.signal(signal.SIGTERM, _interrupt)
    try:
        rc = app(standalone_mode=False)
    except typer.Abort:
        err_console.print("error: interrupted", highlight=False)
        sys.exit(130)
    except typer.TyperException as err:  # bad option or argument: one line, not a panel
        msg = err.format_message() if hasattr(err, "format_message") else str(err)
        hint = f"{err.param_hint}: " if isinstance(getattr(err, "param_hint", None), str) else ""
        err_console.print(f"error: {_line(hint + msg)}", highlight=False, soft_wrap=True, markup=False)
        sys.exit(getattr(err, "exit_code", 2))
    except KeyboardInterrupt:
        err_console.print("error: interrupted", highlight=False)
        sys.exit(130)
    except StudyError as err:  # raised outside a command's own handler
        err_console.print(f"error: {_line(str(err))}", highlight=False, soft_wrap=True, markup=False)
        sys.exit(err.code)
    if rc == 130:  # interrupted in a command, or around one (parsing, the callback): Typer's silent Exit(130)
        err_console.print("error: interrupted", highlight=False)
    sys.exit(rc if isinstance(rc, int) else 0)
