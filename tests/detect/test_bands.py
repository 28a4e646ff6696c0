"""Windows hanging over the left / right border: exactly the search of the frame padded the same way."""
from __future__ import annotations

import cv2
import numpy as np
import pytest

from fastdet.config import SearchBand
from fastdet.detect import Detector
from fastdet.detect.bands import BORDER_MODES, band_geometry, pad_frame, scaled_band, window_boxes
from tests.reference import classic_band_scores, sklearn_pair


@pytest.fixture(scope="module")
def frame(test_images):
    return cv2.imread(str(test_images[0]))


@pytest.fixture(scope="module")
def detector():
    return Detector()


@pytest.mark.parametrize("mode", ["replicate", "reflect"])
@pytest.mark.parametrize("scale", [1.0, 1.5, 0.75])
def test_padded_band_is_the_band_of_the_padded_frame(frame, detector, mode, scale):
    cfg = detector.config
    band = SearchBand(scale, 400, 400 + int(96 * scale))
    geo = band_geometry(band, frame.shape[:2], cfg, 2, border=0.5, border_mode=mode)
    pad = round(32 * scale)
    assert (geo.pad_left, geo.pad_right, geo.x0, geo.x1) == (pad, pad, -pad, frame.shape[1] + pad)
    padded = cv2.copyMakeBorder(frame, 0, 0, pad, pad, BORDER_MODES[mode])
    ref = band_geometry(SearchBand(scale, 400, band.y_stop, 0, padded.shape[1]), padded.shape[:2], cfg, 2)
    assert (geo.nx, geo.ny, geo.scaled_w) == (ref.nx, ref.ny, ref.scaled_w)
    np.testing.assert_array_equal(scaled_band(frame, geo), scaled_band(padded, ref))
    # the same decision values, window for window
    np.testing.assert_array_equal(detector.band_scores(frame, geo), detector.band_scores(padded, ref))
    # boxes: those of the padded frame, shifted back and clipped to the frame
    r, c = np.meshgrid(np.arange(geo.ny), np.arange(geo.nx), indexing="ij")
    r, c = r.ravel(), c.ravel()
    want = window_boxes(ref, r, c, cfg) - np.array([pad, 0, pad, 0])
    want[:, 0::2] = np.clip(want[:, 0::2], 0, frame.shape[1])
    np.testing.assert_array_equal(window_boxes(geo, r, c, cfg), want)


def test_only_edges_the_band_reaches_are_padded(frame, detector):
    cfg = detector.config
    g = band_geometry(SearchBand(1.0, 400, 496, 100, None), frame.shape[:2], cfg, 2, border=0.5)
    assert (g.pad_left, g.pad_right, g.x0, g.x1) == (0, 32, 100, frame.shape[1] + 32)
    g = band_geometry(SearchBand(1.0, 400, 496, None, 900), frame.shape[:2], cfg, 2, border=0.5)
    assert (g.pad_left, g.pad_right, g.x0, g.x1) == (32, 0, -32, 900)
    g = band_geometry(SearchBand(1.0, 400, 496), frame.shape[:2], cfg, 2, border=0.0)
    assert (g.pad_left, g.pad_right, g.x0, g.x1) == (0, 0, 0, frame.shape[1])
    with pytest.raises(ValueError):
        band_geometry(SearchBand(1.0, 400, 496), frame.shape[:2], cfg, 2, border=0.5, border_mode="wrap")


def test_padded_windows_match_the_classic_reference(frame, detector):
    # the classic per-window pipeline on the padded band: every window to 1e-6
    pair = sklearn_pair(detector.model)
    for mode in ("replicate", "reflect"):
        geo = band_geometry(SearchBand(1.25, 400, 528), frame.shape[:2], detector.config, 2, 0.5, mode)
        np.testing.assert_allclose(detector.band_scores(frame, geo),
                                   classic_band_scores(frame, geo, detector.model, pair), rtol=0, atol=1e-6)


