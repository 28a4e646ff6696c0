"""Numba kernels for the colour-histogram and spatial features and the feature layout (HOG
kernels live in ``_hog_kernels``). Each runs on the calling thread over the stack it is given;
:func:`fastdet.features.extract_features` spreads chunks of a stack over threads."""
from __future__ import annotations

import numpy as np
from numba import njit

from .._numba import EXACT


@njit(**EXACT)
def color_hist_batch(images, shift, nbins, out):
    """Per-channel histograms of a stack of uint8 images.

    images: (N, H, W, C) uint8; value v of channel c falls in bin ``v >> shift``.
    out: (N, C * nbins) float64, overwritten; channel c's bins at [c*nbins, (c+1)*nbins).
    """
    n, h, w, c = images.shape
    for i in range(n):
        for k in range(c * nbins):
            out[i, k] = 0.0
        for y in range(h):
            for x in range(w):
                for ch in range(c):
                    out[i, ch * nbins + (images[i, y, x, ch] >> shift)] += 1.0


@njit(**EXACT)
def hog_to_features(hog, out):
    """Copy per-crop block maps into feature rows, channel-major.

    hog: (N, br, bc, nch, blk) float64, blk = cells_per_block**2 * orientations;
    out: (N, >= nch*br*bc*blk) float64: out[i, ((c*br + r)*bc + q)*blk + t] = hog[i, r, q, c, t].
    """
    n, br, bc, nch, blk = hog.shape
    for i in range(n):
        for c in range(nch):
            for r in range(br):
                for q in range(bc):
                    base = ((c * br + r) * bc + q) * blk
                    for t in range(blk):
                        out[i, base + t] = hog[i, r, q, c, t]


@njit(**EXACT)
def spatial_batch(images, factor, out, col0):
    """Spatial bins of a stack of crops into ``out[:, col0:]`` (row, column, channel order):
    the rounded mean of the 2x2 pixels at offsets ``factor/2 - 1`` and ``factor/2`` of every
    ``factor`` x ``factor`` tile (:func:`fastdet.features.spatial_map`), or the pixel itself
    for factor 1.

    images: (N, H, W, C) uint8; out: (N, F) float64.
    """
    n, h, w, c = images.shape
    sh, sw = h // factor, w // factor
    o = factor // 2 - 1
    for i in range(n):
        k = col0
        for y in range(sh):
            for x in range(sw):
                for ch in range(c):
                    if factor == 1:
                        out[i, k] = images[i, y, x, ch]
                    else:
                        y0 = y * factor + o
                        x0 = x * factor + o
                        s = (np.int32(images[i, y0, x0, ch]) + np.int32(images[i, y0 + 1, x0, ch])
                             + np.int32(images[i, y0, x0 + 1, ch]) + np.int32(images[i, y0 + 1, x0 + 1, ch]))
                        out[i, k] = (s + 2) >> 2
                    k += 1


# --------------------------------------------------------------------------------------
# what the package calls, compiled ahead of time (fastdet._numba.ensure_compiled)
# --------------------------------------------------------------------------------------
#: argument types of every call the package makes to each kernel: exactly the types of the
#: calls (C-contiguous arrays, Python ints as int64), so a call finds its machine code
SIGNATURES: dict[str, tuple[str, ...]] = {
    "color_hist_batch": ("uint8[:, :, :, ::1], int64, int64, float64[:, ::1]",),
    "hog_to_features": ("float64[:, :, :, :, ::1], float64[:, ::1]",),
    "spatial_batch": ("uint8[:, :, :, ::1], int64, float64[:, ::1], int64",),
}
#: CPU seconds to compile each, reference machine (docs/benchmarks.md)
COMPILE_SECONDS: dict[str, float] = {"color_hist_batch": 0.35, "hog_to_features": 0.45, "spatial_batch": 0.55}
