"""Detector.detect(columns=...): the windows of the given column ranges of each band, with the
decision values the whole band gives them; the others not scored."""
from __future__ import annotations

import cv2
import numba
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fastdet.detect import Detector, DetectStats


@pytest.fixture(scope="module")
def det():
    d = Detector()
    d.warmup()
    return d


@pytest.fixture(scope="module")
def frames(test_images):
    return [cv2.imread(str(p)) for p in test_images[:3]]


@pytest.fixture(scope="module")
def full(det, frames):
    out = []
    for f in frames:
        stats = DetectStats()
        det.detect(f, stats=stats)
        out.append([dec for _, _, dec in stats.bands])
    return out


@settings(max_examples=25, deadline=None)
@given(st.integers(0, 2), st.lists(st.lists(st.tuples(st.integers(-3, 90), st.integers(0, 95)), max_size=3),
                                   min_size=1, max_size=7), st.sampled_from([1, 2]))
def test_spans_give_the_whole_band_values(det, frames, full, i, columns, threads):
    before = numba.get_num_threads()
    numba.set_num_threads(min(threads, numba.config.NUMBA_NUM_THREADS))
    try:
        stats = DetectStats()
        got = det.detect(frames[i], stats=stats, columns=columns)
    finally:
        numba.set_num_threads(before)
    for b, (_, geo, dec) in enumerate(stats.bands):
        want = np.zeros(geo.nx, bool)
        for j0, j1 in columns[b] if b < len(columns) else [(0, geo.nx)]:
            want[max(j0, 0): max(min(j1, geo.nx), 0)] = True
        np.testing.assert_allclose(dec[:, want], full[i][b][:, want], rtol=0, atol=1e-9)
        assert np.all(dec[:, ~want] == -np.inf)
    # the positive windows: the whole search's, in the scored columns
    ref = DetectStats()
    whole = det.detect(frames[i], stats=ref)
    assert set(map(tuple, got.boxes.tolist())) <= set(map(tuple, whole.boxes.tolist()))


def test_all_columns_is_the_whole_search(det, frames, full):
    stats = DetectStats()
    geos = det.geometries(frames[0].shape[:2])
    det.detect(frames[0], stats=stats, columns=[[(0, g.nx)] for g in geos])
    for (_, _, dec), ref in zip(stats.bands, full[0]):
        np.testing.assert_allclose(dec, ref, rtol=0, atol=1e-9)
    stats = DetectStats()
    assert len(det.detect(frames[0], stats=stats, columns=[[]] * len(geos))) == 0
    assert all(np.all(dec == -np.inf) for _, _, dec in stats.bands)
    with pytest.raises(ValueError, match="entries"):
        det.detect(frames[0], columns=[None] * (len(geos) + 1))
