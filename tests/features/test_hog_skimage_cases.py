"""``fastdet.hog`` as a drop-in for ``skimage.feature.hog`` (issue 14, item 8): the kinds of
case scikit-image's own ``test_hog.py`` checks, written here with expectations worked out by
hand (not copied, not compared with skimage: ``tests/features/test_hog.py`` does that)."""
from __future__ import annotations

import numpy as np
import pytest

from fastdet import hog


def test_small_image_message_starts_with_skimages_wording():
    with pytest.raises(ValueError, match="image is too small given") as exc:
        hog(np.zeros((23, 23)), pixels_per_cell=(8, 8), cells_per_block=(3, 3))
    assert "(23, 23)" in str(exc.value) and "24 rows" in str(exc.value)  # our detail is kept


def test_output_size():
    img = np.random.default_rng(0).random((256, 512))
    out = hog(img, orientations=9, pixels_per_cell=(8, 8), cells_per_block=(1, 1), block_norm="L1")
    assert out.shape == (9 * (256 // 8) * (512 // 8),)
    out5 = hog(img, orientations=9, pixels_per_cell=(8, 8), cells_per_block=(2, 3), feature_vector=False)
    assert out5.shape == (256 // 8 - 1, 512 // 8 - 2, 2, 3, 9)


@pytest.mark.parametrize("dtype", [np.uint8, np.float32, np.float64])
def test_ramps_fill_one_orientation_bin(dtype):
    """A ramp along the columns has gradients at 0 degrees: bin 0; along the rows, 90
    degrees: bin 4 of 9 (80 <= 90 < 100). Every cell's whole histogram is in that bin."""
    ramp = np.tile(np.arange(32, dtype=np.float64) * 4, (32, 1))
    for img, b in ((ramp, 0), (ramp.T, 4)):
        out = hog(img.astype(dtype), orientations=9, pixels_per_cell=(8, 8), cells_per_block=(1, 1),
                  block_norm="L1", feature_vector=False)
        hist = out[:, :, 0, 0, :]  # (4, 4, 9)
        assert np.allclose(hist[..., b], 1.0, atol=1e-4)
        assert np.allclose(np.delete(hist, b, axis=-1), 0.0)


def test_ramps_equal_across_dtypes():
    ramp = np.tile(np.arange(40) * 3, (24, 1))
    ref = hog(ramp.astype(np.float64), pixels_per_cell=(8, 8), cells_per_block=(2, 2))
    for dtype in (np.uint8, np.int32, np.float32):
        assert np.allclose(hog(ramp.astype(dtype), pixels_per_cell=(8, 8), cells_per_block=(2, 2)), ref, atol=1e-6)


def test_disc_uses_every_orientation():
    """The gradients of a round blob point every way: each of the 9 bins gets a share
    (about 1/9 each; a smooth blob, as a binary disc's central differences only take
    multiples of 45 degrees)."""
    yy, xx = np.mgrid[:96, :96]
    disc = 255 * np.exp(-((yy - 47.5) ** 2 + (xx - 47.5) ** 2) / (2 * 20.0 ** 2))
    out = hog(disc, orientations=9, pixels_per_cell=(96, 96), cells_per_block=(1, 1), block_norm="L1")
    assert out.shape == (9,)
    assert np.all(out > 0.5 / 9) and abs(out.sum() - 1) < 1e-4


@pytest.mark.parametrize("block_norm, expected", [("L1", 1.0), ("L2", 1.0), ("L2-Hys", 1.0), ("L1-sqrt", 1.0)])
def test_one_pixel_gradient_by_hand(block_norm, expected):
    """A 3x3 image, one 3x3 cell: only the centre pixel has gradients (the border's are
    zeroed). ``img[1, 2] = 2`` gives g_col = 2, g_row = 0: angle 0, bin 0, magnitude 2, the
    cell value 2/9; any block norm of a single non-zero value is (about) 1."""
    img = np.zeros((3, 3))
    img[1, 2] = 2
    out = hog(img, orientations=9, pixels_per_cell=(3, 3), cells_per_block=(1, 1), block_norm=block_norm)
    want = np.zeros(9)
    want[0] = expected
    assert np.allclose(out, want, atol=1e-3)
    # g_row = g_col = 1: 45 degrees, bin 2 (40 <= 45 < 60)
    img = np.zeros((3, 3))
    img[2, 1] = img[1, 2] = 1
    out = hog(img, orientations=9, pixels_per_cell=(3, 3), cells_per_block=(1, 1), block_norm=block_norm)
    assert np.argmax(out) == 2 and np.allclose(np.delete(out, 2), 0)


def test_visualization_has_the_image_shape():
    img = np.random.default_rng(1).random((150, 200))
    _, picture = hog(img, pixels_per_cell=(8, 8), cells_per_block=(1, 1), visualize=True)
    assert picture.shape == img.shape


def test_vertical_edge_draws_a_vertical_line():
    """skimage draws each bin as a line perpendicular to its gradient: a vertical edge
    (gradient at 0 degrees) draws vertical strokes."""
    img = np.zeros((32, 32))
    img[:, 16:] = 1
    _, picture = hog(img, orientations=9, pixels_per_cell=(16, 16), cells_per_block=(1, 1), visualize=True)
    cell = picture[:16, 16:32] + picture[:16, :16]
    cols = cell.sum(axis=0)
    rows = cell.sum(axis=1)
    assert cols.max() > 4 * np.median(cols)  # energy concentrated in a column ...
    assert rows.max() < 4 * max(np.median(rows), 1e-12) or np.count_nonzero(rows) > 8  # ... spread along rows


def test_multichannel_equals_its_only_non_zero_channel():
    grey = np.random.default_rng(2).random((48, 64))
    for c in range(3):
        rgb = np.zeros((48, 64, 3))
        rgb[:, :, c] = grey
        assert np.allclose(hog(rgb, channel_axis=-1), hog(grey))
    assert np.allclose(hog(np.moveaxis(rgb, -1, 0), channel_axis=0), hog(grey))


@pytest.mark.parametrize("dtype, out_dtype", [(np.float32, np.float32), (np.float64, np.float64),
                                              (np.uint8, np.float64)])
def test_output_dtype(dtype, out_dtype):
    img = (np.random.default_rng(3).random((32, 32)) * 200).astype(dtype)
    assert hog(img, pixels_per_cell=(8, 8), cells_per_block=(2, 2)).dtype == out_dtype


@pytest.mark.parametrize("kwargs, match", [
    ({"block_norm": "Linf"}, "block_norm"),
    ({"transform_sqrt": True, "_negative": True}, "negative"),
])
def test_bad_arguments(kwargs, match):
    img = np.ones((32, 32))
    if kwargs.pop("_negative", False):
        img[0, 0] = -1
    with pytest.raises(ValueError, match=match):
        hog(img, pixels_per_cell=(8, 8), cells_per_block=(2, 2), **kwargs)


def test_wrong_dimensions():
    with pytest.raises(ValueError):
        hog(np.zeros((16, 16, 3, 2)), channel_axis=-1)
    with pytest.raises(ValueError):
        hog(np.zeros((16, 16, 3)))  # a 3-D image needs channel_axis
