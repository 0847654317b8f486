"""LDR-FLIP (Andersson et al. 2020, "FLIP: A Difference Evaluator for Alternating Images") as array code, written
once for every backend, so that the per-pixel error of a figure is computed where its images are (on the GPU with
``cuda``, vectorised on the CPU with ``llvm``).

It follows the published algorithm step by step in float32, as ``flip-evaluator`` (the pip package, NVIDIA's C++
code) computes it in "LDR" mode: sRGB → linear RGB → YCxCz; the colour pipeline filters YCxCz with the
contrast-sensitivity Gaussians (separated: one pass along x, one along y, edges clamped), goes back to linear RGB
(clamped to [0, 1]), to CIELab with the Hunt adjustment, and takes the HyAB distance, raised to q_c = 0.7 and
re-mapped to [0, 1]; the feature pipeline filters the normalised luminance with first and second derivatives of a
Gaussian (edges and points) and raises the larger difference to q_f = 0.5; the error is ΔE_c^(1 − ΔE_f).
``flip-evaluator`` stays the reference: ``tests/measure/test_flip.py`` checks this module against it within 1e-4 in the
mean and in the per-pixel 99th percentile, on study images and synthetic ones. HDR-FLIP is not implemented: the
study measures LDR images only (:mod:`study.measure.metrics`).

Images are :class:`~study.backend.V3` of flat row-major arrays (``height × width``) on one backend;
:func:`ldr_flip_image` is the (H, W, 3) numpy front.
"""

from __future__ import annotations

import math

import numpy as np

from study.backend import V3, Backend
from study.backend import get as get_backend

#: Pixels per degree: a 0.7 m wide 3840-pixel monitor seen from 0.7 m (flip-evaluator's default).
PPD = float(np.float32(0.7 * (3840.0 / 0.7) * (math.pi / 180.0)))
#: FLIP's constants: colour exponent q_c, the error mapping's p_c and p_t, feature width w (degrees), q_f.
QC, PC, PT, GW, QF = 0.7, 0.4, 0.95, 0.082, 0.5
#: The contrast-sensitivity Gaussians (a, b) of Y, Cx and the two of Cz (the paper's Table 1).
A1, B1 = (1.0, 1.0, 34.1), (0.0047, 0.0053, 0.04)
A2, B2 = (0.0, 0.0, 13.5), (1.0e-5, 1.0e-5, 0.025)
D65 = (0.950428545, 1.0, 1.088900371)  # the reference white, XYZ
RGB_TO_XYZ = np.array(
    [
        [10135552 / 24577794, 8788810 / 24577794, 4435075 / 24577794],
        [2613072 / 12288897, 8788810 / 12288897, 887015 / 12288897],
        [1425312 / 73733382, 8788810 / 73733382, 70074185 / 73733382],
    ]
)
XYZ_TO_RGB = np.array(
    [
        [3.241003275, -1.537398934, -0.498615861],
        [-0.969224334, 1.875930071, 0.041554224],
        [0.055639423, -0.204011202, 1.057148933],
    ]
)


# ---------------------------------------------------------------------------------------------- the filters
def spatial_filters(ppd: float = PPD) -> tuple[np.ndarray, np.ndarray]:
    """The separated contrast-sensitivity filters, (2r + 1, 2) each: columns (Y, Cx) and (Cz₁, Cz₂) (Cz's filter is a
    sum of two Gaussians, each separated with the square root of its weight, NVlabs' separatedConvolutions.pdf)."""
    r = int(math.ceil(3.0 * math.sqrt(max(*B1, *B2) / (2.0 * math.pi**2)) * ppd))
    x2 = ((np.arange(2 * r + 1) - r) / ppd) ** 2

    def g(a, b, amplitude=lambda s: s):  # a·√(π/b)·exp(−π²x²/b); Cz's two with √ of the amplitude only
        return amplitude(a * np.sqrt(np.pi / b)) * np.exp(-(np.pi**2) * x2 / b)

    ycx = np.stack([g(A1[0], B1[0]), g(A1[1], B1[1])], -1)
    cz = np.stack([g(A1[2], B1[2], np.sqrt), g(A2[2], B2[2], np.sqrt)], -1)
    ycx = ycx / ycx.sum(0)
    cz = cz / np.hypot(*cz.sum(0))
    return ycx.astype(np.float32), cz.astype(np.float32)


