"""Numba kernel of :mod:`fastdet.video.motion`: which window columns of a search band move."""
from __future__ import annotations

import numpy as np
from numba import njit

from .._numba import EXACT


@njit(**EXACT)
def moving_columns(integral: np.ndarray, ox: int, oy: int, left: np.ndarray, top: np.ndarray,
                   right: np.ndarray, bottom: np.ndarray, min_motion: float, out: np.ndarray) -> None:
    """``out[j] = True`` when some window of column ``j`` -- the box ``left[j]..right[j] x
    top[i]..bottom[i]`` (frame pixels, exclusive) for some row ``i`` -- has a mean motion of
    at least ``min_motion``: the mean of the integral image ``integral`` ``(h + 1, w + 1)
    float64`` (its region's top-left corner at frame pixel ``(ox, oy)``) over the box clipped
    to the region, 0 for a box with nothing left (as :func:`fastdet.video.motion._mean_in`,
    in the same float operations). left, right: ``(nx,) int64``; top, bottom: ``(ny,)
    int64``; out: ``(nx,) bool``."""
    h = integral.shape[0] - 1
    w = integral.shape[1] - 1
    for j in range(left.shape[0]):
        x1 = min(max(left[j] - ox, 0), w)
        x2 = min(max(right[j] - ox, 0), w)
        hit = False
        for i in range(top.shape[0]):
            y1 = min(max(top[i] - oy, 0), h)
            y2 = min(max(bottom[i] - oy, 0), h)
            area = (x2 - x1) * (y2 - y1)
            if area > 0:
                total = integral[y2, x2] - integral[y1, x2] - integral[y2, x1] + integral[y1, x1]
                mean = total / area
            else:
                mean = 0.0
            if mean >= min_motion:
                hit = True
                break
        out[j] = hit


# --------------------------------------------------------------------------------------
# what the package calls, compiled ahead of time (fastdet._numba.ensure_compiled)
# --------------------------------------------------------------------------------------
#: argument types of every call the package makes to each kernel: exactly the types of the
#: calls (C-contiguous arrays, Python ints as int64), so a call finds its machine code
SIGNATURES: dict[str, tuple[str, ...]] = {
    # the window edges are read-only arrays (cached per band geometry)
    "moving_columns": ("float64[:, ::1], int64, int64, Array(int64, 1, 'C', readonly=True), "
                       "Array(int64, 1, 'C', readonly=True), Array(int64, 1, 'C', readonly=True), "
                       "Array(int64, 1, 'C', readonly=True), float64, bool_[::1]",),
}
#: CPU seconds to compile each, reference machine (docs/benchmarks.md)
COMPILE_SECONDS: dict[str, float] = {"moving_columns": 0.5}
