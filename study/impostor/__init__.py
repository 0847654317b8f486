"""Image-based representations that methods search — views, each with distance (or depth), radiance and a
projection: the one cube-map convention (``cubemap``, "no surface" = ``FAR``), a cube map bound to an array backend
(``envmap.EnvMap``), distance impostors captured from a reference point (``capture``: Mitsuba radiance, exact
Embree distances, EXR), depth layers peeled from the same point (``layers``), cube maps at several points
(``probes``), the camera's own depth and colour buffer (``screen``), the request a method makes for them
(``views.Views``), and analytic impostors with exact answers for tests (``analytic``). Imports scene, reference
and the bottom modules only."""
