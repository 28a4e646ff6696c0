"""The band scorer's cached row thresholds against :func:`fastdet.detect.geometry.row_thresholds`."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from fastdet import Detector
from fastdet.config import SearchConfig
from fastdet.detect import band_scorer
from fastdet.detect.bands import band_geometry
from fastdet.detect.geometry import row_thresholds


def _same(a, b) -> bool:
    return np.array_equal(np.broadcast_to(a, np.shape(b) or (1,)), np.broadcast_to(b, np.shape(a) or (1,))) and (
        isinstance(a, np.ndarray) == isinstance(b, np.ndarray))


def test_cached_thresholds_are_row_thresholds_and_follow_the_search():
    det = Detector(search=replace(SearchConfig(), horizon=0.6), oncoming=None)
    sc = det.scorers[0]
    geos = det.geometries((720, 1280))
    assert any(g.band.core is not None for g in geos)  # the default search has slack rows
    first = [sc.row_thresholds(g) for g in geos]
    for g, thr in zip(geos, first):
        assert _same(thr, row_thresholds(g, sc.search, sc.config))
        assert sc.row_thresholds(g) is thr  # computed once
        if isinstance(thr, np.ndarray):
            with pytest.raises(ValueError):
                thr[0] = 0.0  # shared between frames: read-only
    # a new search on the scorer (as the perspective stage and the studies set one): new thresholds
    for search in (replace(sc.search, slack_threshold=sc.search.threshold + 3.0),
                   replace(sc.search, threshold=sc.search.threshold - 0.25), replace(sc.search, slack_threshold=None)):
        sc.search = search
        for g in geos:
            assert _same(sc.row_thresholds(g), row_thresholds(g, search, sc.config))


def test_the_cache_stays_bounded():
    det = Detector(oncoming=None)
    sc = det.scorers[0]
    band = det.geometries((720, 1280))[-1].band
    for k in range(band_scorer._MAX_CACHED_BANDS + 10):  # bands given per frame, each a little lower
        g = band_geometry(replace(band, y_start=band.y_start + k % 100, y_stop=band.y_stop + k % 100,
                                  x_start=k // 100, core=None), (900, 1280), sc.config, 2)
        assert _same(sc.row_thresholds(g), row_thresholds(g, sc.search, sc.config))
    assert len(sc._thresholds) <= band_scorer._MAX_CACHED_BANDS
