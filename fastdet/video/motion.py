"""Frame-to-frame motion for the wide-window (oncoming-traffic) model.

Oncoming cars above the median cross the view in about half a second, several times
faster than the trees, barrier and road beside them, which the wide-window model otherwise
mistakes for cars. :class:`FrameMotion` keeps the previous frame's grey levels over the
region the wide search covers and gives, for any window, the mean absolute grey-level
difference inside it (an integral image of ``|gray_t - gray_{t-1}|``: four lookups a
window). :func:`moving_bands` turns a search band into the sub-bands whose windows move
enough, so the wide model is only run there; :func:`window_motion` gates its positive
windows. Thresholds: :class:`fastdet.config.MotionGate`.
"""
from __future__ import annotations

import math
from collections import deque
from dataclasses import replace
from functools import lru_cache
from typing import NamedTuple

import cv2
import numpy as np

from ..boxes import window_offsets
from ..config import FeatureConfig, SearchBand
from ..detect.bands import BandGeometry
from ._motion_kernels import moving_columns

#: the numba kernels of the motion gate (compiled ahead of time: fastdet._numba.ensure_compiled)
KERNELS = (moving_columns,)


class MotionMap(NamedTuple):
    """Integral image ``(h + 1, w + 1) float64`` of ``|gray - previous gray|`` over the frame
    region whose top-left corner is ``origin = (x, y)`` (frame pixels); ``noise``: the
    median of ``|gray - previous gray|`` over the region (grey levels, from every 4th pixel
    of every 4th row), what :meth:`fastdet.config.MotionGate.threshold` scales with."""

    integral: np.ndarray
    origin: tuple[int, int] = (0, 0)
    noise: float = 0.0


class FrameMotion:
    """The motion of the current frame against the previous one.

    ``update(frame, roi, lag=1)`` takes a ``(H, W, 3) uint8`` BGR frame and returns the
    :class:`MotionMap` of ``roi = (x1, y1, x2, y2)`` (default: the whole frame; only those
    pixels are converted and differenced) against the frame ``lag`` frames back
    (:meth:`fastdet.config.MotionGate.lag`), or ``None`` while fewer than ``lag`` earlier
    frames were seen (the first frame; the first after :meth:`reset`, or after a change of
    frame size or region).
    """

    def __init__(self) -> None:
        self._prev: deque[np.ndarray] = deque()
        self._key: tuple | None = None

    def reset(self) -> None:
        self._prev.clear()
        self._key = None

    def update(self, frame: np.ndarray, roi: tuple[int, int, int, int] | None = None,
               lag: int = 1) -> MotionMap | None:
        h, w = frame.shape[:2]
        x1, y1, x2, y2 = (0, 0, w, h) if roi is None else roi
        x1, x2 = min(max(int(x1), 0), w), min(max(int(x2), 0), w)
        y1, y2 = min(max(int(y1), 0), h), min(max(int(y2), 0), h)
        gray = cv2.cvtColor(np.ascontiguousarray(frame[y1:y2, x1:x2]), cv2.COLOR_BGR2GRAY)
        key = (h, w, x1, y1, x2, y2)
        if self._key != key:
            self._prev.clear()
        self._key = key
        prev = self._prev[0] if len(self._prev) >= lag else None
        self._prev.append(gray)
        while len(self._prev) > lag:
            self._prev.popleft()
        if prev is None:
            return None
        diff = cv2.absdiff(gray, prev)
        noise = float(np.median(diff[::4, ::4])) if diff.size else 0.0
        return MotionMap(cv2.integral(diff, sdepth=cv2.CV_64F), (x1, y1), noise)


def window_motion(motion: MotionMap, boxes: np.ndarray) -> np.ndarray:
    """Mean absolute grey-level change ``(N,) float64`` inside each box ``(N, 4)`` x1, y1,
    x2, y2 (frame pixels, exclusive; clipped to the map's region; a box with nothing inside
    it gives 0)."""
    b = np.asarray(boxes, np.int64).reshape(-1, 4)
    return _mean_in(motion, b[:, 0], b[:, 1], b[:, 2], b[:, 3])