def feature_filter(ppd: float = PPD) -> np.ndarray:
    """(2r + 1, 3): a Gaussian of σ = w/2 · ppd (summing to 1) and its first and second derivatives (positive and
    negative weights each summing to ±1)."""
    sd = 0.5 * GW * ppd
    r = int(math.ceil(3.0 * sd))
    x = np.arange(2 * r + 1, dtype=np.float64) - r
    g = np.exp(-(x * x) / (2 * sd * sd))
    dg, ddg = -x * g, (x * x / (sd * sd) - 1) * g
    out = [g / g.sum()]
    for d in (dg, ddg):
        out.append(np.where(d > 0, d / d[d > 0].sum(), d / -d[d < 0].sum()))
    return np.stack(out, -1).astype(np.float32)


def _convolve(B: Backend, imgs, weights: np.ndarray, w: int, h: int, axis: int) -> list:
    """Σ_k weights[k, j] · imgs[i] shifted by k − r along ``axis``, for each pair (i, j) asked: ``imgs`` a list of
    (image, column) pairs; taps in order, as flip-evaluator sums them."""
    r = len(weights) // 2
    out = [None] * len(imgs)
    for k in range(-r, r + 1):
        for n, (img, col) in enumerate(imgs):
            term = B.shifted(img, w, h, k, axis) * float(weights[k + r, col])
            out[n] = term if out[n] is None else out[n] + term
    B.eval(*out)
    return out


# ---------------------------------------------------------------------------------------------- colour spaces
def _mat(m, v: V3) -> V3:
    f = [[float(c) for c in row] for row in m]
    return V3(*(v.x * f[i][0] + v.y * f[i][1] + v.z * f[i][2] for i in range(3)))


def _srgb_to_linear(B: Backend, c):
    return B.select(c <= 0.04045, c * (1 / 12.92), B.power((c + 0.055) * (1 / 1.055), 2.4))


def _ycxcz(B: Backend, srgb: V3) -> V3:
    lin = V3(*(_srgb_to_linear(B, c) for c in (srgb.x, srgb.y, srgb.z)))
    xyz = _mat(RGB_TO_XYZ, lin)
    x, y, z = xyz.x * (1 / D65[0]), xyz.y * (1 / D65[1]), xyz.z * (1 / D65[2])
    return V3(116.0 * y - 16.0, 500.0 * (x - y), 200.0 * (y - z))


def _hunt_lab(B: Backend, ycxcz: V3) -> V3:
    """Filtered YCxCz → linear RGB clamped to [0, 1] → CIELab, a and b scaled by 0.01·L (Hunt)."""
    yn = (ycxcz.x + 16.0) * (1 / 116.0)
    xyz = V3((yn + ycxcz.y * (1 / 500.0)) * D65[0], yn * D65[1], (yn - ycxcz.z * (1 / 200.0)) * D65[2])
    rgb = _mat(XYZ_TO_RGB, xyz)
    rgb = V3(*(B.minimum(B.maximum(c, 0.0), 1.0) for c in (rgb.x, rgb.y, rgb.z)))
    xyz = _mat(RGB_TO_XYZ, rgb)
    d = 6.0 / 29.0

    def f(t):
        return B.select(t > d**3, B.power(B.maximum(t, d**3), 1.0 / 3.0), t * (1 / (3 * d * d)) + 4.0 / 29.0)

    fx, fy, fz = f(xyz.x * (1 / D65[0])), f(xyz.y * (1 / D65[1])), f(xyz.z * (1 / D65[2]))
    L = 116.0 * fy - 16.0
    return V3(L, 0.01 * L * (500.0 * (fx - fy)), 0.01 * L * (200.0 * (fy - fz)))


def _max_distance() -> float:
    """c_max: the HyAB distance between Hunt-adjusted green and blue, raised to q_c (computed in numpy)."""
    nb = get_backend("numpy")

    def lab(rgb):
        y = V3(*(np.array([c], np.float32) for c in rgb))
        xyz = _mat(RGB_TO_XYZ, y)
        e = V3(
            116.0 * xyz.y / D65[1] - 16.0, 500.0 * (xyz.x / D65[0] - xyz.y), 200.0 * (xyz.y - xyz.z / D65[2])
        )
        return _hunt_lab(nb, e)  # YCxCz → (clamp is a no-op on these primaries) → Lab, Hunt

    g, b = lab((0.0, 1.0, 0.0)), lab((0.0, 0.0, 1.0))
    return float((np.abs(g.x - b.x) + np.hypot(g.y - b.y, g.z - b.z))[0] ** QC)


