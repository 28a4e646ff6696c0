"""Detections: a frozen table of boxes with per-box columns."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from fastdet import Box, Detections
from fastdet.detections import COLUMNS, MAIN_PART, ONCOMING_PART, REPR_ROWS, ROW_FIELDS


def _dets(n: int = 4, **cols) -> Detections:
    boxes = np.array([[i, 2 * i, i + 10, 2 * i + 20] for i in range(n)])
    return Detections(boxes, np.arange(n) / 10, **cols)


def test_len_bool_and_empty():
    e = Detections.empty()
    assert len(e) == 0 and not e and e.boxes.shape == (0, 4)
    assert e.boxes.dtype == np.int32 and e.scores.dtype == np.float32
    assert e.scale is None and e.part is None and e.ids is None
    d = _dets(3)
    assert len(d) == 3 and bool(d)
    assert Detections(np.zeros((0, 4)), []).boxes.shape == (0, 4)
    assert len(Detections([], [])) == 0  # no boxes at all: still (0, 4)


def test_dtypes_and_shapes_normalised():
    d = Detections([[1, 2, 3, 4]], np.array([0.5], np.float32), scale=[1.5], part=[1], ids=[7], frames=[3],
                   consider=[1])
    assert d.boxes.dtype == np.int32 and d.boxes.tolist() == [[1, 2, 3, 4]]
    assert d.scores.dtype == np.float32 and d.scale.dtype == np.float32
    assert d.part.dtype == np.int8 and d.ids.dtype == np.int64
    assert d.frames.dtype == np.int64 and d.consider.dtype == bool and d.consider.tolist() == [True]
    assert Detections([1, 2, 3, 4], 0.5).boxes.shape == (1, 4)  # one box, flat
    assert d.boxes.flags.c_contiguous
    # integer boxes are int32 pixels; floating-point ones keep their value (a box file's
    # continuous coordinates); float64 scores stay float64, any other kind is float32
    f = Detections(np.array([[1.5, 2, 3.25, 4]], np.float32), [0.123456789])
    assert f.boxes.dtype == np.float64 and f.boxes.tolist() == [[1.5, 2, 3.25, 4]]
    assert f.scores.dtype == np.float64 and f.scores[0] == 0.123456789
    assert Detections([[1, 2, 3, 4]], [1]).scores.dtype == np.float32
    assert Detections(np.zeros((0, 4)), np.zeros(0)).boxes.dtype == np.int32  # empty: int32, float32
    assert Detections(np.zeros((0, 4)), np.zeros(0)).scores.dtype == np.float32


@pytest.mark.parametrize("boxes, msg", [
    (np.zeros((2, 6)), r"shape \(N, 4\)"), (np.zeros((3,)), r"shape \(N, 4\)"),
    (np.array([["a", "b", "c", "d"]]), "numbers"), (np.array([[0, 0, 2**31, 5]], np.int64), "fit int32"),
])
def test_bad_boxes_raise(boxes, msg):
    with pytest.raises(ValueError, match=msg):
        Detections(boxes)


@pytest.mark.parametrize("col", ["scores", "scale", "part", "ids", "frames", "consider"])
def test_column_length_mismatch_raises(col):
    cols = {"scores": np.zeros(3)}
    cols[col] = np.zeros(2)
    with pytest.raises(ValueError, match=f"3 boxes but 2 {col}"):
        Detections(np.zeros((3, 4)), **cols)


def test_frozen():
    d = _dets()
    with pytest.raises(dataclasses.FrozenInstanceError):
        d.boxes = np.zeros((0, 4))


def test_getitem_mask_index_slice_int():
    d = _dets(5, scale=np.arange(5) + 1.0, part=[0, 1, 0, 1, 0], ids=[10, 11, 12, 13, 14])
    d = dataclasses.replace(d, frames=[1, 1, 2, 3, 3], consider=[1, 0, 1, 1, 0], source="f.txt")
    for index, rows in ((np.array([True, False, True, False, False]), [0, 2]), (np.array([3, 1]), [3, 1]),
                        ([4], [4]), (slice(1, 3), [1, 2]), (2, [2]), (np.int64(-1), [4])):
        s = d[index]
        assert isinstance(s, Detections) and len(s) == len(rows) and s.source == "f.txt"
        for name in ("boxes", "scores", "scale", "part", "ids", "frames", "consider"):
            np.testing.assert_array_equal(getattr(s, name), getattr(d, name)[rows], err_msg=f"{index!r} {name}")
    assert len(d[np.zeros(5, bool)]) == 0
    # missing columns stay missing
    plain = _dets(3)
    assert plain[[0]].scale is None and plain[[0]].part is None and plain[[0]].ids is None
    assert plain[[0]].frames is None and plain[[0]].consider is None


def test_concat_fills_missing_columns():
    a = _dets(2, scale=[1.0, 2.0], part=[ONCOMING_PART, ONCOMING_PART])
    b = _dets(3)
    c = _dets(1, ids=[5])
    d = Detections.concat([a, b, c])
    assert len(d) == 6
    np.testing.assert_array_equal(d.boxes, np.concatenate([a.boxes, b.boxes, c.boxes]))
    np.testing.assert_array_equal(d.scores, np.concatenate([a.scores, b.scores, c.scores]))
    np.testing.assert_array_equal(d.scale, [1.0, 2.0, np.nan, np.nan, np.nan, np.nan])
    np.testing.assert_array_equal(d.part, [ONCOMING_PART, ONCOMING_PART, MAIN_PART, MAIN_PART, MAIN_PART, MAIN_PART])
    np.testing.assert_array_equal(d.ids, [-1, -1, -1, -1, -1, 5])
    assert Detections.concat([b, b]).scale is None  # a column no part has stays missing
    assert len(Detections.concat([])) == 0
    assert Detections.concat([a]) is a
    assert len(Detections.concat([Detections.empty(), b])) == 3
    # ground truth's consider is True where a part has none; scores and frames have no
    # missing value: a table with them and one without do not join
    g = Detections.concat([Detections(b.boxes, consider=[0, 1, 0]), Detections(c.boxes)])
    assert g.scores is None and g.consider.tolist() == [False, True, False, True]
    with pytest.raises(ValueError, match="some parts have scores"):
        Detections.concat([b, Detections(c.boxes)])
    with pytest.raises(ValueError, match="some parts have frames"):
        Detections.concat([b.with_frames([1, 1, 1]), c])


def test_a_clip_table_from_frames_and_back_by_frame():
    """Many frames' rows in one table (a ``frames`` column, ids -1 where a frame had none),
    split again by ascending frame."""
    f3, f1, f2 = _dets(2, ids=[4, 5]), _dets(3), Detections.empty()
    t = Detections.from_frames([(3, f3), (1, f1), (2, f2)], source="clip.mp4")
    assert len(t) == 5 and t.source == "clip.mp4" and t.num_frames == 3 and t.has_ids
    assert t.frames.tolist() == [3, 3, 1, 1, 1] and t.ids.tolist() == [4, 5, -1, -1, -1]
    np.testing.assert_array_equal(t.boxes, np.concatenate([f3.boxes, f1.boxes]))
    assert t.boxes.dtype == np.int32 and t.scores.dtype == np.float64  # _dets' scores are float64
    parts = list(t.by_frame())
    assert [f for f, _ in parts] == [1, 3]  # frames with rows only, ascending
    np.testing.assert_array_equal(parts[0][1].boxes, f1.boxes)
    np.testing.assert_array_equal(parts[1][1].ids, [4, 5])
    none = Detections.from_frames([])
    assert len(none) == 0 and none.num_frames == 0 and not none.has_ids and none.frames is not None
    assert list(none.by_frame()) == []
    assert not Detections.from_frames([(1, f1)]).has_ids
    with pytest.raises(ValueError, match="no frames column"):
        list(f1.by_frame())
    with pytest.raises(ValueError, match="no frames column"):
        f1.num_frames  # noqa: B018


def test_ground_truth_is_a_table_without_scores():
    gt = Detections(np.array([[0.5, 0, 10, 10], [1, 1, 5, 5]]), frames=[1, 2], ids=[1, 2], consider=[True, False])
    assert gt.scores is None and gt.num_considered == 1 and gt.targets.tolist() == [True, False]
    assert repr(gt) == ("Detections(2 boxes)\n"
                        " x1  y1  x2  y2  id  frame  consider\n"
                        "0.5   0  10  10   1      1      True\n"
                        "  1   1   5   5   2      2     False")
    assert Detections(gt.boxes).num_considered == 2 and Detections(gt.boxes).targets.all()
    assert [b.score for b in gt] == [None, None] and [b.consider for b in gt] == [True, False]


def test_is_oncoming_and_with_ids():
    d = _dets(3, part=[MAIN_PART, ONCOMING_PART, MAIN_PART])
    assert d.is_oncoming.tolist() == [False, True, False]
    assert _dets(3).is_oncoming.tolist() == [False, False, False]
    t = d.with_ids(np.array([4, 5, 6]))
    assert t.ids.tolist() == [4, 5, 6] and d.ids is None  # a new object; the original unchanged
    np.testing.assert_array_equal(t.part, d.part)
    with pytest.raises(ValueError):
        d.with_ids(np.array([1]))


def test_iteration_yields_one_box_a_row():
    d = _dets(3, ids=[4, 5, 6])
    rows = list(d)
    assert len(rows) == 3 and all(isinstance(r, Box) for r in rows)
    assert rows[1] == Box(1, 2, 11, 22, score=pytest.approx(0.1), id=5)
    assert rows[1].x1 == 1 and rows[1].id == 5 and rows[1].frame is None and rows[1].scale is None
    assert type(rows[0].x1) is int and type(rows[0].score) is float and type(rows[0].id) is int
    x1, y1, x2, y2, *_ = rows[2]
    assert (x1, y1, x2, y2) == (2, 4, 12, 24)
    with pytest.raises(AttributeError):
        rows[0].x1 = 7  # type: ignore[misc]  # a row is frozen
    assert list(Detections.empty()) == []
    # the old tuple unpacking is gone: a table of 2 rows unpacks into its 2 rows
    a, b = _dets(2)
    assert isinstance(a, Box) and b.x1 == 1
    f = list(Detections([[0.5, 1, 2.25, 3]]))[0]
    assert f == (0.5, 1.0, 2.25, 3.0, None, None, None, None, None, None) and type(f.y1) is float


def test_repr_is_a_table_of_rows():
    assert repr(Detections.empty()) == "Detections(0 boxes)"
    assert repr(Detections(np.zeros((0, 4)), ids=np.zeros(0), frames=np.zeros(0))) == "Detections(0 boxes)"
    d = Detections([[815, 395, 945, 505], [10, 20, 30, 40]], np.array([41.53, 6.2], np.float32), ids=[1, 12])
    assert repr(d) == str(d) == ("Detections(2 boxes)\n"
                                 " x1   y1   x2   y2  score  id\n"
                                 "815  395  945  505  41.53   1\n"
                                 " 10   20   30   40    6.2  12")
    w = _dets(1, scale=[1.5], part=[ONCOMING_PART])
    assert repr(w) == ("Detections(1 box)\n"
                       "x1  y1  x2  y2  score  scale  part\n"
                       " 0   0  10  20      0    1.5     1")
    many = dataclasses.replace(_dets(25), source="preds.txt")
    lines = repr(many).splitlines()
    assert lines[0] == "Detections(25 boxes from preds.txt)" and lines[-1] == "... 15 more"
    assert len(lines) == 2 + REPR_ROWS + 1 and lines[2].split() == ["0", "0", "10", "20", "0"]


_cols = st.fixed_dictionaries({}, optional={
    "scores": st.just("f"), "scale": st.just("f"), "part": st.just("i"), "ids": st.just("i"),
    "frames": st.just("i"), "consider": st.just("b")})


@st.composite
def tables(draw) -> Detections:
    n = draw(st.integers(0, 3 * REPR_ROWS))
    if draw(st.booleans()):
        boxes = draw(hnp.arrays(np.int32, (n, 4), elements=st.integers(-10**6, 10**6)))
    else:
        boxes = draw(hnp.arrays(np.float64, (n, 4), elements=st.floats(-1e6, 1e6, allow_nan=False)))
    cols = {}
    for name, kind in draw(_cols).items():
        if kind == "f":
            el = st.floats(-1e3, 1e3, allow_nan=False, width=32)
            cols[name] = draw(hnp.arrays(np.float32, n, elements=el))
        elif kind == "i":
            cols[name] = draw(hnp.arrays(np.int8 if name == "part" else np.int64, n, elements=st.integers(-1, 120)))
        else:
            cols[name] = draw(hnp.arrays(np.bool_, n))
    return Detections(boxes, **cols)


@settings(max_examples=150, deadline=None)
@given(tables())
def test_rows_and_repr_of_random_tables(d):
    rows = list(d)
    assert len(rows) == len(d)
    if len(d):  # the rows give back every column
        np.testing.assert_array_equal(np.array([r[:4] for r in rows], d.boxes.dtype), d.boxes)
        for name in COLUMNS:
            got = [getattr(r, ROW_FIELDS[name]) for r in rows]
            if getattr(d, name) is None:
                assert got == [None] * len(d)
            else:
                np.testing.assert_array_equal(np.array(got, getattr(d, name).dtype), getattr(d, name))
    for r, k in zip(rows, range(len(d))):  # and agree with d[i]
        assert r == list(d[k])[0]
    lines = repr(d).splitlines()
    assert lines[0] == f"Detections({len(d)} box{'' if len(d) == 1 else 'es'})"
    if not len(d):
        assert lines == ["Detections(0 boxes)"]
        return
    shown = min(len(d), REPR_ROWS)
    names = ["x1", "y1", "x2", "y2", *(ROW_FIELDS[c] for c in COLUMNS if getattr(d, c) is not None)]
    assert lines[1].split() == names
    assert len({len(line) for line in lines[1:2 + shown]}) == 1  # aligned: every row as wide
    for line, r in zip(lines[2:2 + shown], rows):
        cells = line.split()
        assert len(cells) == len(names)
        if d.boxes.dtype == np.int32:
            assert [int(c) for c in cells[:4]] == list(r[:4])
        else:  # 6 significant digits
            np.testing.assert_allclose([float(c) for c in cells[:4]], r[:4], rtol=1e-5)
        if r.id is not None:
            assert int(cells[names.index("id")]) == r.id
        if r.consider is not None:
            assert cells[names.index("consider")] == str(r.consider)
    assert lines[2 + shown:] == ([f"... {len(d) - REPR_ROWS} more"] if len(d) > REPR_ROWS else [])
