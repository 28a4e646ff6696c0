"""The band scorer's cached row thresholds against :func:`fastdet.detect.geometry.row_thresholds`."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from fastdet import Detector
from fastdet.config import SearchBand, SearchConfig
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


def test_a_bands_image_key_is_every_field_of_its_geometry_but_the_window_rows():
    """Two geometries share a band image (and its HOG) exactly when every field but ``ny`` agrees:
    a field added to BandGeometry must join the key."""
    import dataclasses

    from fastdet.detect.band_scorer import image_key
    from fastdet.detect.bands import BandGeometry

    geo = BandGeometry(SearchBand(1.5, 400, 560), -16, 400, 1296, 560, 874, 106, 51, 3, 2, 16, 16)
    names = [f.name for f in dataclasses.fields(BandGeometry) if f.name != "ny"]
    assert image_key(geo) == tuple(getattr(geo, n) for n in names)
    assert image_key(dataclasses.replace(geo, ny=9)) == image_key(geo)
    for n in names:
        v = getattr(geo, n)
        other = {str: "replicate" if v != "replicate" else "reflect"}.get(type(v), None)
        changed = dataclasses.replace(geo, **{n: other if other is not None else (
            SearchBand(2.0, 400, 560) if isinstance(v, SearchBand) else v + 1)})
        assert image_key(changed) != image_key(geo), n


def test_geometries_are_worked_out_once_per_frame_size_and_search(monkeypatch):
    """The same frame size and search give the same geometries without working them out again; a
    new horizon (a new search) or frame size works them out anew, and a caller's list is its own."""
    det = Detector()
    sc = det.scorers[0]
    calls = []
    real = type(sc.search).for_frame

    def counting(self, *a, **kw):
        calls.append(1)
        return real(self, *a, **kw)

    monkeypatch.setattr(type(sc.search), "for_frame", counting)
    first = sc.geometries((720, 1280))
    again = sc.geometries((720, 1280))
    assert first == again and first is not again and len(calls) == 1
    first.append(None)
    assert None not in sc.geometries((720, 1280))
    det.set_horizon(0.6)
    moved = sc.geometries((720, 1280))
    assert len(calls) == 2 and moved != again
    want = [band_geometry(b, (720, 1280), sc.config, s.cells_per_step, s.border, s.border_mode, s.shrink)
            for s in [real(sc.search, (720, 1280), sc.config.win_w, sc.config.pixels_per_cell)] for b in s.bands]
    assert moved == want
    sc.geometries((360, 640))
    assert len(calls) == 3
