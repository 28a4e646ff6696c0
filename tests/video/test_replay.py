"""fastdet.video.replay: one pass of the frames gives, for each decision offset, the boxes the
pipeline gives with the model moved by it (the frame's windows, and a clip's boxes and ids)."""
from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from fastdet.config import PipelineConfig
from fastdet.detect import Detector, DetectStats
from fastdet.detections import Detections
from fastdet.io.reader import FrameReader
from fastdet.model import load_model
from fastdet.train.blend import offset
from fastdet.video.replay import ReplayDetector, iter_offset_detections
from fastdet.video.run import iter_video_detections
from tests.fakes import model_carrying_side

OFFSETS = (-1.0, 0.0, 3.0)


def _same(a, b) -> bool:
    return (len(a) == len(b) and np.array_equal(a.boxes, b.boxes) and np.array_equal(a.scores, b.scores)
            and np.array_equal(a.part, b.part) and np.array_equal(a.scale, b.scale))


@pytest.fixture(scope="module")
def frame(data):
    with FrameReader(str(data / "videos" / "test_small1.mp4"), 30, 1) as r:
        return next(iter(r))[1]


@pytest.mark.parametrize("delta", OFFSETS)
def test_a_frames_windows_are_those_of_the_moved_model(frame, delta):
    """Every window, the slack rows' stricter threshold and the guided search's columns included,
    is the moved model's own detector's (boxes, probabilities, scales)."""
    model = load_model()
    src = Detector(model)
    stats = DetectStats()
    src.detect(frame, stats=stats)
    moved = Detector(offset(model, delta))
    replay = ReplayDetector(src, delta)
    replay.feed(stats.bands, Detections.empty())  # no oncoming model here
    n = len(src.main_geometries(frame.shape[:2]))
    for columns in (None, [[(0, 6), (20, 31)]] * n, [None, [(3, 9)]] + [[]] * (n - 2)):
        want = moved.detect(frame, columns=columns)
        got = replay.detect(frame, columns=columns)
        assert _same(got, want), (delta, columns)
    if delta:  # the offset moves the windows: the comparison can tell offsets apart
        assert len(replay.detect(frame)) != len(src.windows(stats.bands))


@pytest.mark.slow
@pytest.mark.parametrize("boxes", [None, "nms"])
def test_each_offsets_boxes_and_ids_are_those_of_its_own_run(data, tmp_path, boxes):
    """24 frames of test_small1 (from frame 21, as adapt's kept-aside stretch starts mid-video):
    the replay's boxes, scores and ids of every frame equal a pipeline run of each moved model
    (guided search, tracker, refinement, own vehicle: the defaults; the heat map, or the windows
    after suppression), and the offsets' boxes differ."""
    video = str(data / "videos" / "test_small1.mp4")
    model = load_model()
    base = tmp_path / "base.npz"
    offset(model, 0.0).save(base)
    replayed = list(iter_offset_detections(video, OFFSETS, replace(PipelineConfig(), model=str(base), boxes=boxes),
                                           start=20, frames=24))
    assert len(replayed) == 24 and [f for f, _ in replayed] == list(range(21, 45))
    totals = {}
    for o in OFFSETS:
        path = tmp_path / f"o{o:+g}.npz"
        offset(model, o).save(path)
        real = list(iter_video_detections(video, replace(PipelineConfig(), model=str(path), boxes=boxes),
                                          start=20, frames=24,
                                          progress=False))
        assert [f for f, _ in real] == [f for f, _ in replayed]
        for (fno, want), (_, got) in zip(real, replayed):
            assert len(got[o]) == len(want) and np.array_equal(got[o].boxes, want.boxes), (o, fno)
            assert np.array_equal(got[o].scores, want.scores) and np.array_equal(got[o].ids, want.ids), (o, fno)
        totals[o] = sum(len(d) for _, d in real)
    assert len(set(totals.values())) > 1, totals  # the offsets give other boxes: the test can tell them apart


