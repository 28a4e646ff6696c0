"""fastdet's HOG equals scikit-image's: shapes, dtypes and values (|diff| <= 1e-6; in
practice the kernels reproduce skimage's arithmetic and the difference is 0).

References: ``skimage.feature.hog`` for ``hog``; per-channel ``skimage.feature.hog`` stacked
on axis 2 for ``hog_channels``; ``hog_channels`` per image for ``hog_channels_batch``.
"""
from __future__ import annotations

import cv2
import numba
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import fastdet
from fastdet.features._hog import hog_channels_batch
from tests.reference import sk_channels

skimage_feature = pytest.importorskip("skimage.feature")
sk_hog = skimage_feature.hog

TOL = 1e-6
NORMS = ["L1", "L1-sqrt", "L2", "L2-Hys"]


def assert_same(ours, ref):
    """Same shape and dtype, values within TOL (NaN where skimage has NaN)."""
    ours = np.asarray(ours)
    ref = np.asarray(ref)
    assert ours.shape == ref.shape
    assert ours.dtype == ref.dtype
    np.testing.assert_allclose(ours, ref, rtol=0, atol=TOL, equal_nan=True)


def hc_kwargs(orientations=9, ppc=8, cpb=2, block_norm="L2-Hys", transform_sqrt=False):
    """The same settings as hog_channels arguments and as skimage arguments."""
    ours = dict(orientations=orientations, pixels_per_cell=ppc, cells_per_block=cpb,
                block_norm=block_norm, transform_sqrt=transform_sqrt)
    ppc2 = ppc if isinstance(ppc, tuple) else (ppc, ppc)
    cpb2 = cpb if isinstance(cpb, tuple) else (cpb, cpb)
    ref = dict(orientations=orientations, pixels_per_cell=ppc2, cells_per_block=cpb2,
               block_norm=block_norm, transform_sqrt=transform_sqrt)
    return ours, ref


def _crops(data, per_folder=6):
    paths = []
    for sub in ("vehicles/GTI_Far", "vehicles/GTI_Left", "vehicles/KITTI_extracted",
                "non-vehicles/GTI", "non-vehicles/Extras"):
        paths += sorted((data / sub).glob("*.png"))[:: 97][:per_folder]
    assert len(paths) >= 25
    return np.stack([cv2.imread(str(p)) for p in paths])


# --------------------------------------------------------------------------------------
# real images
# --------------------------------------------------------------------------------------
def test_public_names_are_exported():
    assert fastdet.hog is fastdet.features._hog.hog
    assert fastdet.hog_channels is fastdet.features._hog.hog_channels
    assert fastdet.hog_channels_batch is hog_channels_batch


def test_grey_test_images(test_images):
    for path in test_images:
        grey = cv2.cvtColor(cv2.imread(str(path)), cv2.COLOR_BGR2GRAY)
        assert_same(fastdet.hog(grey), sk_hog(grey))


@pytest.mark.parametrize("block_norm", NORMS)
def test_grey_test_image_block_norms(test_images, block_norm):
    grey = cv2.cvtColor(cv2.imread(str(test_images[0])), cv2.COLOR_BGR2GRAY)[300:556]
    kw = dict(orientations=11, pixels_per_cell=(8, 8), cells_per_block=(2, 2),
              block_norm=block_norm, feature_vector=False)
    assert_same(fastdet.hog(grey, **kw), sk_hog(grey, **kw))


@pytest.mark.slow
def test_luv_per_channel_test_images(test_images):
    ours_kw, ref_kw = hc_kwargs()
    for path in test_images:
        luv = cv2.cvtColor(cv2.imread(str(path))[::2, ::2], cv2.COLOR_BGR2LUV)  # a quarter of skimage's time
        out = fastdet.hog_channels(luv, **ours_kw)
        assert out.flags.c_contiguous and out.dtype == np.float64
        assert_same(out, sk_channels(luv, **ref_kw))


