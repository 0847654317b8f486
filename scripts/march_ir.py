"""Instructions per step of the marches' loops, counted in the LLVM IR that Dr.Jit generates (issue 56's CPU proxy).

    PYTHONPATH=. python scripts/march_ir.py [--methods linear_secant,layered,multi_probe] [--dump DIR]

Each method is traced once (plain path) on the bench's close-up batch at 16² rays, cube 64², on the LLVM backend,
with Dr.Jit's kernel history on; in each kernel every symbolic loop (``l_<id>_cond`` … ``l_<id>_done``) and every
branch of a symbolic ``if`` inside it (``l_<id>_t`` / ``l_<id>_f``) is counted: the instructions Dr.Jit emitted
there, without the broadcasts of literals (an immediate operand on the GPU), the phis (register moves) and the
jumps. Columns: ``ops`` every counted instruction of the loop (both sides of its branches), ``cond`` the loop's
test, ``common`` what every iteration runs outside its branches, ``true``/``false`` each side of the loop's
outermost branches (the hierarchical march: the sample read and the pyramid read), ``gathers`` memory reads
(gathers; a bilinear texture lookup is 4 here, one ``tex`` instruction on CUDA), ``f64`` double-precision
instructions, ``state`` the loop's variables (phis at its test). The per-step cost of a lane is about
common + cond + one side. Counts are of Dr.Jit's IR before LLVM's optimizer (PTX is made from the same trace on
CUDA, with the same operations), so they are a proxy of the instructions a GPU step issues, not a count of them.
"""

from __future__ import annotations

import argparse
import re
import sys
from pathlib import Path

import numpy as np

_LABEL = re.compile(r"^([A-Za-z0-9_.]+):")
_DEF = re.compile(r"^\s+%(\S+) = (.*)$")
_BROADCAST = re.compile(r"insertelement <\d+ x \w+> undef, \w+ [-0-9.a-fA-Fx]+, i32 0$")


def count(ir: str) -> list[dict]:
    """Per symbolic loop of the kernel ``ir``: its counts (see the module docstring), outermost first."""
    loops: dict[str, dict] = {}
    stack: list[tuple[str, str]] = []  # open regions: ("loop", id) or ("t"/"f", if id)
    lits: set[str] = set()
    for line in ir.splitlines():
        m = _LABEL.match(line)
        if m:
            lab = m.group(1)
            parts = lab.split("_")
            if len(parts) >= 3 and parts[0] == "l":
                rid, kind = parts[1], "_".join(parts[2:])
                if kind == "cond":
                    loops[rid] = dict(
                        loop=rid, ops=0, cond=0, common=0, true=0, false=0, gathers=0, f64=0, state=0
                    )
                    stack.append(("loop", rid))
                    stack.append(("cond", rid))
                elif kind == "body" and stack and stack[-1] == ("cond", rid):
                    stack.pop()
                elif kind == "done" and ("loop", rid) in stack:
                    while stack and stack.pop() != ("loop", rid):
                        pass
                elif kind in ("t", "f"):
                    stack.append((kind, rid))
                elif kind in ("t_trailer", "f_trailer") and stack and stack[-1][1] == rid:
                    stack.pop()
            continue
        m = _DEF.match(line)
        if not m or not stack:
            continue
        name, rhs = m.groups()
        if _BROADCAST.search(rhs):
            lits.add(name)
            continue
        if rhs.startswith("shufflevector") and any(f"%{x}," in rhs for x in lits):
            continue
        open_loops = [r for k, r in stack if k == "loop"]
        if not open_loops:
            continue
        inner = open_loops[-1]
        c = loops[inner]
        if rhs.startswith("phi"):
            if stack[-1] == ("cond", inner):
                c["state"] += 1
            continue
        c["ops"] += 1
        c["gathers"] += "gather" in rhs
        c["f64"] += "double" in rhs
        # the loop's own level: its test, its body outside branches, or the outermost branch's side
        below = stack[stack.index(("loop", inner)) + 1 :]
        if below and below[0] == ("cond", inner):
            c["cond"] += 1
        elif not below:
            c["common"] += 1
        else:
            c["true" if below[0][0] == "t" else "false"] += 1
        for outer in open_loops[:-1]:  # a nested loop's ops count in the loops around it too
            loops[outer]["ops"] += 1
    return list(loops.values())


def method_loops(name: str, params: dict, dump: Path | None = None) -> list[dict]:
    """The counts of every loop in the kernels that tracing ``name`` launches (16² close-up rays, cube 64²)."""
    import drjit as dr

    sys.path.insert(0, str(Path(__file__).parent))
    import march_side

    from study import methods
    from study.bench.timing import bench_probes, method_runner

    B, tex, batch, o, info, screen, tracer, _ = march_side.setup("llvm", 16, 64, 1, False)
    m = methods.make(name, **params)
    sets = {sp: bench_probes(sp, tracer, tex, o, info["room"], B) for sp in m.views_needed().probes}
    scr = screen() if m.views_needed().screen else None
    call, finish = method_runner(
        m, B, tex, batch.x - o, batch.R, frozen=False, info=info, screen=scr, probe_sets=sets
    )
    flag = dr.flag(dr.JitFlag.KernelHistory)
    dr.set_flag(dr.JitFlag.KernelHistory, True)
    try:
        dr.kernel_history()
        finish(call())
        finish(None)
        kernels = [k for k in dr.kernel_history() if k.get("type") == dr.KernelType.JIT]
    finally:
        dr.set_flag(dr.JitFlag.KernelHistory, flag)
    out = []
    for i, k in enumerate(kernels):
        ir = k["ir"].getvalue()
        if dump is not None:
            dump.mkdir(parents=True, exist_ok=True)
            (dump / f"{name}-{i}.ll").write_text(ir)
        out += [{"method": m.label, "kernel": i, **c} for c in count(ir)]
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--methods", default="linear_secant,layered,multi_probe")
    ap.add_argument("--variant", default="", help="a restructure undone (scripts/march_side.py --variant)")
    ap.add_argument("--dump", type=Path, default=None, help="write each kernel's IR here")
    a = ap.parse_args()
    sys.path.insert(0, str(Path(__file__).parent))
    import march_side

    march_side.variant(a.variant)
    cols = ["ops", "cond", "common", "true", "false", "gathers", "f64", "state"]
    print(f"{'method':36s} {'kernel':>6s} {'loop':>6s} " + " ".join(f"{c:>7s}" for c in cols))
    for name in a.methods.split(","):
        for r in method_loops(name, {}, a.dump):
            print(
                f"{r['method']:36s} {r['kernel']:6d} {r['loop']:>6s} " + " ".join(f"{r[c]:7d}" for c in cols)
            )
    np.seterr(all="ignore")


if __name__ == "__main__":
    main()
