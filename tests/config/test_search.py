"""The default searches: oncoming traffic on either side of the road, small windows near the horizon."""
from __future__ import annotations

import pytest

from fastdet.config import REFERENCE_HORIZON, ONCOMING_SEARCH, SearchConfig, oncoming_search


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
