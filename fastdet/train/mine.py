"""``python -m fastdet mine-negatives``: save the windows the detector wrongly fires on.

Classic hard-negative mining. A positive window is a *false* alarm when it lies where no
vehicle is: inside ``--x-range``/``--y-range`` (a region you know to be empty), and, with
``--gt``, touching no annotated box at all (targets and ignore regions alike, so a
partially visible or far-away car is never saved as a negative). Each such window is cut
from the frame, resized to its model's window size (64x64 for the main model, e.g. 64x24
for the oncoming-traffic one, chosen with ``--part``) and written as a PNG; ``fastdet train
--negatives DIR`` then adds them to the training negatives of that kind of model.
"""
from __future__ import annotations

import cv2
import numpy as np

from ..boxes import intersection
from ..config import FeatureConfig
from ..detect import Detector
from ..detections import MAIN_PART, ONCOMING_PART


def false_windows(boxes: np.ndarray, x_range=None, y_range=None, gt_boxes: np.ndarray | None = None) -> np.ndarray:
    """Indices of windows that are certainly not vehicles by the rules above."""
    keep = np.ones(len(boxes), bool)
    if x_range is not None:
        keep &= (boxes[:, 0] >= x_range[0]) & (boxes[:, 2] <= x_range[1])
    if y_range is not None:
        keep &= (boxes[:, 1] >= y_range[0]) & (boxes[:, 3] <= y_range[1])
    if gt_boxes is not None and len(gt_boxes) and len(boxes):
        keep &= ~np.any(intersection(boxes, gt_boxes) > 0, axis=1)
    return np.flatnonzero(keep)


def hard_negatives(det: Detector, frame: np.ndarray, part: str, win_cfg: FeatureConfig, x_range=None,
                   y_range=None, gt_boxes: np.ndarray | None = None) -> list[tuple[np.ndarray, np.ndarray]]:
    """``[(box (4,), crop (win_h, win_w, 3) uint8)]``: the positive windows of model ``part``
    (``"main"`` or ``"oncoming"``) in ``frame`` that :func:`false_windows` calls false, cut
    from the frame and resized to the model's window (``INTER_AREA``)."""
    d = det.detect(frame)
    if part not in ("main", "oncoming"):
        raise ValueError(f"part must be 'main' or 'oncoming', got {part!r}")
    want = MAIN_PART if part == "main" else ONCOMING_PART
    d = d[d.part == want]
    out = []
    for i in false_windows(d.boxes, x_range, y_range, gt_boxes):
        x1, y1, x2, y2 = d.boxes[i]
        crop = frame[max(y1, 0): y2, max(x1, 0): x2]
        if crop.shape[0] < 8 or crop.shape[1] < 8:
            continue
        out.append((d.boxes[i], cv2.resize(crop, (win_cfg.win_w, win_cfg.win_h), interpolation=cv2.INTER_AREA)))
    return out
