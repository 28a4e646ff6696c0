"""Wide-window boxes join the main boxes only where the main heat map found nothing."""
from __future__ import annotations

import numpy as np

from fastdet.boxes import overlap_fraction
from fastdet.config import HeatConfig, MotionGate, PipelineConfig
from fastdet.detections import MAIN_PART, ONCOMING_PART, Detections
from fastdet.video import VideoDetector
from fastdet.video.fusion import merge_oncoming
from tests.fakes import FixedDetector


def test_overlap_fraction_by_hand():
    a = np.array([[0, 0, 10, 10], [100, 100, 110, 110]])
    b = np.array([[5, 0, 20, 10]])
    np.testing.assert_allclose(overlap_fraction(a, b), [[0.5], [0.0]])


def test_merge_oncoming_keeps_only_new_places():
    main = Detections(np.array([[100, 100, 200, 160]], np.int32), np.array([9.0], np.float32))
    wide = Detections(np.array([[110, 120, 190, 150], [10, 100, 70, 125]], np.int32), np.array([5.0, 6.0], np.float32))
    out = merge_oncoming(main, wide)
    assert out.boxes.tolist() == [[100, 100, 200, 160], [10, 100, 70, 125]]
    assert out.scores.tolist() == [9.0, 6.0]
    assert merge_oncoming(Detections.empty(), wide).boxes.tolist() == wide.boxes.tolist()
    assert merge_oncoming(main, Detections.empty()) is main


def test_video_detector_routes_wide_windows_to_their_own_heat_map():
    # main windows: three overlapping on a car ahead; wide windows: on that car (must be
    # dropped) and on a small car on the left (must be kept)
    main = [[600, 400, 664, 464], [608, 400, 672, 464], [600, 408, 664, 472]]
    wide = [[610, 420, 674, 444], [100, 430, 164, 454], [104, 430, 168, 454]]
    part = [MAIN_PART] * 3 + [ONCOMING_PART] * 3
    windows = Detections(np.array(main + wide, np.int32), np.full(6, 3.0, np.float32),
                         scale=np.ones(6, np.float32), part=np.array(part, np.int8))
    vd = VideoDetector(FixedDetector(windows, oncoming_model=object()), PipelineConfig(
        heat=HeatConfig(threshold=5.0, n_frames=1),
        oncoming_heat=HeatConfig(threshold=5.0, n_frames=1, box_mode="mean", min_height=10, max_aspect=0.8),
        motion=MotionGate(0), refine=None))  # no motion gate: the fake has no search bands
    out = vd.update(np.zeros((720, 1280, 3), np.uint8))
    assert len(out.boxes) == 2
    left = out.boxes[out.boxes[:, 0] < 300][0]
    assert left.tolist() == [102, 430, 166, 454]  # mean of the two wide windows
    right = out.boxes[out.boxes[:, 0] >= 300][0]
    assert right[0] >= 596 and right[2] <= 676  # the main box, not widened by the wide window
    assert vd.debug.windows.is_oncoming.sum() == 3
    vd.reset()
