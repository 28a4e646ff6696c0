"""Box arithmetic, once: conversions, areas, intersections, IoU, overlap, window grids.

Boxes are ``(N, 4)`` arrays ``x1, y1, x2, y2`` in frame pixels with ``x2, y2`` exclusive
(a box ``0, 0, 64, 64`` covers 64x64 pixels), unless a function says ``ltwh``: ``left, top,
width, height`` (MOTChallenge files). Functions accept anything ``np.asarray`` takes and
return new arrays.
"""
from __future__ import annotations

import numpy as np

#: the largest magnitude of a box coordinate, width or height (frame pixels) read from a file
#: or an option: 2**24, far past any frame and exact in float32; products of two (areas,
#: cross products) stay finite in float64, where 1e200 or 1e308 overflowed to inf and NaN
MAX_COORD = 2.0**24

__all__ = [
    "MAX_COORD", "ltwh_to_xyxy", "xyxy_to_ltwh", "area", "intersection", "iou", "overlap_fraction",
    "clip", "window_offsets", "window_grid_boxes",
]


def ltwh_to_xyxy(ltwh: np.ndarray) -> np.ndarray:
    """``(N, 4)`` left, top, width, height -> ``(N, 4) float64`` x1, y1, x2, y2."""
    a = np.asarray(ltwh, dtype=np.float64).reshape(-1, 4)
    out = a.copy()
    out[:, 2] = a[:, 0] + a[:, 2]
    out[:, 3] = a[:, 1] + a[:, 3]
    return out


def xyxy_to_ltwh(xyxy: np.ndarray) -> np.ndarray:
    """``(N, 4)`` x1, y1, x2, y2 -> ``(N, 4)`` left, top, width, height (same dtype)."""
    a = np.asarray(xyxy).reshape(-1, 4)
    out = a.copy()
    out[:, 2] = a[:, 2] - a[:, 0]
    out[:, 3] = a[:, 3] - a[:, 1]
    return out


def area(b: np.ndarray) -> np.ndarray:
    """``(N,) float64`` areas in pixels² (0 for an empty or inverted box)."""
    b = np.asarray(b, dtype=np.float64).reshape(-1, 4)
    return np.clip(b[:, 2] - b[:, 0], 0.0, None) * np.clip(b[:, 3] - b[:, 1], 0.0, None)


def intersection(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``(N, M) float64`` intersection areas of boxes ``a (N, 4)`` and ``b (M, 4)``."""
    a = np.asarray(a, dtype=np.float64).reshape(-1, 4)
    b = np.asarray(b, dtype=np.float64).reshape(-1, 4)
    w = np.minimum(a[:, None, 2], b[None, :, 2]) - np.maximum(a[:, None, 0], b[None, :, 0])
    h = np.minimum(a[:, None, 3], b[None, :, 3]) - np.maximum(a[:, None, 1], b[None, :, 1])
    return np.clip(w, 0.0, None) * np.clip(h, 0.0, None)


def iou(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``(N, M) float64`` intersection over union (0 where both areas are 0)."""
    inter = intersection(a, b)
    union = area(a)[:, None] + area(b)[None, :] - inter
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(union > 0, inter / np.where(union > 0, union, 1.0), 0.0)


def overlap_fraction(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``(N, M) float64``: the fraction of box ``a[i]``'s area that lies inside box ``b[j]``
    (an empty ``a[i]`` counts as area 1e-9, so its fraction is 0)."""
    a = np.asarray(a, np.float64).reshape(-1, 4)
    ar = np.maximum((a[:, 2] - a[:, 0]) * (a[:, 3] - a[:, 1]), 1e-9)
    return intersection(a, b) / ar[:, None]


def clip(boxes: np.ndarray, shape: tuple[int, ...]) -> np.ndarray:
    """Boxes clipped to a frame of ``shape = (H, W, ...)`` (same dtype)."""
    b = np.asarray(boxes).reshape(-1, 4).copy()
    h, w = int(shape[0]), int(shape[1])
    b[:, [0, 2]] = np.clip(b[:, [0, 2]], 0, w)
    b[:, [1, 3]] = np.clip(b[:, [1, 3]], 0, h)
    return b


def window_offsets(index: np.ndarray, step_cells: int, cell_px: int, scale: float) -> np.ndarray:
    """``(N,) int64`` pixel offsets in the frame of window positions ``index`` of a band
    scaled by ``1/scale``, windows ``step_cells`` cells of ``cell_px`` pixels apart (the
    offset of position k is ``int(k * step_cells * cell_px * scale)``, truncated)."""
    return (np.asarray(index) * step_cells * cell_px * scale).astype(np.int64)


def window_grid_boxes(x0: int, y0: int, rows: np.ndarray, cols: np.ndarray, step_cells: int,
                      cell_px: int, scale: float, win_w: int, win_h: int) -> np.ndarray:
    """``(N, 4) int32`` frame boxes of the windows at grid positions ``(rows, cols)`` of a
    band whose top-left corner is ``(x0, y0)`` in the frame: ``win_w x win_h`` windows of
    the scaled band, i.e. ``int(win_w * scale) x int(win_h * scale)`` frame pixels."""
    boxes = np.empty((len(rows), 4), np.int32)
    boxes[:, 0] = x0 + window_offsets(cols, step_cells, cell_px, scale)
    boxes[:, 1] = y0 + window_offsets(rows, step_cells, cell_px, scale)
    boxes[:, 2] = boxes[:, 0] + int(win_w * scale)
    boxes[:, 3] = boxes[:, 1] + int(win_h * scale)
    return boxes