def test_luv_search_band_hot_path(test_images):
    """The detector's band: a 1280x256 ROI, threaded kernel at 1 and 2 threads."""
    luv = cv2.cvtColor(cv2.imread(str(test_images[0])), cv2.COLOR_BGR2LUV)[400:656]
    ours_kw, ref_kw = hc_kwargs()
    ref = sk_channels(luv, **ref_kw)
    before = numba.get_num_threads()
    try:
        for threads in sorted({1, min(2, numba.config.NUMBA_NUM_THREADS)}):
            numba.set_num_threads(threads)
            assert_same(fastdet.hog_channels(luv, **ours_kw), ref)
    finally:
        numba.set_num_threads(before)


def test_multichannel_test_images(test_images):
    for path in test_images:
        bgr = cv2.imread(str(path))[::2, ::2]  # halves skimage's time, same code paths
        assert_same(fastdet.hog(bgr, channel_axis=-1), sk_hog(bgr, channel_axis=-1))


def test_training_crops(data):
    crops = _crops(data)
    ours_kw, ref_kw = hc_kwargs()
    batch = hog_channels_batch(crops, **{k: v for k, v in ours_kw.items() if k != "transform_sqrt"})
    for i, crop in enumerate(crops):
        ref = sk_channels(crop, **ref_kw)
        assert_same(fastdet.hog_channels(crop, **ours_kw), ref)
        assert_same(batch[i], ref)
        grey = cv2.cvtColor(crop, cv2.COLOR_BGR2GRAY)
        assert_same(fastdet.hog(grey), sk_hog(grey))
        assert_same(fastdet.hog(crop, channel_axis=-1), sk_hog(crop, channel_axis=-1))


@pytest.mark.parametrize("orientations,cpb", [(12, 2), (9, 3), (6, 1)])
def test_training_crops_batch_settings(data, orientations, cpb):
    crops = cv2.cvtColor(_crops(data).reshape(-1, 64, 3), cv2.COLOR_BGR2YCrCb).reshape(-1, 64, 64, 3)
    batch = hog_channels_batch(crops, orientations, 8, cpb, channels=[2, 0])
    _, ref_kw = hc_kwargs(orientations, 8, cpb)
    for i, crop in enumerate(crops):
        assert_same(batch[i], sk_channels(crop, channels=[2, 0], **ref_kw))


# --------------------------------------------------------------------------------------
# random images (hypothesis)
# --------------------------------------------------------------------------------------
@st.composite
def hog_cases(draw, multichannel=None):
    ppc = (draw(st.integers(1, 9)), draw(st.integers(1, 9)))
    cpb = (draw(st.integers(1, 4)), draw(st.integers(1, 4)))
    rows = draw(st.integers(max(8, ppc[0] * cpb[0]), 70))
    cols = draw(st.integers(max(8, ppc[1] * cpb[1]), 70))
    if multichannel is None:
        multichannel = draw(st.booleans())
    shape = (rows, cols, 3) if multichannel else (rows, cols)
    kind = draw(st.sampled_from(["uint8", "uint8-low", "float64", "float32", "float-int"]))
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    if kind == "uint8":
        image = rng.integers(0, 256, shape, dtype=np.uint8)
    elif kind == "uint8-low":  # many zero gradients and channel ties
        image = rng.integers(0, draw(st.integers(1, 4)), shape, dtype=np.uint8)
    elif kind == "float-int":  # integer gradients as floats: exact 45/90 degree angles
        image = rng.integers(0, 4, shape).astype(np.float64)
    else:
        image = rng.random(shape).astype(kind) * draw(st.sampled_from([1.0, 255.0]))
    params = dict(orientations=draw(st.integers(1, 13)), pixels_per_cell=ppc,
                  cells_per_block=cpb, block_norm=draw(st.sampled_from(NORMS)),
                  transform_sqrt=draw(st.booleans()))
    return image, params


@settings(max_examples=150, deadline=None)
@given(hog_cases())
def test_hog_matches_skimage_random(case):
    image, params = case
    axis = -1 if image.ndim == 3 else None
    ours = fastdet.hog(image, feature_vector=False, channel_axis=axis, **params)
    assert_same(ours, sk_hog(image, feature_vector=False, channel_axis=axis, **params))


