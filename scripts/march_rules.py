"""The hierarchical march's rules against their alternatives, by lookups per ray (issue 56; no timing).

    PYTHONPATH=. python scripts/march_rules.py [--scene-res 512] [--cube-res 256] [--trace-res 128]

For every first block (:data:`study.methods.march.FIRST`: 16, 64, the widest) with and without the second read at
a surface (:data:`study.methods.march.AT_SURFACE`), linear_secant(1) and layered(1) on LLVM on the bench's close-up
batch and on its random rays near o (scripts/march_side.py's setup): the mean lookups per ray, the mean over
32-ray warps (consecutive rays) of the warp's most, and the most of any ray. The shown points must not change with
the rules (only cleared samples are skipped): the script says where they do.

Then a trace of linear_secant's march on numpy (``--trace-res``² close-up rays, the widest first block, without and
with the second read at a surface): the mean
iterations per ray, the pyramid reads among them and those that cleared nothing (the march stayed at its sample),
counted from the states that the march's branch (``B.branch`` of :func:`study.methods.march.march`) receives.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from march_side import setup  # noqa: E402


def trace(m, B, tex, x, R, info, runner):
    """(shown, lookups per ray) of method ``m`` on these rays."""
    call, finish = runner(m, B, tex, x, R, frozen=False, info=info, screen=None, probe_sets={})
    out = call()
    finish(out)
    return B.to_numpy(out[0]), np.asarray(B.numpy(out[4]), float)


def rules(a) -> None:
    from study import methods
    from study.bench.timing import method_runner
    from study.methods import march

    print(
        "batch      method         first   at surface   lookups  warp-32 most  most  shown as the first rule's"
    )
    for synthetic in (False, True):
        B, tex, batch, o, info, *_ = setup("llvm", a.scene_res, a.cube_res, 1, False, synthetic)
        x, R = batch.x - o, batch.R
        for name in ("linear_secant", "layered"):
            first_shown = None
            for first in (16, 64, None):
                for at in (False, True):
                    march.FIRST, march.AT_SURFACE = first, at
                    shown, spent = trace(
                        methods.make(name, steps_per_texel=1.0), B, tex, x, R, info, method_runner
                    )
                    first_shown = shown if first_shown is None else first_shown
                    same = np.array_equal(shown, first_shown, equal_nan=True)
                    warp = spent[: len(spent) // 32 * 32].reshape(-1, 32).max(1).mean()
                    print(
                        f"{'random' if synthetic else 'close-up':10s} {name:14s} {str(first or 'widest'):7s} "
                        f"{str(at):12s} {spent.mean():8.2f} {warp:13.2f} {spent.max():5.0f}  "
                        f"{'same' if same else 'DIFFER'}",
                        flush=True,
                    )
    march.FIRST, march.AT_SURFACE = None, True


def steps(a) -> None:
    from study import methods
    from study.bench.timing import method_runner
    from study.methods import march

    B, tex, batch, o, info, *_ = setup("numpy", a.trace_res, a.cube_res, 1, False)
    x, R = batch.x - o, batch.R
    plain = type(B).branch
    for at in (False, True):
        seen = []

        def branch(
            self, cond, state, true_fn, false_fn, seen=seen
        ):  # the march's: state (k, w, …), cond: fine
            seen.append((np.array(state[0]), np.array(cond, bool)))
            return plain(self, cond, state, true_fn, false_fn)

        type(B).branch = branch
        march.AT_SURFACE = at
        try:
            m = methods.make("linear_secant", steps_per_texel=1.0)
            _, spent = trace(m, B, tex, x, R, info, method_runner)
        finally:
            type(B).branch, march.AT_SURFACE = plain, True
        # iterations: the lookups less g(0), the bracket's re-read, the secant steps and the shown point's
        n_it = (spent - 3 - m.params.secant_steps).astype(int)
        ks = np.stack([k for k, _ in seen])
        fine = np.stack([c for _, c in seen])
        active = np.arange(len(seen))[:, None] < n_it[None, :]  # a ray runs its first n_it iterations
        nxt = np.vstack([ks[1:], ks[-1:]])
        coarse = active & ~fine
        print(
            f"linear_secant's march, numpy, {len(spent)} close-up rays, first block widest, at surface {at}: "
            f"{active.sum(0).mean():.2f} iterations per ray, {coarse.sum(0).mean():.2f} pyramid reads, "
            f"{(coarse & (nxt == ks)).sum(0).mean():.2f} of them clearing nothing; {(active & fine).sum(0).mean():.2f} "
            f"samples read alone",
            flush=True,
        )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene-res", type=int, default=512)
    ap.add_argument("--cube-res", type=int, default=256)
    ap.add_argument("--trace-res", type=int, default=128)
    a = ap.parse_args()
    rules(a)
    steps(a)


if __name__ == "__main__":
    main()
