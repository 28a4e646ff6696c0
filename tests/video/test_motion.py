"""Motion for the wide-window (oncoming-traffic) model: window_motion against a per-window
NumPy loop (``tests.reference``), FrameMotion, moving_bands against the full band it narrows, and the
VideoDetector's wide path against its plain reference (full wide search, then the gate)."""
from __future__ import annotations

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fastdet.config import ONCOMING_SEARCH, MotionGate
from fastdet.detect import DetectStats
from fastdet.detect.bands import band_geometry, window_boxes
from fastdet.detections import ONCOMING_PART
from fastdet.video.motion import FrameMotion, moving_bands, window_motion
from tests.reference import naive_window_motion


@settings(max_examples=60, deadline=None)
@given(h=st.integers(1, 40), w=st.integers(1, 50), seed=st.integers(0, 2 ** 31 - 1), n=st.integers(0, 12))
def test_window_motion_equals_the_per_window_loop(h, w, seed, n):
    rng = np.random.default_rng(seed)
    prev = rng.integers(0, 256, (h, w, 3), dtype=np.uint8)
    cur = rng.integers(0, 256, (h, w, 3), dtype=np.uint8)
    xs = np.sort(rng.integers(-5, w + 6, (n, 2)), axis=1)
    ys = np.sort(rng.integers(-5, h + 6, (n, 2)), axis=1)
    boxes = np.stack([xs[:, 0], ys[:, 0], xs[:, 1], ys[:, 1]], axis=1)
    fm = FrameMotion()
    assert fm.update(prev) is None
    integral = fm.update(cur)
    np.testing.assert_allclose(window_motion(integral, boxes), naive_window_motion(prev, cur, boxes), atol=1e-9)


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2 ** 31 - 1), roi=st.tuples(st.integers(0, 20), st.integers(0, 15), st.integers(21, 50),
                                                       st.integers(16, 40)))
def test_motion_of_a_region_equals_the_whole_frames_inside_it(seed, roi):
    rng = np.random.default_rng(seed)
    prev, cur = rng.integers(0, 256, (2, 40, 50, 3), dtype=np.uint8)
    whole, part = FrameMotion(), FrameMotion()
    whole.update(prev)
    part.update(prev, roi)
    m_whole, m_part = whole.update(cur), part.update(cur, roi)
    assert m_part.origin == roi[:2] and m_part.integral.shape == (roi[3] - roi[1] + 1, roi[2] - roi[0] + 1)
    x1, y1, x2, y2 = roi
    xs = np.sort(rng.integers(x1, x2 + 1, (10, 2)), axis=1)
    ys = np.sort(rng.integers(y1, y2 + 1, (10, 2)), axis=1)
    boxes = np.stack([xs[:, 0], ys[:, 0], xs[:, 1], ys[:, 1]], axis=1)
    np.testing.assert_allclose(window_motion(m_part, boxes), window_motion(m_whole, boxes), atol=1e-9)
    # a box reaching outside the region is clipped to it
    clipped = np.array([[x1, y1, x2, y2]])
    np.testing.assert_allclose(window_motion(m_part, [[x1 - 5, y1 - 5, x2 + 5, y2 + 5]]),
                               window_motion(m_whole, clipped))
    assert part.update(cur, (0, 0, 50, 40)) is None  # another region: a new start


def test_frame_motion_restarts_after_reset_and_size_change():
    fm = FrameMotion()
    a = np.zeros((10, 12, 3), np.uint8)
    b = np.full((10, 12, 3), 9, np.uint8)
    assert fm.update(a) is None
    np.testing.assert_allclose(window_motion(fm.update(b), [[0, 0, 12, 10]]), [9.0])
    fm.reset()
    assert fm.update(a) is None
    assert fm.update(np.zeros((8, 12, 3), np.uint8)) is None  # another size: a new start
    assert window_motion(fm.update(np.zeros((8, 12, 3), np.uint8)), [[0, 0, 12, 8]])[0] == 0.0


# ---------------------------------------------------------------- on real frames, real model


@pytest.fixture(scope="module")
def oncoming_frames(data):
    """Frames 55 and 56 of test_small1: two oncoming cars above the median."""
    cap = cv2.VideoCapture(str(data / "videos" / "test_small1.mp4"))
    frames = []
    for i in range(1, 57):
        ok, frame = cap.read()
        assert ok
        if i >= 55:
            frames.append(frame)
    return frames


