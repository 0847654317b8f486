"""The ``study`` command line: :mod:`~study.cli.app` holds the application, its global options and exit codes;
each other module registers one group of commands on it (a new command is a new module imported here).

Every error prints one line (``error: <file>: <key>: <what is allowed>``), never a traceback (``study --debug``
shows it), and ends with a distinct exit code: 2 bad input, 3 a problem of the environment (libLLVM, GPU, disk
full, permissions, memory, another command writing to the same directory), 1 a regression found by ``check``,
4 an internal error (a bug), 130 interrupted.
"""

from study.cli import animate, cache, commands, run  # noqa: F401  (register their commands)
from study.cli.app import app, main

__all__ = ["app", "main"]
