"""Combining the boxes of the main (square-window) and the wide-window heat maps.

The wide-window model also fires on the cars that the main model finds (the middle rows
of a car seen from behind are its "wide window"), and its windows spread sideways beyond
them. So the two kinds of windows go into separate heat maps, and a wide box is kept only
where the main heat map has found no vehicle: it adds the cars half hidden behind a barrier
(oncoming traffic above the median) without disturbing the boxes of the cars ahead.
"""
from __future__ import annotations

import numpy as np

from ..boxes import overlap_fraction
from ..detections import Detections


def merge_oncoming(main: Detections, oncoming: Detections, max_overlap: float = 0.2) -> Detections:
    """``main`` plus the boxes of ``oncoming`` that overlap no main box by more than
    ``max_overlap`` of their own area."""
    if len(oncoming.boxes) == 0:
        return main
    if len(main.boxes):
        keep = overlap_fraction(oncoming.boxes, main.boxes).max(axis=1) <= max_overlap
    else:
        keep = np.ones(len(oncoming.boxes), bool)
    if not keep.any():
        return main
    return Detections(np.concatenate([main.boxes, oncoming.boxes[keep]]).astype(np.int32),
                      np.concatenate([main.scores, oncoming.scores[keep]]).astype(np.float32))
