"""Placement-free window scores: the dense search covers every row and size, each target's best
window and the false windows match a brute-force count, recall at a false-window rate."""
from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fastdet.config import FeatureConfig
from fastdet.detect.bands import band_geometry
from fastdet.detections import MAIN_PART, Detections
from fastdet.model import load_model
from fastdet.train.keyframes import AnnotatedFrame, read_annotated_frames
from fastdet.train.windows import (
    FrameWindows,
    dense_detector,
    dense_search,
    false_window_scores,
    frame_windows,
    near_window_scores,
    score_frames,
    window_score,
)
from tests.reference import box_iou


@pytest.mark.parametrize("shape", [(720, 1280), (450, 800), (360, 640)])
def test_dense_search_covers_every_row_and_size(shape):
    h, w = shape
    s = dense_search(shape)
    sizes = np.array([64 * b.scale for b in s.bands])
    assert sizes[0] == pytest.approx(w / 32) and sizes[-1] <= h < sizes[-1] * 2 ** 0.25
    np.testing.assert_allclose(sizes[1:] / sizes[:-1], 2 ** 0.25)
    cfg = FeatureConfig()
    for b in s.bands:
        assert (b.y_start, b.y_stop, b.x_start) == (0, h, 0) and w - b.x_stop < 8 * b.scale
        g = band_geometry(b, shape, cfg, s.cells_per_step, s.border, s.border_mode)
        assert g.scaled_h >= 64  # at least one row of windows
    assert s.threshold == -math.inf and s.reference_shape is None and s.border == 0
    with pytest.raises(ValueError):
        dense_search((40, 40))


class _Fixed:
    """A detector that returns the same windows (and a wide model's, which must be left out)."""

    def __init__(self, boxes, scores):
        n = len(boxes)
        self.d = Detections(np.r_[boxes, [[0, 0, 5, 5]]], np.r_[scores, 0.99], part=np.r_[np.zeros(n), 1])

    def detect(self, image):
        return self.d


_box = st.tuples(st.integers(0, 150), st.integers(0, 80), st.integers(4, 60), st.integers(4, 40)).map(
    lambda t: [t[0], t[1], t[0] + t[2], t[1] + t[3]])


@settings(max_examples=60, deadline=None)
@given(st.lists(_box, min_size=0, max_size=30), st.lists(_box, max_size=4), st.lists(_box, max_size=3),
       st.integers(0, 10_000))
def test_frame_windows_against_brute_force(wins, targets, ignores, seed):
    rng = np.random.default_rng(seed)
    scores = rng.random(len(wins)).round(3)
    img = np.zeros((120, 200, 3), np.uint8)
    f = AnnotatedFrame("c", 1, img, np.array(targets, float).reshape(-1, 4), np.array(ignores, float).reshape(-1, 4))
    fw = frame_windows(_Fixed(np.array(wins, float).reshape(-1, 4), scores), f)
    for j, t in enumerate(targets):
        hits = [s for b, s in zip(wins, scores) if box_iou(b, t) >= 0.5]
        assert fw.best[j] == pytest.approx(max(hits)) if hits else fw.best[j] == -np.inf
    clear = [(b, s) for b, s in zip(wins, scores)
             if all(min(b[2], a[2]) <= max(b[0], a[0]) or min(b[3], a[3]) <= max(b[1], a[1])
                    for a in targets + ignores)]
    assert sorted(fw.false.tolist()) == pytest.approx(sorted(s for _, s in clear))
    assert len(fw.false_boxes) == len(clear)
    assert len(fw.near) == 0 and fw.near_boxes.shape == (0, 4)
    # near windows: touching a target, IoU < 0.3 with every target, touching no ignore region
    fn = frame_windows(_Fixed(np.array(wins, float).reshape(-1, 4), scores), f, near_iou=0.3)

    def touch(b, a):
        return min(b[2], a[2]) > max(b[0], a[0]) and min(b[3], a[3]) > max(b[1], a[1])

    near = [s for b, s in zip(wins, scores) if any(touch(b, t) for t in targets)
            and all(box_iou(b, t) < 0.3 for t in targets) and not any(touch(b, a) for a in ignores)]
    assert sorted(fn.near.tolist()) == pytest.approx(sorted(near)) and len(fn.near_boxes) == len(near)
    np.testing.assert_array_equal(fn.false, fw.false)


