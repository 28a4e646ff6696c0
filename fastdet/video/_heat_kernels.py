"""Numba kernels of :mod:`fastdet.video.heatmap`: add weighted rectangles to a heat grid."""
from __future__ import annotations

import numpy as np
from numba import njit

from .._numba import EXACT


@njit(**EXACT)
def add_rects(grid: np.ndarray, rects: np.ndarray, weights: np.ndarray, factor: float) -> None:
    """``grid[y1:y2, x1:x2] += factor * weights[i]`` for each ``rects[i] = (x1, y1, x2, y2)``.

    ``rects`` must already lie inside ``grid`` (the caller clips them)."""
    for i in range(rects.shape[0]):
        x1 = rects[i, 0]
        y1 = rects[i, 1]
        x2 = rects[i, 2]
        y2 = rects[i, 3]
        w = factor * weights[i]
        for y in range(y1, y2):
            row = grid[y]
            for x in range(x1, x2):
                row[x] += w


# --------------------------------------------------------------------------------------
# what the package calls, compiled ahead of time (fastdet._numba.ensure_compiled)
# --------------------------------------------------------------------------------------
#: argument types of every call the package makes to each kernel: exactly the types of the
#: calls (C-contiguous arrays, Python ints as int64), so a call finds its machine code
SIGNATURES: dict[str, tuple[str, ...]] = {
    "add_rects": ("float64[:, ::1], int32[:, ::1], float64[::1], float64",),
}
#: CPU seconds to compile each, reference machine (docs/benchmarks.md)
COMPILE_SECONDS: dict[str, float] = {"add_rects": 0.3}
