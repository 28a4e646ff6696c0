"""Batched window features equal the plain reference (skimage HOG + cv2.resize + np.histogram)."""
from __future__ import annotations

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from fastdet.config import FeatureConfig
from fastdet.features import extract_features, spatial_map
from tests.reference import crop_features


def _crops(data, n_per_folder=6):
    paths = []
    for sub in ("vehicles/GTI_Far", "vehicles/KITTI_extracted", "non-vehicles/GTI", "non-vehicles/Extras"):
        paths += sorted((data / sub).glob("*.png"))[:n_per_folder]
    return np.stack([cv2.imread(str(p)) for p in paths])


CONFIGS = [
    FeatureConfig(),
    FeatureConfig(color_space="LUV", orientations=12, spatial_size=16, hist_bins=16),
    FeatureConfig(color_space="HLS", hog_channels=(1,), spatial_size=0, hist_bins=0),
    FeatureConfig(color_space="RGB", hog_channels=(2, 0), spatial_size=8, hist_bins=64, cells_per_block=3),
    FeatureConfig(window_height=32),  # wide windows: the middle rows of the crops
    FeatureConfig(color_space="LUV", window_height=40, spatial_size=16, orientations=11),
]


def _rows(crops, config):
    """The crops cut to the config's window height (middle rows)."""
    top = (64 - config.win_h) // 2
    return np.ascontiguousarray(crops[:, top: top + config.win_h])


@pytest.mark.parametrize("config", CONFIGS, ids=lambda c: f"{c.color_space}-{c.orientations}-{c.spatial_size}")
def test_features_match_reference_on_training_crops(data, config):
    crops = _rows(_crops(data), config)
    fast = extract_features(crops, config)
    ref = np.stack([crop_features(c, config) for c in crops])
    assert fast.shape == (len(crops), config.n_features)
    np.testing.assert_allclose(fast, ref, rtol=0, atol=1e-6)


@settings(max_examples=25, deadline=None)
@given(arrays(np.uint8, st.tuples(st.integers(1, 4), st.just(64), st.just(64), st.just(3))),
       st.sampled_from(CONFIGS))
def test_features_match_reference_on_random_crops(crops, config):
    crops = _rows(crops, config)
    fast = extract_features(crops, config)
    ref = np.stack([crop_features(c, config) for c in crops])
    np.testing.assert_allclose(fast, ref, rtol=0, atol=1e-6)


def test_single_crop_and_empty_stack():
    rng = np.random.default_rng(1)
    crop = rng.integers(0, 256, (64, 64, 3), dtype=np.uint8)
    assert extract_features(crop).shape == (FeatureConfig().n_features,)
    assert extract_features(np.zeros((0, 64, 64, 3), np.uint8)).shape == (0, FeatureConfig().n_features)


@pytest.mark.parametrize("bad", [np.zeros((2, 64, 64, 3), np.float32), np.zeros((2, 32, 32, 3), np.uint8),
                                 np.zeros((2, 64, 64), np.uint8)])
def test_bad_crops_raise(bad):
    with pytest.raises(ValueError, match="crops must be"):
        extract_features(bad)


@settings(max_examples=40, deadline=None)
@given(st.integers(1, 40), st.integers(1, 40), st.sampled_from([2, 4, 8]), st.integers(0, 2 ** 32 - 1))
def test_spatial_map_is_cv2_resize_of_aligned_tiles(h_tiles, w_tiles, factor, seed):
    img = np.random.default_rng(seed).integers(0, 256, (h_tiles * factor, w_tiles * factor, 3), dtype=np.uint8)
    expected = cv2.resize(img, (w_tiles, h_tiles), interpolation=cv2.INTER_LINEAR)
    np.testing.assert_array_equal(spatial_map(img, factor), expected)


def test_feature_config_validation():
    with pytest.raises(ValueError, match="color_space"):
        FeatureConfig(color_space="XYZ")
    with pytest.raises(ValueError, match="hog_channels"):
        FeatureConfig(hog_channels=(0, 3))
    assert FeatureConfig(hog_channels="ALL").hog_channels == (0, 1, 2)
    with pytest.raises(ValueError, match="hist_bins"):
        FeatureConfig(hist_bins=30)
    cfg = FeatureConfig(color_space="LUV", hog_channels=(0,))
    assert FeatureConfig.from_dict(cfg.to_dict()) == cfg
    assert "window_height" not in cfg.to_dict()  # square configs keep their old dict
    wide = FeatureConfig(window_height=32)
    assert FeatureConfig.from_dict(wide.to_dict()) == wide and wide.blocks_y == 3 and wide.blocks_x == 7
    assert FeatureConfig(window_height=64) == FeatureConfig()
    with pytest.raises(ValueError, match="multiples"):
        FeatureConfig(window_height=36)
