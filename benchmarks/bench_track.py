"""What tracking costs per frame, beside what detecting costs.

Run::

    python -m pytest benchmarks/bench_track.py --benchmark-only

The inputs are the real ones: the default :class:`~fastdet.VideoDetector` runs once over
``videos/test_small1.mp4`` (88 frames, 1280x720; up to 3 vehicles at a time) and keeps, per
frame, the positive windows, the heat maps' boxes and the weak boxes. Then:

- ``tracker``: :meth:`fastdet.video.track.Tracker.update` over the 88 frames (the tracker
  alone: Kalman predict / update, buffered IoU, Hungarian assignment, merged-blob split);
- ``weak_blobs``: the heat map's extra work for the tracker, :meth:`HeatMap.weak_boxes` of
  the main heat map at ``low_heat`` x its threshold (replayed from the cached windows);
- ``offline``: the offline pass over the whole clip's tracks;
- ``video_update``: a whole :meth:`VideoDetector.update` (detector, heat maps, tracker) on
  the clip's first 16 frames, with the tracker and without (``tracker=False``).

``extra_info["ms_per_frame"]`` holds the mean per frame (the benchmark's own time is per
call, i.e. per clip or per 16 frames). The tracker runs in the calling thread (numpy and
scipy, no numba), so ``NUMBA_NUM_THREADS`` only changes the detector's figures.
"""
from __future__ import annotations

import numba
import numpy as np
import pytest

from fastdet.config import HeatConfig, PipelineConfig, TrackerConfig
from fastdet.io.reader import FrameReader
from fastdet.video import VideoDetector, make_detector
from fastdet.video.heatmap import HeatMap
from fastdet.video.offline import offline_pass
from fastdet.video.track import Tracker

N_VIDEO_FRAMES = 16


@pytest.fixture(scope="module")
def clip(data):
    """``(frames, per-frame (windows, high boxes, low boxes, output))`` of test_small1."""
    reader = FrameReader(data / "videos" / "test_small1.mp4")
    vd = VideoDetector(make_detector())
    vd.warmup()
    frames, rows = [], []
    try:
        for _, frame, _ in reader:
            out = vd.update(frame)
            frames.append(frame)
            rows.append((vd.debug.windows, vd.debug.boxes, vd.debug.low, out))
    finally:
        reader.close()
    return frames, rows


def _info(benchmark, n: int) -> None:
    benchmark.extra_info["frames_per_call"] = n
    benchmark.extra_info["numba_threads"] = numba.get_num_threads()
    if benchmark.stats is not None:
        benchmark.extra_info["ms_per_frame"] = 1e3 * benchmark.stats.stats.mean / n


def test_tracker(benchmark, clip):
    _, rows = clip
    tr = Tracker(TrackerConfig())

    def run():
        tr.reset()
        for _, high, low, _ in rows:
            tr.update(high, low)

    benchmark.pedantic(run, rounds=30, warmup_rounds=2)
    _info(benchmark, len(rows))


def test_weak_blobs(benchmark, clip):
    frames, rows = clip
    hm = HeatMap(frames[0].shape, HeatConfig(), score_kind=make_detector().score_kind)
    maps = []  # the heat map after each frame, for weak_boxes to read
    for windows, *_ in rows:
        hm.update(windows[~windows.is_oncoming])
        maps.append((hm.heat.copy(), hm._cur))
    thr = TrackerConfig().low_heat * hm.config.threshold

    def run():
        for heat, cur in maps:
            hm.heat, hm._cur = heat, cur
            hm.weak_boxes(thr)

    benchmark.pedantic(run, rounds=10, warmup_rounds=1)
    _info(benchmark, len(rows))


def test_offline(benchmark, clip):
    frames, rows = clip
    outs = [(i + 1, out) for i, (*_, out) in enumerate(rows)]
    benchmark.pedantic(offline_pass, args=(outs, frames[0].shape), rounds=20, warmup_rounds=1)
    _info(benchmark, len(rows))


@pytest.mark.parametrize("tracking", [True, False], ids=["tracker", "no-tracker"])
def test_video_update(benchmark, clip, tracking):
    frames, _ = clip
    vd = VideoDetector(make_detector(), PipelineConfig(tracker=TrackerConfig() if tracking else None))
    vd.warmup()

    def run():
        vd.reset()
        for f in frames[:N_VIDEO_FRAMES]:
            vd.update(f)

    benchmark.pedantic(run, rounds=3, warmup_rounds=1)
    _info(benchmark, N_VIDEO_FRAMES)
    benchmark.extra_info["track_ms_last_frame"] = 1e3 * vd.timings.get("track", np.nan)
