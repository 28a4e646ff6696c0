"""Matching one frame's predictions to its targets (greedy by score at an IoU threshold,
predictions on ignore regions dropped) and the VOC all-point average precision of a
ranking; the rules are described in :mod:`fastdet.eval.metrics`, which re-exports these."""
from __future__ import annotations

import math

import numpy as np

from ..boxes import area, intersection
from ..boxes import iou as box_iou


def match_frame(
    pred_boxes: np.ndarray,
    pred_scores: np.ndarray,
    gt_boxes: np.ndarray,
    ignore_boxes: np.ndarray | None = None,
    iou: float = 0.5,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Match one frame's predictions to its targets (the rules: :mod:`fastdet.eval.metrics`).

    Returns ``(tp, dropped, gt_index)``, each ``(N,)`` over the predictions in input order:
    ``tp`` True for a true positive, ``dropped`` True for a prediction on an ignore region,
    ``gt_index`` the matched target's row (``-1`` if none). FP = ``~tp & ~dropped``.
    """
    pred_boxes = np.asarray(pred_boxes, dtype=np.float64).reshape(-1, 4)
    gt_boxes = np.asarray(gt_boxes, dtype=np.float64).reshape(-1, 4)
    n = pred_boxes.shape[0]
    tp = np.zeros(n, bool)
    gt_index = np.full(n, -1, np.int64)
    if n and gt_boxes.shape[0]:
        order = np.argsort(-np.asarray(pred_scores, dtype=np.float64).reshape(-1), kind="stable")
        ious = box_iou(pred_boxes, gt_boxes)
        taken = np.zeros(gt_boxes.shape[0], bool)
        for p in order:
            row = np.where(taken, -1.0, ious[p])
            j = int(np.argmax(row))
            if row[j] >= iou:
                taken[j] = True
                tp[p] = True
                gt_index[p] = j
    dropped = np.zeros(n, bool)
    if ignore_boxes is not None and n:
        ignore_boxes = np.asarray(ignore_boxes, dtype=np.float64).reshape(-1, 4)
        if ignore_boxes.shape[0]:
            inter = intersection(pred_boxes, ignore_boxes).max(axis=1)
            pred_area = area(pred_boxes)
            dropped = ~tp & (pred_area > 0) & (inter >= 0.5 * pred_area)
    return tp, dropped, gt_index


def precision_envelope(precision: np.ndarray) -> np.ndarray:
    """Monotone envelope: at each rank, the highest precision at this rank or later."""
    p = np.asarray(precision, dtype=np.float64)
    return np.maximum.accumulate(p[::-1])[::-1] if p.size else p.copy()


def average_precision(tp_ranked: np.ndarray, num_gt: int) -> tuple[float, np.ndarray, np.ndarray]:
    """VOC all-point AP of predictions already in ranking order.

    ``tp_ranked``: ``(N,)`` bool, True where the prediction at that rank is a true positive.
    Returns ``(ap, recall, precision)`` with ``recall``/``precision`` after each rank.
    """
    tp = np.asarray(tp_ranked, dtype=bool).reshape(-1)
    ctp = np.cumsum(tp, dtype=np.float64)
    cfp = np.cumsum(~tp, dtype=np.float64)
    precision = ctp / np.maximum(ctp + cfp, 1.0)
    if num_gt <= 0:
        return math.nan, np.full(tp.shape, math.nan), precision
    recall = ctp / float(num_gt)
    if tp.size == 0:
        return 0.0, recall, precision
    steps = np.diff(np.concatenate([[0.0], recall]))
    ap = float(np.sum(steps * precision_envelope(precision)))
    return ap, recall, precision
