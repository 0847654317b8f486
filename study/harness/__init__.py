"""Running many cases: figure and sweep configs (``config``: scenes, methods — ``"all"`` by default — and
overrides), sweep expansion into cases with content keys (``sweep``), and running them in this process, in local
processes or on Dask, with resume, locking and the results table (``runner``)."""
