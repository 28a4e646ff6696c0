"""The offline pass over a file's tracks (fastdet.video.offline): gaps filled by
interpolation, frames kept."""
from __future__ import annotations

import numpy as np

from fastdet.detections import Detections
from fastdet.video.offline import interpolate_gaps, offline_pass
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


def test_offline_pass_keeps_frames_and_adds_nothing_without_ids():
    frames = [(1, dets(car(0, 0))), (2, Detections.empty())]
    assert [len(d) for _, d in offline_pass(frames, (480, 640))] == [1, 0]
    assert offline_pass([], (480, 640)) == []
