"""fastdet.boxes against plain per-box loops (``tests.reference``), on random boxes including
empty, inverted and out-of-frame ones."""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from fastdet import boxes as B
from tests import reference as ref

coord = st.integers(-50, 150)
box_arrays = st.integers(0, 8).flatmap(lambda n: arrays(np.int64, (n, 4), elements=coord))
SETTINGS = settings(max_examples=150, deadline=None)


@SETTINGS
@given(box_arrays, box_arrays)
def test_intersection_iou_overlap_equal_the_loops(a, b):
    for fast, slow in ((B.intersection, ref.box_intersection), (B.iou, ref.box_iou),
                       (B.overlap_fraction, ref.box_overlap_fraction)):
        got = fast(a, b)
        assert got.shape == (len(a), len(b)) and got.dtype == np.float64
        np.testing.assert_allclose(got, ref.pairwise(slow, a, b), rtol=1e-12, atol=1e-12, err_msg=fast.__name__)


@SETTINGS
@given(box_arrays)
def test_area_equals_the_loop(a):
    np.testing.assert_array_equal(B.area(a), [ref.box_area(b) for b in a])


@SETTINGS
@given(box_arrays)
def test_iou_properties(a):
    m = B.iou(a, a)
    np.testing.assert_array_equal(m, m.T)
    assert ((m >= 0) & (m <= 1)).all()
    nonempty = B.area(a) > 0
    np.testing.assert_array_equal(np.diag(m)[nonempty], 1.0)
    np.testing.assert_array_equal(np.diag(m)[~nonempty], 0.0)


@SETTINGS
@given(box_arrays)
def test_conversions_equal_the_loops_and_round_trip(a):
    ltwh = B.xyxy_to_ltwh(a)
    assert ltwh.dtype == a.dtype
    assert ltwh.tolist() == ref.xyxy_to_ltwh(a.tolist())
    back = B.ltwh_to_xyxy(ltwh)
    assert back.dtype == np.float64 and back.tolist() == ref.ltwh_to_xyxy(ltwh.tolist())
    np.testing.assert_array_equal(back, a)


@SETTINGS
@given(box_arrays, st.integers(1, 100), st.integers(1, 100))
def test_clip_equals_the_loop(a, h, w):
    got = B.clip(a, (h, w, 3))
    assert got.dtype == a.dtype and got.shape == a.shape
    assert got.tolist() == [ref.clip_box(b, h, w) for b in a]


@SETTINGS
@given(st.integers(0, 300), st.integers(0, 300), st.integers(1, 3), st.sampled_from([4, 8, 16]),
       st.floats(0.3, 4.0), st.sampled_from([64, 48]), st.sampled_from([64, 24, 32]),
       st.lists(st.tuples(st.integers(0, 30), st.integers(0, 60)), max_size=20))
def test_window_grid_boxes_equal_the_loop(x0, y0, step, cell, scale, win_w, win_h, pos):
    rows = np.array([r for r, _ in pos], np.int64)
    cols = np.array([c for _, c in pos], np.int64)
    got = B.window_grid_boxes(x0, y0, rows, cols, step, cell, scale, win_w, win_h)
    assert got.dtype == np.int32 and got.shape == (len(pos), 4)
    want = [ref.window_grid_box(x0, y0, r, c, step, cell, scale, win_w, win_h) for r, c in pos]
    assert got.tolist() == want
    np.testing.assert_array_equal(B.window_offsets(cols, step, cell, scale), [b[0] - x0 for b in want])


def test_by_hand():
    a = np.array([[0, 0, 10, 10], [100, 100, 110, 110]])
    b = np.array([[5, 0, 20, 10]])
    np.testing.assert_array_equal(B.intersection(a, b), [[50.0], [0.0]])
    np.testing.assert_allclose(B.iou(a, b), [[50 / 200], [0.0]])
    np.testing.assert_allclose(B.overlap_fraction(a, b), [[0.5], [0.0]])
    np.testing.assert_allclose(B.overlap_fraction(b, a), [[50 / 150, 0.0]])
    assert B.ltwh_to_xyxy([[3, 4, 5, 6]]).tolist() == [[3, 4, 8, 10]]
    assert B.xyxy_to_ltwh([[3, 4, 8, 10]]).tolist() == [[3, 4, 5, 6]]
    assert B.clip([[-5, 10, 700, 800]], (720, 640)).tolist() == [[0, 10, 640, 720]]
    # a 64-px window at scale 1.5, grid position (row 1, col 2), 2 cells of 8 px apart
    assert B.window_grid_boxes(10, 400, np.array([1]), np.array([2]), 2, 8, 1.5, 64, 64).tolist() == \
        [[10 + 48, 400 + 24, 10 + 48 + 96, 400 + 24 + 96]]


@pytest.mark.parametrize("fn", [B.intersection, B.iou, B.overlap_fraction])
def test_empty_inputs(fn):
    none = np.zeros((0, 4))
    some = np.array([[0, 0, 4, 4]])
    assert fn(none, some).shape == (0, 1) and fn(some, none).shape == (1, 0) and fn([], []).shape == (0, 0)


def test_inputs_not_modified():
    a = np.array([[0, 0, 10, 10]], np.int32)
    keep = a.copy()
    B.xyxy_to_ltwh(a)
    B.clip(a, (5, 5))
    B.ltwh_to_xyxy(a)
    np.testing.assert_array_equal(a, keep)
