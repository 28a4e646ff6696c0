"""Heat blobs over vehicles side by side split between the modes of their windows."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fastdet.config import HeatConfig
from fastdet.detections import Detections
from fastdet.video._split_kernels import _search, join_modes
from fastdet.video.blobsplit import dominant_modes, mode_cuts, shift_points, split_boxes, window_modes
from fastdet.video.heatmap import HeatMap
from tests.reference import ref_join_modes, ref_mean_shift


@st.composite
def windows(draw, max_n: int = 12):
    n = draw(st.integers(1, max_n))
    xs = draw(st.lists(st.integers(0, 600), min_size=n, max_size=n))
    ys = draw(st.lists(st.integers(0, 300), min_size=n, max_size=n))
    ws = draw(st.lists(st.sampled_from([32, 40, 48, 64, 80, 96, 128]), min_size=n, max_size=n))
    wt = draw(st.lists(st.floats(1.0, 4.0), min_size=n, max_size=n))
    b = np.array([[x, y, x + w, y + w] for x, y, w in zip(xs, ys, ws)], np.float64)
    return b, np.array(wt)


@settings(max_examples=40, deadline=None)
@given(windows(), st.sampled_from([0.15, 0.25, 0.4]), st.sampled_from([0.2, 0.3, 0.6]))
def test_shift_points_match_the_reference(wb, bw, sbw):
    b, wt = wb
    np.testing.assert_allclose(shift_points(b, wt, bw, sbw, 30), ref_mean_shift(b, wt, bw, sbw, 30), atol=1e-6)


@settings(max_examples=60, deadline=None)
@given(windows(max_n=40), st.sampled_from([0.15, 0.25, 0.4]), st.sampled_from([0.2, 0.3, 0.6]),
       st.sampled_from([1, 3, 30]))
def test_the_grouping_matches_the_reference(wb, bw, sbw, iters):
    b, wt = wb
    y = shift_points(b, wt, bw, sbw, iters)  # end points part-way and all the way to the modes
    label = np.full(len(y), -7, np.int64)
    m = join_modes(y, bw, sbw, label)
    assert label.tolist() == ref_join_modes(y, bw, sbw)
    assert m == len(set(label.tolist()))


@settings(max_examples=60, deadline=None)
@given(st.lists(st.integers(-5, 5), max_size=12), st.integers(-6, 6), st.booleans())
def test_the_kernels_binary_search_is_searchsorted(xs, v, right):
    a = np.sort(np.array(xs, np.float64))
    assert _search(a, float(v), right) == np.searchsorted(a, float(v), side="right" if right else "left")


def test_a_blob_of_many_windows_is_shifted_as_the_reference_does():
    # a blob over dense texture: many overlapping windows of several sizes
    rng = np.random.default_rng(5)
    n = 150
    w = rng.choice([48.0, 64.0, 80.0, 96.0], n)
    x, y = rng.uniform(0, 500, n), rng.uniform(300, 400, n)
    b = np.stack([x, y, x + w, y + w], 1)
    wt = rng.uniform(1, 3, n)
    np.testing.assert_allclose(shift_points(b, wt, 0.25, 0.3, 30), ref_mean_shift(b, wt, 0.25, 0.3, 30), atol=1e-6)


@settings(max_examples=40, deadline=None)
@given(windows())
def test_modes_partition_the_windows(wb):
    b, wt = wb
    mb, mw = window_modes(b, wt)
    assert np.isclose(mw.sum(), wt.sum())
    # every mode box is a weighted mean of window boxes: inside their hull
    assert (mb[:, 0] >= b[:, 0].min() - 1e-9).all() and (mb[:, 2] <= b[:, 2].max() + 1e-9).all()
    assert 1 <= len(mb) <= len(b)


def _cluster(x: float, y: float, w: float, n: int = 5, jitter: float = 4.0) -> np.ndarray:
    off = np.linspace(-jitter, jitter, n)
    return np.array([[x + d, y, x + d + w, y + w] for d in off])


def test_two_cars_side_by_side_give_two_modes_one_car_with_its_halves_one():
    two = np.vstack([_cluster(100, 200, 40), _cluster(146, 200, 40)])
    mb, mw = window_modes(two, np.ones(len(two)))
    keep = dominant_modes(mb, mw)
    assert len(keep) == 2
    assert sorted(int(round(v)) for v in mb[keep, 0]) == [100, 146]
    # a large car: many windows covering it, a few on its left and right halves
    car = np.vstack([_cluster(1000, 400, 160, 9), _cluster(1000, 416, 64, 2), _cluster(1096, 416, 64, 2)])
    mb, mw = window_modes(car, np.ones(len(car)))
    assert len(mb) >= 2  # the halves are modes of their own ...
    assert len(dominant_modes(mb, mw)) == 1  # ... inside the heavier whole-car mode


def test_dominant_modes_keeps_the_heaviest_and_drops_what_it_covers():
    mb = np.array([[0, 0, 10, 10], [0, 0, 100, 100], [200, 0, 260, 60], [90, 0, 130, 40]], float)
    mw = np.array([5.0, 9.0, 3.0, 2.0])
    # box 0 is inside box 1; box 3 is 1/4 inside box 1 (kept at inside=0.5, dropped at 0.2)
    assert dominant_modes(mb, mw).tolist() == [1, 2, 3]
    assert dominant_modes(mb, mw, inside=0.2).tolist() == [1, 2]


def test_mode_cuts_at_the_coolest_column_between_separate_modes():
    prof = np.array([1, 5, 6, 5, 2, 1, 3, 7, 7, 2], float)
    modes = np.array([[4, 0, 16, 10], [24, 0, 36, 10]], float)  # centres at columns 2 and 7 (cell 4)
    assert mode_cuts(prof, 0, 4, modes) == [5]
    assert mode_cuts(prof, 0, 4, modes[::-1]) == [5]  # order of the modes does not matter
    # overlapping modes (along x) are one vehicle, adjacent centres leave no column between
    assert mode_cuts(prof, 0, 4, np.array([[4, 0, 20, 10], [10, 0, 26, 10]], float)) == []
    assert mode_cuts(prof, 0, 4, np.array([[0, 0, 8, 4], [6, 0, 12, 4]], float), max_overlap=1.0) == []
    assert mode_cuts(prof, 0, 4, modes[:1]) == []


def _heatmap_with(windows: np.ndarray, shape=(360, 640)) -> tuple[HeatMap, Detections]:
    hm = HeatMap(shape, HeatConfig(n_frames=1, threshold=1.5, min_width=0, min_height=0, reference_rows=None))
    d = hm.update(Detections(windows.astype(np.int32), np.full(len(windows), 2.0, np.float32)))
    return hm, d


def test_split_boxes_two_cars_in_a_row():
    wins = np.vstack([_cluster(100, 200, 40), _cluster(146, 200, 40)])
    hm, boxes = _heatmap_with(wins)
    assert len(boxes) == 1  # one blob over both
    out = split_boxes(boxes, hm.heat, hm.labels, 4, hm.frame_shape, hm._cur[0], hm._cur[1], hm.config.extent)
    assert len(out) == 2
    b = out.boxes[np.argsort(out.boxes[:, 0])]
    assert b[0, 0] <= 100 and b[0, 2] <= 150 and b[1, 0] >= 140 and b[1, 2] >= 186
    assert (out.scores > 0).all()


def test_a_blob_of_more_windows_than_the_bound_shifts_only_the_heaviest(monkeypatch):
    import fastdet.video.blobsplit as bs

    # two cars in a row, each under many light windows (dense texture) and a few heavy ones
    rng = np.random.default_rng(3)
    wins, wts = [], []
    for x in (100, 146):
        wins += [_cluster(x, 200, 40)]
        wts += [np.full(5, 50.0)]
        jit = rng.uniform(-3, 3, (200, 2))
        wins += [np.array([[x + a, 200 + c, x + a + 40, 240 + c] for a, c in jit])]
        wts += [np.full(200, 0.1)]
    b, wt = np.vstack(wins), np.concatenate(wts)
    hm, boxes = _heatmap_with(b)
    assert len(boxes) == 1
    seen = []
    real = bs.window_modes
    monkeypatch.setattr(bs, "window_modes", lambda w, t, *a: (seen.append((w.copy(), t.copy())), real(w, t, *a))[1])
    monkeypatch.setattr(bs, "MAX_WINDOWS", 30)
    out = split_boxes(boxes, hm.heat, hm.labels, 4, hm.frame_shape, b, wt, hm.config.extent)
    assert len(out) == 2  # the split still finds both cars
    (w_in, t_in), = seen
    assert len(w_in) == 30 and (t_in == 50.0).sum() == 10  # the 10 heavy ones, then the first light ones
    order = [int(np.flatnonzero((b == r).all(1) & (wt == t))[0]) for r, t in zip(w_in, t_in)]
    assert order == sorted(order)  # in their input order (the grouping depends on it)



def test_a_frame_budget_leaves_the_blobs_that_no_longer_fit_whole(monkeypatch):
    import fastdet.video.blobsplit as bs
    from fastdet.video.blobsplit import SplitTally

    # three blobs of two cars in a row each: 10, 16 and 6 windows of heat 2 (the middle blob heaviest)
    wins = np.vstack([_cluster(20, 40, 40), _cluster(66, 40, 40),
                      _cluster(300, 40, 40, 8), _cluster(346, 40, 40, 8),
                      _cluster(20, 240, 40, 3), _cluster(66, 240, 40, 3)])
    hm, boxes = _heatmap_with(wins)
    assert len(boxes) == 3
    args = (boxes, hm.heat, hm.labels, 4, hm.frame_shape, hm._cur[0], hm._cur[1], hm.config.extent)
    shifted = []
    real = bs.window_modes
    monkeypatch.setattr(bs, "window_modes", lambda w, t, *a: (shifted.append(len(w)), real(w, t, *a))[1])
    free = SplitTally()
    whole = split_boxes(*args, tally=free)
    assert len(whole) == 6 and shifted == [10, 16, 6]  # every blob split, in input order
    assert (free.frames, free.windows, free.most, free.blob_most, free.refused) == (1, 32, 32, 16, 0)
    # a budget the frame reaches: the heaviest (16) first, then 10 does not fit in 12 but 6 does
    shifted.clear()
    t = SplitTally()
    out = split_boxes(*args, max_frame_windows=22, tally=t)
    assert shifted == [16, 6] and (t.windows, t.most, t.refused) == (22, 22, 1)
    kept = [b for b in out.boxes.tolist() if b in boxes.boxes.tolist()]
    assert kept == [boxes.boxes[0].tolist()]  # the blob of 10 keeps its heat box (and its score)
    assert out.scores[out.boxes.tolist().index(kept[0])] == boxes.scores[0]
    assert len(out) == 5 and out.boxes.tolist()[:1] == kept  # in the boxes' order
    # a budget the frame does not reach changes nothing (the same boxes as no bound)
    assert split_boxes(*args, max_frame_windows=32).boxes.tolist() == whole.boxes.tolist()
    # too small for any blob: nothing is shifted, the boxes come back as they were
    shifted.clear()
    assert split_boxes(*args, max_frame_windows=5) is boxes and shifted == []
    # the pipeline's stage passes its config's budget and keeps the tally
    from fastdet.config import NeighbourSplit
    from fastdet.video.blobsplit import SplitStage
    from fastdet.video.state import FrameState
    stage = SplitStage(NeighbourSplit(max_frame_windows=22))
    state = FrameState(np.zeros((*hm.frame_shape, 3), np.uint8), boxes=boxes, out=boxes, heatmap=hm)
    shifted.clear()
    stage(state)
    assert shifted == [16, 6] and stage.tally.refused == 1 and len(state.boxes) == 5

def test_split_boxes_keeps_a_narrow_blob_and_a_single_wide_vehicle():
    # narrower than min_aspect x its height: never looked at
    wins = np.vstack([_cluster(100, 200, 40), _cluster(130, 200, 40)])
    hm, boxes = _heatmap_with(wins)
    out = split_boxes(boxes, hm.heat, hm.labels, 4, hm.frame_shape, hm._cur[0], hm._cur[1], hm.config.extent,
                      min_aspect=3.0)
    assert out is boxes
    # one large vehicle: windows covering it and a few on its halves: the halves' modes lie
    # inside the whole vehicle's, no cut (looked at whatever its shape: min_aspect 0.5)
    wins = np.vstack([_cluster(300, 100, 160, 9), _cluster(300, 116, 64, 2), _cluster(396, 116, 64, 2)])
    hm, boxes = _heatmap_with(wins)
    out = split_boxes(boxes, hm.heat, hm.labels, 4, hm.frame_shape, hm._cur[0], hm._cur[1], hm.config.extent,
                      min_aspect=0.5)
    assert out is boxes
    # fewer than two windows: nothing to split by
    out = split_boxes(boxes, hm.heat, hm.labels, 4, hm.frame_shape, wins[:1], np.ones(1), hm.config.extent)
    assert out is boxes


def test_the_pipeline_splits_two_cars_in_a_row():
    from fastdet.config import NeighbourSplit, PipelineConfig
    from fastdet.video.pipeline import VideoDetector
    from tests.fakes import FixedDetector

    wins = np.vstack([_cluster(100, 200, 40), _cluster(146, 200, 40)]).astype(np.int32)
    dets = Detections(wins, np.full(len(wins), 2.0, np.float32))
    frame = np.zeros((360, 640, 3), np.uint8)
    base = PipelineConfig(tracker=None, refine=None, horizon=None, split=None,
                          heat=HeatConfig(n_frames=1, threshold=1.5, min_width=0, min_height=0, reference_rows=None))
    vd = VideoDetector(FixedDetector(dets), base)
    assert len(vd.update(frame)) == 1
    assert replace(base, split=NeighbourSplit()) == replace(base, split=PipelineConfig().split)  # on by default
    vd = VideoDetector(FixedDetector(dets), replace(base, split=NeighbourSplit()))
    assert [s.name for s in vd.stages] == ["detect", "ownvehicle", "heatmap", "split", "plausible"]
    out = vd.update(frame)
    assert len(out) == 2 and len(vd.debug.boxes) == 2


def test_the_deleted_min_heat_loads_only_off():
    from fastdet.config import NeighbourSplit

    assert NeighbourSplit.from_dict({"min_heat": None}) == NeighbourSplit()
    assert "min_heat" not in NeighbourSplit().to_dict()
    with pytest.raises(ValueError, match="deleted"):
        NeighbourSplit.from_dict({"min_heat": 1.0})
