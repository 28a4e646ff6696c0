"""Detector(components=...): more whole-vehicle models, each with its own search; their windows
are those the same model gives on its own, tagged with their part."""
from __future__ import annotations

import cv2
import numpy as np
import pytest

from fastdet.config import ONCOMING_SEARCH, SearchBand, SearchConfig
from fastdet.detect import Detector, DetectStats
from fastdet.detections import FIRST_COMPONENT_PART, MAIN_PART, ONCOMING_PART
from fastdet.errors import ModelError
from fastdet.model import ONCOMING_MODEL_PATH, load_model


def _sorted(boxes, scores):
    order = np.lexsort((scores, *boxes.T[::-1]))
    return boxes[order], scores[order]


@pytest.fixture(scope="module")
def frame(test_images):
    return cv2.imread(str(test_images[0]))


def test_component_windows_are_the_models_own(frame):
    low = SearchConfig(bands=(SearchBand(1.0, 380, 480), SearchBand(2.0, 380, 560)), threshold=-2.0)
    plain = Detector(oncoming=ONCOMING_MODEL_PATH, oncoming_search=low)
    ref = plain.detect(frame)
    ref_wide = ref[ref.part == ONCOMING_PART]
    assert len(ref_wide) > 10
    both = Detector(oncoming=ONCOMING_MODEL_PATH, oncoming_search=low, components=[(ONCOMING_MODEL_PATH, low),
                                                                          (None, SearchConfig())])
    assert both.parts == [MAIN_PART, ONCOMING_PART, FIRST_COMPONENT_PART, FIRST_COMPONENT_PART + 1]
    assert both.main_parts == [MAIN_PART, FIRST_COMPONENT_PART, FIRST_COMPONENT_PART + 1]
    got = both.detect(frame)
    for part, want in ((FIRST_COMPONENT_PART, ref_wide), (ONCOMING_PART, ref_wide),
                       (MAIN_PART, ref[ref.part == MAIN_PART]),
                       (FIRST_COMPONENT_PART + 1, ref[ref.part == MAIN_PART])):
        mine = got[got.part == part]
        b1, s1 = _sorted(mine.boxes, mine.scores)
        b2, s2 = _sorted(want.boxes, want.scores)
        np.testing.assert_array_equal(b1, b2)
        np.testing.assert_allclose(s1, s2, rtol=1e-6)


def test_columns_cover_the_component_bands_too(frame):
    comp = SearchConfig(bands=(SearchBand(1.5, 380, 520),), threshold=-3.0)
    det = Detector(components=[(ONCOMING_MODEL_PATH, comp)])
    geos = det.main_geometries(frame.shape[:2])
    assert [p for p, _ in geos] == [MAIN_PART] * len(SearchConfig().bands) + [FIRST_COMPONENT_PART]
    full = DetectStats()
    det.detect(frame, stats=full)
    # score only the component band's columns 3..9; every main band's none
    cols = [[(0, 0)]] * (len(geos) - 1) + [[(3, 9)]]
    part = DetectStats()
    out = det.detect(frame, stats=part, columns=cols)
    assert set(out.part.tolist()) <= {FIRST_COMPONENT_PART}
    dec_full, dec_part = full.bands[-1][2], part.bands[-1][2]
    np.testing.assert_allclose(dec_part[:, 3:9], dec_full[:, 3:9], rtol=0, atol=1e-9)
    assert np.isneginf(dec_part[:, :3]).all() and np.isneginf(dec_part[:, 9:]).all()
    with pytest.raises(ValueError, match="entries"):
        det.detect(frame, columns=[None] * (len(geos) + 1))


def test_horizon_moves_every_component_and_kinds_must_agree(frame, tmp_path):
    comp = SearchConfig(bands=(SearchBand(1.5, 380, 520),))
    det = Detector(components=[(ONCOMING_MODEL_PATH, comp)], horizon=0.5)
    y = det.geometries(frame.shape[:2], FIRST_COMPONENT_PART)[0].y0
    det.set_horizon(None)
    assert det.geometries(frame.shape[:2], FIRST_COMPONENT_PART)[0].y0 > y
    m = load_model(ONCOMING_MODEL_PATH)
    svc = type(m)(m.config, m.coef, m.intercept, m.mean, m.scale, classifier="linearsvc")
    with pytest.raises(ModelError, match="component 1"):
        Detector(components=[(svc, ONCOMING_SEARCH)])
    with pytest.raises(TypeError, match="SearchConfig"):
        Detector(components=[(m, "bands")])  # type: ignore[list-item]
