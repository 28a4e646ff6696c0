"""``hog_channels(..., exact=False)`` (the detector's block map) equals the exact path (skimage
to the last bit, tests/features/test_hog.py) to an ulp or two: random uint8 images, every block norm,
block and cell shapes, channel selections, one and two threads; real frames. The uint8 cell
histograms (both kernels) equal the float path's (NumPy's hypot / arctan2, skimage's float32
sums) bit for bit."""
from __future__ import annotations

import cv2
import numba
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fastdet._numba import split_range
from fastdet.features import _hog, hog_channels
from fastdet.features import _hog_kernels as _k

NORMS = ["L1", "L1-sqrt", "L2", "L2-Hys"]


def _close(fast, exact):
    assert fast.shape == exact.shape and fast.dtype == exact.dtype == np.float64
    np.testing.assert_allclose(fast, exact, rtol=1e-13, atol=1e-15)


@settings(max_examples=80, deadline=None)
@given(st.integers(1, 6), st.integers(1, 12), st.integers(1, 4), st.sampled_from(NORMS),
       st.integers(1, 18), st.integers(4, 10), st.integers(1, 3), st.booleans(), st.integers(0, 2**32 - 1))
def test_fast_blocks_equal_exact_ones(extra_r, extra_c, n_ch, norm, orientations, ppc, cpb, flat, seed):
    rng = np.random.default_rng(seed)
    h, w = cpb * ppc + extra_r, cpb * ppc + extra_c * 3
    img = rng.integers(0, 256, (h, w, n_ch), dtype=np.uint8)
    if flat:  # flat patches: zero gradients, blocks of zeros (eps decides)
        img[: h // 2] = 128
    chans = list(rng.permutation(n_ch)[: rng.integers(1, n_ch + 1)])
    kw = {"orientations": orientations, "pixels_per_cell": ppc, "cells_per_block": cpb, "block_norm": norm,
          "channels": chans}
    _close(hog_channels(img, exact=False, **kw), hog_channels(img, **kw))


@pytest.mark.parametrize("threads", [1, 2])
def test_fast_blocks_on_a_band_at_one_and_two_threads(test_images, threads):
    img = cv2.cvtColor(cv2.imread(str(test_images[0])), cv2.COLOR_BGR2YCrCb)[400:656]
    before = numba.get_num_threads()
    numba.set_num_threads(min(threads, numba.config.NUMBA_NUM_THREADS))
    try:  # 1280x256x3 samples: the threaded kernel at 2 threads
        for kw in ({"orientations": 16, "cells_per_block": 2},
                   {"orientations": 9, "cells_per_block": 3, "channels": [2, 0]}):
            _close(hog_channels(img, exact=False, **kw), hog_channels(img, **kw))
    finally:
        numba.set_num_threads(before)


def test_other_inputs_take_the_exact_path():
    img = np.random.default_rng(0).random((40, 40, 3))
    np.testing.assert_array_equal(hog_channels(img, exact=False), hog_channels(img))
    u8 = (img * 255).astype(np.uint8)
    np.testing.assert_array_equal(hog_channels(u8, transform_sqrt=True, exact=False),
                                  hog_channels(u8, transform_sqrt=True))


# --------------------------------------------------------------------------------------
# the cell histograms themselves, bit for bit: the uint8 kernels (planar de-interleave,
# LUT binning, float32 sums) against the float path (NumPy's hypot / arctan2, exactly
# skimage's steps)
# --------------------------------------------------------------------------------------
def _float_hist(img, chans, ppc, orientations):
    """(n_cells_row, n_ch, n_cells_col, n_or) cell histograms by NumPy's float steps."""
    n_cells, n_blocks = _hog._geometry(img.shape[:2], ppc, (1, 1))
    ht, _ = _hog._blocks_float(img.astype(np.float64), chans, False, ppc, (1, 1), orientations,
                               _k.NORM_L2, n_cells, n_blocks)
    return ht


def _fast_hist(img, chans, ppc, orientations, parallel):
    """The uint8 kernel's cell histograms (the detector's and the exact path's), all cell rows
    at once or cut in two ranges run on two threads at once."""
    bin_lut, mag_lut = _hog._luts(orientations)
    n_cells, n_blocks = _hog._geometry(img.shape[:2], ppc, (1, 1))
    ht = np.full((n_cells[0], len(chans), n_cells[1], orientations), np.nan)
    split_range(lambda lo, hi: _k.cell_hists_u8(img, chans, False, lo, hi, ppc[0], ppc[1], bin_lut, mag_lut, ht),
                n_cells[0], 2 if parallel else 1)
    return ht


@settings(max_examples=120, deadline=None)
@given(st.integers(1, 6), st.integers(1, 9), st.integers(1, 9), st.integers(0, 20), st.integers(0, 20),
       st.sampled_from([1, 2, 9, 16]), st.sampled_from(["full", "low", "flat"]), st.booleans(),
       st.integers(0, 2**32 - 1))
def test_cell_histograms_equal_the_float_path_bit_for_bit(n_ch, p_row, p_col, extra_r, extra_c, orientations,
                                                           kind, parallel, seed):
    """Every channel count (1-4: constant-stride de-interleave, 5-6: the generic loop), cell
    shapes down to 1x1 (every pixel on an image edge), images whose width is a whole number
    of cells (the last column's g_col = 0 falls inside a cell) or not, channel subsets in any
    order, one and several threads."""
    rng = np.random.default_rng(seed)
    h, w = p_row + extra_r, p_col + extra_c
    high = {"full": 256, "low": 3, "flat": 1}[kind]
    img = rng.integers(0, high, (h, w, n_ch), dtype=np.uint8)
    chans = np.asarray(rng.permutation(n_ch)[: rng.integers(1, n_ch + 1)], dtype=np.int64)
    ref = _float_hist(img, chans, (p_row, p_col), orientations)
    np.testing.assert_array_equal(_fast_hist(img, chans, (p_row, p_col), orientations, parallel), ref)
    bin_lut, mag_lut = _hog._luts(orientations)
    hist = np.full(ref.shape, np.nan)
    # both implementations, whatever the width (the kernels pick one by PLANES_MIN_CELLS)
    _k._cell_rows_planes(img, chans, 0, ref.shape[0], p_row, p_col, bin_lut, mag_lut, hist)
    np.testing.assert_array_equal(hist, ref)
    hist[...] = np.nan
    for ci in range(ref.shape[0]):
        _k._cell_row_interleaved(img, chans, ci, p_row, p_col, bin_lut, mag_lut, hist)
    np.testing.assert_array_equal(hist, ref)


def test_cell_histograms_of_the_detector_bands_bit_for_bit(test_images):
    """Real frames: YCrCb bands as the detector sees them (wide: the de-interleaved kernel;
    narrow: the interleaved one), 16 and 9 orientations."""
    frame = cv2.cvtColor(cv2.imread(str(test_images[0])), cv2.COLOR_BGR2YCrCb)
    assert 640 // 8 >= _k.PLANES_MIN_CELLS > 300 // 8
    for y0, y1, x1 in ((400, 496, 1280), (380, 480, 1277), (500, 720, 640), (400, 464, 300)):
        img = np.ascontiguousarray(frame[y0:y1, :x1])
        chans = np.arange(3, dtype=np.int64)
        for orientations in (16, 9):
            ref = _float_hist(img, chans, (8, 8), orientations)
            for parallel in (False, True):
                np.testing.assert_array_equal(_fast_hist(img, chans, (8, 8), orientations, parallel), ref)


@pytest.mark.parametrize("n_ch", [1, 2, 3, 4, 5, 7])
def test_planar_rows(n_ch):
    img = np.random.default_rng(n_ch).integers(0, 256, (9, 37, n_ch), dtype=np.uint8)
    buf = np.zeros((n_ch, 4, 37), dtype=np.uint8)
    _k._planar_rows(img, 3, 7, buf)
    np.testing.assert_array_equal(buf, img[3:7].transpose(2, 0, 1))
