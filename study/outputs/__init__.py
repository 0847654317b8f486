"""What people read, made from results tables only: figure grids (``figures``) with per-case EXRs and viewer images
(``viewer``), error curves (``plots``), the paper's claims as checks (``claims``), the CI regression check against a
baseline (``check``), the report as Markdown and HTML with image viewers (``report``, ``html``) and the motion
study (``animation``)."""
