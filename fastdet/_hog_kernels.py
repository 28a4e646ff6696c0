"""Numba kernels behind :mod:`fastdet._hog` (private: call the wrappers there).

Every kernel reproduces scikit-image's ``feature.hog`` arithmetic step for step, so that
results agree to the last bit on the same machine:

* cell sums are accumulated pixel by pixel in row-major order in a float32 total, each step
  computed in double and rounded back to float32 (``cdef float total`` in skimage's
  ``_hoghistogram.pyx``), then divided by the cell area in float32;
* block sums reproduce NumPy's pairwise summation (``np.sum`` over a contiguous block);
* normalisation divides (never multiplies by a reciprocal), with ``eps = 1e-5``.

Conventions: an image is ``(rows, cols, channels)``; a cell-histogram map ``hist`` is
``(n_cells_row, n_cells_col, n_channels, orientations)`` float64; a block map ``out`` is
``(n_blocks_row, n_blocks_col, n_channels, b_row * b_col * orientations)``, i.e. the
normalised ``(b_row, b_col, orientations)`` block of each channel is contiguous.
"""
from __future__ import annotations

import numpy as np
from numba import njit, prange

# block_norm codes (see _hog.BLOCK_NORMS)
NORM_L1 = 0
NORM_L1_SQRT = 1
NORM_L2 = 2
NORM_L2_HYS = 3

EPS = 1e-5
EPS2 = EPS**2  # as skimage spells it: eps**2 evaluated in double
HYS_CLIP = 0.2

# uint8 gradients lie in [-255, 255]: LUT index = (g_row + 255) * LUT_SIDE + (g_col + 255)
LUT_OFFSET = 255
LUT_SIDE = 511

_JIT = dict(cache=True, nogil=True, fastmath=False)
_PJIT = dict(cache=True, nogil=True, fastmath=False, parallel=True)


# --------------------------------------------------------------------------------------
# block normalisation
# --------------------------------------------------------------------------------------
@njit(**_JIT)
def _pairwise_sum(a, lo, n):
    """Sum of ``a[lo:lo + n]`` in exactly the order NumPy's float64 ``add.reduce`` uses
    (8-way unrolled pairwise summation, blocks of at most 128)."""
    if n < 8:
        res = 0.0
        for i in range(lo, lo + n):
            res += a[i]
        return res
    elif n <= 128:
        r0 = a[lo]
        r1 = a[lo + 1]
        r2 = a[lo + 2]
        r3 = a[lo + 3]
        r4 = a[lo + 4]
        r5 = a[lo + 5]
        r6 = a[lo + 6]
        r7 = a[lo + 7]
        i = 8
        stop = n - n % 8
        while i < stop:
            r0 += a[lo + i]
            r1 += a[lo + i + 1]
            r2 += a[lo + i + 2]
            r3 += a[lo + i + 3]
            r4 += a[lo + i + 4]
            r5 += a[lo + i + 5]
            r6 += a[lo + i + 6]
            r7 += a[lo + i + 7]
            i += 8
        res = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
        while i < n:
            res += a[lo + i]
            i += 1
        return res
    else:
        n2 = n // 2
        n2 -= n2 % 8
        return _pairwise_sum(a, lo, n2) + _pairwise_sum(a, lo + n2, n - n2)


@njit(**_JIT)
def _normalize_block_row(hist, bi, b_row, b_col, method, out):
    """Normalise every block of block row ``bi`` of every channel into ``out[bi]``."""
    n_blocks_col = out.shape[1]
    n_ch = out.shape[2]
    n_or = hist.shape[3]
    size = b_row * b_col * n_or
    buf = np.empty(size)
    sq = np.empty(size)
    for bj in range(n_blocks_col):
        for k in range(n_ch):
            p = 0
            for i in range(b_row):
                for j in range(b_col):
                    for o in range(n_or):
                        buf[p] = hist[bi + i, bj + j, k, o]
                        p += 1
            dst = out[bi, bj, k]
            if method == NORM_L1 or method == NORM_L1_SQRT:
                for p in range(size):
                    sq[p] = abs(buf[p])
                den = _pairwise_sum(sq, 0, size) + EPS
                if method == NORM_L1:
                    for p in range(size):
                        dst[p] = buf[p] / den
                else:
                    for p in range(size):
                        dst[p] = np.sqrt(buf[p] / den)
            else:
                for p in range(size):
                    sq[p] = buf[p] * buf[p]
                den = np.sqrt(_pairwise_sum(sq, 0, size) + EPS2)
                if method == NORM_L2:
                    for p in range(size):
                        dst[p] = buf[p] / den
                else:
                    for p in range(size):
                        v = buf[p] / den
                        if v > HYS_CLIP:  # np.minimum(v, 0.2), NaN-propagating
                            v = HYS_CLIP
                        buf[p] = v
                        sq[p] = v * v
                    den = np.sqrt(_pairwise_sum(sq, 0, size) + EPS2)
                    for p in range(size):
                        dst[p] = buf[p] / den


