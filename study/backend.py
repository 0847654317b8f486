"""The array backend: the few operations methods use, on numpy or on Dr.Jit (LLVM on the CPU, CUDA on a GPU).

Methods are written once against :class:`Backend` and :class:`V3` (structure-of-arrays 3-vectors): arithmetic,
comparisons, ``select``, ``sqrt``, ``abs``, ``minimum``/``maximum`` and bilinear texture samples (the cube-map
lookup on top of them is :class:`study.impostor.envmap.EnvMap`). Everything is float32 on
every backend, as on a GPU. The cube lookup is the only backend-specific piece: numpy gathers four texels, Dr.Jit
samples a ``Texture2f`` holding the six faces stacked vertically (hardware-accelerated on CUDA).
"""

from __future__ import annotations

import functools
import gc

import numpy as np

from study import runtime as llvm
from study.errors import StudyError
from study.vec import V3

BACKENDS = ("numpy", "llvm", "cuda")


class Backend:
    """Array operations of one backend. ``name`` is 'numpy', 'llvm' or 'cuda'."""

    name: str

    def array(self, a: np.ndarray): ...
    def numpy(self, a) -> np.ndarray: ...
    def select(self, cond, a, b): ...
    def sqrt(self, a): ...
    def rcp(self, a):
        """1/a, to within a few ulp: on CUDA the hardware's approximate reciprocal (``rcp.approx.ftz``: one
        instruction, where an IEEE division ``div.rn`` is a sequence of about eight); for values that bound, with
        a margin, what the exact ones would say (the march's pyramid boxes), never for values a method reports."""

    def abs(self, a): ...
    def minimum(self, a, b): ...
    def maximum(self, a, b): ...
    def isfinite(self, a): ...
    def floor(self, a): ...
    def sin(self, a): ...
    def cos(self, a): ...
    def exponent(self, a):
        """⌊log₂ a⌋ for a ≥ 1, exactly: the float's binary exponent."""

    def pow2(self, q): ...  # 2^q for whole q (floats) in float32's normal range, exactly: its exponent's bits

    def gather(self, data, index): ...
    def gather_at(self, data, base, index): ...
    def arange(self, n: int):
        """0, 1, …, n − 1 as a float array, made on the device (no data from the host: a frozen function replays
        it)."""

    def power(self, a, b): ...
    def acos(self, a): ...
    def atan2(self, y, x): ...
    def array64(self, a: np.ndarray):
        """A 1-D float64 array of this backend (measurements that must agree with numpy's to rounding)."""

    def shifted(self, a, width: int, height: int, k: int, axis: int):
        """The image ``a`` (a flat row-major ``height × width`` array) moved by ``k`` pixels along ``axis`` (1: x,
        0: y), edges clamped: pixel (y, x) of the result holds ``a[y, clip(x + k)]`` (axis 1)."""

    def total(self, a) -> float: ...
    def texture(self, texels: np.ndarray): ...
    def sample(self, tex, face, u, v) -> list: ...
    def eval(self, *arrays) -> None: ...
    def loop(self, n: int, state: tuple, body, *, index: bool = False) -> tuple: ...
    def while_loop(self, state: tuple, cond, body, *, limit: int, counted: bool = False) -> tuple: ...
    def branch(self, cond, state: tuple, true_fn, false_fn) -> tuple: ...
    def freeze(self, fn): ...
    def sync(self) -> None: ...
    def shape_of(self, a) -> tuple[str, int] | None:
        """("bool" / "float" / another kind, length) of a 1-D array of this backend; None for anything else."""

    # -------------------------------------------------------------- shared helpers built on the above
    def vec(self, a: np.ndarray) -> V3:
        """(N, 3) numpy → V3 on this backend."""
        a = np.asarray(a, np.float32)
        return V3(self.array(a[:, 0]), self.array(a[:, 1]), self.array(a[:, 2]))

    def to_numpy(self, v: V3) -> np.ndarray:
        return np.stack([self.numpy(v.x), self.numpy(v.y), self.numpy(v.z)], axis=-1)

    def length(self, v: V3):
        return self.sqrt(v.dot(v))

    def normalize(self, v: V3) -> V3:
        return v / self.length(v)


