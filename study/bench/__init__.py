"""``study bench``: every method timed side by side with exact ray casting of the same rays.

Modules, bottom to top:
    batches : the ray batches (fig4, close-up, synthetic), the room's triangles (+ heightfield), impostor texels
    timing  : the timing harness (median of repeats, device synced) for methods, Embree and Mitsuba
    machine : CPU, GPU, package versions, the backends available here
    scaling : cost vs rays, knob value, cube resolution and scene complexity
    run     : :class:`BenchOptions` and :func:`run_bench` (the main table, then the scaling studies)
    output  : the CSV, Markdown and PNG files
"""
