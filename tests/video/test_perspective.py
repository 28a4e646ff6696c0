"""fastdet.video.perspective: the main search follows the horizon and ratio the tracked vehicles show
(the updater tools/studies/geometry_study.py --joint drives; the pipeline's stage was deleted)."""
from __future__ import annotations

from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest

from fastdet.config import SearchConfig
from fastdet.detect.geometry import GeometricSearch, GeometryConfig
from fastdet.detections import Detections
from fastdet.video.perspective import PerspectiveConfig, PerspectiveUpdater


def fake_detector(horizon=None):
    return SimpleNamespace(scorers=[SimpleNamespace(search=SearchConfig(horizon=horizon))])


def frames_of_vehicles(horizon: float, ratio: float, rows: int = 720, n: int = 12):
    """Per frame: two tracked vehicles approaching (bottoms moving down), w = ratio x depth."""
    for f in range(n):
        boxes, ids = [], []
        for tid, d0 in ((1, 30.0), (2, 60.0)):
            depth = d0 + 8 * f
            w = ratio * depth
            y2 = horizon * rows + depth
            boxes.append([400.0, y2 - 0.8 * w, 400.0 + w, y2])
            ids.append(tid)
        yield Detections(np.array(boxes, np.int32), np.full(2, 30.0, np.float32), ids=np.array(ids))


def test_search_becomes_geometric_at_the_prior_with_slack():
    det = fake_detector(horizon=0.55)
    up = PerspectiveUpdater(det)
    up.start()
    s = det.scorers[0].search
    assert isinstance(s, GeometricSearch) and s.horizon == 0.55 and s.ratio is None
    assert s.geometry.slack == PerspectiveConfig().geometry.slack and up.prior == 0.55


@pytest.mark.parametrize("prior", [0.46, 0.5, 0.54])
def test_horizon_and_ratio_follow_the_vehicles(prior):
    det = fake_detector(horizon=prior)
    up = PerspectiveUpdater(det)
    for dets in frames_of_vehicles(0.5, 2.2):
        up.update(dets, 720)
    s = det.scorers[0].search
    assert up.estimate is not None
    assert s.horizon == pytest.approx(0.5, abs=0.01) and s.ratio == pytest.approx(2.2, rel=0.05)
    assert s.geometry.slack == PerspectiveConfig().settled_slack
    assert up.prior == prior  # the prior stays what the pipeline gave


def test_weak_or_untracked_boxes_do_not_count():
    det = fake_detector(horizon=0.5)
    up = PerspectiveUpdater(det, PerspectiveConfig(min_score=50.0))
    for dets in frames_of_vehicles(0.5, 2.2):
        up.update(dets, 720)  # scores 30 < 50
        up.update(replace(dets, ids=None), 720)
    assert up.estimate is None and det.scorers[0].search.ratio is None


def test_a_new_flow_horizon_is_the_new_prior():
    det = fake_detector(horizon=None)
    up = PerspectiveUpdater(det)
    up.update(Detections(np.zeros((0, 4), np.int32), np.zeros(0, np.float32)), 720)
    assert up.prior == SearchConfig().reference_horizon
    det.scorers[0].search = replace(det.scorers[0].search, horizon=0.5)  # the flow estimate arrived
    up.update(Detections(np.zeros((0, 4), np.int32), np.zeros(0, np.float32)), 720)
    assert up.prior == 0.5
    for dets in frames_of_vehicles(0.52, 2.0):
        up.update(dets, 720)
    assert det.scorers[0].search.horizon == pytest.approx(0.52, abs=0.01)
    det.scorers[0].search = replace(det.scorers[0].search, horizon=0.45)  # moved again: the estimate stays
    up.update(Detections(np.zeros((0, 4), np.int32), np.zeros(0, np.float32)), 720)
    assert up.prior == 0.45 and det.scorers[0].search.horizon == pytest.approx(0.52, abs=0.01)


def test_config_checks():
    with pytest.raises(ValueError):
        PerspectiveConfig(settled_slack=1.0)
    with pytest.raises(ValueError):
        PerspectiveConfig(min_tracks=0)
    with pytest.raises(ValueError):
        PerspectiveConfig(sigma_h=0)
    assert PerspectiveConfig(geometry=GeometryConfig(slack=0.03)).geometry.slack == 0.03


def test_the_slack_ends_when_no_estimate_comes():
    det = fake_detector(horizon=0.5)
    up = PerspectiveUpdater(det, PerspectiveConfig(prior_frames=3))
    empty = Detections(np.zeros((0, 4), np.int32), np.zeros(0, np.float32))
    for _ in range(3):
        up.update(empty, 720)
    assert det.scorers[0].search.geometry.slack == PerspectiveConfig().geometry.slack
    up.update(empty, 720)
    s = det.scorers[0].search
    assert s.geometry.slack == 0.0 and s.horizon == 0.5 and s.ratio is None
    for dets in frames_of_vehicles(0.52, 2.0):  # vehicles later still move the bands
        up.update(dets, 720)
    assert det.scorers[0].search.horizon == pytest.approx(0.52, abs=0.01)


def test_the_updater_moves_a_real_detectors_search():
    # as tools/studies/geometry_study.py --joint drives it (the pipeline's stage was deleted)
    from fastdet.video import make_detector

    det = make_detector()
    det.set_horizon(0.55)
    up = PerspectiveUpdater(det)
    for dets in frames_of_vehicles(0.5, 2.2):
        up.update(dets, 720)
    s = det.scorers[0].search
    assert isinstance(s, GeometricSearch) and s.horizon == pytest.approx(0.5, abs=0.01)
    assert det.horizon == s.horizon  # what the horizon stage and the debug view read
