"""The default searches: oncoming traffic on either side of the road, small windows near the horizon."""
from __future__ import annotations

from dataclasses import replace

import pytest

from fastdet.config import ONCOMING_SEARCH, REFERENCE_HORIZON, SearchBand, SearchConfig, oncoming_search
from fastdet.config.search import BAND_SLACK, SLACK_THRESHOLD


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


def _without_slack(search: SearchConfig) -> SearchConfig:
    return replace(search, bands=tuple(replace(b, slack_above=None) for b in search.bands))


def _tops(band: SearchBand) -> set[float]:
    """Frame rows of the window tops of ``band`` (main model: 64-px windows two 8-px cells apart)."""
    side, step = 64 * band.scale, 16 * band.scale
    n = int((band.y_stop - band.y_start - side) // step + 1e-6) + 1
    return {round(band.y_start + k * step, 3) for k in range(max(n, 0))}


def _covered(tops: set[float], searched: set[float]) -> bool:
    """Every row of ``tops`` is within a pixel of a row of ``searched`` (bands start on whole rows)."""
    return all(any(abs(t - u) <= 1 for u in searched) for t in tops)


@pytest.mark.parametrize("shape", [(720, 1280), (360, 640), (450, 800), (540, 960), (1080, 1920)])
def test_default_bands_search_a_slack_above_on_their_grid(shape):
    """Every default band but the 48-px one also searches BAND_SLACK of the height above its
    rows (the nearest whole window steps), and keeps its rows without slack as its core."""
    cfg = SearchConfig()
    smallest = min(b.scale for b in cfg.bands)
    for b in cfg.bands:
        assert b.slack_above == (None if b.scale == smallest else BAND_SLACK)
    assert cfg.slack_threshold == SLACK_THRESHOLD > cfg.threshold
    bare = _without_slack(cfg).for_frame(shape).bands
    for b, n in zip(cfg.for_frame(shape).bands, bare):
        step = 16 * b.scale
        assert b.scale == n.scale and b.y_stop == n.y_stop
        if b.scale == smallest * shape[0] / 720:
            assert b == n and b.core is None
            continue
        assert b.core == (n.y_start, n.y_stop)
        assert (n.y_start - b.y_start) == pytest.approx(round(BAND_SLACK * shape[0] / step) * step, abs=1)
        assert _covered(_tops(n), _tops(b))


@pytest.mark.parametrize("shape", [(720, 1280), (360, 640), (540, 960)])
@pytest.mark.parametrize("error", [0.0, 0.01, 0.02, 0.025])
def test_slack_above_keeps_the_windows_of_a_horizon_set_too_low(shape, error):
    """Bands placed from a horizon ``error`` of the height too low in the picture still search
    (to the row rounding of the grid) every window the bands at the true horizon search
    without slack, in every band whose slack rows exceed the error by half a window step (a
    band moves with the horizon by the nearest whole number of steps)."""
    true = 0.55
    right = _without_slack(replace(SearchConfig(), horizon=true)).for_frame(shape).bands
    off = replace(SearchConfig(), horizon=true + error).for_frame(shape).bands
    checked = 0
    for r, o in zip(right, off):
        assert r.scale == o.scale
        step = 16 * o.scale
        if o.core is None or o.core[0] - o.y_start < error * shape[0] + step / 2 - 1:
            continue  # the 48-px band (no slack), or a window step too coarse for this error
        assert _covered({t for t in _tops(r) if t + 64 * r.scale <= o.y_stop}, _tops(o)), (r, o)
        checked += 1
    assert checked >= (5 if error <= 0.01 else 1)


def test_band_slack_checks_and_dicts():
    with pytest.raises(ValueError, match="slack_above"):
        SearchBand(1.0, 400, 496, slack_above=1.5)
    with pytest.raises(ValueError, match="core"):
        SearchBand(1.0, 400, 496, core=(450, 420))
    with pytest.raises(ValueError, match="slack_threshold"):
        SearchConfig(slack_threshold=float("inf"))
    plain = SearchBand(1.0, 400, 496)
    assert "slack_above" not in plain.to_dict() and "core" not in plain.to_dict()  # old dicts read back the same
    cfg = SearchConfig()
    assert SearchConfig.from_dict(cfg.to_dict()) == cfg
    framed = cfg.for_frame((360, 640))
    assert SearchConfig.from_dict(framed.to_dict()) == framed and framed.for_frame((360, 640)) == framed


def test_the_deleted_slack_rounding_rule_loads_only_off():
    assert SearchConfig.from_dict({"slack_steps": None}) == SearchConfig()
    assert "slack_steps" not in SearchConfig().to_dict()
    with pytest.raises(ValueError, match="deleted"):
        SearchConfig.from_dict({"slack_steps": "cover"})


def test_the_deleted_slack_below_a_band_loads_only_off():
    """Slack below a band was deleted (docs/accuracy.md, "Deleted stages"): a band's dict
    holding it off (null) loads, one holding a value is refused in one line, and a search's
    digest is what it was."""
    assert SearchBand.from_dict({"scale": 1.0, "y_start": 400, "y_stop": 496, "slack_below": None}) == \
        SearchBand(1.0, 400, 496)
    with pytest.raises(ValueError, match="SearchBand.slack_below: this stage was deleted"):
        SearchBand.from_dict({"scale": 1.0, "y_start": 400, "y_stop": 496, "slack_below": 0.04})
    d = SearchConfig().to_dict()
    d["bands"] = [{**b, "slack_below": None} for b in d["bands"]]
    assert SearchConfig.from_dict(d) == SearchConfig()
    assert all("slack_below" not in b for b in SearchConfig().to_dict()["bands"])


@pytest.mark.parametrize("landscape", [(720, 1280), (1080, 1920), (360, 640), (480, 640), (720, 1436)])
@pytest.mark.parametrize("horizon", [None, 0.45, 0.62])
def test_an_upright_phones_frames_are_searched_with_the_windows_of_its_frames_held_sideways(landscape, horizon):
    """A frame taller than wide (a phone filming upright: the same lens as its landscape frames)
    gets the windows of the landscape frame with its short side, each band at the same distance
    below the horizon (to a window step); landscape frames keep ``H / 720``."""
    h, w = landscape
    portrait = (w, h)
    cfg = replace(SearchConfig(), horizon=horizon)
    side, up = cfg.for_frame(landscape).bands, cfg.for_frame(portrait).bands
    f = h / 720
    assert [b.scale for b in side] == [pytest.approx(b.scale * f) for b in cfg.bands]
    hz = REFERENCE_HORIZON if horizon is None else horizon
    kept = {b.scale: b for b in up}
    for ref, b in zip(cfg.bands, side):
        step = 16 * b.scale
        if b.y_start <= 0 or b.core is None or b.scale not in kept:
            continue  # clipped at the top in either frame, or the 48-px band (no core)
        want = ((ref.y_start - REFERENCE_HORIZON * 720) * f, (ref.y_stop - REFERENCE_HORIZON * 720) * f)
        # both frames: the band's rows about the horizon as the reference's, to half a window
        # step (each band moves by whole steps)
        for band, rows in ((b, h), (kept[b.scale], w)):
            got = (band.core[0] - hz * rows, band.core[1] - hz * rows)
            assert abs(got[0] - want[0]) <= step / 2 + 1 and abs(got[1] - want[1]) <= step / 2 + 1, (band, want)
    assert {b.scale for b in side} <= set(kept)  # every window size of the landscape frame, no other
    assert set(kept) <= {b.scale for b in side}
    assert all(x.x_start is None and x.x_stop is None for x in up)