def test_window_score_recall_at_false_rates():
    # two frames; targets best 0.9, 0.6, 0.3 and one unreachable; false windows 0.95 0.8 | 0.7 0.5 0.2
    a = FrameWindows(np.array([0.9, 0.6]), np.array([0.95, 0.8]), np.zeros((2, 4)))
    b = FrameWindows(np.array([0.3, -np.inf]), np.array([0.7, 0.5, 0.2]), np.zeros((3, 4)))
    s = window_score([a, b], rates=(0.5, 1.0, 2.0, 10.0))
    assert (s.frames, s.targets, s.reachable) == (2, 4, 3)
    # 0.5 FW/frame = the best false window (0.95): nothing beats it
    assert s.recall_at[0.5] == 0.0
    assert s.recall_at[1.0] == 0.25      # threshold 0.8: only 0.9
    assert s.recall_at[2.0] == 0.5       # threshold 0.5: 0.9, 0.6
    assert s.recall_at[10.0] == 0.75     # more false windows asked for than there are: every reachable one
    assert s.recall_half == 0.5 and s.false_half == 1.5
    assert s.to_dict()["recall_at"]["1.0"] == 0.25


def test_real_frames_with_the_bundled_model(data):
    frames = read_annotated_frames(data, "boston_street")[:2]
    model = load_model(None)
    seen = []
    s = score_frames(model, frames, on_frame=lambda f, fw: seen.append(fw), cells_per_step=2)
    assert len(seen) == 2 and s.targets == sum(len(f.targets) for f in frames) > 0
    assert 0 < s.reachable <= s.targets and 0 <= s.recall_at[1.0] <= s.recall_at[10.0] <= 1
    # the windows are the dense detector's: its best window on a target equals the one found here
    det = dense_detector(model, frames[0].image.shape[:2], cells_per_step=2)
    d = det.detect(frames[0].image)
    assert (d.part == MAIN_PART).all() and len(d) > 1000
    np.testing.assert_allclose(seen[0].best, frame_windows(det, frames[0]).best)


def test_false_window_scores_of_two_models_on_the_same_windows(data):
    from fastdet.train.blend import offset

    frames = read_annotated_frames(data, "boston_street")[:1]
    model = load_model(None)
    s = false_window_scores([model, offset(model, 1.5)], frames, cells_per_step=2)
    assert s.shape[0] == 2 and s.shape[1] > 1000
    np.testing.assert_allclose(s[1], s[0] - 1.5, atol=1e-9)
    # the same false windows frame_windows finds, as decision values (it gives probabilities)
    det = dense_detector(model, frames[0].image.shape[:2], cells_per_step=2)
    fw = frame_windows(det, frames[0])
    assert len(fw.false) == s.shape[1]
    np.testing.assert_allclose(np.sort(1 / (1 + np.exp(-s[0]))), np.sort(fw.false), rtol=1e-5, atol=1e-6)
    with pytest.raises(ValueError):
        false_window_scores([], frames)
    # a side-view component a model carries is not searched: its own windows only
    from dataclasses import replace

    from fastdet.model import Model
    from fastdet.train.side import side_config

    cfg = side_config(model.config)
    side = Model(cfg, np.zeros(cfg.n_features), 5.0, np.zeros(cfg.n_features), np.ones(cfg.n_features),
                 classifier="logreg")
    np.testing.assert_array_equal(false_window_scores([replace(model, side=side), model], frames, cells_per_step=2),
                                  np.stack([s[0], s[0]]))
    with pytest.raises(ValueError, match="near_iou"):
        frame_windows(det, frames[0], near_iou=0.6)
    # the near windows, likewise: those frame_windows finds with near_iou
    n = near_window_scores([model, offset(model, -0.5)], frames, cells_per_step=2)
    np.testing.assert_allclose(n[1], n[0] + 0.5, atol=1e-9)
    fn = frame_windows(det, frames[0], near_iou=0.3)
    assert len(fn.near) == n.shape[1] > 0
    np.testing.assert_allclose(np.sort(1 / (1 + np.exp(-n[0]))), np.sort(fn.near), rtol=1e-5, atol=1e-6)
    with pytest.raises(ValueError, match="near_iou"):
        near_window_scores([model], frames, near_iou=0.7)
