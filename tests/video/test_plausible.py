"""fastdet.video.plausible: duplicates dropped by greedy non-maximum suppression, and the
stage that applies it to the boxes VideoDetector returns."""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fastdet.boxes import iou
from fastdet.config import PipelineConfig, PlausibleConfig
from fastdet.detections import Detections
from fastdet.eval.clips import annotated_clips
from fastdet.video import VideoDetector, make_detector
from fastdet.video.plausible import PlausibleStage, duplicates
from fastdet.video.stages import FrameState
from tests.fakes import SquareDetector


def reference_nms(boxes: np.ndarray, scores: np.ndarray, max_iou: float) -> np.ndarray:
    """The obvious greedy non-maximum suppression, one pair at a time."""
    order = sorted(range(len(boxes)), key=lambda i: (-scores[i], i))
    kept: list[int] = []
    for i in order:
        if all(iou(boxes[i:i + 1], boxes[j:j + 1])[0, 0] <= max_iou for j in kept):
            kept.append(i)
    keep = np.zeros(len(boxes), bool)
    keep[kept] = True
    return keep


def test_the_lower_scored_of_two_boxes_over_max_iou_goes():
    a = [100, 100, 200, 200]
    b = [110, 100, 210, 200]  # IoU 90 / 110 = 0.82
    c = [150, 100, 250, 200]  # IoU with a: 50 / 150 = 0.33
    keep = duplicates(np.array([a, b, c]), np.array([5.0, 9.0, 1.0]), 0.5)
    assert keep.tolist() == [False, True, True]
    # exactly at max_iou is kept: two vehicles each half in view can reach IoU 0.5
    d = [100, 100, 300, 200]  # a is half of d: IoU 0.5
    assert duplicates(np.array([a, d]), np.array([1.0, 2.0]), 0.5).tolist() == [True, True]
    assert duplicates(np.array([a, d]), np.array([1.0, 2.0]), 0.49).tolist() == [False, True]


def test_ties_keep_the_earlier_row_and_a_dropped_box_suppresses_nothing():
    a = [0, 0, 100, 100]
    b = [10, 0, 110, 100]   # overlaps a (0.82) and c (0.82)
    c = [20, 0, 120, 100]   # overlaps a by 80 / 120 = 0.67
    assert duplicates(np.array([a, b]), np.array([3.0, 3.0]), 0.5).tolist() == [True, False]
    # b goes because of a; c overlaps a too, so it goes as well
    assert duplicates(np.array([a, b, c]), np.array([3.0, 2.0, 1.0]), 0.5).tolist() == [True, False, False]
    e = [60, 0, 160, 100]   # overlaps b by 50 / 150 = 0.33 and a by 40 / 160 = 0.25: kept
    f = [30, 0, 130, 100]   # overlaps b (0.67), a (0.54), e (0.54)
    assert duplicates(np.array([a, f, e]), np.array([1.0, 3.0, 2.0]), 0.5).tolist() == [False, True, False]
    assert duplicates(np.zeros((0, 4)), np.zeros(0), 0.5).tolist() == []
    assert duplicates(np.array([a]), np.array([0.0]), 0.0).tolist() == [True]
    with pytest.raises(ValueError, match="2 boxes but 1 scores"):
        duplicates(np.array([a, b]), np.array([1.0]), 0.5)


boxes_st = st.lists(st.tuples(st.integers(0, 300), st.integers(0, 200), st.integers(1, 120), st.integers(1, 90),
                              st.integers(0, 5)), min_size=0, max_size=12)


@settings(max_examples=200, deadline=None)
@given(boxes_st, st.sampled_from([0.0, 0.3, 0.5, 0.7]))
def test_duplicates_is_greedy_nms(rows, max_iou):
    b = np.array([[x, y, x + w, y + h] for x, y, w, h, _ in rows], np.float64).reshape(-1, 4)
    s = np.array([float(k) for *_, k in rows])  # few distinct scores: many ties
    keep = duplicates(b, s, max_iou)
    assert keep.tolist() == reference_nms(b, s, max_iou).tolist()
    kept = b[keep]
    if len(kept) > 1:
        m = iou(kept, kept)
        np.fill_diagonal(m, 0)
        assert m.max() <= max_iou


def test_no_two_annotated_vehicles_overlap_by_more_than_half(data):
    """The rule behind max_iou = 0.5: on every annotated frame of every clip, no target is
    dropped as a duplicate of another, whichever of them scores higher."""
    clips = annotated_clips(data)
    assert len(clips) >= 5
    frames = 0
    for clip in clips:
        for _, g in clip.gt().by_frame():
            t = g.boxes[g.targets].astype(np.float64)
            if len(t) < 2:
                continue
            frames += 1
            for scores in (np.arange(len(t), dtype=float), -np.arange(len(t), dtype=float)):
                assert duplicates(t, scores, PlausibleConfig().max_iou).all(), clip.name
    assert frames > 50


