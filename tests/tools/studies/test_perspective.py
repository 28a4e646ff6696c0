"""tools/studies/perspective.py: search bands from the camera's geometry (the horizon and the
ratio), the ratio and the perspective estimated from a video's tracked vehicles, the updater
that moves a detector's main search with them (what geometry_study, placement_study and
horizon_study run; no stage of the pipeline since the perspective stage was deleted), and
their settings."""
from __future__ import annotations

from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fastdet.config import FeatureConfig, SearchBand, SearchConfig
from fastdet.detect.bands import band_geometry
from fastdet.detections import Detections
from tools.studies.perspective import (
    GeometricSearch,
    GeometryConfig,
    PerspectiveConfig,
    PerspectiveEstimator,
    PerspectiveUpdater,
    RatioEstimator,
    band_on_grid,
    geometric_bands,
    window_bottoms,
)

CFG = FeatureConfig()


def window_rows(band: SearchBand, shape: tuple[int, int], step_cells: int = 2) -> np.ndarray:
    """(top, bottom) frame rows of every window row of ``band`` (what the detector searches)."""
    g = band_geometry(band, shape, CFG, step_cells)
    tops = band.y_start + np.arange(g.ny) * step_cells * 8 * band.scale
    return np.stack([tops, tops + 64 * band.scale], 1)


@settings(max_examples=200, deadline=None)
@given(scale=st.sampled_from([0.5, 0.625, 0.75, 1.0, 1.25, 1.5, 2.0, 2.5, 3.0]),
       anchor=st.floats(0, 500), first=st.floats(-50, 800), width=st.floats(0, 400), rows=st.integers(200, 800))
def test_band_on_grid_covers_the_bottoms_on_the_grid(scale, anchor, first, width, rows):
    last = first + width
    step = 16 * scale
    band = band_on_grid(scale, first, last, anchor, step, rows)
    side = 64 * scale
    # the grid windows inside the frame whose bottoms fall in [first, last] (the brute-force answer)
    n = np.arange(-200, 200)
    tops = anchor + n * step
    inside = (tops >= -1e-6) & (tops + side <= rows - 0.5)  # bands start on whole rows: half a pixel either way
    want = inside & (tops + side >= first - 1e-6) & (tops + side <= last + 1e-6)
    if band is None:
        assert not want.any()
        return
    got = window_rows(band, (rows, 2000))
    assert 0 <= band.y_start and band.y_stop <= rows
    # every searched window is on the grid (bands start on whole rows: to half a pixel), inside the frame
    k = (got[:, 0] - anchor) / step
    np.testing.assert_allclose(k, np.round(k), atol=0.5 / step + 1e-9)
    assert got[:, 1].max() <= rows + 1e-6
    # every wanted window is searched, and at most one step of windows beyond each end
    have = set(np.round(k).astype(int).tolist())
    assert set(n[want].tolist()) <= have
    if want.any():
        assert min(have) >= n[want].min() - 1 and max(have) <= n[want].max() + 1


def test_window_bottoms():
    lo, hi = window_bottoms(450, 500, 420, 380, 0.5, 10)
    assert lo == pytest.approx(380 + 30 * 0.5 - 10) and hi == pytest.approx(380 + 80 * 0.5 + 10)
    lo, hi = window_bottoms(450, 500, 420, 380, 0.5, 10, 0)
    assert lo == pytest.approx(380 + 30 * 0.5 - 10) and hi == pytest.approx(380 + 80 * 0.5)


def no_slack(search: SearchConfig) -> SearchConfig:
    """``search`` with no band slack of its own (the reference bands as they were written)."""
    return replace(search, bands=tuple(replace(b, slack_above=None) for b in search.bands))


@pytest.mark.parametrize("shape", [(720, 1280), (360, 640), (450, 800), (540, 960), (1080, 1920)])
def test_reference_camera_gets_the_reference_bands(shape):
    """At the reference horizon and ratio, without slack: exactly today's bands."""
    assert GeometricSearch(geometry=GeometryConfig(slack=0.0)).for_frame(shape).bands == \
        SearchConfig().for_frame(shape).bands


def test_search_checks():
    with pytest.raises(ValueError, match="ratio must be > 0 or None"):
        GeometricSearch(ratio=-1.0)