@settings(max_examples=60, deadline=None)
@given(hog_cases(multichannel=True), st.sampled_from([None, [0], [2, 1], [1, 0, 2]]))
def test_hog_channels_matches_skimage_random(case, channels):
    image, params = case
    ours = fastdet.hog_channels(image, params["orientations"], params["pixels_per_cell"],
                                params["cells_per_block"], params["block_norm"],
                                params["transform_sqrt"], channels=channels)
    assert ours.dtype == np.float64 and ours.flags.c_contiguous
    ref = sk_channels(image, channels=channels, **params)
    np.testing.assert_allclose(ours, ref, rtol=0, atol=TOL)
    assert ours.shape == ref.shape


@settings(max_examples=25, deadline=None)
@given(st.integers(1, 5), st.integers(16, 40), st.integers(16, 40), st.integers(0, 2**32 - 1),
       st.sampled_from(NORMS), st.sampled_from([None, [1], [2, 0]]))
def test_batch_equals_per_image_random(n, rows, cols, seed, block_norm, channels):
    images = np.random.default_rng(seed).integers(0, 256, (n, rows, cols, 3), dtype=np.uint8)
    batch = hog_channels_batch(images, 9, 8, 2, block_norm, channels=channels)
    assert batch.flags.c_contiguous and batch.dtype == np.float64
    for i in range(n):
        single = fastdet.hog_channels(images[i], 9, 8, 2, block_norm, channels=channels)
        np.testing.assert_array_equal(batch[i], single)


# --------------------------------------------------------------------------------------
# edge cases
# --------------------------------------------------------------------------------------
@pytest.mark.parametrize("value", [0, 7, 255])
@pytest.mark.parametrize("block_norm", NORMS)
def test_constant_image(value, block_norm):
    image = np.full((40, 48), value, dtype=np.uint8)
    assert_same(fastdet.hog(image, block_norm=block_norm), sk_hog(image, block_norm=block_norm))
    rgb = np.full((40, 48, 3), value, dtype=np.uint8)
    assert_same(fastdet.hog(rgb, block_norm=block_norm, channel_axis=-1),
                sk_hog(rgb, block_norm=block_norm, channel_axis=-1))


@pytest.mark.parametrize("shape,ppc,cpb", [
    ((24, 24), (8, 8), (3, 3)),    # exactly one block
    ((16, 16), (8, 8), (2, 2)),    # exactly one block, pipeline settings
    ((31, 45), (8, 8), (3, 3)),    # not a multiple of the cell size
    ((70, 33), (7, 5), (2, 3)),    # non-square cells and blocks
    ((9, 9), (1, 1), (1, 1)),      # one-pixel cells
    ((64, 64), (16, 16), (4, 4)),  # one big block of 16 cells (> 128 values: pairwise split)
])
def test_shapes(shape, ppc, cpb):
    image = np.random.default_rng(sum(shape)).integers(0, 256, shape, dtype=np.uint8)
    kw = dict(pixels_per_cell=ppc, cells_per_block=cpb, feature_vector=False)
    assert_same(fastdet.hog(image, **kw), sk_hog(image, **kw))
    assert_same(fastdet.hog(image.astype(np.float32), **kw), sk_hog(image.astype(np.float32), **kw))


@pytest.mark.parametrize("dtype", [np.uint8, np.uint16, np.int16, np.int64, np.float16,
                                   np.float32, np.float64, bool])
def test_dtypes(dtype):
    rng = np.random.default_rng(3)
    image = (rng.random((37, 41, 3)) * (1 if dtype is bool else 200)).astype(dtype)
    if np.issubdtype(dtype, np.signedinteger):
        image -= 100
    assert_same(fastdet.hog(image, channel_axis=-1), sk_hog(image, channel_axis=-1))
    assert_same(fastdet.hog(image[:, :, 1]), sk_hog(image[:, :, 1]))
    np.testing.assert_allclose(fastdet.hog_channels(image), sk_channels(image, cells_per_block=(2, 2)),
                               rtol=0, atol=TOL)


