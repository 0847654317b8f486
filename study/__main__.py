"""``python -m study``: the ``study`` command (:func:`study.cli.main`)."""

from study.cli import main

main()