def _rows(bands, shape):
    return {b.scale: window_rows(b, shape) for b in bands}


@pytest.mark.parametrize("shape", [(720, 1280), (360, 640), (450, 800), (540, 960)])
@pytest.mark.parametrize("shift", [-0.05, -0.03, 0.02, 0.05])
def test_slack_loses_no_window_when_the_horizon_is_off(shape, shift):
    """The bands placed from a horizon ``shift`` away (of the height) with a slack of 0.05
    search every window the bands at the true horizon without slack search."""
    ref = no_slack(SearchConfig())
    true = 0.55
    exact = geometric_bands(shape, true, 1.9, GeometryConfig(slack=0.0), ref)
    off = geometric_bands(shape, true + shift, 1.9, GeometryConfig(slack=0.05), ref)
    a, b = _rows(exact, shape), _rows(off, shape)
    assert set(a) == set(b)
    anchors = {band.scale: band.y_start for band in ref.bands}
    fy = shape[0] / 720
    def index(tops, s):
        return set(np.round((tops - anchors[s / fy] * fy) / (16 * s)).astype(int).tolist())

    for s, rows in a.items():
        assert index(rows[:, 0], s) <= index(b[s][:, 0], s), s


def test_ratio_moves_the_bands():
    """A larger ratio (a lower camera, or wider vehicles) puts each window size nearer the horizon."""
    ref = SearchConfig()
    shape = (720, 1280)
    g = GeometryConfig(slack=0.0)
    near = geometric_bands(shape, 0.5, 3.0, g, ref)
    far = geometric_bands(shape, 0.5, 1.2, g, ref)
    for a, b in zip(near, far):
        assert a.scale == b.scale and a.y_start <= b.y_start and a.y_stop < b.y_stop


def test_same_picture_rows_at_every_resolution():
    ref = SearchConfig()
    g = GeometryConfig()
    big = geometric_bands((720, 1280), 0.5, 1.9, g, ref)
    small = geometric_bands((360, 640), 0.5, 1.9, g, ref)
    for a, b in zip(big, small):
        assert b.scale == pytest.approx(a.scale / 2)
        # within one window step of the small frame (the grid rounds differently)
        assert abs(a.y_start / 720 - b.y_start / 360) <= 16 * b.scale / 360 + 1e-9
        assert abs(a.y_stop / 720 - b.y_stop / 360) <= 16 * b.scale / 360 + 2 / 360
        assert (a.x_start is None) == (b.x_start is None)


def test_grid_is_the_reference_bands_grid():
    ref = SearchConfig()
    bands = geometric_bands((720, 1280), 0.6, 1.9, GeometryConfig(), ref)
    anchors = {b.scale: b.y_start for b in ref.bands}
    for b in bands:
        step = 16 * b.scale
        k = (b.y_start - anchors[b.scale]) / step
        assert k == pytest.approx(round(k), abs=0.5 / step)


def test_a_horizon_near_the_top_or_bottom():
    ref = SearchConfig()
    high = geometric_bands((720, 1280), 0.05, 1.9, GeometryConfig(), ref)
    assert all(b.y_start >= 0 for b in high)
    low = geometric_bands((720, 1280), 0.95, 1.9, GeometryConfig(), ref)
    assert all(b.y_stop <= 720 for b in low) and len(low) < len(ref.bands)
    with pytest.raises(ValueError, match="leaves no search band"):
        geometric_bands((720, 1280), 1.0, 1.9, GeometryConfig(slack=0.0), ref)


def test_geometric_search_follows_horizon_and_ratio():
    s = GeometricSearch()
    area = GeometricSearch.from_search(replace(SearchConfig(), shrink="area", slack_threshold=3.0), s.geometry, 2.0)
    framed = area.for_frame((720, 1280))
    assert (area.ratio, framed.shrink, framed.slack_threshold) == (2.0, "area", 3.0)  # every field carried
    f = s.for_frame((720, 1280))
    assert type(f) is SearchConfig and f.reference_shape is None and f.horizon is None
    assert f.bands == geometric_bands((720, 1280), s.reference_horizon, s.geometry.ratio, s.geometry, s)
    moved = replace(s, horizon=0.45).for_frame((720, 1280))
    assert all(a.y_start >= b.y_start for a, b in zip(f.bands, moved.bands))
    assert moved.bands == geometric_bands((720, 1280), 0.45, s.geometry.ratio, s.geometry, s)
    r = s.with_ratio(2.5)
    assert r.ratio == 2.5 and r.for_frame((720, 1280)).bands == geometric_bands(
        (720, 1280), s.reference_horizon, 2.5, s.geometry, s)


