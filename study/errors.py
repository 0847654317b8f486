"""The one exception type users see: a single line naming the file, the key and what is allowed."""


class StudyError(Exception):
    """Bad input or environment. ``str(err)`` is one line meant for the user; the CLI prints it and exits 2."""

    def __init__(self, message: str, *, file: str | None = None, key: str | None = None):
        self.file, self.key, self.detail = file, key, message
        where = ": ".join(str(p) for p in (file, key) if p)
        super().__init__(f"{where}: {message}" if where else message)
