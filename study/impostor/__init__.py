"""Image-based representations that methods search: the one cube-map convention (``cubemap``), a cube map bound
to an array backend (``envmap.EnvMap``), distance impostors captured from a reference point (``capture``: Mitsuba
radiance, exact Embree distances, EXR), depth layers peeled from the same point (``layers``), and analytic
impostors with exact answers for tests (``analytic``). Imports scene, reference and the bottom modules only."""