def test_detector_searches_the_geometric_bands(test_images):
    import cv2

    from fastdet import Detector
    from fastdet.detect import DetectStats

    frame = cv2.imread(str(test_images[0]))
    det = Detector(search=GeometricSearch.from_search(no_slack(SearchConfig()), GeometryConfig()))
    det.set_horizon(0.5)
    assert det.horizon == 0.5 and isinstance(det.scorers[0].search, GeometricSearch)
    stats = DetectStats()
    det.detect(frame, stats=stats)
    want = geometric_bands(frame.shape[:2], 0.5, GeometryConfig().ratio, GeometryConfig(), no_slack(SearchConfig()))
    assert [g.band for _, g, _ in stats.bands] == list(want)


@pytest.mark.parametrize("shape", [(720, 1280), (360, 640), (540, 960)])
def test_geometric_bands_keep_the_bands_own_slack_and_their_core(shape):
    """The default bands' own slack above: at the reference horizon and ratio, the geometric
    bands are the plain search's, core included; a larger geometric slack widens both sides
    and keeps the rows without slack as the core."""
    plain = SearchConfig().for_frame(shape).bands
    assert any(b.core is not None and b.y_start < b.core[0] for b in plain)
    assert GeometricSearch(geometry=GeometryConfig(slack=0.0)).for_frame(shape).bands == plain
    wide = GeometricSearch(geometry=GeometryConfig(slack=0.05)).for_frame(shape).bands
    bare = GeometricSearch.from_search(no_slack(SearchConfig()), GeometryConfig(slack=0.0)).for_frame(shape)
    for w, b in zip(wide, bare.bands):
        assert w.scale == b.scale and w.core == (b.y_start, b.y_stop)
        assert w.y_start < b.y_start and (w.y_stop > b.y_stop or w.y_stop == shape[0])


def test_ratio_estimator():
    est = RatioEstimator(min_depth=0.03, min_boxes=3, min_tracks=2)
    rows, horizon = 720, 0.5
    assert est.estimate is None
    for k, tid in ((1.8, 1), (2.2, 2), (5.0, -1)):  # untracked boxes do not count
        for depth in (40, 60, 80, 100):
            w = k * depth
            est.update(np.array([[100, 0, 100 + w, 360 + depth]]), np.array([tid]), horizon, rows)
    assert est.tracks == 2 and est.estimate == pytest.approx(2.0)
    # boxes whose bottom is near the horizon are left out (a row's error is most of the depth)
    est.update(np.array([[0, 0, 1000, 365]] * 5), np.array([3] * 5), horizon, rows)
    assert est.tracks == 2
    est.reset()
    assert est.estimate is None
    with pytest.raises(ValueError, match="ids"):
        est.update(np.zeros((2, 4)), np.zeros(1), horizon, rows)


def _tracks(horizon: float, ratio: float, rows: int = 720, n_tracks: int = 4, seed: int = 0):
    """Boxes of ``n_tracks`` vehicles at several depths below the horizon, widths off by up to 10%."""
    rng = np.random.default_rng(seed)
    out = []
    for t in range(n_tracks):
        for depth in np.linspace(20, 200, 8) * (1 + t / 3):
            w = ratio * depth * rng.uniform(0.9, 1.1)
            y2 = horizon * rows + depth
            out.append(([300.0, y2 - 0.8 * w, 300.0 + w, y2], t))
    return out


