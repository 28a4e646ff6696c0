"""The dense scores of every window equal the classic per-window pipeline; boxes land on cars."""
from __future__ import annotations

from dataclasses import replace

import cv2
import numpy as np
import pytest

from fastdet.config import FeatureConfig, SearchBand, SearchConfig
from fastdet.detect import Detector, DetectStats
from fastdet.model import Model
from tests.reference import classic_band_scores, sklearn_pair


@pytest.fixture(scope="module")
def frames(test_images):
    return [cv2.imread(str(p)) for p in test_images]


def _random_model(config: FeatureConfig, seed=0) -> Model:
    rng = np.random.default_rng(seed)
    n = config.n_features
    return Model(config, rng.normal(size=n) * 0.01, -0.2, rng.normal(size=n), rng.uniform(0.5, 2.0, n))


def _compare_all_windows(det: Detector, frame: np.ndarray, part: int = 0) -> int:
    model = det.model if part == 0 else det.oncoming_model
    pair = sklearn_pair(model)
    n = 0
    for geo in det.geometries(frame.shape[:2], part):
        fast = det.band_scores(frame, geo, part=part)
        ref = classic_band_scores(frame, geo, model, pair)
        assert fast.shape == ref.shape == (geo.ny, geo.nx)
        np.testing.assert_allclose(fast, ref, rtol=0, atol=1e-6, err_msg=f"part {part} band {geo.band}")
        n += geo.n_windows
    return n


@pytest.mark.slow
def test_every_window_of_every_default_band_matches_classic(frames):
    det = Detector()  # bundled model, default search
    # two of the test images: every window of every band either way (1,364 a frame), a third
    # of the classic pipeline's time
    n = sum(_compare_all_windows(det, f) for f in frames[::3])
    assert n > 1000


def test_one_cell_step_and_other_feature_configs(frames):
    cfg = FeatureConfig(color_space="LUV", orientations=12, spatial_size=16, hist_bins=16, hog_channels=(0, 2))
    search = SearchConfig(bands=(SearchBand(1.0, 400, 500, 100, 400), SearchBand(1.7, 380, 600)), cells_per_step=1)
    det = Detector(_random_model(cfg), search)
    assert _compare_all_windows(det, frames[0]) > 500
    cfg = FeatureConfig(window_height=32, orientations=11, spatial_size=16)  # wide windows: the oncoming model
    search = SearchConfig(bands=(SearchBand(0.75, 400, 480, 0, 640), SearchBand(1.0, 390, 470)), cells_per_step=1)
    det = Detector(_random_model(FeatureConfig(), 3), search, oncoming=_random_model(cfg, 2), oncoming_search=search)
    assert _compare_all_windows(det, frames[2], part=1) > 500
    cfg = FeatureConfig(color_space="HSV", spatial_size=0, hist_bins=0, cells_per_block=3)
    det = Detector(_random_model(cfg, 1), SearchConfig(bands=(SearchBand(1.3, 390, 610),), cells_per_step=3))
    _compare_all_windows(det, frames[1])


def test_detect_boxes_and_scores(frames):
    det = Detector()
    stats = DetectStats()
    d = det.detect(frames[0], stats=stats)
    assert d.boxes.dtype == np.int32 and d.boxes.shape[1] == 4 and d.scores.dtype == np.float32
    assert len(d) == len(d.boxes) == len(d.scores) == len(d.scale) == len(d.part) > 0
    assert not d.is_oncoming.any()  # no oncoming model
    assert set(d.scale.tolist()) <= {b.scale for b in det.search.bands}
    if det.score_kind == "probability":
        assert np.all((d.scores > 0.5) & (d.scores <= 1))
    assert np.all(d.boxes[:, 2] > d.boxes[:, 0]) and np.all(d.boxes[:, 3] > d.boxes[:, 1])
    # each window is 64 * scale frame pixels square
    np.testing.assert_array_equal(d.boxes[:, 2] - d.boxes[:, 0], (64 * d.scale).astype(np.int32))
    assert set(stats.timings) == {"resize_colour", "hog", "score"}
    assert [g.band for _, g, _ in stats.bands] == [g.band for g in det.geometries(frames[0].shape[:2])]
    # the positive windows are those of the recorded decision values above the threshold (above
    # the slack threshold where a window reaches into its band's slack rows)
    n_pos = 0
    for _, g, dec in stats.bands:
        tops = g.y0 + np.arange(g.ny) * g.step * 8 * g.band.scale
        core = g.band.core if g.band.core is not None else (g.y0, g.y1)
        inside = (tops >= core[0] - 1) & (tops + 64 * g.band.scale <= core[1] + 1)
        thr = np.where(inside, det.search.threshold, det.search.slack_threshold)
        n_pos += int((dec > thr[:, None]).sum())
    assert n_pos == len(d)
    rgb = det.detect(np.ascontiguousarray(frames[0][:, :, ::-1]), rgb=True)
    np.testing.assert_array_equal(rgb.boxes, d.boxes)


