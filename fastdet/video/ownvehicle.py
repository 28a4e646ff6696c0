"""The own vehicle in the picture: regions that stay fixed while the scene flows.

A dashcam sees parts of its own vehicle -- the hood, the dashboard, mirrors, the windscreen
frame -- and some videos carry letterbox bars. They never hold a vehicle to find, yet their
edges can look like one to a window classifier. They are found in the first seconds of a
video, as the horizon is (:mod:`fastdet.video.horizon`), and every positive window that lies
mostly on them is dropped (:func:`window_fraction`, :class:`OwnVehicleConfig`
``max_fraction``).

How (:class:`OwnVehicleEstimator`): frames shrunk to ``work_rows`` rows (grey), compared in
pairs ``gap_s`` seconds apart. A pixel is *textured* when its grey-level gradient
(central difference) is at least ``min_gradient``, and *still* when it also changed by less
than ``max_change`` grey levels: a textured pixel that moved by more than about
``max_change / min_gradient`` of a work pixel is not still. A pair counts only when the
scene moves: at least ``min_moving`` of its textured pixels are not still. A static camera
(or a stop at a red light) gives no counted pair, so nothing is masked. Per cell
(``1 / cells`` of the width), ``still / textured`` over the counted pairs; a cell is *fixed*
when that is at least ``min_still`` and it had enough texture.

Fixed cells alone are not the own vehicle: a car driving ahead at the same speed, a solid
lane line (a line pointing at the focus of expansion does not change as the scene flows
along it) and the far scenery near the horizon are still too. The own vehicle's parts are
also at the picture's border: the region is the union of the 8-connected components of the
fixed cells (after closing gaps of one cell) that touch the frame's border, their holes
filled, plus below them: each column's run of cells without motion evidence from the bottom
border up to the highest fixed cell of the run (the plain surface of a hood or a dashboard
below its edge). Letterbox bars (border rows or columns that are near black on every
frame) are added.

What is not found: a camera that moves relative to its vehicle (a helmet camera on a
motorcycle: the dash then wobbles by several pixels between frames) -- its parts are not
still in the picture.
"""
from __future__ import annotations

from collections.abc import Iterator

import cv2
import numpy as np

from ..config import OwnVehicleConfig
from .state import FrameState, Stage


def _grey(frame: np.ndarray, rows: int) -> np.ndarray:
    h, w = frame.shape[:2]
    rows = min(rows, h)
    small = cv2.resize(frame, (max(1, round(w * rows / h)), rows), interpolation=cv2.INTER_AREA)
    return cv2.cvtColor(small, cv2.COLOR_BGR2GRAY).astype(np.float32)


def pair_stillness(a: np.ndarray, b: np.ndarray, min_gradient: float,
                   max_change: float) -> tuple[np.ndarray, np.ndarray]:
    """``(textured, still)``: two ``(h, w) bool`` maps of a pair of grey frames ``a`` (the
    earlier) and ``b`` (``(h, w) float32``): textured where ``a``'s central-difference
    gradient magnitude is at least ``min_gradient``, still where textured and
    ``|b - a| < max_change``."""
    gx = np.zeros_like(a)
    gy = np.zeros_like(a)
    gx[:, 1:-1] = (a[:, 2:] - a[:, :-2]) / 2
    gy[1:-1, :] = (a[2:, :] - a[:-2, :]) / 2
    textured = np.hypot(gx, gy) >= min_gradient
    still = textured & (np.abs(b - a) < max_change)
    return textured, still


def _touches_border(labels: np.ndarray, n: int) -> np.ndarray:
    """``(n,) bool``: which labels 1..n occur on the border of ``labels``."""
    edge = np.concatenate([labels[0], labels[-1], labels[:, 0], labels[:, -1]])
    out = np.zeros(n + 1, bool)
    out[edge] = True
    return out[1:]