@pytest.fixture(scope="module")
def detector():
    from fastdet.video import make_detector

    return make_detector()


def _wide_windows(det, frame, bands=None):
    """All wide-model windows (any score) of ``bands`` (default: its full search), as
    {box tuple: decision value}."""
    stats = DetectStats()
    det.detect(frame, oncoming_bands=bands, stats=stats)
    out = {}
    for part, geo, dec in stats.bands:
        if part != ONCOMING_PART:
            continue
        r, c = np.nonzero(np.ones_like(dec, bool))
        for box, v in zip(window_boxes(geo, r, c, det.oncoming_model.config), dec[r, c]):
            out[tuple(int(x) for x in box)] = float(v)
    return out


def test_moving_bands_cover_every_moving_window_with_the_same_scores(detector, oncoming_frames):
    prev, cur = oncoming_frames
    fm = FrameMotion()
    fm.update(prev)
    integral = fm.update(cur)
    gate = MotionGate().min_motion
    cfg = detector.oncoming_model.config
    geos = detector.geometries(cur.shape[:2], part=1)
    bands = [b for g in geos for b in moving_bands(g, cfg, integral, gate)]
    assert bands, "the oncoming cars move: some band must be searched"
    full = _wide_windows(detector, cur)
    narrowed = _wide_windows(detector, cur, bands)
    assert set(narrowed) <= set(full), "narrowed windows must sit where the full band's do"
    moving = [k for k in full if window_motion(integral, [k])[0] >= gate]
    assert moving and set(moving) <= set(narrowed)
    # whole cells at every default wide scale: resampled exactly as the full band
    np.testing.assert_allclose([narrowed[k] for k in moving], [full[k] for k in moving], rtol=0, atol=1e-6)
    # narrowing is the point: far fewer windows than the full search
    assert len(narrowed) < 0.5 * len(full)


def test_moving_bands_is_empty_without_motion(detector, oncoming_frames):
    cur = oncoming_frames[1]
    fm = FrameMotion()
    fm.update(cur)
    integral = fm.update(cur)
    for g in detector.geometries(cur.shape[:2], part=1):
        assert moving_bands(g, detector.oncoming_model.config, integral, 1.0) == []
    # and a band's geometry with no windows gives nothing either
    g = band_geometry(ONCOMING_SEARCH.bands[0].__class__(1.0, 0, 10), cur.shape[:2], detector.oncoming_model.config, 1)
    assert moving_bands(g, detector.oncoming_model.config, integral, 0.0) == []


def test_detect_with_no_wide_bands_is_the_main_model_alone(detector, oncoming_frames):
    from fastdet.detect import Detector

    frame = oncoming_frames[1]
    main_only = Detector().detect(frame)
    both = detector.detect(frame, oncoming_bands=[])
    assert both.boxes.tolist() == main_only.boxes.tolist()
    np.testing.assert_array_equal(both.scores, main_only.scores)
    assert len(both) and not both.is_oncoming.any()
    np.testing.assert_array_equal(both.scale, main_only.scale)


def test_video_detector_wide_windows_are_the_gated_full_search(detector, oncoming_frames):
    """VideoDetector's wide windows = the wide model's positive windows over its whole
    search, kept where the motion reaches the gate."""
    from fastdet.video import VideoDetector

    prev, cur = oncoming_frames
    vd = VideoDetector(detector)
    vd.update(prev)
    assert not vd.debug.windows.is_oncoming.any(), "no previous frame: no motion, no wide windows"
    vd.update(cur)
    got = {tuple(int(v) for v in b) for b in vd.debug.windows[vd.debug.windows.is_oncoming].boxes}
    fm = FrameMotion()
    fm.update(prev)
    integral = fm.update(cur)
    thr, gate = ONCOMING_SEARCH.threshold, MotionGate().min_motion
    full = _wide_windows(detector, cur)
    want = {k for k, v in full.items() if v > thr and window_motion(integral, [k])[0] >= gate}
    assert want, "the oncoming cars must give gated wide windows"
    assert got == want
    assert "motion" in vd.timings