def test_multichannel_pick_uses_float_magnitudes():
    """g = (1, 189) and (99, 161) have the same g_row² + g_col² but np.hypot rounds the
    second one ulp higher: skimage picks channel 1, so must we."""
    image = np.zeros((16, 16, 3), dtype=np.uint8)
    image[2, 1, 0], image[1, 2, 0] = 1, 189
    image[2, 1, 1], image[1, 2, 1] = 99, 161
    assert np.hypot(99.0, 161.0) > np.hypot(1.0, 189.0)
    kw = dict(pixels_per_cell=(8, 8), cells_per_block=(1, 1), block_norm="L1", channel_axis=-1)
    assert_same(fastdet.hog(image, **kw), sk_hog(image, **kw))
    assert_same(fastdet.hog(image.astype(np.float64), **kw), sk_hog(image.astype(np.float64), **kw))


@pytest.mark.parametrize("axis", [0, 1, 2, -3])
def test_channel_axis(axis):
    image = np.random.default_rng(4).integers(0, 256, (30, 30, 30), dtype=np.uint8)
    assert_same(fastdet.hog(image, channel_axis=axis), sk_hog(image, channel_axis=axis))


def test_nan_propagates_like_skimage():
    image = np.random.default_rng(5).random((32, 32))
    image[9, 17] = np.nan
    for norm in NORMS:
        assert_same(fastdet.hog(image, block_norm=norm), sk_hog(image, block_norm=norm))


def test_hog_channels_two_d_and_channel_order():
    rng = np.random.default_rng(6)
    image = rng.integers(0, 256, (48, 56, 4), dtype=np.uint8)
    out = fastdet.hog_channels(image, channels=[3, 1])
    assert out.shape == (5, 6, 2, 2, 2, 9)
    assert_same(out, sk_channels(image, channels=[3, 1], cells_per_block=(2, 2)))
    assert_same(fastdet.hog_channels(image[:, :, 2]), sk_channels(image[:, :, 2], cells_per_block=(2, 2)))
    np.testing.assert_array_equal(fastdet.hog_channels(image, channels=[-1]),
                                  fastdet.hog_channels(image, channels=[3]))


def test_hog_channels_non_contiguous_input():
    frame = np.random.default_rng(7).integers(0, 256, (90, 200, 3), dtype=np.uint8)
    view = frame[10:74, 17:150:2]
    assert_same(fastdet.hog_channels(view), sk_channels(np.ascontiguousarray(view), cells_per_block=(2, 2)))


def test_batch_fallbacks():
    images = np.random.default_rng(8).random((3, 24, 32, 3))
    batch = hog_channels_batch(images)
    for i in range(3):
        np.testing.assert_array_equal(batch[i], fastdet.hog_channels(images[i]))
    grey = (images[..., 0] * 255).astype(np.uint8)
    np.testing.assert_array_equal(hog_channels_batch(grey)[1], fastdet.hog_channels(grey[1]))
    empty = hog_channels_batch(np.zeros((0, 64, 64, 3), np.uint8))
    assert empty.shape == (0, 7, 7, 3, 2, 2, 9)


# --------------------------------------------------------------------------------------
# visualisation
# --------------------------------------------------------------------------------------
@pytest.mark.parametrize("shape,ppc,orientations,dtype,axis", [
    ((64, 80), (8, 8), 9, np.uint8, None),
    ((61, 47), (6, 10), 7, np.float32, None),
    ((50, 50, 3), (5, 5), 12, np.uint8, -1),
    ((40, 40), (16, 16), 4, np.float64, None),
    ((12, 12), (2, 2), 9, np.uint8, None),
    ((15, 15), (3, 3), 5, np.float64, None),
])
def test_visualize(shape, ppc, orientations, dtype, axis):
    image = (np.random.default_rng(9).random(shape) * 255).astype(dtype)
    kw = dict(orientations=orientations, pixels_per_cell=ppc, cells_per_block=(1, 1),
              visualize=True, channel_axis=axis)
    feats, picture = fastdet.hog(image, **kw)
    ref_feats, ref_picture = sk_hog(image, **kw)
    assert_same(feats, ref_feats)
    assert_same(picture, ref_picture)


