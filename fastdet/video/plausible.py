"""Dropping returned boxes that cannot be vehicles: a second box on one vehicle
(:class:`~fastdet.config.PlausibleConfig`).

**Duplicates** (:func:`duplicates`): two vehicles that are each at least half in view overlap
by at most IoU 0.5, so of two returned boxes above ``max_iou`` the lower-scored one is a second
box on the same vehicle (two tracks on one car, or two boxes the refinement moved onto it) and
is dropped -- greedy non-maximum suppression by score over the boxes of the frame.

The stage (:class:`PlausibleStage`) runs on the boxes :meth:`VideoDetector.update
<fastdet.VideoDetector.update>` returns, after the refinement: the tracker, the heat maps and
the guided search keep every box. With the offline pass the rules run after it instead
(:func:`fastdet.video.run.offline_boxes`).
"""
from __future__ import annotations

import numpy as np

from ..boxes import iou, overlap_fraction
from ..config import PlausibleConfig
from ..detections import Detections
from .state import FrameState, Stage

#: up to this many boxes :func:`duplicates` builds the whole IoU matrix (8 MB); above, one row a kept box
DENSE_DUPLICATES = 1024


def duplicates(boxes: np.ndarray, scores: np.ndarray, max_iou: float, max_inside: float | None = None) -> np.ndarray:
    """``(N,) bool``, True for each box to keep of ``boxes (N, 4)`` (x1, y1, x2, y2) scored
    ``scores (N,)``: greedily by score (ties: the earlier row first), a box whose IoU with a
    box already kept exceeds ``max_iou`` is dropped, and so is one with more than ``max_inside``
    of its area inside a box already kept (``None``: IoU alone)."""
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
        if max_inside is not None:
            over |= overlap_fraction(b, b).T > max_inside  # [i, j]: box j's area inside box i
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
            over = iou(ranked[k:k + 1], ranked[k + 1:])[0] > max_iou
            if max_inside is not None:
                over |= overlap_fraction(ranked[k + 1:], ranked[k:k + 1])[:, 0] > max_inside
            alive[k + 1:] &= ~over
    keep[order] = alive
    return keep


class PlausibleStage(Stage):
    """Drop the returned boxes that are duplicates (module docstring).

    ``deferred``: let every box through and leave the rules to :meth:`filter`, called on the
    frames later -- for the offline pass (:func:`fastdet.video.run.offline_boxes`), which would
    fill the gap a dropped box leaves in its track with a box interpolated over it."""

    name = "plausible"

    def __init__(self, config: PlausibleConfig) -> None:
        self.config = config
        self.deferred = False
        self.dropped = 0  # boxes dropped since the start (or the last reset)

    def filter(self, dets: Detections) -> Detections:
        """``dets`` (one frame's boxes) less the boxes the rules drop."""
        if not len(dets) or self.config.max_iou is None:
            return dets
        scores = dets.scores if dets.scores is not None else np.zeros(len(dets))
        keep = duplicates(dets.boxes, scores, self.config.max_iou)
        if keep.all():
            return dets
        self.dropped += int((~keep).sum())
        return dets[keep]

    def __call__(self, s: FrameState) -> FrameState:
        if not self.deferred:
            s.out = self.filter(s.out)
        return s

    def reset(self) -> None:
        self.dropped = 0