@pytest.mark.parametrize("residuals", ["log", "rows"])
@pytest.mark.parametrize("true_h, prior_h", [(0.55, 0.55), (0.55, 0.59), (0.55, 0.51), (0.42, 0.45)])
def test_perspective_estimator_finds_horizon_and_ratio(true_h, prior_h, residuals):
    est = PerspectiveEstimator(residuals=residuals)
    assert est.estimate(prior_h, 1.9) is None
    for box, tid in _tracks(true_h, 2.2):
        est.update(np.array([box]), np.array([tid]), 720)
    h, k = est.estimate(prior_h, 1.9)
    assert h == pytest.approx(true_h, abs=0.01) and k == pytest.approx(2.2, rel=0.1)
    est.reset()
    assert est.estimate(prior_h, 1.9) is None


def test_perspective_estimator_needs_tracks():
    est = PerspectiveEstimator(min_boxes=5, min_tracks=2)
    for box, tid in _tracks(0.5, 2.0, n_tracks=1):
        est.update(np.array([box]), np.array([tid]), 720)
    est.update(np.array([[0, 0, 50, 400]] * 9), np.array([-1] * 9), 720)  # untracked: not counted
    assert est.estimate(0.5, 1.9) is None
    with pytest.raises(ValueError, match="ids"):
        est.update(np.zeros((2, 4)), np.zeros(1), 720)


def test_one_vehicle_followed_long_enough_gives_an_estimate():
    est = PerspectiveEstimator(min_boxes=5, min_tracks=2, long_track=25)
    for depth in np.linspace(30, 150, 24):
        est.update(np.array([[0, 0, 2.0 * depth, 360 + depth]]), np.array([7]), 720)
    assert est.estimate(0.52, 1.9) is None  # 24 boxes of one vehicle: not yet
    est.update(np.array([[0, 0, 2.0 * 160, 360 + 160]]), np.array([7]), 720)
    h, k = est.estimate(0.52, 1.9)
    assert h == pytest.approx(0.5, abs=0.01) and k == pytest.approx(2.0, rel=0.05)


@pytest.mark.parametrize("prior", [0.44, 0.56])
def test_row_residuals_find_the_horizon_from_noisy_tracks_near_it(prior):
    """Vehicles far ahead (bottoms 1-3% of the height below the horizon) and near ones, boxes
    a pixel or two off and widths 3% off, the prior 0.06 off either way: the row fit finds
    the horizon and the ratio."""
    rng = np.random.default_rng(3)
    true_h, k, rows = 0.50, 1.5, 360
    far = [(tid, np.linspace(0.008, 0.03, 8) + 0.002 * tid) for tid in range(1, 7)]
    near = [(10, np.linspace(0.06, 0.2, 8)), (11, np.linspace(0.1, 0.3, 8))]
    est = PerspectiveEstimator(residuals="rows", reach=0.12)
    for tid, depths in far + near:
        for d in depths:
            y2 = (true_h + d) * rows + rng.normal(0, 1.0)
            w = k * d * rows * (1 + rng.normal(0, 0.03))
            est.update(np.array([[100, y2 - 0.8 * w, 100 + w, y2]]), np.array([tid]), rows)
    h, r = est.estimate(prior, 1.9)
    assert h == pytest.approx(true_h, abs=0.01) and r == pytest.approx(k, rel=0.15)


def test_perspective_estimator_refuses_unknown_residuals():
    with pytest.raises(ValueError, match="residuals"):
        PerspectiveEstimator(residuals="pixels")


# ---- the updater (geometry_study --joint)


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


# ---- the settings


@pytest.mark.parametrize("kw, words", [
    ({"ratio": 0}, "ratio"), ({"reference_ratio": -1}, "ratio"), ({"slack": 1.0}, "slack"), ({"slack": -0.1}, "slack"),
])
def test_geometry_checks(kw, words):
    with pytest.raises(ValueError, match=words):
        GeometryConfig(**kw)


@pytest.mark.parametrize("kw", [{"settled_slack": 1.0}, {"min_tracks": 0}, {"min_boxes": 0}, {"sigma_h": 0},
                                {"sigma_ratio": 0}, {"prior_frames": -1}])
def test_perspective_checks(kw):
    with pytest.raises(ValueError):
        PerspectiveConfig(**kw)


def test_round_trip():
    c = PerspectiveConfig(geometry=GeometryConfig(ratio=2.2, slack=0.03), prior_frames=50, long_track=30)
    assert PerspectiveConfig.from_dict(c.to_dict()) == c
    assert PerspectiveConfig().geometry == GeometryConfig()