def fixed_region(still: np.ndarray, textured: np.ndarray, pairs: int, config: OwnVehicleConfig) -> np.ndarray:
    """The own-vehicle region on the cell grid (``(gh, gw) bool``) from per-cell sums over
    ``pairs`` counted pairs: ``still`` and ``textured`` ``(gh, gw)`` (mean per pixel of the
    cell, summed over pairs) (module docstring; letterbox bars are added by the caller)."""
    gh, gw = still.shape
    region = np.zeros((gh, gw), bool)
    if pairs >= config.min_pairs:
        decided = textured >= config.min_texture * pairs
        ratio = np.where(decided, still / np.maximum(textured, 1e-12), 0.0)
        fixed = decided & (ratio >= config.min_still)
        moving = decided & ~fixed
        # close gaps of one cell (OpenCV's default border: the border neither erodes nor dilates)
        closed = cv2.morphologyEx(fixed.astype(np.uint8), cv2.MORPH_CLOSE, np.ones((3, 3), np.uint8)).astype(bool)
        closed = fixed | (closed & ~moving)  # closing never covers a cell that moved
        n, labels = cv2.connectedComponents(closed.astype(np.uint8), connectivity=8)
        if n > 1:
            keep = np.concatenate([[False], _touches_border(labels, n - 1)])
            region = keep[labels]
            region = _fill_holes(region)
            # below the region: runs of cells without motion from the bottom border up to it
            for x in range(gw):
                y = gh - 1
                top = -1
                while y >= 0 and not moving[y, x]:
                    if region[y, x]:
                        top = y
                    y -= 1
                if top >= 0:
                    region[top:, x] = True
    return region


def _fill_holes(mask: np.ndarray) -> np.ndarray:
    """``mask`` with every region of False cells not connected to the border set True."""
    inv = (~mask).astype(np.uint8)
    n, labels = cv2.connectedComponents(inv, connectivity=4)
    if n <= 1:
        return mask
    outside = np.concatenate([[True], _touches_border(labels, n - 1)])
    return mask | ~outside[labels]


