"""The road's vanishing point from line segments (fastdet.video.vanishing)."""
from __future__ import annotations

import math

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fastdet.io.reader import read_frames
from fastdet.video.horizon import HorizonEstimator
from fastdet.video.vanishing import road_segments, segments_vanishing_point, vanishing_point
from tests.reference import ref_vanishing_score


def _road(vx: float, vy: float, shape=(360, 640), distractors: bool = True) -> np.ndarray:
    """A grey picture with lane lines from the bottom edge to ``(vx, vy)`` (stopping short of it)
    and, with ``distractors``, vertical poles and horizontal edges that must not count."""
    h, w = shape
    img = np.full((h, w, 3), 90, np.uint8)
    img[: int(vy)] = 170  # sky
    for x0 in np.linspace(-0.6 * w, 1.6 * w, 9):
        t = 0.15  # the lines end 15% of the way short of the vanishing point
        x1, y1 = vx + (x0 - vx) * t, vy + (h - 1 - vy) * t
        cv2.line(img, (int(round(x0)), h - 1), (int(round(x1)), int(round(y1))), (255, 255, 255), 3, cv2.LINE_AA)
    if distractors:
        for x in (0.1 * w, 0.8 * w, 0.9 * w):
            cv2.line(img, (int(x), 20), (int(x), int(vy) + 30), (30, 30, 30), 4)
        cv2.rectangle(img, (int(0.55 * w), int(vy) + 10), (int(0.7 * w), int(vy) + 40), (20, 20, 20), -1)
    return img


@pytest.mark.parametrize("vx, vy", [(320, 200), (250, 150), (400, 260)])
def test_vanishing_point_of_a_drawn_road(vx, vy):
    p = vanishing_point(_road(vx, vy))
    assert p is not None
    assert p == pytest.approx((vx, vy), abs=3)


def test_vanishing_point_in_frame_pixels():
    small = _road(320, 200)
    big = cv2.resize(small, (1280, 720), interpolation=cv2.INTER_LINEAR)
    p = vanishing_point(big)
    assert p is not None
    assert p == pytest.approx((640, 400), abs=6)


def test_no_vanishing_point_without_oblique_lines():
    img = np.full((360, 640, 3), 100, np.uint8)
    for x in range(40, 640, 80):
        cv2.line(img, (x, 0), (x, 359), (250, 250, 250), 3)
    for y in range(40, 360, 80):
        cv2.line(img, (0, y), (639, y), (10, 10, 10), 3)
    assert vanishing_point(img) is None
    assert segments_vanishing_point(np.zeros((0, 4)), (360, 640)) is None


def test_road_segments_keeps_oblique_long_ones():
    s = np.array([[0, 0, 100, 0],  # horizontal
                  [0, 0, 0, 100],  # vertical
                  [0, 0, 5, 5],  # short
                  [0, 0, 100, 60]])  # oblique, long
    assert road_segments(s).tolist() == [[0, 0, 100, 60]]


def test_horizon_estimator_falls_back_on_segments():
    frames = [_road(320, 150)] * 20  # a camera that stands still: no flow, but the road's lines
    est = HorizonEstimator(gap=1, every=1, max_pairs=15)
    for k, f in enumerate(frames):
        est.update(f)
        if k == 10:  # the flow may still come: no estimate yet
            assert est.estimate is None and len(est.segment_rows) == 11
    assert est.rows == []
    assert len(est.segment_rows) == 15 and est.done is False
    assert est.source == "segments"
    assert est.estimate == pytest.approx(150 / 360, abs=0.01)
    flow_only = HorizonEstimator(gap=1, every=1, segments=False)
    for f in frames:
        flow_only.update(f)
    assert flow_only.estimate is None and flow_only.source is None and flow_only.segment_rows == []


def test_segments_spread_too_wide_gives_nothing():
    est = HorizonEstimator(gap=1, every=1, min_pairs=5, max_spread=0.02)
    for k in range(12):
        est.update(_road(320, 100 + 25 * (k % 4)))  # the row jumps by 25-75 px of 360
    assert len(est.segment_rows) >= 5
    assert est.estimate is None


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 2**31 - 1), st.integers(4, 30), st.integers(0, 20))
def test_scores_match_the_slow_reference(seed, n_road, n_noise):
    rng = np.random.default_rng(seed)
    h, w = 360, 640
    vx, vy = rng.uniform(0.1 * w, 0.9 * w), rng.uniform(0.2 * h, 0.8 * h)
    segs = []
    for _ in range(n_road):  # segments along rays from the vanishing point, a little off
        a = rng.uniform(0.1, math.pi - 0.1) * rng.choice([1, -1])
        r0, r1 = rng.uniform(20, 200), rng.uniform(20, 150)
        a2 = a + rng.normal(0, 0.01)
        segs.append([vx + r0 * math.cos(a2), vy + r0 * math.sin(a2),
                     vx + (r0 + r1) * math.cos(a2), vy + (r0 + r1) * math.sin(a2)])
    for _ in range(n_noise):
        x, y = rng.uniform(0, w), rng.uniform(0, h)
        segs.append([x, y, x + rng.uniform(-80, 80), y + rng.uniform(-80, 80)])
    s = np.array(segs)
    s = s[np.hypot(s[:, 2] - s[:, 0], s[:, 3] - s[:, 1]) > 1]
    got = segments_vanishing_point(s, (h, w), tolerance=1.5, hypotheses=25, min_segments=1)
    ref = ref_vanishing_score(s, (h, w), 1.5, 25)
    lengths = np.hypot(s[:, 2] - s[:, 0], s[:, 3] - s[:, 1])
    if ref < 0:
        assert got is None
        return
    assert got is not None
    assert got[2] * lengths.sum() == pytest.approx(ref, rel=1e-6, abs=1e-6)
    if n_road >= 8 and 2 * n_noise <= n_road:
        assert math.hypot(got[0] - vx, got[1] - vy) < 8  # most segments point there: found


def test_segments_give_boston_streets_horizon(data):
    """A city street seen in jumps: the flow's pairs disagree, the line segments agree with the
    horizon the annotated vehicles imply (the Theil-Sen line through their widths and bottom
    rows, where their width would be 0)."""
    from scipy.stats import theilslopes

    frames = read_frames(data / "videos" / "boston_street.mp4", frames=40)
    est = HorizonEstimator()
    for f in frames:
        est.update(f)
    flow_only = HorizonEstimator(segments=False)
    for f in frames:
        flow_only.update(f)
    assert flow_only.estimate is None
    gt = np.loadtxt(data / "annotations" / "boston_street.gt.txt", delimiter=",", ndmin=2)
    t = gt[gt[:, 6] == 1]
    k, c, _, _ = theilslopes(t[:, 4], t[:, 3] + t[:, 5])
    boxes_horizon = -c / k / frames[0].shape[0]
    assert est.source == "segments"
    assert est.estimate == pytest.approx(boxes_horizon, abs=0.03)


def test_segments_agree_with_the_flow_on_the_udacity_clip(data):
    frames = read_frames(data / "videos" / "test_video.mp4", frames=38)
    rows = [p[1] / f.shape[0] for f in frames[::3] if (p := vanishing_point(f)) is not None]
    flow = HorizonEstimator(segments=False)
    for f in frames:
        flow.update(f)
    assert len(rows) >= 10 and flow.estimate is not None
    assert float(np.median(rows)) == pytest.approx(flow.estimate, abs=0.01)
