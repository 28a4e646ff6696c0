"""fastdet.detect.geometry: the slack rows' thresholds of a search band, and the detector that
applies them (bands from the camera's geometry moved to tools/studies/perspective.py, with their
tests: tests/tools/studies/test_perspective.py)."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from fastdet.config import FeatureConfig, SearchBand, SearchConfig
from fastdet.detect.bands import band_geometry
from fastdet.detect.geometry import row_thresholds

CFG = FeatureConfig()


def window_rows(band: SearchBand, shape: tuple[int, int], step_cells: int = 2) -> np.ndarray:
    """(top, bottom) frame rows of every window row of ``band`` (what the detector searches)."""
    g = band_geometry(band, shape, CFG, step_cells)
    tops = band.y_start + np.arange(g.ny) * step_cells * 8 * band.scale
    return np.stack([tops, tops + 64 * band.scale], 1)


def test_row_thresholds_gate_only_the_windows_reaching_into_the_slack():
    band = SearchBand(1.0, 376, 496, core=(400, 496))  # 24 rows of slack above, windows 16 rows apart
    geo = band_geometry(band, (720, 1280), CFG, 2)
    search = SearchConfig(bands=(band,), reference_shape=None, threshold=0.5, slack_threshold=2.0)
    thr = row_thresholds(geo, search, CFG)
    tops = window_rows(band, (720, 1280))[:, 0]
    assert len(thr) == geo.ny == len(tops)
    np.testing.assert_array_equal(thr, np.where(tops >= 399, 0.5, 2.0))
    assert row_thresholds(geo, replace(search, slack_threshold=None), CFG) == 0.5
    assert row_thresholds(band_geometry(replace(band, core=None), (720, 1280), CFG, 2), search, CFG) == 0.5
    below = SearchBand(1.0, 400, 528, core=(400, 496))  # 32 rows of slack below
    geo = band_geometry(below, (720, 1280), CFG, 2)
    bottoms = window_rows(below, (720, 1280))[:, 1]
    np.testing.assert_array_equal(row_thresholds(geo, search, CFG), np.where(bottoms <= 497, 0.5, 2.0))


def test_detector_needs_the_slack_threshold_in_the_slack_rows(test_images):
    """Detector.detect's positive windows, against the obvious rule applied to every window's
    decision value: above ``threshold`` inside a band's core rows, above ``slack_threshold``
    where the window reaches into its slack (the default slack above the main bands)."""
    import cv2

    from fastdet import Detector
    from fastdet.detect import DetectStats
    from fastdet.detect.bands import window_boxes

    frame = cv2.imread(str(test_images[0]))
    search = replace(SearchConfig(), horizon=0.6, slack_threshold=5.0)  # cars in the slack rows of some bands
    det = Detector(search=search, oncoming=None)
    stats = DetectStats()
    got = det.detect(frame, stats=stats)
    want, gated, kept = [], 0, 0
    for part, geo, dec in stats.bands:
        sc = det.scorers[det.parts.index(part)]
        for i in range(geo.ny):
            for j in range(geo.nx):
                box = window_boxes(geo, np.array([i]), np.array([j]), sc.config)[0]
                core = geo.band.core
                slack = core is not None and not (core[0] - 1 <= box[1] and box[3] <= core[1] + 1)
                if dec[i, j] > (sc.search.slack_threshold if slack else sc.search.threshold):
                    want.append((*box.tolist(), float(dec[i, j])))
                    kept += slack
                elif dec[i, j] > sc.search.threshold:
                    gated += 1
    assert gated > 0 and kept > 0  # the gate dropped some windows in the slack rows and kept others
    have = sorted((*b.tolist(), float(v)) for b, v in zip(got.boxes, got.scores))
    assert len(have) == len(want)
    for h, w in zip(have, sorted(want)):
        score = 1 / (1 + np.exp(-w[4])) if det.score_kind == "probability" else w[4]
        assert h[:4] == w[:4] and h[4] == pytest.approx(score, rel=1e-5)