@njit(**_JIT)
def normalize_blocks(hist, b_row, b_col, method, out):
    """Serial block normalisation of a whole cell-histogram map into ``out``."""
    for bi in range(out.shape[0]):
        _normalize_block_row(hist, bi, b_row, b_col, method, out)


# --------------------------------------------------------------------------------------
# uint8 images: exact integer gradients, orientation bin and magnitude from look-up tables
# --------------------------------------------------------------------------------------
@njit(**_JIT)
def _cell_row_u8(img, chans, max_channel, ci, c_row, c_col, bin_lut, mag_lut, hist):
    """Histograms of cell row ``ci`` of a uint8 ``(rows, cols, C)`` image into ``hist[ci]``.

    ``max_channel=False``: one histogram per channel ``chans[k]`` (``hist[ci, :, k]``).
    ``max_channel=True``: per pixel the channel with the largest gradient magnitude (first
    on ties) votes into ``hist[ci, :, 0]`` (skimage's multichannel HOG).
    """
    n_rows = img.shape[0]
    n_cols = img.shape[1]
    n_cells_col = hist.shape[1]
    n_ch = hist.shape[2]
    n_or = hist.shape[3]
    n_sel = chans.shape[0]
    acc = np.zeros((n_cells_col, n_ch, n_or), dtype=np.float32)
    x_stop = n_cells_col * c_col
    for y in range(ci * c_row, ci * c_row + c_row):
        # skimage zeroes g_row on the first and last image rows, g_col on the first and
        # last columns: reading the same pixel twice gives exactly that zero.
        if y == 0 or y == n_rows - 1:
            yu = y
            yd = y
        else:
            yu = y + 1
            yd = y - 1
        for x in range(x_stop):
            if x == 0 or x == n_cols - 1:
                xl = x
                xr = x
            else:
                xl = x - 1
                xr = x + 1
            cx = x // c_col
            if max_channel:
                best = -1
                gr_b = 0
                gc_b = 0
                for k in range(n_sel):
                    ch = chans[k]
                    gr = np.int32(img[yu, x, ch]) - np.int32(img[yd, x, ch])
                    gc = np.int32(img[y, xr, ch]) - np.int32(img[y, xl, ch])
                    m2 = gr * gr + gc * gc
                    if m2 > best:
                        best = m2
                        gr_b = gr
                        gc_b = gc
                idx = (gr_b + LUT_OFFSET) * LUT_SIDE + (gc_b + LUT_OFFSET)
                m = mag_lut[idx]
                if m != 0.0:
                    b = bin_lut[idx]
                    if b >= 0:
                        acc[cx, 0, b] = np.float32(acc[cx, 0, b] + m)
            else:
                for k in range(n_sel):
                    ch = chans[k]
                    gr = np.int32(img[yu, x, ch]) - np.int32(img[yd, x, ch])
                    gc = np.int32(img[y, xr, ch]) - np.int32(img[y, xl, ch])
                    idx = (gr + LUT_OFFSET) * LUT_SIDE + (gc + LUT_OFFSET)
                    m = mag_lut[idx]
                    if m != 0.0:  # adding 0.0 never changes a float32 total
                        b = bin_lut[idx]
                        if b >= 0:
                            acc[cx, k, b] = np.float32(acc[cx, k, b] + m)
    area = np.float32(c_row * c_col)
    for cx in range(n_cells_col):
        for k in range(n_ch):
            for o in range(n_or):
                hist[ci, cx, k, o] = np.float64(acc[cx, k, o] / area)


@njit(**_JIT)
def hog_u8(img, chans, max_channel, c_row, c_col, b_row, b_col, bin_lut, mag_lut, method,
           hist, out):
    """Whole uint8 HOG, single thread: cell histograms into ``hist``, blocks into ``out``."""
    for ci in range(hist.shape[0]):
        _cell_row_u8(img, chans, max_channel, ci, c_row, c_col, bin_lut, mag_lut, hist)
    for bi in range(out.shape[0]):
        _normalize_block_row(hist, bi, b_row, b_col, method, out)


@njit(**_PJIT)
def hog_u8_parallel(img, chans, max_channel, c_row, c_col, b_row, b_col, bin_lut, mag_lut,
                    method, hist, out):
    """As :func:`hog_u8`, threads over cell rows, then over block rows."""
    for ci in prange(hist.shape[0]):
        _cell_row_u8(img, chans, max_channel, ci, c_row, c_col, bin_lut, mag_lut, hist)
    for bi in prange(out.shape[0]):
        _normalize_block_row(hist, bi, b_row, b_col, method, out)


