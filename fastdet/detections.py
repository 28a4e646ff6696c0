"""The result type shared by :class:`~fastdet.Detector` and :class:`~fastdet.VideoDetector`."""
from __future__ import annotations

from typing import NamedTuple

import numpy as np


class Detections(NamedTuple):
    """Boxes found in one frame.

    boxes: ``(N, 4) int32`` ``x1, y1, x2, y2`` in frame pixels (x2, y2 exclusive).
    scores: ``(N,) float32`` confidences, higher is more certain.
    """

    boxes: np.ndarray
    scores: np.ndarray

    @classmethod
    def empty(cls) -> "Detections":
        return cls(np.zeros((0, 4), np.int32), np.zeros((0,), np.float32))