class NumpyBackend(Backend):
    name = "numpy"

    def array(self, a):
        return np.ascontiguousarray(a, dtype=np.float32)

    def numpy(self, a):
        return np.asarray(a)

    def shape_of(self, a):
        if not isinstance(a, np.ndarray) or a.ndim != 1:
            return None
        return ("bool" if a.dtype == bool else "float" if a.dtype.kind == "f" else str(a.dtype)), len(a)

    def select(self, c, a, b):
        return np.where(c, a, b).astype(np.float32, copy=False)

    def sqrt(self, a):
        return np.sqrt(a)

    def rcp(self, a):
        return np.float32(1.0) / a

    def abs(self, a):
        return np.abs(a)

    def minimum(self, a, b):
        return np.minimum(a, b)

    def maximum(self, a, b):
        return np.maximum(a, b)

    def isfinite(self, a):
        return np.isfinite(a)

    def floor(self, a):
        return np.floor(a)

    def sin(self, a):
        return np.sin(a).astype(np.float32)

    def cos(self, a):
        return np.cos(a).astype(np.float32)

    def exponent(self, a):
        return (np.frexp(a)[1] - 1).astype(np.float32)

    def pow2(self, q):
        return np.ldexp(np.float32(1.0), np.asarray(q).astype(np.int32)).astype(np.float32)

    def gather(self, data, index):
        """data[index] (``index`` a float array of integer values)."""
        return data[np.asarray(index).astype(np.int64)]

    def arange(self, n):
        return np.arange(n, dtype=np.float32)

    def gather_at(self, data, base, index):
        """data[base + index], the two whole numbers (floats, or ``base`` a Python int) made integers before they
        are added: a float32 sum is exact only to 2²⁴, which a stack of 512² probes' pyramids passes."""
        return data[np.asarray(base).astype(np.int64) + np.asarray(index).astype(np.int64)]

    def power(self, a, b):
        return np.power(a, np.float32(b) if np.isscalar(b) else b)

    def acos(self, a):
        return np.arccos(a)

    def atan2(self, y, x):
        return np.arctan2(y, x).astype(np.result_type(y, x, np.float32))

    def array64(self, a):
        return np.asarray(a, np.float64)

    def shifted(self, a, width, height, k, axis):
        img = np.asarray(a).reshape(height, width)
        n = img.shape[axis]
        idx = np.clip(np.arange(n) + k, 0, n - 1)
        return np.take(img, idx, axis=axis).reshape(-1)

    def total(self, a):
        return float(np.sum(np.asarray(a, np.float64)))

    def eval(self, *arrays):
        pass

    def sync(self):
        pass

    def freeze(self, fn):
        return fn

    def loop(self, n, state, body, *, index=False):
        """``state = body(*state)`` n times (``body(i, *state)`` for i = 0..n−1 with ``index``; i a Python int);
        see :meth:`DrJitBackend.loop`."""
        for i in range(n):
            state = tuple(body(i, *state) if index else body(*state))
        return tuple(state)

    def while_loop(self, state, cond, body, *, limit, counted=False):
        """``state = body(*state)`` where ``cond(*state)`` holds, ≤ ``limit`` times; see DrJitBackend's."""
        state, i = tuple(state), np.float32(0.0)
        for _ in range(limit):
            active = cond(*state)
            if not np.any(active):
                break
            new = body(*state)
            state = tuple(np.where(active, b, a) for a, b in zip(state, new))
            i = i + active.astype(np.float32)
        return (i + np.zeros(np.shape(state[0]), np.float32), *state) if counted else state

    def branch(self, cond, state, true_fn, false_fn):
        """``true_fn(*state)`` where ``cond``, ``false_fn(*state)`` elsewhere (numpy evaluates both sides, or the
        one side every lane takes)."""
        if np.all(cond) or not np.any(cond):
            return tuple(true_fn(*state) if np.all(cond) else false_fn(*state))
        a, b = true_fn(*state), false_fn(*state)
        return tuple(np.where(cond, p, q) for p, q in zip(a, b))

    def texture(self, texels):
        return np.ascontiguousarray(texels, dtype=np.float32)

    def sample(self, tex, face, u, v):
        R, C = tex.shape[1], tex.shape[-1]
        cj = np.clip(u * R - 0.5, 0, R - 1)
        ci = np.clip(v * R - 0.5, 0, R - 1)
        j0 = np.minimum(cj.astype(np.int32), max(R - 2, 0))
        i0 = np.minimum(ci.astype(np.int32), max(R - 2, 0))
        fj, fi = (cj - j0)[:, None], (ci - i0)[:, None]
        # the four texels by flat index (np.take on one axis is ~5× faster than indexing three axes)
        flat = tex.reshape(-1, C)
        t00 = (face.astype(np.int32) * R + i0) * R + j0
        dj, di = (
            (j0 + 1 <= R - 1).astype(np.int32),
            (i0 + 1 <= R - 1).astype(np.int32) * R,
        )  # clamped at R − 1
        a, b, c, d = (np.take(flat, t00 + k, axis=0) for k in (0, dj, di, di + dj))
        out = (1 - fi) * ((1 - fj) * a + fj * b) + fi * ((1 - fj) * c + fj * d)
        return [out[:, k].astype(np.float32) for k in range(C)]


