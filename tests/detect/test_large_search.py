"""The large-vehicle search (``fastdet.config.search.LARGE_SEARCH``) on real frames: it boxes
a near SUV past the main search's largest window, also where the SUV is cut by the frame's
edge, and fires on next to nothing else on the Udacity clip with two cars."""
from __future__ import annotations

import numpy as np
import pytest

from fastdet.boxes import iou, overlap_fraction
from fastdet.config.search import LARGE_SEARCH
from fastdet.detect import Detector
from fastdet.detections import MAIN_PART
from fastdet.io.motfiles import read_gt
from fastdet.io.reader import read_frames_at


def _truth(data, clip, fno):
    gt = read_gt(data / "annotations" / f"{clip}.gt.txt")
    m = gt.frames == fno
    return gt.boxes[m & gt.consider], gt.boxes[m & ~gt.consider]


@pytest.fixture(scope="module")
def large():
    return Detector(search=LARGE_SEARCH)


def test_large_search_boxes_the_near_suv_also_where_the_frame_edge_cuts_it(data, large):
    # highway_640: the SUV overtaking on the left, 280-312 px of 1280 (frames 191-211); at 191
    # it is cut by the left edge of the frame
    frames = read_frames_at(data / "videos" / "highway_640.mp4", {191, 201, 211})
    for fno, frame in frames.items():
        targets, _ = _truth(data, "highway_640", fno)
        suv = targets[np.argmax(targets[:, 2] - targets[:, 0])]
        assert (suv[2] - suv[0]) * 2 >= 240  # larger than the main search's largest window
        w = large.detect(frame)
        assert len(w) and (w.part == MAIN_PART).all()
        best = int(np.argmax(iou(w.boxes, suv[None])[:, 0]))
        assert iou(w.boxes[best:best + 1], suv[None])[0, 0] >= 0.5, fno
        if fno == 191:
            assert suv[0] == 0 and w.boxes[best, 0] == 0  # a window over the edge, clipped to the frame


def test_large_search_fires_on_little_else_on_test_video(data, large):
    # the hand-read frames of test_video: two cars of 127-214 px; a window of the large search
    # that overlaps neither (IoU < 0.3) and lies not on an ignore region is a false one
    wanted = set(range(1, 39, 5))
    frames = read_frames_at(data / "videos" / "test_video.mp4", wanted)
    false = 0
    for fno, frame in frames.items():
        targets, ignore = _truth(data, "test_video", fno)
        w = large.detect(frame)
        if not len(w):
            continue
        on_target = iou(w.boxes, targets).max(axis=1) >= 0.3
        on_ignore = overlap_fraction(w.boxes, ignore).max(axis=1) >= 0.5 if len(ignore) else np.zeros(len(w), bool)
        false += int((~on_target & ~on_ignore).sum())
    assert false / len(frames) <= 0.25  # 1.6 a frame at the main search's threshold 0, 0.5 at 2
