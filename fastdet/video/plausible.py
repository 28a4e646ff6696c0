"""Dropping returned boxes that cannot be vehicles: a second box on one vehicle, and (off by
default) a box whose size does not fit where it stands (:class:`~fastdet.config.PlausibleConfig`).

**Duplicates** (:func:`duplicates`): two vehicles that are each at least half in view overlap
by at most IoU 0.5, so of two returned boxes above ``max_iou`` the lower-scored one is a second
box on the same vehicle (two tracks on one car, or two boxes the refinement moved onto it) and
is dropped -- greedy non-maximum suppression by score over the boxes of the frame.

**Perspective** (:func:`perspective_ok`): on a flat road a vehicle's width in pixels is
``W / h_c`` times how many rows its bottom edge is below the horizon (``W`` its width, ``h_c``
the camera's height above the road; Hoiem, Efros & Hebert, CVPR 2006). The pipeline knows the
horizon (:mod:`fastdet.video.horizon`) but not the camera's height, so the test asks only what
no vehicle and no camera can give: a ratio below ``min_ratio`` (too narrow for how low it
stands: a bollard, a sign, the dashboard) or above ``max_ratio`` (too wide for how close to
the horizon it stands, or its bottom above the horizon), with the horizon allowed ``slack``
of the frame height either way.

The stage (:class:`PlausibleStage`) runs on the boxes :meth:`VideoDetector.update
<fastdet.VideoDetector.update>` returns, after the refinement: the tracker, the heat maps and
the guided search keep every box. With the offline pass the rules run after it instead
(:func:`fastdet.video.run.offline_boxes`).
"""
from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ..boxes import iou
from ..config import REFERENCE_HORIZON, PlausibleConfig
from ..detections import Detections
from .state import FrameState, Stage

#: up to this many boxes :func:`duplicates` builds the whole IoU matrix (8 MB); above, one row a kept box
DENSE_DUPLICATES = 1024


def duplicates(boxes: np.ndarray, scores: np.ndarray, max_iou: float) -> np.ndarray:
    """``(N,) bool``, True for each box to keep of ``boxes (N, 4)`` (x1, y1, x2, y2) scored
    ``scores (N,)``: greedily by score (ties: the earlier row first), a box whose IoU with a
    box already kept exceeds ``max_iou`` is dropped."""
    b = np.asarray(boxes, np.float64).reshape(-1, 4)
    s = np.asarray(scores, np.float64).reshape(-1)
    if len(s) != len(b):
        raise ValueError(f"{len(b)} boxes but {len(s)} scores")
    keep = np.ones(len(b), bool)
    if len(b) < 2:
        return keep
    order = np.argsort(-s, kind="stable")
    if len(b) <= DENSE_DUPLICATES:
        over = iou(b, b) > max_iou
        for k, i in enumerate(order):
            if keep[i]:
                rest = order[k + 1:]
                keep[rest[over[i, rest]]] = False
        return keep
    # many boxes (a picture of noise: 15,000 windows over the threshold): the (N, N) IoU matrix
    # and its temporaries took 4.1 GB; each kept box's row against the boxes after it gives the
    # same IoUs, pair by pair, in O(N) memory
    ranked = b[order]
    alive = np.ones(len(b), bool)
    for k in range(len(b)):
        if alive[k]:
            alive[k + 1:] &= ~(iou(ranked[k:k + 1], ranked[k + 1:])[0] > max_iou)
    keep[order] = alive
    return keep


def perspective_ok(boxes: np.ndarray, frame_shape: tuple[int, int], horizon: float, min_ratio: float,
                   max_ratio: float, slack: float) -> np.ndarray:
    """``(N,) bool``, True for each box of ``boxes (N, 4)`` (x1, y1, x2, y2 pixels of a frame of
    ``frame_shape = (rows, cols)``) whose width fits where it stands (module docstring).

    With ``w`` the box's width and ``d`` the rows from the horizon (``horizon`` x rows) down to
    its bottom edge, both over the frame's rows, a box fails when ``d + slack <= w / max_ratio``
    (too wide, or its bottom above the horizon by ``slack`` or more) or, unless it touches the
    frame's left or right edge, when ``d - slack > w / min_ratio`` (too narrow)."""
    b = np.asarray(boxes, np.float64).reshape(-1, 4)
    rows, cols = int(frame_shape[0]), int(frame_shape[1])
    w = (b[:, 2] - b[:, 0]) / rows
    d = b[:, 3] / rows - float(horizon)
    too_wide = d + slack <= w / max_ratio
    at_side = (b[:, 0] <= 1) | (b[:, 2] >= cols - 1)
    too_narrow = (d - slack > w / min_ratio) & ~at_side
    return ~(too_wide | too_narrow)


class _Now:
    """The default of :meth:`PlausibleStage.filter`'s ``horizon``: ask the pipeline."""


NOW = _Now()


class PlausibleStage(Stage):
    """Drop the returned boxes that are duplicates or, with ``config.perspective``, do not fit
    the perspective (module docstring). ``horizon``: the horizon the pipeline searches at now,
    a fraction of the height (``None``: :data:`~fastdet.config.REFERENCE_HORIZON`, where the
    default bands put it); asked only when the perspective test is on.

    ``deferred``: let every box through and leave the rules to :meth:`filter`, called on the
    frames later -- for the offline pass (:func:`fastdet.video.run.offline_boxes`), which would
    fill the gap a dropped box leaves in its track with a box interpolated over it."""

    name = "plausible"

    def __init__(self, config: PlausibleConfig, horizon: Callable[[], float | None] | None = None) -> None:
        self.config = config
        self.horizon = horizon if horizon is not None else (lambda: None)
        self.deferred = False
        self.dropped = 0  # boxes dropped since the start (or the last reset)

    def filter(self, dets: Detections, frame_shape: tuple[int, int], horizon: float | None | _Now = NOW
               ) -> Detections:
        """``dets`` (one frame's boxes, of a frame of ``frame_shape = (rows, cols)``) less the
        boxes the rules drop. ``horizon``: the frame's horizon (a fraction of the height,
        ``None`` the reference); by default the one the pipeline searches at now."""
        if not len(dets):
            return dets
        c = self.config
        keep = np.ones(len(dets), bool)
        if c.perspective:
            h = self.horizon() if isinstance(horizon, _Now) else horizon
            keep &= perspective_ok(dets.boxes, frame_shape, REFERENCE_HORIZON if h is None else h,
                                   c.min_ratio, c.max_ratio, c.slack)
        if c.max_iou is not None:
            idx = np.flatnonzero(keep)
            scores = dets.scores if dets.scores is not None else np.zeros(len(dets))
            keep[idx[~duplicates(dets.boxes[idx], scores[idx], c.max_iou)]] = False
        if keep.all():
            return dets
        self.dropped += int((~keep).sum())
        return dets[keep]

    def __call__(self, s: FrameState) -> FrameState:
        if not self.deferred:
            s.out = self.filter(s.out, s.shape, s.horizon if s.placed else NOW)
        return s

    def reset(self) -> None:
        self.dropped = 0
