"""Frame-to-frame motion for the wide-window (oncoming-traffic) model.

Oncoming cars above the median cross the view in about half a second, several times
faster than the trees, barrier and road beside them, which the wide-window model otherwise
mistakes for cars. :class:`FrameMotion` keeps the previous frame's grey levels and gives,
for any window, the mean absolute grey-level difference inside it (an integral image of
``|gray_t - gray_{t-1}|``, so each window costs four lookups). :func:`moving_bands` turns a
search band into the sub-bands whose windows move enough, so the wide model is only run
there; :func:`window_motion` gates its positive windows. Thresholds: :class:`fastdet.config.MotionGate`.
"""
from __future__ import annotations

import cv2
import numpy as np

from .config import FeatureConfig, SearchBand
from .search import BandGeometry


class FrameMotion:
    """The motion of the current frame against the previous one.

    ``update(frame)`` takes a ``(H, W, 3) uint8`` BGR frame and returns the integral image
    ``(H + 1, W + 1) float64`` of ``|gray - previous gray|``, or ``None`` for the first frame
    (or the first after :meth:`reset`, or after a change of frame size).
    """

    def __init__(self) -> None:
        self._prev: np.ndarray | None = None

    def reset(self) -> None:
        self._prev = None

    def update(self, frame: np.ndarray) -> np.ndarray | None:
        gray = cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY)
        prev, self._prev = self._prev, gray
        if prev is None or prev.shape != gray.shape:
            return None
        return cv2.integral(cv2.absdiff(gray, prev), sdepth=cv2.CV_64F)


def window_motion(integral: np.ndarray, boxes: np.ndarray) -> np.ndarray:
    """Mean absolute grey-level change ``(N,) float64`` inside each box ``(N, 4)`` x1, y1,
    x2, y2 (exclusive; clipped to the frame; an empty box gives 0)."""
    boxes = np.asarray(boxes, np.int64).reshape(-1, 4)
    h, w = integral.shape[0] - 1, integral.shape[1] - 1
    x1, x2 = np.clip(boxes[:, 0], 0, w), np.clip(boxes[:, 2], 0, w)
    y1, y2 = np.clip(boxes[:, 1], 0, h), np.clip(boxes[:, 3], 0, h)
    total = integral[y2, x2] - integral[y1, x2] - integral[y2, x1] + integral[y1, x1]
    area = (x2 - x1) * (y2 - y1)
    return np.where(area > 0, total / np.maximum(area, 1), 0.0)


def moving_bands(geo: BandGeometry, config: FeatureConfig, integral: np.ndarray,
                 min_motion: float) -> list[SearchBand]:
    """The parts of one search band worth searching: for each run of window columns in which
    some window's :func:`window_motion` reaches ``min_motion``, a :class:`SearchBand` of the
    same scale and rows spanning those windows and one window position more on each side.
    Its windows sit where the full band's do (the span starts on a window position). When
    a cell is a whole number of frame pixels at the band's scale and the full band a whole
    number of cells wide (the default wide search), the sub-band is resampled exactly as the
    full band and its windows' decision values equal the full band's (to rounding);
    otherwise they differ by the resampling of slightly different widths."""
    if geo.n_windows == 0:
        return []
    from .search import window_boxes

    rows, cols = np.divmod(np.arange(geo.n_windows), geo.nx)
    boxes = window_boxes(geo, rows, cols, config)
    moving = (window_motion(integral, boxes) >= min_motion).reshape(geo.ny, geo.nx).any(axis=0)
    if not moving.any():
        return []
    idx = np.flatnonzero(moving)
    # runs of moving columns; columns less than a window apart are searched together
    per_window = max(1, config.blocks_x // geo.step)
    breaks = np.flatnonzero(np.diff(idx) > per_window)
    starts = np.concatenate([[idx[0]], idx[breaks + 1]])
    stops = np.concatenate([idx[breaks], [idx[-1]]])
    b = geo.band
    cell_px = config.pixels_per_cell * b.scale  # one cell of the scaled band, in frame pixels
    win_cells = config.win_w // config.pixels_per_cell
    out = []
    for c0, c1 in zip(starts, stops):
        # one window position of margin on each side: the moving windows' pixels then see
        # the same neighbours as in the full band (HOG gradients, resampling)
        c0, c1 = max(c0 - 1, 0), min(c1 + 1, geo.nx - 1)
        x_a = int(boxes[c0, 0])
        # whole cells wide: when a cell is a whole number of pixels (every default wide
        # scale), the sub-band resamples exactly as the full band does
        x_b = x_a + int(np.ceil(((c1 - c0) * geo.step + win_cells) * cell_px - 1e-9))
        out.append(SearchBand(b.scale, b.y_start, b.y_stop, x_a, min(x_b, geo.x1)))
    return out
