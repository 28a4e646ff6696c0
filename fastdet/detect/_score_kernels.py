"""Numba kernels: the decision value of every window position of a band, at once.

A window's score is a sum of three correlations with the folded linear weights (see
DESIGN.md, "score all windows at once"): its 7x7 blocks of the band's HOG block map, its
crop of the band's spatial-bin map, and the window sum of the per-pixel histogram-weight
map (four look-ups in an integral image). The innermost loops run over contiguous rows.
"""
from __future__ import annotations

from numba import njit, prange

from .._numba import EXACT, REASSOC, REASSOC_INLINE, REASSOC_PARALLEL


# fastmath: only "reassoc" and "contract", so LLVM may vectorise the dot products (split
# them into SIMD lanes and fuse multiply-adds). That changes the rounding of a sum of ~10k
# products by ~1e-13, far inside the 1e-6 the exactness tests demand; no nan/inf assumptions.
# Measured on a 1280x720 frame: 6.2 → 4.4 ms of scoring at 2 threads. (fastdet._numba.REASSOC)


@njit(**REASSOC_INLINE)
def _patch_dot(rows, weights, r0, c0, acc):
    """``acc`` plus the correlation of ``weights`` (R, C) with ``rows[r0:r0+R, c0:c0+C]``."""
    for dr in range(weights.shape[0]):
        r = rows[r0 + dr]
        wr = weights[dr]
        for t in range(weights.shape[1]):
            acc += r[c0 + t] * wr[t]
    return acc


@njit(**REASSOC_INLINE)
def _window_score(block_rows, w_hog, nbx, k, spat_rows, w_sp, sp_off, integ, win_h, win_w, cell, yb, xb, bias):
    """Decision value of the window whose top-left block is (yb, xb); see dense_scores.
    (``w_hog`` rows are ``nbx * k`` long: the window's blocks of one block row.)"""
    acc = _patch_dot(block_rows, w_hog, yb, xb * k, 0.0)
    if spat_rows.shape[0] > 0:
        acc = _patch_dot(spat_rows, w_sp, (yb * cell) // sp_off, ((xb * cell) // sp_off) * 3, acc)
    if integ.shape[0] > 1:
        y0 = yb * cell
        x0 = xb * cell
        acc += integ[y0 + win_h, x0 + win_w] - integ[y0, x0 + win_w] - integ[y0 + win_h, x0] + integ[y0, x0]
    return acc + bias


@njit(**REASSOC_PARALLEL)
def dense_scores(block_rows, w_hog, nbx, k, spat_rows, w_sp, sp_off, integ, win_h, win_w, cell, step, bias, out):
    """Scores of every window of one band, windows spread over Numba's threads.

    block_rows: (R, Cb*k) float64, the HOG block map with one row of blocks contiguous
        (k = values per block position, all channels).
    w_hog: (nby, nbx*k) float64, HOG weights laid out like nby consecutive rows of nbx blocks.
    spat_rows: (Hs, Ws*3) float64 spatial-bin map (Hs = 0 when unused); w_sp: (Sh, Sw*3).
    sp_off: pixels per spatial-map pixel (the spatial factor).
    integ: (H+1, W+1) float64 integral image of the histogram-weight map ((1, 1) when unused).
    win_h, win_w, cell, step: window and cell size in pixels, stride in cells.
    out: (ny, nx) float64, overwritten: out[i, j] is the window at block (i*step, j*step).
    """
    ny, nx = out.shape
    for ij in prange(ny * nx):
        i = ij // nx
        j = ij - i * nx
        out[i, j] = _window_score(block_rows, w_hog, nbx, k, spat_rows, w_sp, sp_off, integ, win_h, win_w,
                                  cell, i * step, j * step, bias)


@njit(**REASSOC)
def dense_scores_serial(block_rows, w_hog, nbx, k, spat_rows, w_sp, sp_off, integ, win_h, win_w, cell, step,
                        bias, out):
    """:func:`dense_scores` on the calling thread only (for bands run in parallel threads)."""
    ny, nx = out.shape
    for i in range(ny):
        for j in range(nx):
            out[i, j] = _window_score(block_rows, w_hog, nbx, k, spat_rows, w_sp, sp_off, integ, win_h, win_w,
                                      cell, i * step, j * step, bias)


@njit(**EXACT)
def hist_weight_integral(image, w_hist, shift, out):
    """Integral image of the per-pixel histogram weight ``sum_c w_hist[c, image[y, x, c] >> shift]``.

    image: (H, W, 3) uint8; w_hist: (3, bins) float64; out: (H+1, W+1) float64, overwritten.
    """
    h, w, c = image.shape
    for x in range(w + 1):
        out[0, x] = 0.0
    for y in range(h):
        out[y + 1, 0] = 0.0
        run = 0.0
        for x in range(w):
            v = 0.0
            for ch in range(c):
                v += w_hist[ch, image[y, x, ch] >> shift]
            run += v
            out[y + 1, x + 1] = out[y, x + 1] + run
