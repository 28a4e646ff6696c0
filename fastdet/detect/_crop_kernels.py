"""Numba kernel: the box regressor's and the verifier's context crops, shrunk to the feature
window with exactly OpenCV's ``INTER_AREA`` arithmetic, straight from the frame.

Call it through :func:`fastdet.detect.regressor.regions_crops`, which picks the crops this
kernel makes (a region at least the window's size in both directions whose two scales are
not both whole numbers: OpenCV's general area path) and checks the arguments; the others
(enlarged, or shrunk by whole numbers) it leaves to ``cv2.resize``.

OpenCV's general ``INTER_AREA`` (``ResizeArea_Invoker``, ``computeResizeAreaTab`` in
``imgproc/resize.cpp``) works in float32: each source row is first reduced along x,
``buf[dx] = sum_k S[si_k] * alpha_k`` in table order, then the rows are summed along y,
``sum[dx] = beta_0 * buf_0 (+ beta_j * buf_j ...)``, and the sum is rounded half to even and
saturated to uint8. The weights (``alpha``, ``beta``) are the tables' double-precision
fractions rounded to float32. This kernel does the same float32 operations in the same order
(so the same bits: the tests compare it with ``cv2.resize`` on random regions), but converts each
region row to float32 once, keeps each output's running sum in a register and reduces four
rows at a time (twelve independent sums), where OpenCV converts every pixel as it goes and adds
into memory one row at a time (a chain of dependent loads, adds and stores); each region row is
reduced once, where OpenCV reduces a row shared by two output rows twice. About 2x faster on the
picture search's crops (docs/benchmarks.md). It reads the frame directly: pixels of the region
outside its clamp rectangle repeat its border (``cv2.BORDER_REPLICATE`` of the region's part
inside the frame), so no padded copy is made. (Written against OpenCV 4.x's code; another
OpenCV that changed its arithmetic would show in ``tests/detect/test_crops.py``, which compares
with the installed ``cv2.resize``.)
"""
from __future__ import annotations

import numpy as np
from numba import njit

from .._numba import EXACT


@njit(**EXACT)
def _area_table(ssize, dsize, scale, kofs, si, alpha):
    """OpenCV's ``computeResizeAreaTab`` for one axis (``cn = 1``): the source indices
    ``si[k]`` and float32 weights ``alpha[k]`` of output ``d`` are ``kofs[d] <= k < kofs[d+1]``
    (``kofs (dsize + 1,) int64``; ``si``, ``alpha``: at least ``2 * ssize`` long). ``scale``:
    source pixels per output pixel (float64, ``1 / (dsize / ssize)`` as OpenCV computes it)."""
    k = 0
    for d in range(dsize):
        kofs[d] = k
        fs1 = d * scale
        fs2 = fs1 + scale
        cell = min(scale, ssize - fs1)
        s1 = int(np.ceil(fs1))
        s2 = int(np.floor(fs2))
        s2 = min(s2, ssize - 1)
        s1 = min(s1, s2)
        if s1 - fs1 > 1e-3:
            si[k] = s1 - 1
            alpha[k] = np.float32((s1 - fs1) / cell)
            k += 1
        for s in range(s1, s2):
            si[k] = s
            alpha[k] = np.float32(1.0 / cell)
            k += 1
        if fs2 - s2 > 1e-3:
            si[k] = s2
            alpha[k] = np.float32(min(min(fs2 - s2, 1.0), cell) / cell)
            k += 1
    kofs[dsize] = k


@njit(**EXACT)
def _row_to_float(row, x0, sw, xlo, xhi, f):
    """``f[3*u + c] = row[3*clamp(x0 + u, xlo, xhi) + c]`` for ``u < sw``: a region row as
    float32 (``row (W * 3,) uint8``, ``f (sw * 3,) float32``); the columns inside the frame in
    one contiguous run, those past ``xlo`` / ``xhi`` repeating the border pixel."""
    ul = min(max(xlo - x0, 0), sw)
    ur = max(min(xhi + 1 - x0, sw), ul)
    q = 3 * xlo
    for u in range(ul):
        f[3 * u] = np.float32(row[q])
        f[3 * u + 1] = np.float32(row[q + 1])
        f[3 * u + 2] = np.float32(row[q + 2])
    src = row[3 * (x0 + ul): 3 * (x0 + ur)]
    dst = f[3 * ul: 3 * ur]
    for i in range(src.shape[0]):
        dst[i] = np.float32(src[i])
    q = 3 * xhi
    for u in range(ur, sw):
        f[3 * u] = np.float32(row[q])
        f[3 * u + 1] = np.float32(row[q + 1])
        f[3 * u + 2] = np.float32(row[q + 2])


