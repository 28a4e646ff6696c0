"""Numba kernels for the colour-histogram features (HOG kernels live in ``_hog_kernels``)."""
from __future__ import annotations

import numpy as np
from numba import njit, prange


@njit(cache=True, nogil=True, parallel=True)
def color_hist_batch(images, shift, nbins, out):
    """Per-channel histograms of a stack of uint8 images.

    images: (N, H, W, C) uint8; value v of channel c falls in bin ``v >> shift``.
    out: (N, C * nbins) float64, overwritten; channel c's bins at [c*nbins, (c+1)*nbins).
    """
    n, h, w, c = images.shape
    for i in prange(n):
        for k in range(c * nbins):
            out[i, k] = 0.0
        for y in range(h):
            for x in range(w):
                for ch in range(c):
                    out[i, ch * nbins + (images[i, y, x, ch] >> shift)] += 1.0
