"""The offline pass over a file's tracks (fastdet.video.offline): gaps filled by
interpolation, tracks extended back, frames kept."""
from __future__ import annotations

import numpy as np

from fastdet.detections import Detections
from fastdet.video.offline import extend_back, interpolate_gaps, offline_pass
from tests.video.test_track import car, dets, ids_of, run


def test_offline_pass_fills_the_occlusion():
    frames = [dets(car(0, f)) if not 10 <= f < 14 else dets() for f in range(25)]
    out = offline_pass(list(enumerate(run(frames), start=1)), (480, 640))
    for f, (fno, o) in enumerate(out):
        assert fno == f + 1 and ids_of(o) == [1], f
        if 10 <= f < 14:
            assert o.scores[0] == 0.0  # added by the offline pass
            np.testing.assert_array_equal(o.boxes[0], np.round(car(0, f)))
        else:
            assert o.scores[0] == 10.0


def test_interpolate_gaps_linear_and_bounded():
    tr = [(1, np.array([0.0, 0, 10, 10])), (4, np.array([30.0, 0, 40, 10])), (20, np.array([0.0, 0, 10, 10]))]
    got = interpolate_gaps(tr, max_gap=5)
    assert [f for f, _ in got] == [2, 3]
    np.testing.assert_allclose(got[0][1], [10, 0, 20, 10])
    np.testing.assert_allclose(got[1][1], [20, 0, 30, 10])


def test_extend_back_moves_the_first_box_at_the_starting_velocity():
    tr = [(10, np.array([100.0, 50, 140, 70])), (11, np.array([90.0, 50, 134, 72]))]
    # centre velocity (-8, +1) per frame; the first box's size is kept
    got = extend_back(tr, 3, first_frame=1, frame_shape=(480, 640))
    assert [f for f, _ in got] == [7, 8, 9]
    np.testing.assert_allclose(got[-1][1], [108, 49, 148, 69])
    np.testing.assert_allclose(got[0][1], [124, 47, 164, 67])
    assert [f for f, _ in extend_back(tr, 3, first_frame=9, frame_shape=(480, 640))] == [9]
    # stops where less than half the box would be in the picture
    tr = [(10, np.array([0.0, 50, 40, 70])), (11, np.array([30.0, 50, 70, 70]))]
    assert extend_back(tr, 3, 1, (480, 640)) == []


def test_offline_pass_keeps_frames_and_adds_nothing_without_ids():
    frames = [(1, dets(car(0, 0))), (2, Detections.empty())]
    assert [len(d) for _, d in offline_pass(frames, (480, 640))] == [1, 0]
    assert offline_pass([], (480, 640)) == []
