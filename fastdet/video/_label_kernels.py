"""Numba kernels of :mod:`fastdet.video.heatmap`: threshold, label and measure the blobs of a
heat grid in one go (what ``scipy.ndimage.label`` + ``find_objects`` + a loop over the blobs
did, at a tenth of the cost on a 180 x 320 grid, and without importing SciPy).

Labels are those of ``scipy.ndimage.label`` with its default (4-connected) structure:
numbered 1, 2, ... in raster order of each blob's first cell (``tests/video/test_heatmap.py``
checks them against SciPy and against a flood fill).
"""
from __future__ import annotations

import numpy as np
from numba import njit

from .._numba import EXACT


@njit(**EXACT)
def _find(parent: np.ndarray, i: int) -> int:
    while parent[i] != i:
        parent[i] = parent[parent[i]]  # path halving
        i = parent[i]
    return i


@njit(**EXACT)
def label_blobs(heat: np.ndarray, threshold: float, labels: np.ndarray, bbox: np.ndarray,
                peak: np.ndarray) -> int:
    """Label the 4-connected blobs of ``heat > threshold``; returns their number ``n``.

    heat: ``(H, W) float64``; labels: ``(H, W) int32`` output (0 = background, blobs 1..n
    in raster order of their first cell, as ``scipy.ndimage.label``); bbox: ``(K, 4) int64``
    output, row ``i`` = ``(y0, y1, x0, x1)`` (grid cells, end exclusive) of blob ``i + 1``;
    peak: ``(K,) float64`` output, the largest heat of blob ``i + 1``. ``K`` must be at
    least the number of blobs (``(H * W + 1) // 2 + 1`` always is)."""
    h, w = heat.shape
    parent = np.empty(h * w // 2 + 2, np.int64)
    nxt = 1
    for y in range(h):
        for x in range(w):
            if not heat[y, x] > threshold:
                labels[y, x] = 0
                continue
            up = labels[y - 1, x] if y > 0 else 0
            left = labels[y, x - 1] if x > 0 else 0
            if up == 0 and left == 0:
                parent[nxt] = nxt
                labels[y, x] = nxt
                nxt += 1
            elif up == 0:
                labels[y, x] = left
            elif left == 0:
                labels[y, x] = up
            else:
                a = _find(parent, up)
                b = _find(parent, left)
                if a < b:
                    parent[b] = a
                elif b < a:
                    parent[a] = b
                labels[y, x] = min(a, b)
    # a blob's root is its smallest provisional label, the one of its first cell in raster
    # order: numbering the roots in increasing order numbers the blobs in that order
    final = np.zeros(nxt, np.int64)
    n = 0
    for i in range(1, nxt):
        r = _find(parent, i)
        if r == i:
            n += 1
            final[i] = n
        else:
            final[i] = final[r]
    for i in range(n):
        bbox[i, 0] = h
        bbox[i, 1] = 0
        bbox[i, 2] = w
        bbox[i, 3] = 0
        peak[i] = -np.inf
    for y in range(h):
        for x in range(w):
            p = labels[y, x]
            if p == 0:
                continue
            k = final[p]
            labels[y, x] = k
            j = k - 1
            if y < bbox[j, 0]:
                bbox[j, 0] = y
            if y + 1 > bbox[j, 1]:
                bbox[j, 1] = y + 1
            if x < bbox[j, 2]:
                bbox[j, 2] = x
            if x + 1 > bbox[j, 3]:
                bbox[j, 3] = x + 1
            v = heat[y, x]
            if v > peak[j]:
                peak[j] = v
    return n


@njit(**EXACT)
def extent_boxes(heat: np.ndarray, labels: np.ndarray, n: int, bbox: np.ndarray, peak: np.ndarray,
                 extent: float, out: np.ndarray) -> None:
    """``out[i] = (y0, y1, x0, x1)``: the bounding box (grid cells, end exclusive) of the cells
    of blob ``i + 1`` whose heat is at least ``extent * peak[i]`` (``extent = 0``: the whole
    blob; never empty, the peak cell is in it). heat ``(H, W) float64``, labels ``(H, W)
    int32`` and ``bbox``, ``peak`` as :func:`label_blobs` left them; out ``(>= n, 4) int64``."""
    for i in range(n):
        y0, y1, x0, x1 = bbox[i, 0], bbox[i, 1], bbox[i, 2], bbox[i, 3]
        if extent <= 0:
            out[i, 0], out[i, 1], out[i, 2], out[i, 3] = y0, y1, x0, x1
            continue
        lim = extent * peak[i]
        oy0, oy1, ox0, ox1 = y1, y0, x1, x0
        for y in range(y0, y1):
            for x in range(x0, x1):
                if labels[y, x] == i + 1 and heat[y, x] >= lim:
                    if y < oy0:
                        oy0 = y
                    if y + 1 > oy1:
                        oy1 = y + 1
                    if x < ox0:
                        ox0 = x
                    if x + 1 > ox1:
                        ox1 = x + 1
        out[i, 0], out[i, 1], out[i, 2], out[i, 3] = oy0, oy1, ox0, ox1


# --------------------------------------------------------------------------------------
# what the package calls, compiled ahead of time (fastdet._numba.ensure_compiled)
# --------------------------------------------------------------------------------------
#: argument types of every call the package makes to each kernel: exactly the types of the
#: calls (C-contiguous arrays, Python ints as int64), so a call finds its machine code
SIGNATURES: dict[str, tuple[str, ...]] = {
    "label_blobs": ("float64[:, ::1], float64, int32[:, ::1], int64[:, ::1], float64[::1]",),
    "extent_boxes": ("float64[:, ::1], int32[:, ::1], int64, int64[:, ::1], float64[::1], float64, int64[:, ::1]",),
}
#: CPU seconds to compile each, reference machine (docs/benchmarks.md)
COMPILE_SECONDS: dict[str, float] = {"label_blobs": 1.8, "extent_boxes": 0.6}