def test_default_search_boxes_stay_in_the_frame(frame, detector):
    assert detector.search.border > 0
    geos = detector.geometries(frame.shape[:2])
    assert any(g.pad_left for g in geos) and any(g.pad_right for g in geos)
    d = detector.detect(frame)
    assert len(d)
    assert d.boxes[:, 0].min() >= 0 and d.boxes[:, 2].max() <= frame.shape[1]
    # some windows reach past the edge: their boxes are clipped, narrower than 64 x scale
    geo_boxes = np.concatenate([window_boxes(g, *[a.ravel() for a in np.meshgrid(np.arange(g.ny), np.arange(g.nx),
                                                                                 indexing="ij")], detector.config)
                                for g in geos])
    assert geo_boxes[:, 0].min() == 0 and geo_boxes[:, 2].max() == frame.shape[1]


@pytest.mark.parametrize("mode", sorted(BORDER_MODES))
def test_shared_padded_frame_gives_the_same_scaled_bands(frame, detector, mode):
    """Bands cut from one pad_frame copy (the widest padding, all their rows) equal the bands
    padded one by one, bit for bit: reflect-101 and replicate padding of a column does not
    depend on the padding's width. Bands with one padded side, or none, included."""
    h, w = frame.shape[:2]
    cfg = detector.config
    bands = [SearchBand(s, y, y + int(64 * s) + 8 * k, x0, x1)
             for k, (s, y, x0, x1) in enumerate([(1.0, 380, None, None), (1.25, 400, None, 900),
                                                 (1.5, 390, 300, None), (2.0, 410, None, None),
                                                 (3.0, 400, None, None), (0.75, 420, 100, 600)])]
    geos = [band_geometry(b, (h, w), cfg, 2, border=1.0, border_mode=mode) for b in bands]
    padded = pad_frame(frame, geos)
    assert padded is not None and padded.pad == max(g.pad_left for g in geos)
    for g in geos:
        assert not (g.pad_left or g.pad_right) or padded.covers(g)
        np.testing.assert_array_equal(scaled_band(frame, g, padded), scaled_band(frame, g))
    assert pad_frame(frame, geos[:1]) is None


@pytest.mark.parametrize("scale", [1.25, 1.75, 2.0, 0.75])
def test_area_shrink_is_inter_area_of_the_band(frame, scale):
    from fastdet.config import FeatureConfig, SearchConfig
    from fastdet.model import Model

    SMALL_FEATURES = FeatureConfig(window=32, spatial_size=16, orientations=9)  # a small-window model's

    band = SearchBand(scale, 380, 380 + int(48 * scale))
    geo = band_geometry(band, frame.shape[:2], SMALL_FEATURES, 1, shrink="area")
    lin = band_geometry(band, frame.shape[:2], SMALL_FEATURES, 1)
    assert (geo.shrink, lin.shrink) == ("area", "linear")
    roi = frame[geo.y0: geo.y1, geo.x0: geo.x1]
    got = scaled_band(frame, geo)
    # shrunk: the mean of the pixels each scaled pixel covers; enlarged: INTER_LINEAR as before
    interp = cv2.INTER_AREA if scale > 1 else cv2.INTER_LINEAR
    np.testing.assert_array_equal(got, cv2.resize(roi, (geo.scaled_w, geo.scaled_h), interpolation=interp))
    np.testing.assert_array_equal(scaled_band(frame, lin),
                                  cv2.resize(roi, (geo.scaled_w, geo.scaled_h), interpolation=cv2.INTER_LINEAR))
    if scale > 1 and scale != int(scale):  # (at a whole factor INTER_LINEAR is the area mean too)
        assert not np.array_equal(got, scaled_band(frame, lin))
    with pytest.raises(ValueError, match="shrink"):
        band_geometry(band, frame.shape[:2], SMALL_FEATURES, 1, shrink="cubic")
    # the Detector scores an area-shrunk band as the classic per-window pipeline does
    rng = np.random.default_rng(0)
    n = SMALL_FEATURES.n_features
    model = Model(SMALL_FEATURES, rng.normal(size=n) * 0.01, -0.2, rng.normal(size=n), rng.uniform(0.5, 2.0, n))
    narrow = SearchBand(scale, band.y_start, band.y_stop, None, 320)  # the left edge, past it too
    det = Detector(model, SearchConfig(bands=(narrow,), cells_per_step=1, shrink="area", border=0.25))
    (g,) = det.geometries(frame.shape[:2])
    assert g.shrink == "area" and g.pad_left > 0
    np.testing.assert_allclose(det.band_scores(frame, g), classic_band_scores(frame, g, model, sklearn_pair(model)),
                               rtol=0, atol=1e-6)
