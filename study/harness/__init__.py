"""Running many cases: figure and sweep configs (``config``: scenes, methods — ``"all"`` by default — and
overrides), sweep expansion into cases with content keys (``sweep``), the resource guard that checks every case's
view, memory and time before anything runs (``budget``), and running them in this process, in local processes or
on Dask, with resume, locking and the results table (``runner``)."""