def test_boxes_land_on_the_cars(frames, data):
    """test1.jpg has two cars on the right (black ~x 816-944, white ~x 1052-1270, y 400-510)."""
    det = Detector()
    d = det.detect(frames[0])
    cars = [(810, 400, 950, 510), (1050, 400, 1270, 520)]
    for x1, y1, x2, y2 in cars:
        cx = (d.boxes[:, 0] + d.boxes[:, 2]) / 2
        cy = (d.boxes[:, 1] + d.boxes[:, 3]) / 2
        assert np.any((cx > x1) & (cx < x2) & (cy > y1 - 20) & (cy < y2 + 20)), (x1, x2)
    # and not on the empty road in front (lower left quarter of the search region)
    cx = (d.boxes[:, 0] + d.boxes[:, 2]) / 2
    cy = (d.boxes[:, 1] + d.boxes[:, 3]) / 2
    assert not np.any((cx > 300) & (cx < 700) & (cy > 560))


@pytest.mark.parametrize("frame, msg", [
    (np.zeros((720, 1280, 3), np.float32), "uint8"),
    (np.zeros((720, 1280), np.uint8), r"\(H, W, 3\)"),
])
def test_bad_frames(frame, msg):
    with pytest.raises(ValueError, match=msg):
        Detector().detect(frame)


def test_bands_in_pixels_must_fit_the_frame():
    bands = tuple(replace(b, slack_above=None) for b in SearchConfig().bands)  # slack bands are clipped
    search = SearchConfig(bands=bands, reference_shape=None)
    with pytest.raises(ValueError, match="does not fit"):
        Detector(search=search).detect(np.zeros((300, 400, 3), np.uint8))


def test_other_frame_sizes_get_rescaled_bands(frames):
    """Bands are written for 1280x720; a 1920x1080 or 640x360 frame searches the same part
    of the picture at proportional scales, and still finds the two cars of test1.jpg."""
    cfg = SearchConfig()
    big = cfg.for_frame((1080, 1920))
    assert [b.scale for b in big.bands] == [1.5 * b.scale for b in cfg.bands]
    one = next(b for b in big.bands if b.scale == 1.5)  # the 64-px band at y 400..496 of 720 rows
    assert one.core == (600, 744) and one.y_stop == 744
    assert one.y_start == 600 - 24  # its slack above: 0.03 of 1080 rows is about one 24-row window step
    framed = cfg.for_frame((720, 1280))
    assert framed.for_frame((720, 1280)) is framed
    det = Detector()
    for size in ((1920, 1080), (640, 360)):
        frame = cv2.resize(frames[0], size, interpolation=cv2.INTER_AREA)
        d = det.detect(frame)
        f = size[0] / 1280
        cx = (d.boxes[:, 0] + d.boxes[:, 2]) / 2 / f
        for x1, x2 in ((816, 944), (1052, 1270)):
            assert np.any((cx > x1) & (cx < x2)), (size, x1)


def test_band_threads_give_the_same_windows(frames):
    """With 2 Numba threads the bands run in 2 Python threads on the serial kernels; the
    positive windows must be those of the single-threaded run."""
    import numba

    det = Detector()
    before = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        one_stats, two_stats = DetectStats(), DetectStats()
        one = det.detect(frames[3], stats=one_stats)
        numba.set_num_threads(min(2, numba.config.NUMBA_NUM_THREADS))
        two = det.detect(frames[3], stats=two_stats)
    finally:
        numba.set_num_threads(before)
    np.testing.assert_array_equal(one.boxes, two.boxes)
    np.testing.assert_allclose(one.scores, two.scores, rtol=0, atol=1e-6)
    assert len(one_stats.bands) == len(two_stats.bands) > 1
    for (pa, ga, a), (pb, gb, b) in zip(one_stats.bands, two_stats.bands):
        assert pa == pb and ga == gb
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-9)
    det.close()
    try:  # a closed detector starts new band threads when it is used again
        numba.set_num_threads(min(2, numba.config.NUMBA_NUM_THREADS))
        np.testing.assert_array_equal(det.detect(frames[3]).boxes, two.boxes)
    finally:
        numba.set_num_threads(before)
    det.close()


def test_the_former_names_of_the_oncoming_model_still_work_and_warn():
    """``Detector(wide=, wide_search=)`` and ``fastdet.config.WIDE_SEARCH`` / ``WIDE_HEAT`` /
    ``wide_search``: the names before ``oncoming``, deprecated."""
    import fastdet.config as config

    cfg = FeatureConfig(window_height=32)
    wide, search = _random_model(cfg, 2), SearchConfig(bands=(SearchBand(1.0, 390, 470),), cells_per_step=1)
    with pytest.warns(DeprecationWarning, match="oncoming="):
        det = Detector(_random_model(FeatureConfig()), wide=wide, wide_search=search)
    assert det.oncoming_model is wide and det.scorers[1].search == search and det.parts == [0, 1]
    with pytest.raises(TypeError, match="not both"):
        Detector(oncoming=wide, wide=wide)
    for old, new in (("WIDE_SEARCH", config.ONCOMING_SEARCH), ("WIDE_HEAT", config.ONCOMING_HEAT),
                     ("wide_search", config.oncoming_search)):
        with pytest.warns(DeprecationWarning, match=old):
            assert getattr(config, old) is new
    with pytest.raises(AttributeError):
        config.NO_SUCH_NAME  # noqa: B018
