"""tools/studies/tune_video.py replays the real VideoDetector: its boxes over cached windows are the
boxes (and track ids) of the video pipeline itself with the full search (``--full-search``:
the cache holds every window of every band; the tracking-guided search scores a subset)."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from fastdet import Detector, HeatConfig, MotionGate, VideoDetector
from fastdet.config import ONCOMING_HEAT, ONCOMING_SEARCH, PipelineConfig
from fastdet.detections import Detections
from fastdet.io.reader import FrameReader
from fastdet.video import iter_video_detections, make_detector
from tools.studies.tune_video import cache_windows, replay

pytestmark = pytest.mark.slow  # each runs the video pipeline over a clip twice


@pytest.fixture(scope="module")
def clip(data):
    return data / "videos" / "test_video.mp4"


@pytest.fixture(scope="module")
def cached(clip):
    det = make_detector()  # the bundled main and oncoming models, as `fastdet video`
    return det, cache_windows(det, clip, low=-1.0)


def _same(a: Detections, b: Detections) -> None:
    assert len(a.frames) > 0
    np.testing.assert_array_equal(a.frames, b.frames)
    np.testing.assert_array_equal(a.boxes, b.boxes)
    np.testing.assert_allclose(a.scores, b.scores, rtol=0, atol=1e-5)
    np.testing.assert_array_equal(a.ids, b.ids)


def test_replay_of_the_defaults_is_the_video_pipeline(clip, cached):
    det, windows = cached
    got = replay(windows, det.search.threshold, HeatConfig(), ONCOMING_HEAT, MotionGate())
    want = Detections.from_frames(iter_video_detections(clip, PipelineConfig(guided=None), progress=False))
    _same(got, want)
    assert (got.ids >= 1).all()  # tracked, as the pipeline
    untracked = replay(windows, det.search.threshold, HeatConfig(), ONCOMING_HEAT, MotionGate(), tracker=False)
    untracked_config = PipelineConfig(tracker=None, guided=None)
    _same(untracked, Detections.from_frames(iter_video_detections(clip, untracked_config, progress=False)))


def test_replay_of_other_settings_is_video_detector_with_them(clip, cached):
    det, windows = cached
    heat = HeatConfig(threshold=2.0, n_frames=4)
    oncoming_heat = HeatConfig(threshold=5.0, n_frames=1, extent=0.3, min_height=10, max_aspect=0.8)
    thr = 0.5
    got = replay(windows, thr, heat, oncoming_heat, MotionGate(30.0), thr_oncoming=0.5)
    # the same settings, run for real: the window thresholds are the searches' own
    real = Detector(search=replace(det.search, threshold=thr),
                    oncoming=det.oncoming_model, oncoming_search=replace(ONCOMING_SEARCH, threshold=0.5))
    vd = VideoDetector(real, PipelineConfig(heat=heat, oncoming_heat=oncoming_heat, motion=MotionGate(30.0),
                                            guided=None))
    reader = FrameReader(clip)
    try:
        want = Detections.from_frames((f, vd.update(frame)) for f, frame, _ in reader)
    finally:
        reader.close()
    _same(got, want)
