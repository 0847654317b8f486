"""One case end to end (``case.run_case``): its inputs (impostor, renders, the object's secondary rays), every
method traced on the same rays, the exact references (Embree hits, the oracle), and the metrics (``metrics``)
that turn them into one row per method."""