def _mean_in(motion: MotionMap, x1, y1, x2, y2) -> np.ndarray:
    """Mean of the map over the boxes ``x1..x2 x y1..y2`` (frame pixels, exclusive), given
    as integer arrays that broadcast together (one box per element); clipped to the map's
    region, 0 where nothing is left."""
    integral, (ox, oy) = motion.integral, motion.origin
    h, w = integral.shape[0] - 1, integral.shape[1] - 1
    x1, x2 = np.clip(x1 - ox, 0, w), np.clip(x2 - ox, 0, w)
    y1, y2 = np.clip(y1 - oy, 0, h), np.clip(y2 - oy, 0, h)
    total = integral[y2, x2] - integral[y1, x2] - integral[y2, x1] + integral[y1, x1]
    area = (x2 - x1) * (y2 - y1)
    return np.where(area > 0, total / np.maximum(area, 1), 0.0)


@lru_cache(maxsize=64)
def _window_edges(geo: BandGeometry, win_w: int, win_h: int,
                  cell: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``(left (nx,), top (ny,), right (nx,), bottom (ny,))`` int64 frame pixels of the window
    columns and rows of a band, as ``window_boxes()`` gives them (the same for every frame
    of a video: kept, read-only)."""
    s = geo.band.scale
    left = geo.x0 + window_offsets(np.arange(geo.nx), geo.step, cell, s)
    top = geo.y0 + window_offsets(np.arange(geo.ny), geo.step, cell, s)
    right, bottom = left + int(win_w * s), top + int(win_h * s)
    out = tuple(np.ascontiguousarray(a, np.int64) for a in (left, top, right, bottom))
    for a in out:
        a.flags.writeable = False
    return out  # type: ignore[return-value]


def moving_bands(geo: BandGeometry, config: FeatureConfig, motion: MotionMap,
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
    s = geo.band.scale
    cell = config.pixels_per_cell
    left, top, right, bottom = _window_edges(geo, int(config.win_w), int(config.win_h), int(cell))
    # columns with a window whose mean motion reaches min_motion (the grid of _mean_in)
    moving = np.empty(geo.nx, bool)
    integral = motion.integral
    if integral.dtype != np.float64 or not integral.flags.c_contiguous:
        integral = np.ascontiguousarray(integral, np.float64)
    moving_columns(integral, int(motion.origin[0]), int(motion.origin[1]), left, top, right, bottom,
                   float(min_motion), moving)
    idx = np.flatnonzero(moving)
    if not len(idx):
        return []
    # runs of moving columns; columns less than a window apart are searched together
    per_window = max(1, config.blocks_x // geo.step)
    breaks = np.flatnonzero(np.diff(idx) > per_window)
    starts = [int(idx[0]), *idx[breaks + 1].tolist()]
    stops = [*idx[breaks].tolist(), int(idx[-1])]
    b = geo.band
    cell_px = cell * s  # one cell of the scaled band, in frame pixels
    win_cells = config.win_w // cell
    out = []
    for c0, c1 in zip(starts, stops):
        # one window position of margin on each side: the moving windows' pixels then see
        # the same neighbours as in the full band (HOG gradients, resampling)
        c0, c1 = max(c0 - 1, 0), min(c1 + 1, geo.nx - 1)
        x_a = int(left[c0])
        # whole cells wide: when a cell is a whole number of pixels (every default wide
        # scale), the sub-band resamples exactly as the full band does
        x_b = x_a + math.ceil(((c1 - c0) * geo.step + win_cells) * cell_px - 1e-9)
        out.append(replace(b, x_start=x_a, x_stop=min(x_b, geo.x1)))  # its rows and their core kept
    return out


def warmup_motion() -> None:
    """Compile (or load from cache) the numba kernel of :func:`moving_bands`, for the
    read-only window edges it is called with."""
    e, e1 = np.zeros(1, np.int64), np.ones(1, np.int64)
    e.flags.writeable = e1.flags.writeable = False
    moving_columns(np.zeros((2, 2), np.float64), 0, 0, e, e, e1, e1, 1.0, np.empty(1, bool))