def test_video_detector_rgb_frames_give_the_same_boxes(detector, oncoming_frames):
    from fastdet.video import VideoDetector

    bgr, rgb = VideoDetector(detector), VideoDetector(detector)
    for frame in oncoming_frames:
        a = bgr.update(frame)
        b = rgb.update(np.ascontiguousarray(frame[:, :, ::-1]), rgb=True)
        assert a.boxes.tolist() == b.boxes.tolist()
        assert bgr.debug.windows.boxes.tolist() == rgb.debug.windows.boxes.tolist()
    assert bgr.debug.windows.is_oncoming.any(), "the second frame has moving oncoming cars"


# ------------------------------------------------------------------ the moving-columns kernel


def _old_moving_bands(geo, config, motion, min_motion):
    """moving_bands as it was, in NumPy (the reference for the kernel version)."""
    from fastdet.boxes import window_offsets
    from fastdet.config import SearchBand
    from fastdet.video.motion import _mean_in

    if geo.n_windows == 0:
        return []
    s, cell = geo.band.scale, config.pixels_per_cell
    left = geo.x0 + window_offsets(np.arange(geo.nx), geo.step, cell, s)
    top = geo.y0 + window_offsets(np.arange(geo.ny), geo.step, cell, s)
    right, bottom = left + int(config.win_w * s), top + int(config.win_h * s)
    moving = (_mean_in(motion, left, top[:, None], right, bottom[:, None]) >= min_motion).any(axis=0)
    if not moving.any():
        return []
    idx = np.flatnonzero(moving)
    per_window = max(1, config.blocks_x // geo.step)
    breaks = np.flatnonzero(np.diff(idx) > per_window)
    starts = np.concatenate([[idx[0]], idx[breaks + 1]])
    stops = np.concatenate([idx[breaks], [idx[-1]]])
    out = []
    for c0, c1 in zip(starts, stops):
        c0, c1 = max(c0 - 1, 0), min(c1 + 1, geo.nx - 1)
        x_a = int(left[c0])
        x_b = x_a + int(np.ceil(((c1 - c0) * geo.step + config.win_w // cell) * cell * s - 1e-9))
        out.append(SearchBand(geo.band.scale, geo.band.y_start, geo.band.y_stop, x_a, min(x_b, geo.x1)))
    return out


@settings(max_examples=150, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), roi=st.tuples(st.integers(0, 300), st.integers(0, 200),
                                                     st.integers(1, 320), st.integers(1, 240)),
       gate=st.sampled_from([0.0, 0.5, 2.0, 5.0, 20.0]), blob=st.integers(0, 4))
def test_moving_bands_same_as_the_numpy_version(detector, seed, roi, gate, blob):
    """Random motion (a few moving patches over noise) in a region of a 320x240 frame that
    may miss the bands: the kernel's bands equal the NumPy grid's."""
    rng = np.random.default_rng(seed)
    prev = rng.integers(0, 256, (240, 320, 3), np.uint8)
    cur = prev.copy()
    cur = np.clip(cur.astype(np.int16) + rng.integers(-3, 4, cur.shape), 0, 255).astype(np.uint8)
    for _ in range(blob):
        x, y = rng.integers(0, 300), rng.integers(0, 220)
        cur[y:y + 30, x:x + 40] = rng.integers(0, 256, 3)
    fm = FrameMotion()
    x1, y1, w, h = roi  # a non-empty region, maybe past the frame's edge (clipped)
    x2, y2 = min(x1 + w, 320), min(y1 + h, 240)
    fm.update(prev, (x1, y1, x2, y2))
    motion = fm.update(cur, (x1, y1, x2, y2))
    cfg = detector.oncoming_model.config
    for g in detector.geometries((240, 320), part=1):
        assert moving_bands(g, cfg, motion, gate) == _old_moving_bands(g, cfg, motion, gate)


def test_moving_bands_same_as_the_numpy_version_on_real_frames(detector, oncoming_frames):
    prev, cur = oncoming_frames
    cfg = detector.oncoming_model.config
    for lag_frames in ((prev, cur), (cur, prev)):
        fm = FrameMotion()
        fm.update(lag_frames[0])
        motion = fm.update(lag_frames[1])
        for gate in (0.0, 1.0, MotionGate().threshold(motion.noise), 8.0, 50.0):
            for g in detector.geometries(cur.shape[:2], part=1):
                assert moving_bands(g, cfg, motion, gate) == _old_moving_bands(g, cfg, motion, gate)
