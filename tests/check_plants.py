"""Planted regressions for `study check` (a test-only helper, not a test module): each one patches the running
code (pytest's monkeypatch, or any object with its ``setattr``) the way a bug would change a number, without
editing a method's source. Used by tests/measure/test_check_noise.py; a by-hand run:
``python tests/check_plants.py PLANT [--seed N]`` runs the check with one planted and prints what fails."""

from __future__ import annotations

import sys
from collections.abc import Callable
from pathlib import Path

from study.backend import V3
from study.impostor.views import Captured
from study.measure import case, truth
from study.methods.base import Method
from study.methods.localized import Localized


def radiance_times(factor: float) -> Callable:
    """Every method's radiance (what it reads for the shown point) × ``factor``; the references unchanged."""

    def plant(mp) -> None:
        original = Method.trace

        def trace(self, B, env, x, R, **kw):
            tr = original(self, B, env, x, R, **kw)
            tr.radiance = tr.radiance * factor
            return tr

        mp.setattr(Method, "trace", trace)

    return plant


def radiance_times_in(name: str, factor: float) -> Callable:
    """One method's radiance (``name``: every label of that method) × ``factor``; the others and the references
    unchanged (issue 53: classical × 1.03 passed the check)."""

    def plant(mp) -> None:
        original = Method.trace

        def trace(self, B, env, x, R, **kw):
            tr = original(self, B, env, x, R, **kw)
            if self.name == name:
                tr.radiance = tr.radiance * factor
            return tr

        mp.setattr(Method, "trace", trace)

    return plant


def truth_times(factor: float) -> Callable:
    """truth_at_hit's radiance (both its seeds) × ``factor``: the reference every image is measured against."""

    def plant(mp) -> None:
        original = truth.truth_at_hit

        def truth_at_hit(scene, cache, rays):
            t1, t2 = original(scene, cache, rays)
            return t1 * factor, t2 * factor

        mp.setattr(truth, "truth_at_hit", truth_at_hit)

    return plant


def impostor_blurred(mp) -> None:
    """The impostor's radiance blurred by a 3 × 3 box within each cube face (its distances unchanged): what every
    cube-map method reads, and the oracle's map, lose their texel detail (issue 53: it passed the check)."""
    from scipy.ndimage import uniform_filter

    from study.impostor.capture import Impostor

    original = case.impostor

    def impostor(scene, cache, tracer=None):
        imp = original(scene, cache, tracer)
        blurred = uniform_filter(imp.radiance, size=(1, 3, 3, 1), mode="nearest")
        return Impostor(imp.reference, blurred.astype(imp.radiance.dtype), imp.distance)

    mp.setattr(case, "impostor", impostor)


def texel_offset(mp) -> None:
    """Every method's shown point moved sideways by one cube-map texel (2/res of its distance from o, the angle
    of one texel at a face's centre), horizontally (perpendicular to it and to y); its radiance unchanged."""
    original = Method.trace

    def trace(self, B, env, x, R, **kw):
        tr = original(self, B, env, x, R, **kw)
        s, res = tr.shown, Captured.of(env).res
        step = B.length(s) * (2.0 / res) / (B.sqrt(s.x * s.x + s.z * s.z) + 1e-12)
        tr.shown = V3(s.x - s.z * step, s.y, s.z + s.x * step)
        return tr

    mp.setattr(Method, "trace", trace)


def one_iteration_fewer(mp) -> None:
    """``localized`` (and whatever searches with it) runs one false-position iteration fewer than it says."""
    original = Localized.localize

    def localize(self, B, env, x, R):
        fewer = Localized(**{**self.params.model_dump(), "iterations": max(0, self.params.iterations - 1)})
        return original(fewer, B, env, x, R)

    mp.setattr(Localized, "localize", localize)


def one_iteration_more(mp) -> None:
    """``localized`` (and whatever searches with it) runs one false-position iteration more than it says."""
    original = Localized.localize

    def localize(self, B, env, x, R):
        more = Localized(**{**self.params.model_dump(), "iterations": self.params.iterations + 1})
        return original(more, B, env, x, R)

    mp.setattr(Localized, "localize", localize)


def truth_half_samples(mp) -> None:
    """The truth (truth_at_hit: Mitsuba along the exact rays, two seeds) with half its samples per ray; its cache
    key follows the samples, so nothing cached is overwritten."""
    original = truth.truth_at_hit

    def truth_at_hit(scene, cache, rays):
        half = scene.with_updates({"render.spp": max(1, scene.render.spp // 2)})
        return original(half, cache, rays)

    mp.setattr(truth, "truth_at_hit", truth_at_hit)


def mitsuba_half_samples(mp) -> None:
    """Mitsuba's camera render with the object (both seeds) with half its samples; the background unchanged."""
    original = case.camera_render

    def camera_render(scene, cache, *, with_object):
        if with_object:
            scene = scene.with_updates({"render.spp": max(1, scene.render.spp // 2)})
        return original(scene, cache, with_object=with_object)

    mp.setattr(case, "camera_render", camera_render)


PLANTS: dict[str, Callable] = {
    "radiance ×1.02": radiance_times(1.02),
    "radiance ×1.05": radiance_times(1.05),
    "shown point one texel off": texel_offset,
    "localized one iteration fewer": one_iteration_fewer,
    "truth at half its samples": truth_half_samples,
    "Mitsuba at half its samples": mitsuba_half_samples,
    "classical radiance ×1.03": radiance_times_in("classical", 1.03),
    "truth ×1.03": truth_times(1.03),
    "impostor radiance blurred 3×3": impostor_blurred,
    "localized one iteration more": one_iteration_more,
}


class _Patch:
    """monkeypatch's ``setattr`` outside pytest (for the by-hand run)."""

    def setattr(self, obj, name, value):
        setattr(obj, name, value)


if __name__ == "__main__":  # python tests/check_plants.py "radiance ×1.02" [--seed N] [--cache DIR]
    from study.report.check import run_check

    args = sys.argv[1:]
    opt = {a: args[args.index(a) + 1] for a in ("--seed", "--cache") if a in args}
    if args[0] != "none":
        PLANTS[args[0]](_Patch())
    fails, lines = run_check(
        Path("configs/check.toml"),
        cache=opt.get("--cache", ".cache"),
        seed=int(opt["--seed"]) if "--seed" in opt else None,
    )
    print("\n".join(lines))
    print("\n".join(f.message for f in fails))
    print(f"{args[0]}: {len(fails)} failure(s)")
