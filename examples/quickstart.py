"""study from Python: load a scene, register a method of your own, evaluate, look at the numbers, save.

    .venv/bin/python examples/quickstart.py [OUT]      # OUT: where to save (default reports/quickstart)

Runs in about 15 s on 2 cores: a tiny version of the shipped room (32 × 32 pixels, 16² cube faces, few samples).
Every line works the same in a notebook cell (there, ``res`` alone shows the table and thumbnails).
"""

import sys

import study
from study.methods import Localization, Method, register

# ----------------------------------------------------------------------------------------------- a scene
# A shipped scene, found from any working directory, with dotted-key overrides (any key of the scene TOML).
scene = study.load_scene(
    "scenes/room.toml",
    **{
        "render.cube_res": 16,
        "render.cube_spp": 4,
        "render.spp": 4,
        "render.supersample": 1,
        "camera.width": 32,
        "camera.height": 32,
        "object.center": [0.6, 1.2, 0.3],
        "object.radius": 0.4,
    },
)
# Other sources: study.load_scene("scenes/meshes/bunny.obj") would take a mesh file as the environment, and
# study.load_scene(mitsuba.cornell_box()) a Mitsuba scene dict (see README, "Python API").


# ----------------------------------------------------------------------------------------------- a method of your own
@register
class HalfwayProbe(Method):
    """Look the reflected ray up as if the environment were twice as far as the reference point's distance to
    the shading point: a toy between classical (infinitely far) and a proxy."""

    name = "halfway_probe"

    def localize(self, B, env, x, R):
        # x: shading points relative to the reference point, R: unit reflected directions (backend vectors);
        # the method answers with l, the direction from the reference point in which to look up the impostor
        return Localization(l=x + R * (2.0 * B.length(x)), valid=B.isfinite(B.length(R)))

    def lookups_per_ray(self):
        return 1


# ----------------------------------------------------------------------------------------------- evaluate
# methods="all" is every registered method (the one just registered too); a list picks some, by name or label.
res = study.evaluate(scene, methods=["classical", "localized(iterations=3)", "halfway_probe"], cache=None)
print(res)  # the leading columns; res.table holds them all (pandas)

table = res.table.set_index("label")
assert "halfway_probe" in table.index  # the notebook's method was measured beside the built-in ones
assert "halfway_probe" in [m.name for m in study.method_list("all")]  # and methods="all" would include it
best = table.drop(index=["oracle_map", "truth_at_hit"])["angle_median_deg"].idxmin()
print(f"closest to the exact hits: {best}")

err = res.error_maps["classical"]  # (H, W) per-pixel RMS radiance error against truth_at_hit
flip = res.flip_maps["classical"]  # (H, W) FLIP against truth_at_hit; NaN off the object
print(f"classical: mean per-pixel error {err[res.mask].mean():.3f}, mean FLIP {flip[res.mask].mean():.3f}")

out = sys.argv[1] if len(sys.argv) > 1 else "reports/quickstart"
res.save(out)  # table.csv/.parquet, exr/run.exr (every image and map a layer), run.png, index.html
print(f"saved to {out}")