@njit(**EXACT)
def _reduce_rows4(f0, f1, f2, f3, si, alpha, kofs, dw, b0, b1, b2, b3):
    """The x-reduction of four region rows (``f*``: :func:`_row_to_float`) into ``b* (dw * 3,)
    float32``: ``b[3*dx + c] = sum_k f[3*si[k] + c] * alpha[k]``, ``kofs[dx] <= k <
    kofs[dx+1]``, each sum in table order from 0 (twelve independent sums in registers)."""
    for dx in range(dw):
        a00 = a01 = a02 = a10 = a11 = a12 = np.float32(0.0)
        a20 = a21 = a22 = a30 = a31 = a32 = np.float32(0.0)
        for k in range(kofs[dx], kofs[dx + 1]):
            q = 3 * si[k]
            w = alpha[k]
            a00 = a00 + f0[q] * w
            a01 = a01 + f0[q + 1] * w
            a02 = a02 + f0[q + 2] * w
            a10 = a10 + f1[q] * w
            a11 = a11 + f1[q + 1] * w
            a12 = a12 + f1[q + 2] * w
            a20 = a20 + f2[q] * w
            a21 = a21 + f2[q + 1] * w
            a22 = a22 + f2[q + 2] * w
            a30 = a30 + f3[q] * w
            a31 = a31 + f3[q + 1] * w
            a32 = a32 + f3[q + 2] * w
        o = 3 * dx
        b0[o] = a00
        b0[o + 1] = a01
        b0[o + 2] = a02
        b1[o] = a10
        b1[o + 1] = a11
        b1[o + 2] = a12
        b2[o] = a20
        b2[o + 1] = a21
        b2[o + 2] = a22
        b3[o] = a30
        b3[o + 1] = a31
        b3[o + 2] = a32


@njit(**EXACT)
def _area_crop(frame, g, scale_x, scale_y, out):
    """One crop (:func:`area_crops`): geometry ``g`` (8 int64), ``out (dh, dw, 3) uint8``.
    Every region row is reduced along x once (four at a time), then each output row sums its
    rows' reductions in table order."""
    dh, dw = out.shape[0], out.shape[1]
    y0, y1, x0, x1, ylo, yhi, xlo, xhi = g[0], g[1], g[2], g[3], g[4], g[5], g[6], g[7]
    sh, sw = y1 - y0, x1 - x0
    xofs = np.empty(dw + 1, np.int64)
    xsi = np.empty(2 * sw + 2, np.int64)
    xal = np.empty(2 * sw + 2, np.float32)
    _area_table(sw, dw, scale_x, xofs, xsi, xal)
    yofs = np.empty(dh + 1, np.int64)
    ysi = np.empty(2 * sh + 2, np.int64)
    yal = np.empty(2 * sh + 2, np.float32)
    _area_table(sh, dh, scale_y, yofs, ysi, yal)
    n3 = 3 * dw
    red = np.empty((sh + 3, n3), np.float32)  # row y's x-reduction (3 spare rows for the last group of four)
    f = np.empty((4, 3 * sw), np.float32)
    y = 0
    while y < sh:
        for r in range(4):
            _row_to_float(frame[min(max(y0 + min(y + r, sh - 1), ylo), yhi)], x0, sw, xlo, xhi, f[r])
        _reduce_rows4(f[0], f[1], f[2], f[3], xsi, xal, xofs, dw, red[y], red[y + 1], red[y + 2], red[y + 3])
        y += 4
    acc = np.empty(n3, np.float32)
    for dy in range(dh):
        # along y in table order: the first row sets the sum (OpenCV's 0 + x is x), the others add to it
        j0, j1 = yofs[dy], yofs[dy + 1]
        beta = yal[j0]
        b = red[ysi[j0]]
        for q in range(n3):
            acc[q] = beta * b[q]
        for j in range(j0 + 1, j1):
            beta = yal[j]
            b = red[ysi[j]]
            for q in range(n3):
                acc[q] = acc[q] + beta * b[q]
        o = out[dy].reshape(n3)
        for q in range(n3):
            v = np.rint(acc[q])  # cvRound: half to even, then saturated
            o[q] = np.uint8(0.0 if v < 0.0 else (255.0 if v > 255.0 else v))


@njit(**EXACT)
def area_crops(frame, geometry, scales, order, out):
    """Crops ``order[i]`` for each ``i`` of ``order``, shrunk with OpenCV's general
    ``INTER_AREA`` (module docstring), into ``out[order[i]]``.

    frame: ``(H, W * 3) uint8`` (read-only), the frame's rows (3 channels interleaved).
    geometry: ``(N, 8) int64`` per crop: the region's rows ``y0 <= y < y1`` and columns
        ``x0 <= x < x1`` in frame pixels (may run past the frame), then the rectangle
        ``ylo..yhi``, ``xlo..xhi`` (inclusive, inside the frame) a pixel's row and column are
        clamped to (border replication). Needs ``y1 - y0 >= dh`` and ``x1 - x0 >= dw``.
    scales: ``(N, 2) float64``: source pixels per output pixel along x and y, as OpenCV computes
        them: ``1 / (dw / (x1 - x0))``, ``1 / (dh / (y1 - y0))``.
    order: ``(n,) int64`` the crops to make (on the calling thread).
    out: ``(N, dh, dw, 3) uint8``; only the rows of ``order`` are written.
    """
    for i in range(order.shape[0]):
        c = order[i]
        _area_crop(frame, geometry[c], scales[c, 0], scales[c, 1], out[c])


# --------------------------------------------------------------------------------------
# what the package calls, compiled ahead of time (fastdet._numba.ensure_compiled)
# --------------------------------------------------------------------------------------
#: argument types of every call the package makes to each kernel: exactly the types of the
#: calls (C-contiguous arrays, Python ints as int64), so a call finds its machine code
SIGNATURES: dict[str, tuple[str, ...]] = {
    # the frame's rows are passed read-only (a read-only view of whatever the caller gave)
    "area_crops": ("Array(uint8, 2, 'C', readonly=True), int64[:, ::1], float64[:, ::1], int64[::1], "
                   "uint8[:, :, :, ::1]",),
}
#: CPU seconds to compile each, reference machine (docs/benchmarks.md)
COMPILE_SECONDS: dict[str, float] = {"area_crops": 4.3}
