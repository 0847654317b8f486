"""Everything that reads finished results tables and writes the report: the headline (``summary``), the paper's
claims as checks and their register (``claims``, ``claims_convergence``, ``claims_glossy``, ``verdicts``,
``register``), how much each table can tell (``power``), the equal-cost front (``pareto``), the CI regression check
(``check``), the report's sections and pages (``sections``, ``report``), and the figure kinds (``kinds``: one file
each, with its runner, its files and its report section). It sits above :mod:`study.outputs`, :mod:`study.bench`
and :mod:`study.caustics` (an import-linter layer: nothing below imports it)."""
