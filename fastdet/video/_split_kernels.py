"""Numba kernels of :mod:`fastdet.video.blobsplit`: mean shift of a blob's windows and the
grouping of the points where they end.

Both are quadratic in the windows (every point against every window, every point against
every mode found so far); a blob over dense texture can hold hundreds of windows, where the
NumPy form built several ``(N, N)`` arrays per step and the grouping was a Python loop.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from .._numba import EXACT

#: squared distance in sigmas beyond which a window adds nothing to the shift (e**-30)
FAR = 60.0


@njit(**EXACT)
def _search(xs: np.ndarray, v: float, right: bool) -> int:
    """Where ``v`` goes in sorted ``xs``, as ``np.searchsorted`` with side ``'left'`` (the first
    index whose value is >= ``v``) or, with ``right``, side ``'right'`` (the first whose value is
    > ``v``); ``len(xs)`` if none."""
    lo = 0
    hi = xs.shape[0]
    while lo < hi:
        mid = (lo + hi) // 2
        if xs[mid] < v or (right and xs[mid] == v):
            lo = mid + 1
        else:
            hi = mid
    return lo


@njit(**EXACT)
def mean_shift(pts: np.ndarray, ps: np.ndarray, pw: np.ndarray, bandwidth: float, scale_bandwidth: float,
               iters: int, out: np.ndarray) -> None:
    """Move every point of ``pts`` ``(N, 3)`` (centre x, centre y, log2 width) by mean shift
    over the windows ``ps`` ``(N, 3)`` -- the same points sorted by centre x -- with weights
    ``pw`` ``(N,)`` (in ``ps``'s order), all points together, at most ``iters`` steps or until
    none moves by more than 1e-3; the end points go to ``out`` ``(N, 3)``, in ``pts``' order.
    Gaussian kernel: sigma ``bandwidth`` x 2 ** (the moving point's log2 width) in x and y,
    ``scale_bandwidth`` in log2 width. A point whose kernel sums to 0 stays. Windows further
    than ``sqrt(FAR)`` sigma from the moving point (kernel below e**-30 of its peak) are
    skipped, and only the windows whose centre x is within that reach are visited: a wide
    blob's windows are mostly far from each other, and what the skipped ones would add is far
    below the 1e-3 step the shift stops at."""
    n = pts.shape[0]
    px = np.empty(n)
    y = np.empty((n, 3))
    nxt = np.empty((n, 3))
    for j in range(n):
        px[j] = ps[j, 0]
        for c3 in range(3):
            y[j, c3] = pts[j, c3]
    reach = math.sqrt(FAR)
    for _ in range(iters):
        moved = 0.0
        for i in range(n):
            s = bandwidth * 2.0 ** y[i, 2]
            lo = _search(px, y[i, 0] - reach * s, False)
            hi = _search(px, y[i, 0] + reach * s, True)
            den = 0.0
            n0 = 0.0
            n1 = 0.0
            n2 = 0.0
            for j in range(lo, hi):
                a = (y[i, 0] - ps[j, 0]) / s
                b = (y[i, 1] - ps[j, 1]) / s
                c = (y[i, 2] - ps[j, 2]) / scale_bandwidth
                d2 = a * a + b * b + c * c
                if d2 > FAR:
                    continue
                k = pw[j] * math.exp(-0.5 * d2)
                den += k
                n0 += k * ps[j, 0]
                n1 += k * ps[j, 1]
                n2 += k * ps[j, 2]
            if den > 0:
                nxt[i, 0] = n0 / den
                nxt[i, 1] = n1 / den
                nxt[i, 2] = n2 / den
            else:
                nxt[i, 0] = y[i, 0]
                nxt[i, 1] = y[i, 1]
                nxt[i, 2] = y[i, 2]
            for c3 in range(3):
                d = abs(nxt[i, c3] - y[i, c3])
                if d > moved:
                    moved = d
        y, nxt = nxt, y
        if moved <= 1e-3:
            break
    for j in range(n):
        for c3 in range(3):
            out[j, c3] = y[j, c3]


@njit(**EXACT)
def join_modes(y: np.ndarray, bandwidth: float, scale_bandwidth: float, label: np.ndarray) -> int:
    """Group the end points ``y`` ``(N, 3)`` in input order: a point within a quarter sigma
    (``bandwidth`` x 2 ** the mode's log2 width in x and y, ``scale_bandwidth`` in log2
    width) of a mode found before it joins the first such mode, else it starts one.
    ``label`` ``(N,) int64`` receives each point's mode; returns the number of modes."""
    n = y.shape[0]
    reps = np.empty(n, np.int64)  # the point that started each mode
    m = 0
    for i in range(n):
        found = -1
        for j in range(m):
            r = reps[j]
            s = bandwidth * 2.0 ** y[r, 2]
            if (abs(y[i, 0] - y[r, 0]) < 0.25 * s and abs(y[i, 1] - y[r, 1]) < 0.25 * s
                    and abs(y[i, 2] - y[r, 2]) < 0.25 * scale_bandwidth):
                found = j
                break
        if found >= 0:
            label[i] = found
        else:
            label[i] = m
            reps[m] = i
            m += 1
    return m


# --------------------------------------------------------------------------------------
# what the package calls, compiled ahead of time (fastdet._numba.ensure_compiled)
# --------------------------------------------------------------------------------------
#: argument types of every call the package makes to each kernel: exactly the types of the
#: calls (C-contiguous arrays, Python ints as int64), so a call finds its machine code
SIGNATURES: dict[str, tuple[str, ...]] = {
    "mean_shift": ("float64[:, ::1], float64[:, ::1], float64[::1], float64, float64, int64, float64[:, ::1]",),
    "join_modes": ("float64[:, ::1], float64, float64, int64[::1]",),
}
#: CPU seconds to compile each, reference machine (docs/benchmarks.md)
COMPILE_SECONDS: dict[str, float] = {"mean_shift": 0.4, "join_modes": 0.3}