# ---------------------------------------------------------------------------------------------- the map
def image_terms(B: Backend, srgb: V3, width: int, height: int, ppd: float = PPD) -> tuple:
    """What FLIP needs of one image alone, (L, a, b, edge, point): its CSF-filtered colour in Hunt-adjusted CIELab
    and the magnitudes of its luminance's first and second derivatives (edges and points). An image's terms do not
    depend on the image it is compared with, so a reference's are computed once for every test image
    (:func:`flip_error`; :func:`ldr_flip` is the two in a row). ``B``'s ``shifted`` decides the images' edges: a
    :class:`Stacked` backend filters several images of one size, each with its own clamped edges."""
    w, h = width, height
    y = _ycxcz(B, srgb)
    B.eval(y.x, y.y, y.z)
    # ------------------------------------------------------------------ colour: CSF filtering, Hunt
    ycx, cz = spatial_filters(ppd)
    s1 = _convolve(B, [(y.x, 0), (y.y, 1)], ycx, w, h, 1)
    c1 = _convolve(B, [(y.z, 0), (y.z, 1)], cz, w, h, 1)
    s2 = _convolve(B, [(s1[0], 0), (s1[1], 1)], ycx, w, h, 0)
    c2 = _convolve(B, [(c1[0], 0), (c1[1], 1)], cz, w, h, 0)
    lab = _hunt_lab(B, V3(s2[0], s2[1], c2[0] + c2[1]))
    # ------------------------------------------------------------------ features: edges and points of luminance
    ff = feature_filter(ppd)
    n = y.x * (1 / 116.0) + 16.0 / 116.0
    B.eval(n)
    f1 = _convolve(B, [(n, 1), (n, 2), (n, 0)], ff, w, h, 1)
    dx, ddx, dy, ddy = _convolve(B, [(f1[0], 0), (f1[1], 0), (f1[2], 1), (f1[2], 2)], ff, w, h, 0)
    edge, point = B.sqrt(dx * dx + dy * dy), B.sqrt(ddx * ddx + ddy * ddy)
    B.eval(lab.x, lab.y, lab.z, edge, point)
    return lab.x, lab.y, lab.z, edge, point


def flip_error(B: Backend, ref: tuple, test: tuple):
    """The per-pixel FLIP error from two images' :func:`image_terms` (arrays of one length): the HyAB distance of
    their colours raised to q_c and re-mapped to [0, 1], to the power 1 − the feature difference."""
    lr, ar, br, er, pr = ref
    lt, at, bt, et, pt = test
    da, db = ar - at, br - bt
    hyab = B.abs(lr - lt) + B.sqrt(da * da + db * db)
    cmax = _max_distance()
    pcc = PC * cmax
    dc = B.power(hyab, QC)
    dc = B.select(dc < pcc, dc * (PT / pcc), PT + (dc - pcc) * ((1.0 - PT) / (cmax - pcc)))
    df = B.power(B.maximum(B.abs(er - et), B.abs(pr - pt)) * (1 / math.sqrt(2.0)), QF)
    err = B.select(dc > 0.0, B.power(B.maximum(dc, 1e-30), 1.0 - df), 0.0 * dc)
    B.eval(err)
    return err


def ldr_flip(B: Backend, ref: V3, test: V3, width: int, height: int, ppd: float = PPD):
    """Per-pixel LDR-FLIP error of ``test`` against ``ref`` on backend ``B``.

    Parameters
    ----------
    ref, test : V3
        sRGB-encoded LDR images in [0, 1], channels as flat row-major arrays of ``height · width`` values.
    width, height : int
    ppd : float
        Pixels per degree of visual angle (flip-evaluator's default 67.02).

    Returns
    -------
    (height · width,) float array of ``B``: the FLIP error per pixel, in [0, 1].
    """
    return flip_error(B, image_terms(B, ref, width, height, ppd), image_terms(B, test, width, height, ppd))


