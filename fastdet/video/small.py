"""A second look at the small-vehicle component's boxes (:class:`MainModelCheck`): the main
model scores each box's square surroundings, resized to its window, and a box it rejects with
confidence is dropped.

The small component's coarse 32x32 template fires on much that is vehicle-sized at the horizon
(posts and bushes on the verge, a median barrier, far traffic); the main model's finer template
sees those for what they are even where it cannot find a distant car itself. The check is
loose on purpose: a box passes unless the main model gives it less than a small probability of
being a vehicle (:data:`~fastdet.config.small.SMALL_CHECK`), since the main model scores the
small cars it cannot find negative too (docs/components.md).
"""
from __future__ import annotations

import numpy as np

from ..detect.regressor import region_crops
from ..model import Model


class MainModelCheck:
    """``check(frame, boxes) -> keep (N,) bool``: whether ``model`` scores each box's square
    crop above ``threshold`` (its decision value). The crop is the box's longer side plus
    ``margin`` of it on each side, centred on the box, as the data set's crops frame their cars,
    resized to the model's window (``INTER_AREA`` shrinking, ``INTER_LINEAR`` enlarging; pixels
    past the frame edge replicate it). ``frame``: ``(H, W, 3) uint8`` BGR; ``boxes``: ``(N, 4)``
    x1, y1, x2, y2 frame pixels."""

    def __init__(self, model: Model, threshold: float, margin: float = 0.0625) -> None:
        if model.config.window_height is not None:
            raise ValueError("the check needs a square-window model")
        if not margin >= 0:
            raise ValueError(f"margin must be >= 0, got {margin!r}")
        self.model, self.threshold, self.margin = model, float(threshold), float(margin)

    def squares(self, boxes: np.ndarray) -> np.ndarray:
        """The square crop of each box: ``(N, 4) float64``."""
        b = np.asarray(boxes, np.float64).reshape(-1, 4)
        cx, cy = (b[:, 0] + b[:, 2]) / 2, (b[:, 1] + b[:, 3]) / 2
        half = np.maximum(b[:, 2] - b[:, 0], b[:, 3] - b[:, 1]) * (0.5 + self.margin)
        return np.stack([cx - half, cy - half, cx + half, cy + half], 1)

    def scores(self, frame: np.ndarray, boxes: np.ndarray) -> np.ndarray:
        """The model's decision value of each box's crop: ``(N,) float64``."""
        b = np.asarray(boxes, np.float64).reshape(-1, 4)
        if not len(b):
            return np.zeros(0)
        w = self.model.config.win_w
        return self.model.decision_function(region_crops(frame, self.squares(b), 1.0, (w, w)))

    def __call__(self, frame: np.ndarray, boxes: np.ndarray) -> np.ndarray:
        return self.scores(frame, boxes) > self.threshold
