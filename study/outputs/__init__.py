"""What people read, made from results tables only: figure grids (``figures``), error curves (``plots``), the
paper's claims as checks (``claims``), the CI regression check against a baseline (``check``) and the report
(``report``)."""
