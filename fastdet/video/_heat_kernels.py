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