def test_visualize_test_image(test_images):
    grey = cv2.cvtColor(cv2.imread(str(test_images[1])), cv2.COLOR_BGR2GRAY)
    _, picture = fastdet.hog(grey, visualize=True)
    _, ref_picture = sk_hog(grey, visualize=True)
    assert_same(picture, ref_picture)


# --------------------------------------------------------------------------------------
# bad input
# --------------------------------------------------------------------------------------
IMG = np.zeros((32, 32), dtype=np.uint8)
RGB = np.zeros((32, 32, 3), dtype=np.uint8)


@pytest.mark.parametrize("args,kwargs,name", [
    ((np.zeros((4, 32, 32, 3)),), {}, "image"),           # wrong ndim
    ((RGB,), {}, "image"),                                 # 3-D without channel_axis
    ((IMG,), {"channel_axis": -1}, "image"),               # 2-D with channel_axis
    ((np.zeros(32),), {}, "image"),                        # 1-D
    ((np.zeros((0, 32)),), {}, "image"),                   # empty
    ((np.zeros((10, 10)),), {}, "image"),                  # smaller than a block
    ((np.zeros((40, 20)),), {"pixels_per_cell": (8, 8)}, "image"),
    ((np.zeros((32, 32), complex),), {}, "image"),         # complex
    ((np.array([["a"] * 32] * 32),), {}, "image"),         # strings
    ((IMG - 1.0,), {"transform_sqrt": True}, "transform_sqrt"),
    ((IMG,), {"block_norm": "L3"}, "block_norm"),
    ((IMG,), {"block_norm": None}, "block_norm"),
    ((RGB,), {"channel_axis": 3}, "channel_axis"),
    ((RGB,), {"channel_axis": -4}, "channel_axis"),
    ((RGB,), {"channel_axis": 1.5}, "channel_axis"),
    ((IMG,), {"orientations": 0}, "orientations"),
    ((IMG,), {"orientations": 2.5}, "orientations"),
    ((IMG,), {"pixels_per_cell": (0, 8)}, "pixels_per_cell"),
    ((IMG,), {"pixels_per_cell": (8, 8, 8)}, "pixels_per_cell"),
    ((IMG,), {"cells_per_block": (-1, 2)}, "cells_per_block"),
])
def test_hog_bad_input(args, kwargs, name):
    with pytest.raises(ValueError, match=name):
        fastdet.hog(*args, **kwargs)


@pytest.mark.parametrize("args,kwargs,name", [
    ((np.zeros((2, 32, 32, 3)),), {}, "image"),
    ((np.zeros((0, 32, 3)),), {}, "image"),
    ((np.zeros((8, 8, 3)),), {}, "image"),
    ((RGB,), {"channels": [3]}, "channels"),
    ((RGB,), {"channels": []}, "channels"),
    ((RGB,), {"channels": ["a"]}, "channels"),
    ((RGB,), {"block_norm": "l2"}, "block_norm"),
    ((RGB - 1.0,), {"transform_sqrt": True}, "transform_sqrt"),
])
def test_hog_channels_bad_input(args, kwargs, name):
    with pytest.raises(ValueError, match=name):
        fastdet.hog_channels(*args, **kwargs)


@pytest.mark.parametrize("images,kwargs,name", [
    (np.zeros((2, 32)), {}, "images"),
    (np.zeros((2, 8, 8, 3), np.uint8), {}, "images"),
    (np.zeros((2, 0, 8, 3), np.uint8), {}, "images"),
    (np.zeros((2, 32, 32, 3), np.uint8), {"channels": [5]}, "channels"),
    (np.zeros((2, 32, 32, 3), np.uint8), {"orientations": 0}, "orientations"),
])
def test_batch_bad_input(images, kwargs, name):
    with pytest.raises(ValueError, match=name):
        hog_channels_batch(images, **kwargs)