class DrJitBackend(Backend):
    """Dr.Jit on LLVM (CPU) or CUDA.

    ``symbolic_loops`` (default True): :meth:`loop` records the loop body once (``dr.while_loop``), so the whole
    search is one kernel whose size and tracing cost do not grow with the iteration count; False unrolls it in
    Python (one traced copy of the body per iteration), as a plain ``for`` loop would.
    """

    symbolic_loops: bool = True

    def __init__(self, device: str):
        if device == "llvm":
            llvm.require()
        import drjit as dr

        self.dr = dr
        self.name = device
        self.m = dr.llvm if device == "llvm" else dr.cuda
        if device == "cuda":
            try:
                dr.cuda.Float(0.0)
                dr.eval()
            except Exception as err:  # pragma: no cover - needs a machine without CUDA to hit
                raise StudyError(
                    f"the cuda backend needs an NVIDIA GPU and driver ({err})", key="backend"
                ) from None

    def array(self, a):
        return self.m.Float(np.ascontiguousarray(a, dtype=np.float32))

    def numpy(self, a):
        return np.asarray(a)

    def shape_of(self, a):
        dr = self.dr
        if not dr.is_array_v(a) or dr.depth_v(a) != 1:
            return None
        kind = "bool" if dr.is_mask_v(a) else "float" if dr.is_float_v(a) else type(a).__name__
        return kind, dr.width(a)

    def select(self, c, a, b):
        return self.dr.select(c, a, b)

    def sqrt(self, a):
        return self.dr.sqrt(a)

    def rcp(self, a):
        return self.dr.rcp(a)

    def abs(self, a):
        return self.dr.abs(a)

    def minimum(self, a, b):
        return self.dr.minimum(a, b)

    def maximum(self, a, b):
        return self.dr.maximum(a, b)

    def isfinite(self, a):
        return self.dr.isfinite(a)

    def floor(self, a):
        return self.dr.floor(a)

    def sin(self, a):
        return self.dr.sin(a)

    def cos(self, a):
        return self.dr.cos(a)

    def exponent(self, a):
        bits = self.dr.reinterpret_array(self.m.UInt32, self.m.Float(a))
        return self.m.Float(self.m.Int32(bits >> 23) - 127)

    def pow2(self, q):
        return self.dr.reinterpret_array(self.m.Float, self.m.UInt32(self.m.Int32(q) + 127) << 23)

    def gather(self, data, index):
        return self.dr.gather(self.m.Float, data, self.m.UInt32(index))

    def arange(self, n):
        return self.dr.arange(self.m.Float, n)

    def gather_at(self, data, base, index):
        base = self.m.UInt32(int(base)) if isinstance(base, int | float) else self.m.UInt32(base)
        return self.dr.gather(self.m.Float, data, base + self.m.UInt32(index))

    def power(self, a, b):
        return self.dr.power(a, b)

    def acos(self, a):
        return self.dr.acos(a)

    def atan2(self, y, x):
        return self.dr.atan2(y, x)

    def array64(self, a):
        return self.m.Float64(np.ascontiguousarray(a, dtype=np.float64))

    def shifted(self, a, width, height, k, axis):
        dr, m = self.dr, self.m
        w, h = dr.opaque(m.Int32, width), dr.opaque(m.Int32, height)  # one kernel for every image size
        i = dr.arange(m.Int32, width * height)
        x, y = i % w, i // w
        if axis == 1:
            x = dr.clip(x + k, 0, w - 1)
        else:
            y = dr.clip(y + k, 0, h - 1)
        return dr.gather(type(a), a, m.UInt32(y * w + x))

    def total(self, a):
        return float(self.dr.sum(self.m.Float64(a))[0]) if self.dr.width(a) else 0.0

    def eval(self, *arrays):
        self.dr.eval(*arrays)

    def sync(self):
        self.dr.sync_thread()

    def loop(self, n, state, body, *, index=False):
        """``state = body(*state)`` n times, as one symbolic loop (``dr.while_loop``) in the kernel: the body is
        traced once and must not evaluate. With ``index``, ``body(i, *state)`` with i = 0..n−1 as a Float array
        (a Python int when the loop is unrolled). ``state`` is a flat tuple of arrays."""
        if n == 0 or not self.symbolic_loops:
            return NumpyBackend.loop(self, n, state, body, index=index)
        i = self.m.UInt32(0)
        if index:
            step = lambda i, *s: (i + 1, *body(self.m.Float(i), *s))  # noqa: E731
        else:
            step = lambda i, *s: (i + 1, *body(*s))  # noqa: E731
        out = self.dr.while_loop((i, *state), lambda i, *s: i < n, step)
        return tuple(out[1:])

    def while_loop(self, state, cond, body, *, limit, counted=False):
        """``state = body(*state)`` while ``cond(*state)`` holds, per lane (``dr.while_loop``: a lane stops when its
        condition fails; one symbolic loop in the kernel), at most ``limit`` times. ``state``: a flat tuple of
        arrays; ``counted``: the iterations each lane ran (a float array) come first."""
        i = self.m.UInt32(0)
        out = self.dr.while_loop(
            (i, *state), lambda i, *s: (i < limit) & cond(*s), lambda i, *s: (i + 1, *body(*s))
        )
        return (self.m.Float(out[0]), *out[1:]) if counted else tuple(out[1:])

    def branch(self, cond, state, true_fn, false_fn):
        """``dr.if_stmt``: each lane runs only its side (a lane's lookups on the other side are not made)."""
        return tuple(
            self.dr.if_stmt(tuple(state), cond, lambda *s: tuple(true_fn(*s)), lambda *s: tuple(false_fn(*s)))
        )

    def freeze(self, fn):
        """``dr.freeze(fn)``: the first call records the kernels fn launches, later calls replay them without
        running fn's Python code (array sizes may change between calls). Every Dr.Jit array and texture fn
        reads must come in through its arguments (dataclasses such as V3 are traversed).

        The garbage collector is paused while the frozen function runs: a Dr.Jit object freed from cyclic garbage
        during a recording is a host call that cannot be recorded, and Dr.Jit aborts the process."""
        return _NoCollection(self.dr.freeze(fn))

    def texture(self, texels):
        six, R, _, C = texels.shape
        data = np.ascontiguousarray(texels.reshape(six * R, R, C), dtype=np.float32)
        return self.m.Texture2f(
            self.m.TensorXf(data),
            filter_mode=self.dr.FilterMode.Linear,
            wrap_mode=self.dr.WrapMode.Clamp,
            use_accel=self.name == "cuda",
        )

    def sample(self, tex, face, u, v):
        R = tex.shape[1]
        lo, hi = 0.5 / R, 1 - 0.5 / R
        faces = tex.shape[0] // R  # 6 for a cube map; more for stacked cube maps (probes)
        pos = self.m.Array2f(self.dr.clip(u, lo, hi), (face + self.dr.clip(v, lo, hi)) / float(faces))
        return list(tex.eval(pos))


_cache: dict[str, Backend] = {}


def get(name: str = "numpy") -> Backend:
    """The backend called ``name`` ('numpy', 'llvm' or 'cuda')."""
    if name not in BACKENDS:
        raise StudyError(f"unknown backend {name!r}; allowed: {', '.join(BACKENDS)}", key="backend")
    if name not in _cache:
        _cache[name] = NumpyBackend() if name == "numpy" else DrJitBackend(name)
    return _cache[name]


class _NoCollection:
    """A frozen function called with the garbage collector paused; its attributes (``n_recordings``, …) are the
    frozen function's."""

    def __init__(self, frozen):
        self._frozen = frozen
        functools.update_wrapper(self, frozen, updated=())

    def __call__(self, *args, **kwargs):
        paused = gc.isenabled()
        gc.disable()
        try:
            return self._frozen(*args, **kwargs)
        finally:
            if paused:
                gc.enable()

    def __getattr__(self, name):
        return getattr(self._frozen, name)