class Stacked:
    """Backend ``B`` for ``count`` images of one size stacked in one flat array (image after image, each row-major):
    :meth:`shifted` clamps at each image's own edges, so every filter of :func:`image_terms` treats each image as
    if alone; everything else is ``B``'s."""

    def __init__(self, B: Backend, count: int):
        self.B, self.count = B, count

    def __getattr__(self, name):
        return getattr(self.B, name)

    def shifted(self, a, width: int, height: int, k: int, axis: int):
        if self.B.name == "numpy":  # rows along x are rows of the whole stack; along y, of each image
            if axis == 1:
                return self.B.shifted(a, width, self.count * height, k, 1)
            return _shift_rows(a, width, height, self.count, k)
        dr, m = self.B.dr, self.B.m
        w, h = dr.opaque(m.Int32, width), dr.opaque(m.Int32, height)
        i = dr.arange(m.Int32, width * height * self.count)
        local = i % (w * h)
        x, y = local % w, local // w
        if axis == 1:
            x = dr.clip(x + k, 0, w - 1)
        else:
            y = dr.clip(y + k, 0, h - 1)
        return dr.gather(type(a), a, m.UInt32(i - local + y * w + x))

    def tiled(self, a, size: int):
        """A one-image array (``size`` values) repeated for every image of the stack."""
        if self.B.name == "numpy":
            return np.tile(np.asarray(a), self.count)
        dr, m = self.B.dr, self.B.m
        i = dr.arange(m.UInt32, size * self.count) % dr.opaque(m.UInt32, size)
        return dr.gather(type(a), a, i)


def _shift_rows(a, width: int, height: int, count: int, k: int):
    img = np.asarray(a).reshape(count, height, width)
    idx = np.clip(np.arange(height) + k, 0, height - 1)
    return np.take(img, idx, axis=1).reshape(-1)


#: A stack holds at most this many pixels at once (the filters keep about 30 float32 arrays of its size alive).
STACK_PIXELS = 1 << 22


def flip_stack(
    ref: np.ndarray | None,
    tests: np.ndarray,
    backend: str,
    *,
    refs: np.ndarray | None = None,
    linear: bool = True,
) -> np.ndarray:
    """(M, H, W) float32 FLIP maps of ``tests`` (M, H, W, 3) against one ``ref`` (H, W, 3), whose
    :func:`image_terms` are computed once, or against ``refs`` (M, H, W, 3), one per test, on ``backend``
    ('numpy', 'llvm' or 'cuda': this module's array code; values as :func:`ldr_flip_image` of each pair, within
    float32 rounding). At most :data:`STACK_PIXELS` pixels are filtered at once."""
    B = get_backend(backend)
    tests = np.asarray(tests)
    M, h, w = tests.shape[:3]
    size = h * w

    def upload(a):
        v = B.vec(np.asarray(a, np.float32).reshape(-1, 3))
        return V3(*(_linear_to_srgb(B, c) for c in (v.x, v.y, v.z))) if linear else v

    one = None if ref is None else image_terms(B, upload(ref), w, h)
    step = max(1, STACK_PIXELS // max(size, 1))
    out = []
    for s in range(0, M, step):
        part = tests[s : s + step]
        S = Stacked(B, len(part))
        t = image_terms(S, upload(part), w, h)
        r = (
            tuple(S.tiled(c, size) for c in one)
            if one is not None
            else image_terms(S, upload(refs[s : s + step]), w, h)
        )
        out.append(np.asarray(B.numpy(flip_error(S, r, t)), np.float32).reshape(len(part), h, w))
    return np.concatenate(out) if out else np.zeros((0, h, w), np.float32)


def _linear_to_srgb(B: Backend, c):
    """Linear radiance → sRGB-encoded [0, 1] on backend ``B`` (clip at 1, exposure 1): the encoding of
    :func:`study.measure.metrics.to_ldr`, in float32 where the images are."""
    c = B.minimum(B.maximum(c, 0.0), 1.0)
    return B.select(c <= 0.0031308, 12.92 * c, 1.055 * B.power(B.maximum(c, 1e-30), 1 / 2.4) - 0.055)


def ldr_flip_image(
    ref: np.ndarray, test: np.ndarray, backend: str = "numpy", *, linear: bool = False
) -> np.ndarray:
    """:func:`ldr_flip` of two (H, W, 3) sRGB LDR numpy images on ``backend``, as an (H, W) float32 numpy map.
    ``linear``: the images are linear radiance, encoded to sRGB on ``backend`` before FLIP (:func:`_linear_to_srgb`)."""
    B = get_backend(backend)
    h, w = np.shape(ref)[:2]
    v = [B.vec(np.asarray(a, np.float32).reshape(-1, 3)) for a in (ref, test)]
    if linear:
        v = [V3(*(_linear_to_srgb(B, c) for c in (a.x, a.y, a.z))) for a in v]
    return np.asarray(B.numpy(ldr_flip(B, v[0], v[1], w, h)), np.float32).reshape(h, w)
