"""The configuration dataclasses: validation, derived sizes, dict round trips, frame rescaling.
(HeatConfig's checks: tests/config/test_heat.py; MotionGate's: tests/config/test_motion.py.)"""
from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from fastdet.config import (
    ONCOMING_HEAT,
    ONCOMING_SEARCH,
    FeatureConfig,
    HeatConfig,
    MotionGate,
    SearchBand,
    SearchConfig,
)
from tests.reference import crop_features

FEATURE_CONFIGS = [
    FeatureConfig(),
    FeatureConfig(color_space="LUV", orientations=9, hog_channels=(0,), spatial_size=16, hist_bins=16),
    FeatureConfig(color_space="HLS", hog_channels=(2, 0), spatial_size=0, hist_bins=0, cells_per_block=3),
    FeatureConfig(window_height=24, spatial_size=32),
    FeatureConfig(window=48, pixels_per_cell=8, spatial_size=16, hist_bins=64),
]


@pytest.mark.parametrize("cfg", FEATURE_CONFIGS, ids=repr)
def test_feature_sizes_are_those_of_the_reference_features(cfg):
    """n_features (and its parts) count what the plain per-crop pipeline produces."""
    crop = np.random.default_rng(0).integers(0, 256, (cfg.win_h, cfg.win_w, 3), dtype=np.uint8)
    assert len(crop_features(crop, cfg)) == cfg.n_features == cfg.n_hog + cfg.n_spatial + cfg.n_hist
    assert cfg.n_hist == 3 * cfg.hist_bins
    sh, sw = cfg.spatial_shape
    assert cfg.n_spatial == 3 * sh * sw and (sh == 0) == (cfg.spatial_size == 0)
    assert cfg.blocks_x == cfg.win_w // cfg.pixels_per_cell - cfg.cells_per_block + 1
    assert cfg.blocks_y == cfg.win_h // cfg.pixels_per_cell - cfg.cells_per_block + 1


def test_feature_config_by_hand():
    cfg = FeatureConfig()  # 64x64, 8-px cells, 2x2 blocks, 16 orientations, 3 channels, 32x32, 32 bins
    assert (cfg.win_w, cfg.win_h, cfg.blocks_x, cfg.blocks_y, cfg.block_len) == (64, 64, 7, 7, 64)
    assert cfg.n_features == 3 * 7 * 7 * 64 + 3 * 32 * 32 + 3 * 32
    wide = FeatureConfig(window_height=24)
    assert (wide.win_w, wide.win_h, wide.blocks_y, wide.spatial_shape) == (64, 24, 2, (12, 32))
    assert FeatureConfig(window_height=64).window_height is None  # square: same as no height
    assert FeatureConfig(hog_channels="ALL").hog_channels == (0, 1, 2)
    assert FeatureConfig(hog_channels=[2, 0]).hog_channels == (2, 0)


@pytest.mark.parametrize("kw, msg", [
    (dict(color_space="XYZ"), "color_space"),
    (dict(hog_channels=()), "hog_channels"),
    (dict(hog_channels=(0, 3)), "hog_channels"),
    (dict(hog_channels=(1, 1)), "hog_channels"),
    (dict(hog_channels="some"), "hog_channels"),
    (dict(orientations=0), "orientations"),
    (dict(pixels_per_cell=0), "pixels_per_cell"),
    (dict(cells_per_block=0), "cells_per_block"),
    (dict(pixels_per_cell=12), "multiples of pixels_per_cell"),
    (dict(window_height=20), "multiples of pixels_per_cell"),
    (dict(window_height=8), "at least one block"),
    (dict(spatial_size=-1), "spatial_size"),
    (dict(hist_bins=-1), "hist_bins"),
    (dict(spatial_size=24), "window // spatial_size"),
    (dict(window_height=24, spatial_size=4), "window // spatial_size"),
    (dict(hist_bins=24), "divide 256"),
])
def test_feature_config_refuses(kw, msg):
    with pytest.raises(ValueError, match=msg):
        FeatureConfig(**kw)


