"""fastdet/eval/matching.py: one frame's greedy matching and the VOC all-point AP, against the
slow, obvious versions (a loop over predictions by score and pairs of boxes; AP as the sum
over each recall step of the best precision at that recall or later). The metrics built on
them: tests/eval/test_metrics.py."""
from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fastdet.eval.matching import average_precision, match_frame, precision_envelope
from tests.reference import box_area, box_intersection, box_iou


def ref_match(preds, scores, gts, ignores, iou):
    """Predictions by descending score (ties: input order) each take the free target of highest
    IoU (first such target on a tie) if that IoU reaches ``iou``; an unmatched prediction with
    at least half its area on one ignore region is dropped."""
    n = len(preds)
    tp, dropped, gi = [False] * n, [False] * n, [-1] * n
    taken = set()
    for p in sorted(range(n), key=lambda k: -scores[k]):
        best, best_iou = -1, -1.0
        for j, g in enumerate(gts):
            if j not in taken and box_iou(preds[p], g) > best_iou:
                best, best_iou = j, box_iou(preds[p], g)
        if best >= 0 and best_iou >= iou:
            taken.add(best)
            tp[p], gi[p] = True, best
    for p in range(n):
        a = box_area(preds[p])
        dropped[p] = (not tp[p] and a > 0 and any(box_intersection(preds[p], r) >= 0.5 * a for r in ignores))
    return tp, dropped, gi


def ref_ap(tp, num_gt):
    """Sum over ranks k where recall rises of (rise) x max precision at rank >= k."""
    if num_gt <= 0:
        return math.nan
    prec = [sum(tp[:k + 1]) / (k + 1) for k in range(len(tp))]
    total = 0.0
    for k, hit in enumerate(tp):
        if hit:
            total += (1 / num_gt) * max(prec[k:])
    return total


_box = st.tuples(st.integers(0, 40), st.integers(0, 40), st.integers(1, 30), st.integers(1, 30)).map(
    lambda t: [float(t[0]), float(t[1]), float(t[0] + t[2]), float(t[1] + t[3])])


def test_match_frame_flags():
    tp, dropped, gi = match_frame(
        np.array([[0, 0, 10, 10], [100, 0, 110, 10], [50, 50, 60, 60]], float), np.array([0.1, 0.2, 0.3]),
        np.array([[0, 0, 10, 10]], float), np.array([[95, 0, 120, 20]], float))
    assert tp.tolist() == [True, False, False]
    assert dropped.tolist() == [False, True, False]
    assert gi.tolist() == [0, -1, -1]


@settings(max_examples=150, deadline=None)
@given(preds=st.lists(_box, max_size=8), gts=st.lists(_box, max_size=6), ignores=st.lists(_box, max_size=2),
       scores=st.lists(st.sampled_from([0.1, 0.5, 0.5, 0.9]), min_size=8, max_size=8),
       iou=st.sampled_from([0.1, 0.3, 0.5]))
def test_match_frame_is_the_greedy_loop(preds, gts, ignores, scores, iou):
    scores = scores[:len(preds)]
    tp, dropped, gi = match_frame(np.array(preds).reshape(-1, 4), np.array(scores), np.array(gts).reshape(-1, 4),
                                  np.array(ignores).reshape(-1, 4), iou)
    want = ref_match(preds, scores, gts, ignores, iou)
    assert (tp.tolist(), dropped.tolist(), gi.tolist()) == want


@settings(max_examples=200, deadline=None)
@given(tp=st.lists(st.booleans(), max_size=20), missed=st.integers(0, 5))
def test_average_precision_is_the_all_point_sum(tp, missed):
    num_gt = sum(tp) + missed
    ap, recall, precision = average_precision(np.array(tp, bool), num_gt)
    want = ref_ap(tp, num_gt)
    if math.isnan(want):
        assert math.isnan(ap)
    else:
        assert ap == pytest.approx(want)
        np.testing.assert_allclose(recall, np.cumsum(tp) / num_gt)
    np.testing.assert_allclose(precision, [sum(tp[:k + 1]) / (k + 1) for k in range(len(tp))])


def test_precision_envelope():
    np.testing.assert_array_equal(precision_envelope(np.array([0.0, 0.5, 2 / 3, 0.4])), [2 / 3, 2 / 3, 2 / 3, 0.4])
    assert precision_envelope(np.zeros(0)).size == 0