def test_lanes_of_either_box_formation_are_those_of_each_formations_own_replay(data):
    """iter_lane_detections with lanes of both formations in one pass: each lane's boxes, scores
    and ids are those of iter_offset_detections for its formation (itself checked against real
    runs above); the two formations' boxes differ."""
    from fastdet.video.replay import iter_lane_detections

    video = str(data / "videos" / "test_small1.mp4")
    lanes = [("heat", 0.0), ("nms", 3.0), ("nms", 0.0), ("heat", 3.0)]
    mixed = list(iter_lane_detections(video, lanes, PipelineConfig(), start=20, frames=12))
    own = {b: list(iter_offset_detections(video, (0.0, 3.0), PipelineConfig(boxes=b), start=20, frames=12))
           for b in ("heat", "nms")}
    assert [f for f, _ in mixed] == [f for f, _ in own["heat"]] == list(range(21, 33))
    differ = 0
    for k, (fno, tables) in enumerate(mixed):
        for (b, o), got in zip(lanes, tables):
            want = own[b][k][1][o]
            assert np.array_equal(got.boxes, want.boxes) and np.array_equal(got.scores, want.scores), (fno, o, b)
            assert np.array_equal(got.ids, want.ids), (fno, o, b)
        differ += not np.array_equal(tables[0].boxes, tables[2].boxes)
    assert differ > 0
    with pytest.raises(ValueError, match="distinct"):
        next(iter_lane_detections(video, [("nms", 0.0), ("nms", 0.0)]))


# ---- a model carrying a side-view component: its own offset, or none ----------------------

SIDE_OFFSETS = (0.0, 2.0, math.inf)


@pytest.mark.parametrize("delta, side_delta", [(0.0, 0.0), (0.0, 2.0), (1.0, -1.0), (0.0, math.inf)])
def test_a_frames_windows_are_those_of_the_side_component_moved(frame, delta, side_delta):
    """ReplayDetector(source, delta, component_delta): the main model moved by delta, its side-view
    component by component_delta (inf: without it), window for window, the guided search's
    columns of the main bands (which the side bands follow) included."""
    from fastdet.detections import FIRST_COMPONENT_PART
    from fastdet.train.blend import side_offset

    model = model_carrying_side(frame)
    src = Detector(model)
    stats = DetectStats()
    whole = src.detect(frame, stats=stats)
    assert (whole.part == FIRST_COMPONENT_PART).sum() > 3
    moved = Detector(offset(side_offset(model, side_delta), delta))
    replay = ReplayDetector(src, delta, side_delta)
    replay.feed(stats.bands, Detections.empty())
    n = len(src.geometries(frame.shape[:2], 0))
    for columns in (None, [[(0, 6), (20, 31)]] * n, [None, [(3, 9)]] + [[]] * (n - 2)):
        want = moved.detect(frame, columns=columns)
        got = replay.detect(frame, columns=columns)
        assert _same(got, want), (delta, side_delta, columns)
    if side_delta == math.inf:
        assert not (replay.detect(frame).part == FIRST_COMPONENT_PART).any()


@pytest.mark.slow
def test_each_side_offsets_boxes_and_ids_are_those_of_its_own_run(data, tmp_path):
    """Lanes ("nms", 0, s) of a model carrying a side-view component: each lane's boxes, scores and
    ids of every frame equal a pipeline run of the model with its component moved by s (inf:
    without it), and the side offsets' boxes differ."""
    from fastdet.train.blend import side_offset
    from fastdet.video.replay import iter_lane_detections

    video = str(data / "videos" / "test_small1.mp4")
    with FrameReader(video, 20, 1) as r:
        model = model_carrying_side(next(iter(r))[1])
    base = tmp_path / "base.npz"
    offset(model, 0.0).save(base)
    lanes = [("nms", 0.0, s) for s in SIDE_OFFSETS]
    replayed = list(iter_lane_detections(video, lanes, replace(PipelineConfig(), model=str(base)), start=20,
                                         frames=20))
    assert [f for f, _ in replayed] == list(range(21, 41))
    totals = {}
    for k, s in enumerate(SIDE_OFFSETS):
        path = tmp_path / f"s{s:+g}.npz"
        side_offset(model, s).save(path)
        assert (load_model(path).side is None) == (s == math.inf)
        real = list(iter_video_detections(video, replace(PipelineConfig(), model=str(path), boxes="nms"),
                                          start=20, frames=20, progress=False))
        assert [f for f, _ in real] == [f for f, _ in replayed]
        for (fno, want), (_, got) in zip(real, replayed):
            got = got[k]
            assert len(got) == len(want) and np.array_equal(got.boxes, want.boxes), (s, fno)
            assert np.array_equal(got.scores, want.scores) and np.array_equal(got.ids, want.ids), (s, fno)
        totals[s] = sum(len(d) for _, d in real)
    assert totals[0.0] > totals[2.0] > totals[math.inf], totals  # the side offsets give other boxes
    with pytest.raises(ValueError, match="distinct"):  # (boxes, offset) is (boxes, offset, 0)
        next(iter_lane_detections(video, [("nms", 0.0), ("nms", 0.0, 0.0)], replace(PipelineConfig(), model=str(base))))