@pytest.mark.parametrize("cfg", [*FEATURE_CONFIGS, MotionGate(), MotionGate(0), HeatConfig(), ONCOMING_HEAT,
                                 HeatConfig(n_frames=3, decay=0.5, box_mode="mean", score_lo=0.1, score_hi=0.9)],
                         ids=repr)
def test_dict_round_trip_through_json(cfg):
    d = json.loads(json.dumps(cfg.to_dict()))
    back = type(cfg).from_dict(d)
    assert back == cfg and hash(back) == hash(cfg)
    with pytest.raises(ValueError, match="unknown"):
        type(cfg).from_dict({**d, "bogus": 1})


def test_square_feature_config_dict_has_no_window_height():
    """Model files written before wide windows existed hold no window_height: same dict."""
    assert "window_height" not in FeatureConfig().to_dict()
    assert FeatureConfig(window_height=24).to_dict()["window_height"] == 24


@pytest.mark.parametrize("cfg", [FeatureConfig(), SearchBand(1.0, 400, 500), SearchConfig(), ONCOMING_SEARCH,
                                 HeatConfig(), MotionGate()], ids=lambda c: type(c).__name__)
def test_frozen_hashable_comparable(cfg):
    assert cfg == dataclasses.replace(cfg) and hash(cfg) == hash(dataclasses.replace(cfg))
    name = dataclasses.fields(cfg)[0].name
    with pytest.raises(dataclasses.FrozenInstanceError):
        setattr(cfg, name, getattr(cfg, name))


@pytest.mark.parametrize("args, msg", [
    ((0.0, 400, 500), "scale"), ((-1.0, 400, 500), "scale"), ((1.0, 500, 500), "y_stop"),
    ((1.0, 400, 500, 300, 200), "x_stop"), ((1.0, 400, 500, 300, 300), "x_stop"),
])
def test_search_band_refuses(args, msg):
    with pytest.raises(ValueError, match=msg):
        SearchBand(*args)


@pytest.mark.parametrize("kw, msg", [
    (dict(bands=()), "at least one band"), (dict(cells_per_step=0), "cells_per_step"),
    (dict(reference_shape=(720,)), "reference_shape"), (dict(reference_shape=(0, 1280)), "reference_shape"),
])
def test_search_config_refuses(kw, msg):
    with pytest.raises(ValueError, match=msg):
        SearchConfig(**kw)


def test_search_config_keeps_bands_as_a_tuple():
    bands = [SearchBand(1.0, 400, 500)]
    assert SearchConfig(bands=bands).bands == tuple(bands)


def test_for_frame_rescales_rows_columns_and_scales():
    cfg = SearchConfig(bands=(SearchBand(1.0, 400, 496), SearchBand(2.0, 380, 700, 100, 1200)), threshold=0.3)
    assert cfg.for_frame((720, 1280)) is cfg
    pixels = SearchConfig(bands=cfg.bands, reference_shape=None)
    assert pixels.for_frame((100, 100)).bands == cfg.bands  # bands in pixels, without slack: as given
    half = cfg.for_frame((360, 640))
    assert half.bands == (SearchBand(0.5, 200, 248), SearchBand(1.0, 190, 350, 50, 600))
    assert (half.threshold, half.cells_per_step, half.reference_shape) == (0.3, 2, None)
    # columns and rows scale separately; bands are clipped to the frame
    wide = cfg.for_frame((720, 2560))
    assert wide.bands == (SearchBand(1.0, 400, 496), SearchBand(2.0, 380, 700, 200, 2400))
    short = SearchConfig(bands=(SearchBand(1.0, 600, 720, 0, 1280),), reference_shape=(700, 1280))
    assert short.for_frame((700, 960)).bands == (SearchBand(1.0, 600, 700, 0, 960),)


def test_wide_search_bands_hold_whole_cells():
    """Each default wide band is a whole number of its 8 * scale px cells wide, so a band
    narrowed to part of it (fastdet.video.motion) resamples exactly as the full band."""
    for b in ONCOMING_SEARCH.bands:
        cell = 8 * b.scale
        assert b.x_start == 0 and (b.x_stop / cell) == int(b.x_stop / cell), b
        assert b.y_stop - b.y_start >= 24 * b.scale  # room for one 64x24 window