def out_state(boxes: list[list[int]], scores: list[float]) -> FrameState:
    s = FrameState(np.zeros((720, 1280, 3), np.uint8))
    s.out = Detections(np.array(boxes, np.int32).reshape(-1, 4), np.array(scores, np.float32),
                       ids=np.arange(1, len(boxes) + 1))
    return s


def test_the_stage_drops_duplicates():
    boxes = [[500, 380, 700, 460], [510, 380, 710, 460], [600, 650, 630, 700]]
    st_ = PlausibleStage(PlausibleConfig())
    out = st_(out_state(boxes, [1.0, 2.0, 3.0])).out
    assert out.ids.tolist() == [2, 3] and st_.dropped == 1
    st_.reset()
    assert st_.dropped == 0
    wide = [[300, 300, 900, 370], [330, 300, 870, 370]]  # IoU 0.9
    assert PlausibleStage(PlausibleConfig())(out_state(wide, [9.0, 1.0])).out.ids.tolist() == [1]
    no_dup = PlausibleStage(PlausibleConfig(max_iou=None))
    assert no_dup(out_state(boxes, [1.0, 2.0, 3.0])).out.ids.tolist() == [1, 2, 3]
    assert len(PlausibleStage(PlausibleConfig())(out_state([], [])).out) == 0


def test_the_pipeline_runs_the_stage_last_after_the_search_learns():
    vd = VideoDetector(make_detector())
    names = [s.name for s in vd.stages]
    assert names[-2:] == ["refine", "plausible"]  # after the search learns: no later frame reads them
    assert isinstance(vd.stage(PlausibleStage), PlausibleStage)
    off = VideoDetector(make_detector(), PipelineConfig(plausible=None))
    assert off.stage(PlausibleStage) is None


def test_with_the_offline_pass_the_rules_run_after_it():
    """A box the rules dropped before the offline pass would leave a gap in its track that the
    pass fills with an interpolated box; deferred, they run on the pass's boxes."""
    from fastdet.video.offline import offline_pass
    from fastdet.video.run import defer_plausible, offline_boxes

    vd = VideoDetector(SquareDetector(), PipelineConfig(refine=None))
    st_ = vd.stage(PlausibleStage)
    assert isinstance(st_, PlausibleStage) and not st_.deferred
    defer_plausible(vd)
    assert st_.deferred
    s = st_(out_state([[500, 380, 700, 460], [510, 380, 710, 460]], [1.0, 2.0]))
    assert len(s.out) == 2  # deferred: every box through
    a, b = [100, 100, 200, 200], [110, 100, 210, 200]  # IoU 0.82
    pair = Detections(np.array([a, b], np.int32), np.array([9.0, 5.0], np.float32), ids=np.array([1, 2]))
    none = Detections(np.zeros((0, 4), np.int32), np.zeros(0, np.float32), ids=np.zeros(0, np.int64))
    done = [(1, pair), (2, none), (3, pair)]
    filled = offline_pass(done, (360, 640), vd.tracker.config)
    assert [d.ids.tolist() for _, d in filled] == [[1, 2], [1, 2], [1, 2]]  # both gaps filled
    final = offline_boxes(vd, done, (360, 640))
    assert [d.ids.tolist() for _, d in final] == [[1], [1], [1]]
    assert final[1][1].boxes.tolist() == [a]
    with pytest.raises(ValueError, match="needs the tracker"):
        offline_boxes(VideoDetector(SquareDetector(), PipelineConfig(refine=None, tracker=None)), done, (360, 640))


def test_duplicates_of_many_boxes_stay_small_and_equal_the_dense_answer():
    """``image --merge nms`` of a 640x360 picture of noise: about 15,000 windows over the threshold,
    and the (N, N) IoU matrix with its temporaries peaked at 4.1 GB (issue 34's walk through
    ``image``); above ``DENSE_DUPLICATES`` boxes the rows of the kept boxes are computed one by
    one: the same boxes kept, memory linear in N."""
    import tracemalloc

    from fastdet.video import plausible

    rng = np.random.default_rng(3)

    def boxes(n):
        xy = rng.uniform(0, 600, (n, 2))
        wh = rng.uniform(16, 128, (n, 2))
        return np.hstack([xy, xy + wh]), rng.normal(size=n).round(1)  # ties in the scores too

    b, s = boxes(3000)
    dense = duplicates(b, s, 0.3)
    old = plausible.DENSE_DUPLICATES
    try:
        plausible.DENSE_DUPLICATES = 10**9
        assert np.array_equal(duplicates(b, s, 0.3), dense)
    finally:
        plausible.DENSE_DUPLICATES = old
    b, s = boxes(20_000)
    tracemalloc.start()
    try:
        keep = duplicates(b, s, 0.5)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 20 * 2**20, peak  # the dense matrix alone: 3.2 GB
    assert 0 < keep.sum() < len(keep)