class OwnVehicleEstimator:
    """The own-vehicle region of a video from its first frames (module docstring).

    Feed frames in order with :meth:`update` (``(H, W, 3) uint8`` BGR or RGB); :attr:`done`
    once ``config.n_frames(fps)`` frames were seen. :meth:`region` gives the region as a
    ``(H, W) bool`` frame-pixel mask, ``None`` while there is none (too few counted pairs:
    the camera stood still, or too early)."""

    def __init__(self, config: OwnVehicleConfig | None = None, fps: float | None = None) -> None:
        self.config = config if config is not None else OwnVehicleConfig()
        self.gap = self.config.gap(fps)
        self.max_frames = self.config.n_frames(fps)
        self._recent: list[np.ndarray] = []
        self._n = 0
        self._shape: tuple[int, int] | None = None
        self.pairs = 0  # counted pairs (the scene moved)
        self._still: np.ndarray | None = None
        self._tex: np.ndarray | None = None
        self._dark: np.ndarray | None = None  # per work pixel: dark on every frame so far
        self._cache: tuple[int, np.ndarray | None] | None = None

    @property
    def done(self) -> bool:
        return self._n >= self.max_frames

    @property
    def frames(self) -> int:
        return self._n

    def cut(self) -> None:
        """The next frame does not follow the last one: pair no frames across it."""
        self._recent.clear()

    def update(self, frame: np.ndarray) -> None:
        """Add the next frame; nothing once :attr:`done`. A frame of another size restarts."""
        if self.done:
            return
        shape = (int(frame.shape[0]), int(frame.shape[1]))
        if self._shape != shape:
            self._shape = shape
            self._recent.clear()
            self.pairs = 0
            self._still = self._tex = self._dark = None
        c = self.config
        take = self._n % c.every == 0
        need = (self._n + self.gap) % c.every == 0  # the earlier frame of a later pair
        self._n += 1
        self._recent.append(None)  # type: ignore[arg-type]
        if not (take or need):
            self._trim()
            return
        g = _grey(frame, c.work_rows)
        self._recent[-1] = g
        dark = g < c.bar_level
        self._dark = dark if self._dark is None else self._dark & dark
        if take and len(self._recent) > self.gap and self._recent[-1 - self.gap] is not None:
            a = self._recent[-1 - self.gap]
            textured, still = pair_stillness(a, g, c.min_gradient, c.max_change)
            nt = int(textured.sum())
            if nt and 1 - still.sum() / nt >= c.min_moving:
                cs = self._cell_px(g.shape)
                gh, gw = -(-g.shape[0] // cs), -(-g.shape[1] // cs)
                if self._still is None:
                    self._still = np.zeros((gh, gw))
                    self._tex = np.zeros((gh, gw))
                assert self._tex is not None
                self._still += _cell_mean(still, cs, (gh, gw))
                self._tex += _cell_mean(textured, cs, (gh, gw))
                self.pairs += 1
        self._trim()

    def _trim(self) -> None:
        while len(self._recent) > self.gap + 1:
            self._recent.pop(0)

    def _cell_px(self, work_shape: tuple[int, int]) -> int:
        return max(2, round(work_shape[1] / self.config.cells))

    def region(self) -> np.ndarray | None:
        """``(H, W) bool``: the own-vehicle region in frame pixels, or ``None``."""
        if self._cache is not None and self._cache[0] == self._n:
            return self._cache[1]
        out = self._region()
        self._cache = (self._n, out)
        return out

    def _region(self) -> np.ndarray | None:
        if self._shape is None or self._dark is None:
            return None
        c = self.config
        work = self._dark.shape
        cs = self._cell_px(work)
        gh, gw = -(-work[0] // cs), -(-work[1] // cs)
        h, w = self._shape
        out = np.zeros((h, w), bool)
        if self._still is not None and self.pairs >= c.min_pairs:
            assert self._tex is not None
            cells = fixed_region(self._still, self._tex, self.pairs, c)
            # cell (i, j) covers work rows i*cs .. (i+1)*cs: frame rows scaled by h / work rows
            ys = np.minimum((np.arange(h) + 0.5) * work[0] / h // cs, gh - 1).astype(np.int64)
            xs = np.minimum((np.arange(w) + 0.5) * work[1] / w // cs, gw - 1).astype(np.int64)
            out = cells[ys[:, None], xs[None, :]]
        if self._n >= 2:
            top, bottom, left, right = bar_widths(self._dark)
            fy, fx = h / work[0], w / work[1]
            out[:int(top * fy)] = True
            out[h - int(bottom * fy):] = True
            out[:, :int(left * fx)] = True
            out[:, w - int(right * fx):] = True
        if not out.any() or out.mean() > c.max_area:
            return None  # nothing, or not the own vehicle (a camera that stood still, a dark video)
        return out


def _cell_mean(m: np.ndarray, cs: int, grid: tuple[int, int]) -> np.ndarray:
    """Mean of ``m`` (bool ``(h, w)``) over each ``cs x cs`` cell (partial cells at the
    right and bottom edge: over their pixels)."""
    gh, gw = grid
    h, w = m.shape
    pad = np.zeros((gh * cs, gw * cs), np.float64)
    pad[:h, :w] = m
    cnt = np.zeros_like(pad)
    cnt[:h, :w] = 1
    s = pad.reshape(gh, cs, gw, cs).sum((1, 3))
    n = cnt.reshape(gh, cs, gw, cs).sum((1, 3))
    return s / np.maximum(n, 1)


def bar_widths(dark: np.ndarray) -> tuple[int, int, int, int]:
    """Letterbox bars of a ``(h, w) bool`` map of pixels dark on every frame: the number of
    whole dark rows at the top and at the bottom and of whole dark columns at the left and at
    the right, ``(top, bottom, left, right)`` (an all-dark map: all its rows at the top)."""
    rows = dark.all(1)
    cols = dark.all(0)

    def run(line: np.ndarray) -> int:
        nz = np.flatnonzero(~line)
        return int(nz[0]) if len(nz) else len(line)

    top, left = run(rows), run(cols)
    bottom = run(rows[::-1]) if top < len(rows) else 0
    right = run(cols[::-1]) if left < len(cols) else 0
    return top, bottom, left, right


def window_fraction(region: np.ndarray, boxes: np.ndarray, integral: np.ndarray | None = None) -> np.ndarray:
    """Fraction ``(N,) float64`` of each box ``(N, 4)`` x1, y1, x2, y2 (frame pixels,
    exclusive) inside ``region`` (``(H, W) bool``); a box clipped to nothing gives 0.
    ``integral``: ``cv2.integral(region)`` when the caller keeps it."""
    if integral is None:
        integral = cv2.integral(region.astype(np.uint8))
    b = np.asarray(boxes, np.int64).reshape(-1, 4)
    h, w = region.shape
    x1, x2 = np.clip(b[:, 0], 0, w), np.clip(b[:, 2], 0, w)
    y1, y2 = np.clip(b[:, 1], 0, h), np.clip(b[:, 3], 0, h)
    inside = integral[y2, x2] - integral[y1, x2] - integral[y2, x1] + integral[y1, x1]
    # an inverted box (x2 < x1 and y2 < y1) has no area, not the product of two negative sides
    a = np.maximum(b[:, 2] - b[:, 0], 0) * np.maximum(b[:, 3] - b[:, 1], 0)
    return np.where(a > 0, inside / np.maximum(a, 1), 0.0)


class OwnVehicleStage(Stage):
    """Drop the positive windows lying mostly on the own vehicle: at least
    ``config.max_fraction`` of their area in the region :class:`OwnVehicleEstimator` finds in
    the first ``config.frames_s`` seconds (:meth:`prime` gives them ahead of time)."""

    name = "ownvehicle"

    def __init__(self, config: OwnVehicleConfig, fps: float | None) -> None:
        self.config = config
        self.estimator = OwnVehicleEstimator(config, fps)
        self._region: np.ndarray | None = None
        self._integral: np.ndarray | None = None
        self.dropped = 0  # windows dropped so far

    def tee(self, frames: Iterator[np.ndarray]) -> Iterator[np.ndarray]:
        """``frames`` passed on, each also fed to the estimate (while it takes more)."""
        for f in frames:
            if not self.estimator.done:
                self.estimator.update(np.asarray(f))
            yield f

    def prime(self, frames: Iterator[np.ndarray]) -> None:
        """Feed the first frames of the video (those :meth:`tee` has not fed; at most what the
        estimate takes) before :meth:`__call__` sees any frame; the frames fed after are not
        paired with these."""
        for f in frames:
            if self.estimator.done:
                break
            self.estimator.update(np.asarray(f))
        self.estimator.cut()

    @property
    def region(self) -> np.ndarray | None:
        """``(H, W) bool``: the region windows are dropped on (``None``: none yet)."""
        return self.estimator.region()

    def __call__(self, s: FrameState) -> FrameState:
        est = self.estimator
        if not est.done:
            est.update(s.bgr)
        n = len(s.windows)
        s = self.filter(s)
        self.dropped += n - len(s.windows)
        return s

    def filter(self, s: FrameState) -> FrameState:
        """``s`` less its windows on the region as it is now (none while it is being
        estimated), the estimate not fed."""
        if not self.estimator.done:
            return s  # no region while it is being estimated
        region = self.estimator.region()
        if region is None or not len(s.windows):
            return s
        if region is not self._region:
            self._region, self._integral = region, cv2.integral(region.astype(np.uint8))
        keep = window_fraction(region, s.windows.boxes, self._integral) < self.config.max_fraction
        if not keep.all():
            s.windows = s.windows[keep]
        return s

    def reset(self) -> None:
        self.estimator.cut()  # the camera stays: keep the region, pair no frames across a cut


class OwnVehicleFollower(Stage):
    """Drop the positive windows on the own vehicle's region as ``leader`` (an
    :class:`OwnVehicleStage` fed the same frame just before) has it now, without feeding its
    estimate: pipelines run side by side over one video (:mod:`fastdet.video.replay`) share one
    estimate, and each drops its own windows as its own stage would."""

    name = "ownvehicle"

    def __init__(self, leader: OwnVehicleStage) -> None:
        self.leader = leader
        self.dropped = 0  # windows dropped so far

    def __call__(self, s: FrameState) -> FrameState:
        n = len(s.windows)
        s = self.leader.filter(s)
        self.dropped += n - len(s.windows)
        return s
