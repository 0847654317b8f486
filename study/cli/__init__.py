"""The ``study`` command line: :mod:`~study.cli.app` holds the application, its global options and exit codes;
each other module registers one group of commands on it (a new command is a new module listed in :func:`_load`).

Every error prints one line (``error: <file>: <key>: <what is allowed>``), never a traceback (``study --debug``
shows it), and ends with a distinct exit code: 2 bad input, 3 a problem of the environment (libLLVM, GPU, disk
full, permissions, memory, encoding, network), 1 a regression found by ``check``, 4 an internal error (a bug),
130 interrupted.

This module stays light: the executable's :func:`main` first makes Ctrl-C and SIGTERM during start-up (importing
Typer, numpy, the methods) end the process at once with ``error: interrupted`` and exit 130 — nothing has been
written yet, and an interrupt inside the import machinery would otherwise surface as a ``SystemError`` or a
traceback — then imports the application.
"""

import os
import signal
import sys

__all__ = ["app", "main"]


def _interrupted_at_start(signum, frame):
    sys.stderr.write("error: interrupted\n")
    sys.stderr.flush()
    os._exit(130)


def _load():
    """Import the application and its commands; ``study.cli.app`` names the Typer application from then on."""
    from study.cli import animate, cache, commands, convergence, run  # noqa: F401  (register their commands)
    from study.cli.app import app

    globals()["app"] = app
    return app


def main() -> None:
    """The ``study`` executable (see :func:`study.cli.app.main`)."""
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, _interrupted_at_start)
    _load()
    from study.cli.app import main as run_app

    signal.signal(signal.SIGINT, signal.default_int_handler)  # from here on: KeyboardInterrupt, cleaned up
    run_app()


def __getattr__(name: str):
    if name == "app":
        return _load()
    raise AttributeError(f"module 'study.cli' has no attribute {name!r}")
