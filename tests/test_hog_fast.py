"""``hog_channels(..., exact=False)`` (the detector's block map) equals the exact path (skimage
to the last bit, tests/test_hog.py) to an ulp or two: random uint8 images, every block norm,
block and cell shapes, channel selections, one and two threads; real frames."""
from __future__ import annotations

import cv2
import numba
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fastdet.features import hog_channels

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
