"""``frame_counts``: each keyframe's (tp, fp, fn) in one pass, checked against its slow twin, one
:func:`evaluate` a frame (what ``fastdet adapt``'s operating point did before)."""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fastdet.detections import Detections
from fastdet.errors import DataError
from fastdet.eval.metrics import evaluate, frame_counts


def _per_frame_evaluate(gt: Detections, preds: Detections, keyframes: np.ndarray, iou: float = 0.5) -> np.ndarray:
    rows = []
    for f in keyframes:
        r = evaluate(gt[gt.frames == f], preds[preds.frames == f], iou=iou, keyframes=np.array([f]), tracking=False)
        rows.append((r.tp, r.fp, r.fn))
    return np.array(rows, np.int64).reshape(-1, 3)


_box = st.tuples(st.integers(0, 60), st.integers(0, 60), st.integers(4, 40), st.integers(4, 40))


def _table(rows: list, scores: bool) -> Detections:
    boxes = np.array([[x, y, x + w, y + h] for _, (x, y, w, h), _ in rows], np.float64).reshape(-1, 4)
    frames = np.array([f for f, _, _ in rows], np.int64)
    if scores:
        return Detections(boxes, np.array([v for _, _, v in rows], np.float32), frames=frames)
    return Detections(boxes, frames=frames, consider=np.array([v for _, _, v in rows], bool))


@settings(max_examples=150, deadline=None)
@given(gt=st.lists(st.tuples(st.integers(1, 5), _box, st.booleans()), max_size=14),
       preds=st.lists(st.tuples(st.integers(1, 7), _box, st.floats(0.01, 1.0)), max_size=14),
       order=st.permutations(list(range(1, 6))), iou=st.sampled_from([0.3, 0.5, 0.7]))
def test_frame_counts_are_one_evaluate_a_frame(gt, preds, order, iou):
    g, p = _table(gt, scores=False), _table(preds, scores=True)
    keyframes = np.array(order, np.int64)  # frames 6 and 7 of the predictions are not keyframes
    got = frame_counts(g, p, keyframes, iou=iou)
    np.testing.assert_array_equal(got, _per_frame_evaluate(g, p, keyframes, iou))
    total = evaluate(g, p, iou=iou, keyframes=keyframes, tracking=False)
    assert tuple(got.sum(axis=0)) == (total.tp, total.fp, total.fn)


def test_frame_counts_on_a_real_clips_labels():
    from fastdet.eval.clips import annotated_clips

    clip = {c.name: c for c in annotated_clips()}["boston_street"]
    gt, keyframes = clip.gt(), np.asarray(clip.keyframes(), np.int64)
    rng = np.random.default_rng(0)
    # predictions: the targets moved by a few px (some hits, some misses) plus random boxes
    moved = gt.boxes + rng.integers(-12, 13, gt.boxes.shape)
    extra = rng.integers(0, 400, (40, 2))
    boxes = np.concatenate([moved, np.concatenate([extra, extra + rng.integers(20, 120, (40, 2))], 1)])
    frames = np.concatenate([gt.frames, rng.choice(keyframes, 40)])
    preds = Detections(boxes.astype(np.float64), rng.uniform(0.1, 1, len(boxes)).astype(np.float32), frames=frames)
    got = frame_counts(gt, preds, keyframes)
    np.testing.assert_array_equal(got, _per_frame_evaluate(gt, preds, keyframes))
    assert got[:, 0].sum() > 0 and got[:, 1].sum() > 0 and got[:, 2].sum() > 0


def test_frame_counts_refuses_repeated_keyframes_and_ground_truth_elsewhere():
    gt = Detections(np.array([[0, 0, 10, 10]], np.float64), frames=np.array([3]), consider=np.array([True]))
    preds = Detections(np.zeros((0, 4)), np.zeros(0, np.float32), frames=np.zeros(0, np.int64))
    with pytest.raises(ValueError, match="unique"):
        frame_counts(gt, preds, np.array([3, 3]))
    with pytest.raises(DataError, match="frame 3"):
        frame_counts(gt, preds, np.array([1, 2]))
    np.testing.assert_array_equal(frame_counts(gt, preds, np.array([1, 3])), [[0, 0, 0], [0, 0, 1]])
