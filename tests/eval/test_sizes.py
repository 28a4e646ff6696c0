"""fastdet/eval/sizes.py: recall by box width in reference pixels, against evaluate's matches."""
from __future__ import annotations

import numpy as np

from fastdet.detections import Detections
from fastdet.eval import evaluate
from fastdet.eval.sizes import recall_by_width


def test_recall_by_width_matches_evaluate():
    gt = Detections(np.array([[0, 0, 50, 30], [100, 0, 170, 40], [300, 0, 420, 60],
                              [0, 0, 50, 30], [100, 0, 190, 40]], float),
                    frames=np.array([1, 1, 1, 2, 2]), ids=np.array([1, 2, 3, 1, 2]), consider=np.ones(5, bool))
    preds = Detections(np.array([[0, 0, 50, 30], [300, 0, 420, 60], [100, 0, 190, 40]], float), np.ones(3),
                       frames=np.array([1, 1, 2]), ids=-np.ones(3, np.int64))
    bins = recall_by_width(gt, preds, frame_rows=720)
    assert [(b.label, b.found, b.total) for b in bins] == [("40-60", 1, 2), ("60-80", 0, 1), ("80-100", 1, 1),
                                                          (">=100", 1, 1)]
    assert sum(b.found for b in bins) == evaluate(gt, preds).tp
    # the same boxes in a 360-row frame are twice as wide in reference pixels
    bins = recall_by_width(gt, preds, frame_rows=360)
    assert [(b.found, b.total) for b in bins] == [(0, 0), (0, 0), (0, 0), (3, 5)]
