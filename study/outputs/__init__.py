"""What a case or a figure produces: figure grids (``figures``) with per-case EXRs and viewer images (``viewer``,
``case_images``), error curves (``plots``), the glossy split (``glossy``), convergence curves (``convergence``), the
motion study (``animation``), a run's own files (``run_files``) and the page format they share (``html``,
``markup``). What reads finished tables and writes the report lives one floor up, in :mod:`study.report`."""
