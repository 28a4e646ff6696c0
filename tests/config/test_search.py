"""The default searches: oncoming traffic on either side of the road, small windows near the horizon."""
from __future__ import annotations

import pytest

from fastdet.config import ONCOMING_SEARCH, REFERENCE_HORIZON, SearchConfig, oncoming_search


def test_wide_search_sides():
    right, left, both = oncoming_search("right"), oncoming_search("left"), oncoming_search("both")
    assert right == ONCOMING_SEARCH
    for r, l, b in zip(right.bands, left.bands, both.bands):
        cell = 8 * r.scale
        assert (r.scale, r.y_start, r.y_stop) == (l.scale, l.y_start, l.y_stop) == (b.scale, b.y_start, b.y_stop)
        # the left-hand-traffic columns mirror the right-hand ones, whole cells wide
        assert r.x_start == 0 and (l.x_start, l.x_stop) == (1280 - r.x_stop, 1280)
        assert (l.x_stop - l.x_start) % cell == 0 and r.x_stop % cell == 0
        assert b.x_start == 0 and 1280 - cell < b.x_stop <= 1280 and b.x_stop % cell == 0
    with pytest.raises(ValueError, match="traffic"):
        oncoming_search("middle")


def test_default_search_reaches_the_sizes_the_annotations_count():
    cfg = SearchConfig()
    smallest = min(cfg.bands, key=lambda b: b.scale)
    assert 64 * smallest.scale <= 48  # windows for 45-70 px cars
    # near the horizon only: its band ends within two windows below it
    assert smallest.y_stop <= REFERENCE_HORIZON * 720 + 2 * 64 * smallest.scale
    assert cfg.border > 0 and cfg.border_mode == "replicate"


def test_large_search_reaches_past_the_default_sizes_where_near_vehicles_stand():
    from fastdet.config.search import LARGE_SCALES, LARGE_SEARCH, LARGE_THRESHOLD

    default = SearchConfig()
    assert LARGE_SEARCH.bands and tuple(b.scale for b in LARGE_SEARCH.bands) == LARGE_SCALES
    assert min(LARGE_SCALES) > max(b.scale for b in default.bands)  # only sizes the default lacks
    assert 64 * max(LARGE_SCALES) >= 400  # a vehicle alongside, 400+ px of 1280
    hz = REFERENCE_HORIZON * 720
    for b in LARGE_SEARCH.bands:
        w = 64 * b.scale
        assert b.x_start is None and b.x_stop is None  # the whole width, past the edges as the default
        assert 0 <= b.y_start and b.y_stop <= 720 and b.y_stop - b.y_start >= w  # at least one window
        # window tops from half a window above the horizon (or as high as the frame lets a
        # window reach its bottom), bottoms down to 1.2 windows below it or the frame's bottom
        assert b.y_start <= max(hz - 0.5 * w, 0) + 1 or b.y_start == b.y_stop - int(-(-w // 1))
        assert b.y_stop >= min(720, hz + 1.2 * w) - 1
    assert LARGE_SEARCH.threshold == LARGE_THRESHOLD > default.threshold
    assert (LARGE_SEARCH.border, LARGE_SEARCH.border_mode) == (default.border, default.border_mode)


@pytest.mark.parametrize("shape", [(360, 640), (450, 800), (540, 960), (720, 1280), (1080, 1920)])
def test_large_search_keeps_every_band_on_the_annotated_frame_sizes(shape):
    from fastdet.config.search import LARGE_SEARCH

    bands = LARGE_SEARCH.for_frame(shape).bands
    assert len(bands) == len(LARGE_SEARCH.bands)
    f = shape[0] / 720
    for b, ref in zip(bands, LARGE_SEARCH.bands):
        assert b.scale == pytest.approx(ref.scale * f)
        assert 0 <= b.y_start and b.y_stop <= shape[0] and b.y_stop - b.y_start >= 64 * b.scale - 1