@njit(**_PJIT)
def hog_u8_batch(imgs, chans, c_row, c_col, b_row, b_col, n_cells_row, n_cells_col,
                 bin_lut, mag_lut, method, out):
    """Per-channel HOG of each image of a ``(N, rows, cols, C)`` uint8 stack, threads
    over images; ``out`` is ``(N, n_blocks_row, n_blocks_col, n_channels, block size)``."""
    n_img = imgs.shape[0]
    n_ch = chans.shape[0]
    n_or = out.shape[4] // (b_row * b_col)
    for n in prange(n_img):
        hist = np.empty((n_cells_row, n_cells_col, n_ch, n_or))
        hog_u8(imgs[n], chans, False, c_row, c_col, b_row, b_col, bin_lut, mag_lut, method,
               hist, out[n])


# --------------------------------------------------------------------------------------
# float images: magnitude and orientation come from NumPy (bit-identical to skimage);
# the kernels bin, accumulate and normalise
# --------------------------------------------------------------------------------------
@njit(**_JIT)
def cell_hist_float(mag, orient, c_row, c_col, k, hist):
    """Hard-binned cell histograms of one channel into ``hist[:, :, k]``.

    ``mag`` and ``orient`` (degrees in [0, 180]) are float64 maps covering at least the
    whole cells. A pixel votes into bin ``i`` when ``180/n*i <= orient < 180/n*(i+1)``;
    like skimage, a NaN orientation votes into every bin and an orientation at or above
    the last edge into none.
    """
    n_cells_row = hist.shape[0]
    n_cells_col = hist.shape[1]
    n_or = hist.shape[3]
    per180 = 180.0 / n_or
    edges = np.empty(n_or + 1)
    for i in range(n_or + 1):
        edges[i] = per180 * i
    acc = np.zeros((n_cells_col, n_or), dtype=np.float32)
    area = np.float32(c_row * c_col)
    for ci in range(n_cells_row):
        acc[:, :] = 0
        for y in range(ci * c_row, ci * c_row + c_row):
            for x in range(n_cells_col * c_col):
                cx = x // c_col
                m = mag[y, x]
                o = orient[y, x]
                if o != o:
                    for b in range(n_or):
                        acc[cx, b] = np.float32(acc[cx, b] + m)
                    continue
                b = int(o / per180)
                if b > n_or:
                    b = n_or
                if b < 0:
                    b = 0
                while b > 0 and o < edges[b]:
                    b -= 1
                while b < n_or and o >= edges[b + 1]:
                    b += 1
                if b < n_or and o >= edges[b]:
                    acc[cx, b] = np.float32(acc[cx, b] + m)
        for cx in range(n_cells_col):
            for o2 in range(n_or):
                hist[ci, cx, k, o2] = np.float64(acc[cx, o2] / area)


# --------------------------------------------------------------------------------------
# visualisation
# --------------------------------------------------------------------------------------
@njit(**_JIT)
def _add_line(img, r0, c0, r1, c1, value):
    """``img[line(r0, c0, r1, c1)] += value`` with Bresenham's integer line (the pixel
    sequence of ``skimage.draw.line``); negative indices wrap like NumPy's."""
    n_rows = img.shape[0]
    n_cols = img.shape[1]
    steep = False
    r = r0
    c = c0
    dr = abs(r1 - r0)
    dc = abs(c1 - c0)
    sc = 1 if c1 - c > 0 else -1
    sr = 1 if r1 - r > 0 else -1
    if dr > dc:
        steep = True
        r, c = c, r
        dr, dc = dc, dr
        sr, sc = sc, sr
    d = 2 * dr - dc
    for _ in range(dc + 1):
        if _ == dc:
            pr = r1
            pc = c1
        elif steep:
            pr = c
            pc = r
        else:
            pr = r
            pc = c
        if pr < 0:
            pr += n_rows
        if pc < 0:
            pc += n_cols
        if 0 <= pr < n_rows and 0 <= pc < n_cols:
            img[pr, pc] = img[pr, pc] + value
        if _ < dc:
            while d >= 0:
                r += sr
                d -= 2 * dc
            c += sc
            d += 2 * dr


@njit(**_JIT)
def draw_hog_image(hist, c_row, c_col, dr_arr, dc_arr, out):
    """skimage's HOG picture: per cell and bin, a line through the cell centre
    perpendicular to the bin's mid angle, brightness = the cell's histogram value."""
    n_or = hist.shape[3]
    for r in range(hist.shape[0]):
        for c in range(hist.shape[1]):
            centre_r = r * c_row + c_row // 2
            centre_c = c * c_col + c_col // 2
            for o in range(n_or):
                dr = dr_arr[o]
                dc = dc_arr[o]
                _add_line(out, int(centre_r - dc), int(centre_c + dr),
                          int(centre_r + dc), int(centre_c - dr), hist[r, c, 0, o])
