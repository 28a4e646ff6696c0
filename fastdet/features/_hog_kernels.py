"""Numba kernels behind :mod:`fastdet.features._hog` (private: call the wrappers there).

Every kernel reproduces scikit-image's ``feature.hog`` arithmetic step for step, so that
results agree to the last bit on the same machine:

* cell sums are accumulated pixel by pixel in row-major order in a float32 total, each step
  computed in double and rounded back to float32 (``cdef float total`` in skimage's
  ``_hoghistogram.pyx``), then divided by the cell area in float32;
* block sums reproduce NumPy's pairwise summation (``np.sum`` over a contiguous block);
* normalisation divides (never multiplies by a reciprocal), with ``eps = 1e-5``.

Conventions: an image is ``(rows, cols, channels)``; a cell-histogram map ``ht`` is
``(n_cells_row, n_channels, n_cells_col, orientations)`` float64, channel-major within a cell
row (a block row of one channel, ``b_col`` cells of ``orientations`` bins, is one contiguous
run); a block map ``out`` is ``(n_blocks_row, n_blocks_col, n_channels, b_row * b_col *
orientations)``, i.e. the normalised ``(b_row, b_col, orientations)`` block of each channel is
contiguous.

The kernels Python calls (:data:`SIGNATURES`, each compiled for exactly the argument types
listed there) work on a range of rows -- cell rows, block rows -- on the calling thread: the
wrappers in :mod:`fastdet.features._hog` spread the ranges over threads
(:func:`fastdet._numba.split_range`) when that pays, so one compiled kernel serves one thread
and many, and none is a ``parallel=True`` kernel (those compile several times slower).
"""
from __future__ import annotations

import numpy as np
from numba import njit

from .._numba import EXACT, REASSOC

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

# error_model="numpy": x / 0 gives inf/nan as in NumPy instead of a Python-style check,
# which also lets LLVM vectorise the division loops (5x faster normalisation).
_JIT = EXACT


# --------------------------------------------------------------------------------------
# block normalisation
# --------------------------------------------------------------------------------------
@njit(**_JIT)
def _pairwise_leaf(a, lo, n):
    """NumPy's pairwise-summation leaf (n <= 128): plain loop below 8 elements, else
    8 interleaved partial sums combined as ((r0+r1)+(r2+r3))+((r4+r5)+(r6+r7)), then the
    remainder added one by one."""
    if n < 8:
        res = 0.0
        for i in range(lo, lo + n):
            res += a[i]
        return res
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


@njit(**_JIT)
def _pairwise_sum(a, lo, n):
    """Sum of ``a[lo:lo + n]`` in exactly the order of NumPy's float64 ``add.reduce``:
    leaves of at most 128 elements, larger ranges split at ``n // 2`` rounded down to a
    multiple of 8 and summed left + right. The recursion runs on an explicit stack
    (Numba cannot cache self-recursive functions reliably)."""
    if n <= 128:
        return _pairwise_leaf(a, lo, n)
    f_lo = np.empty(64, dtype=np.int64)
    f_n = np.empty(64, dtype=np.int64)
    f_stage = np.empty(64, dtype=np.int64)
    vals = np.empty(64)
    vp = 0
    f_lo[0] = lo
    f_n[0] = n
    f_stage[0] = 0
    sp = 1
    while sp > 0:
        t = sp - 1
        start = f_lo[t]
        m = f_n[t]
        if m <= 128:
            sp -= 1
            vals[vp] = _pairwise_leaf(a, start, m)
            vp += 1
            continue
        m2 = m // 2
        m2 -= m2 % 8
        if f_stage[t] == 0:
            f_stage[t] = 1
            f_lo[sp] = start
            f_n[sp] = m2
            f_stage[sp] = 0
            sp += 1
        elif f_stage[t] == 1:
            f_stage[t] = 2
            f_lo[sp] = start + m2
            f_n[sp] = m - m2
            f_stage[sp] = 0
            sp += 1
        else:
            sp -= 1
            right = vals[vp - 1]
            left = vals[vp - 2]
            vp -= 2
            vals[vp] = left + right
            vp += 1
    return vals[0]


# Blocks normalised together, one SIMD lane each. Lane arrays are flat ``(size, L)``
# with a compile-time L, so that the lane loops have unit stride and vectorise.
L = 48


@njit(**_JIT)
def _lane_sums(x, size, r, res):
    """``res[b] = np.sum(x[p * L + b] for p < size)`` for every lane ``b``, in NumPy's
    pairwise order, with the lanes as the inner (vectorised) loop; ``r`` is ``8 * L``
    scratch."""
    if size > 128:
        col = np.empty(size)
        for b in range(L):
            for p in range(size):
                col[p] = x[p * L + b]
            res[b] = _pairwise_sum(col, np.int64(0), size)  # not a literal 0: one compile of the leaf
        return
    if size < 8:
        for b in range(L):
            res[b] = 0.0
        for p in range(size):
            for b in range(L):
                res[b] += x[p * L + b]
        return
    for i in range(8 * L):
        r[i] = x[i]
    full = size - size % 8
    for i in range(8, full, 8):
        for j in range(8 * L):
            r[j] += x[i * L + j]
    for b in range(L):
        res[b] = ((r[b] + r[L + b]) + (r[2 * L + b] + r[3 * L + b])) + \
                 ((r[4 * L + b] + r[5 * L + b]) + (r[6 * L + b] + r[7 * L + b]))
    for i in range(full, size):
        for b in range(L):
            res[b] += x[i * L + b]


@njit(**_JIT)
def _normalize_range(ht, g_start, g_stop, b_row, b_col, method, out):
    """Normalise blocks ``g_start <= g < g_stop`` of the cell histograms ``ht`` into ``out``,
    where block
    ``g = (bi * n_blocks_col + bj) * n_channels + k`` is block ``(bi, bj)`` of channel
    ``k``, i.e. ``out.reshape(-1)[g * size:(g + 1) * size]``.

    Blocks are processed in groups of ``L``, transposed so that block ``b`` of the group
    is lane ``b``: every step (squares, NumPy-order pairwise sums, divisions, clipping)
    is then a loop over lanes that LLVM vectorises, while each lane does exactly NumPy's
    scalar arithmetic for its block.
    """
    n_blocks_col = out.shape[1]
    n_ch = out.shape[2]
    size = out.shape[3]
    n_cells_col = ht.shape[2]
    n_or = ht.shape[3]
    n = size * L
    v = np.zeros(n)
    w = np.empty(n)
    s = np.empty(n)
    r = np.empty(8 * L)
    den = np.empty(L)
    flat = out.reshape(out.size)
    src = ht.reshape(ht.size)
    ch_step = n_cells_col * n_or  # the same cell of the next channel
    row_step = n_ch * ch_step  # next cell row
    for g0 in range(g_start, g_stop, L):
        g1 = min(g0 + L, g_stop)
        # gather: lane b <- block g0 + b
        for g in range(g0, g1):
            bk = g // n_ch
            k = g - bk * n_ch
            bi = bk // n_blocks_col
            bj = bk - bi * n_blocks_col
            q = np.uint64(g - g0)
            base = bi * row_step + k * ch_step + bj * n_or
            for i in range(b_row):
                for j in range(b_col):
                    c0 = base + i * row_step + j * n_or
                    for o in range(n_or):
                        v[q] = src[np.uint64(c0 + o)]
                        q += np.uint64(L)
        # every step writes a different array than it reads: in-place lane loops do
        # not vectorise well
        if method == NORM_L1 or method == NORM_L1_SQRT:
            for i in range(n):
                s[i] = abs(v[i])
            _lane_sums(s, size, r, den)
            for b in range(L):
                den[b] = den[b] + EPS
            for p in range(size):
                for b in range(L):
                    w[p * L + b] = v[p * L + b] / den[b]
            if method == NORM_L1_SQRT:
                for i in range(n):
                    w[i] = np.sqrt(w[i])
        else:
            for i in range(n):
                s[i] = v[i] * v[i]
            _lane_sums(s, size, r, den)
            for b in range(L):
                den[b] = np.sqrt(den[b] + EPS2)
            for p in range(size):
                for b in range(L):
                    w[p * L + b] = v[p * L + b] / den[b]
            if method == NORM_L2_HYS:
                for i in range(n):
                    x = w[i]
                    x = HYS_CLIP if x > HYS_CLIP else x  # np.minimum: NaN stays NaN
                    v[i] = x
                    s[i] = x * x
                _lane_sums(s, size, r, den)
                for b in range(L):
                    den[b] = np.sqrt(den[b] + EPS2)
                for p in range(size):
                    for b in range(L):
                        w[p * L + b] = v[p * L + b] / den[b]
        # scatter back: block g is contiguous in the output
        for g in range(g0, g1):
            q = np.uint64(g - g0)
            base = g * size
            for p in range(size):
                flat[np.uint64(base + p)] = w[q]
                q += np.uint64(L)


@njit(**_JIT)
def normalize_blocks(ht, bi0, bi1, b_row, b_col, method, out):
    """Block rows ``bi0 <= bi < bi1`` of ``out`` from the cell histograms ``ht``, to the last
    bit as skimage normalises them (NumPy's pairwise sums, divisions)."""
    per_row = out.shape[1] * out.shape[2]
    _normalize_range(ht, bi0 * per_row, bi1 * per_row, b_row, b_col, method, out)


# --------------------------------------------------------------------------------------
# uint8 images: exact integer gradients, orientation bin and magnitude from look-up tables
# --------------------------------------------------------------------------------------
@njit(**_JIT)
def _lut_index_row(up, dn, cur, n_ch, idx):
    """LUT index ``(g_row + 255) * 511 + (g_col + 255)`` of every sample of one image row.

    ``up``, ``dn``, ``cur`` are the rows below, above and at the current row, flattened
    ``(cols * n_ch,)`` uint8 (pass ``cur`` for both ``up`` and ``dn`` on the first and
    last image rows: skimage's g_row is zero there). g_col is zero on the first and last
    columns. Written with zero-based slices so that LLVM vectorises the interior loop.
    """
    n = cur.shape[0]
    m = n - 2 * n_ch
    if m > 0:
        u = up[n_ch:n - n_ch]
        d = dn[n_ch:n - n_ch]
        r = cur[2 * n_ch:]
        l = cur[:m]
        o = idx[n_ch:n - n_ch]
        for t in range(m):
            o[t] = ((np.int32(u[t]) - np.int32(d[t]) + LUT_OFFSET) * LUT_SIDE
                    + (np.int32(r[t]) - np.int32(l[t]) + LUT_OFFSET))
    for j in range(min(n_ch, n)):
        o1 = j
        o2 = n - n_ch + j
        idx[o1] = (np.int32(up[o1]) - np.int32(dn[o1]) + LUT_OFFSET) * LUT_SIDE + LUT_OFFSET
        idx[o2] = (np.int32(up[o2]) - np.int32(dn[o2]) + LUT_OFFSET) * LUT_SIDE + LUT_OFFSET


@njit(**_JIT)
def _planar_rows(img, y0, y1, buf):
    """De-interleave image rows ``y0 <= y < y1`` of a uint8 ``(rows, cols, C)``
    C-contiguous image into ``buf[:, y - y0]``: ``buf`` is ``(C, y1 - y0, cols)`` uint8,
    one plane per channel.

    One to four channels have loops with a constant stride, which LLVM turns into byte
    shuffles (0.06 ms for the detector's 1.8 M samples; with the planes as ``(rows, C,
    cols)`` it does not, 0.5 ms); other counts take a plain strided loop.
    """
    n_cols = img.shape[1]
    c = img.shape[2]
    for y in range(y0, y1):
        row = img[y].reshape(n_cols * c)
        r = y - y0
        if c == 1:
            o0 = buf[0, r]
            for x in range(n_cols):
                o0[x] = row[x]
        elif c == 2:
            o0 = buf[0, r]
            o1 = buf[1, r]
            for x in range(n_cols):
                o0[x] = row[2 * x]
                o1[x] = row[2 * x + 1]
        elif c == 3:
            o0 = buf[0, r]
            o1 = buf[1, r]
            o2 = buf[2, r]
            for x in range(n_cols):
                o0[x] = row[3 * x]
                o1[x] = row[3 * x + 1]
                o2[x] = row[3 * x + 2]
        elif c == 4:
            o0 = buf[0, r]
            o1 = buf[1, r]
            o2 = buf[2, r]
            o3 = buf[3, r]
            for x in range(n_cols):
                o0[x] = row[4 * x]
                o1[x] = row[4 * x + 1]
                o2[x] = row[4 * x + 2]
                o3[x] = row[4 * x + 3]
        else:
            for k in range(c):
                ok = buf[k, r]
                for x in range(n_cols):
                    ok[x] = row[x * c + k]


@njit(**_JIT)
def _plane_index_row(up, dn, cur, n_x, idx):
    """LUT index ``(g_row + 255) * 511 + (g_col + 255)`` of the first ``n_x`` pixels of one
    row of one channel plane into ``idx[:n_x]``.

    ``up``, ``dn``, ``cur`` are ``(cols,)`` uint8: the rows below, above and at the
    current row (``cur`` for both on the image's first and last rows, where skimage's
    g_row is zero); g_col is zero on the image's first and last columns. ``n_x <= cols``.
    """
    n_cols = cur.shape[0]
    hi = min(n_x, n_cols - 1)  # interior pixels are 1 <= x < hi
    if hi > 1:
        m = hi - 1
        u = up[1:hi]
        d = dn[1:hi]
        r = cur[2:hi + 1]
        l = cur[:m]
        o = idx[1:hi]
        for t in range(m):
            o[t] = ((np.int32(u[t]) - np.int32(d[t]) + LUT_OFFSET) * LUT_SIDE
                    + (np.int32(r[t]) - np.int32(l[t]) + LUT_OFFSET))
    if n_x > 0:
        idx[0] = (np.int32(up[0]) - np.int32(dn[0]) + LUT_OFFSET) * LUT_SIDE + LUT_OFFSET
    if n_x == n_cols and n_cols > 1:
        e = n_cols - 1
        idx[e] = (np.int32(up[e]) - np.int32(dn[e]) + LUT_OFFSET) * LUT_SIDE + LUT_OFFSET


# Cells across from which the de-interleaved kernel wins: below it the per-row set-up of
# the planes costs more than the shorter strides save (64x64 crops: 0.30 vs 0.38 ms per
# 15 crops; 512 px: even; 1024 px: 0.24 vs 0.21 ms; the detector's bands are 490-1365 px).
PLANES_MIN_CELLS = 64


@njit(**_JIT)
def _image_row_index(img, y, idx):
    """:func:`_lut_index_row` of image row ``y`` of a uint8 ``(rows, cols, C)`` C-contiguous
    image into ``idx (cols * C,)``, with skimage's zero g_row on the first and last rows."""
    n = img.shape[1] * img.shape[2]
    cur = img[y].reshape(n)
    if y == 0 or y == img.shape[0] - 1:
        _lut_index_row(cur, cur, cur, img.shape[2], idx)
    else:
        _lut_index_row(img[y + 1].reshape(n), img[y - 1].reshape(n), cur, img.shape[2], idx)


@njit(**_JIT)
def _store_cell_row(acc, area, ci, ht):
    """Cell row ``ci`` of ``ht (n_cells_row, n_channels, n_cells_col, orientations)`` from
    its float32 totals ``acc`` laid out ``(cell, channel, bin)``, each divided by the cell
    ``area`` in float32 (skimage's ``total / (cell_rows * cell_columns)``)."""
    p = 0
    for cx in range(ht.shape[2]):
        for k in range(ht.shape[1]):
            for o in range(ht.shape[3]):
                ht[ci, k, cx, o] = np.float64(acc[p] / area)
                p += 1


@njit(**_JIT)
def _cell_row_interleaved(img, chans, ci, c_row, c_col, bin_lut, mag_lut, ht):
    """As :func:`_cell_rows_planes` for one cell row, straight from the interleaved
    image: LUT indices of every sample of an image row, totals ``(cell, channel, bin)``
    (faster on narrow images, e.g. 64x64 training crops)."""
    n_cols = img.shape[1]
    n_img_ch = img.shape[2]
    n_ch = ht.shape[1]
    n_cells_col = ht.shape[2]
    n_or = ht.shape[3]
    n = n_cols * n_img_ch
    acc = np.zeros(n_cells_col * n_ch * n_or, dtype=np.float32)
    idx = np.empty(n, dtype=np.int32)
    stride = n_ch * n_or
    step = c_col * n_img_ch
    for y in range(ci * c_row, ci * c_row + c_row):
        _image_row_index(img, y, idx)
        # channel, then column offset, then cell: consecutive updates hit different cells
        # (independent float32 chains); unsigned indices skip wraparound checks
        for k in range(n_ch):
            for xo in range(c_col):
                j = xo * n_img_ch + chans[k]
                a0 = k * n_or
                for cx in range(n_cells_col):
                    t = np.uint64(idx[np.uint64(j)])
                    a = np.uint64(a0 + bin_lut[t])
                    acc[a] = np.float32(acc[a] + mag_lut[t])
                    j += step
                    a0 += stride
    _store_cell_row(acc, np.float32(c_row * c_col), ci, ht)


@njit(**_JIT)
def _cell_rows_planes(img, chans, ci0, ci1, c_row, c_col, bin_lut, mag_lut, ht):
    """Per-channel histograms of cell rows ``ci0 <= ci < ci1`` of a uint8 ``(rows, cols,
    C)`` C-contiguous image into ``ht[ci] (n_channels, n_cells_col, orientations)``:
    channel ``chans[k]`` into ``ht[ci, k]``.

    Per cell row, its image rows (and the one above and below) are first de-interleaved
    into channel planes; then per image row and channel: the LUT indices of the row's
    pixels (vectorised), and each pixel adds its magnitude to its bin's float32 total.
    Within a cell the pixels are visited in row-major order (skimage's order, which fixes
    the float32 rounding); across cells the loop runs column offset first, so that
    consecutive updates hit different cells and their dependency chains overlap. The
    totals of one channel are contiguous ``(cell, bin)`` float32, one 64-byte line per
    cell of 16 bins: a channel's pass touches a third of the L1 lines an interleaved
    layout would (with the planes: 2.7 -> 2.3 ms for the detector's bands). The work
    buffers are allocated once for all the rows.
    """
    n_rows = img.shape[0]
    n_cols = img.shape[1]
    n_ch = ht.shape[1]
    n_cells_col = ht.shape[2]
    n_or = ht.shape[3]
    n_x = n_cells_col * c_col
    buf = np.empty((img.shape[2], c_row + 2, n_cols), dtype=np.uint8)
    idx = np.empty(max(n_x, 1), dtype=np.int32)
    acc = np.empty(n_ch * n_cells_col * n_or, dtype=np.float32)
    area = np.float32(c_row * c_col)
    for ci in range(ci0, ci1):
        y0 = ci * c_row
        lo = max(y0 - 1, 0)
        hi = min(y0 + c_row + 1, n_rows)
        _planar_rows(img, lo, hi, buf)
        acc[:] = 0
        for y in range(y0, y0 + c_row):
            r = y - lo
            for k in range(n_ch):
                ch = chans[k]
                cur = buf[ch, r]
                if y == 0 or y == n_rows - 1:
                    _plane_index_row(cur, cur, cur, n_x, idx)
                else:
                    _plane_index_row(buf[ch, r + 1], buf[ch, r - 1], cur, n_x, idx)
                # unsigned indices: no wraparound checks
                for xo in range(c_col):
                    j = np.uint64(xo)
                    a0 = np.uint64(k * n_cells_col * n_or)
                    for cx in range(n_cells_col):
                        t = np.uint64(idx[j])
                        a = a0 + np.uint64(bin_lut[t])
                        acc[a] = np.float32(acc[a] + mag_lut[t])
                        j += np.uint64(c_col)
                        a0 += np.uint64(n_or)
        row = ht[ci].reshape(n_ch * n_cells_col * n_or)  # (channel, cell, bin), as acc
        for p in range(n_ch * n_cells_col * n_or):
            row[p] = np.float64(acc[p] / area)


@njit(**_JIT)
def _cell_row_max_channel(img, chans, ci, c_row, c_col, bin_lut, mag_lut, ht):
    """skimage's multichannel histograms of cell row ``ci`` into ``ht[ci, 0]``: per pixel
    the channel of ``chans`` with the largest gradient magnitude (first on ties) votes."""
    n_cols = img.shape[1]
    n_img_ch = img.shape[2]
    n_ch = ht.shape[1]
    n_cells_col = ht.shape[2]
    n_or = ht.shape[3]
    n_sel = chans.shape[0]
    n = n_cols * n_img_ch
    acc = np.zeros(n_cells_col * n_ch * n_or, dtype=np.float32)
    idx = np.empty(n, dtype=np.int32)
    stride = n_ch * n_or
    for y in range(ci * c_row, ci * c_row + c_row):
        _image_row_index(img, y, idx)
        for xo in range(c_col):
            for cx in range(n_cells_col):
                j = (cx * c_col + xo) * n_img_ch
                # compare skimage's float magnitudes, not g_row² + g_col²: equal
                # integer sums can differ by an ulp after np.hypot
                t = idx[j + chans[0]]
                best = mag_lut[t]
                for k in range(1, n_sel):
                    tk = idx[j + chans[k]]
                    if mag_lut[tk] > best:
                        best = mag_lut[tk]
                        t = tk
                a = cx * stride + bin_lut[t]
                acc[a] = np.float32(acc[a] + best)
    _store_cell_row(acc, np.float32(c_row * c_col), ci, ht)


@njit(**_JIT)
def cell_hists_u8(img, chans, max_channel, ci0, ci1, c_row, c_col, bin_lut, mag_lut, ht):
    """Histograms of cell rows ``ci0 <= ci < ci1`` of a uint8 ``(rows, cols, C)``
    C-contiguous image into ``ht[ci] (n_channels, n_cells_col, orientations)``.

    ``max_channel=False``: one histogram per channel ``chans[k]`` (``ht[ci, k]``), by
    :func:`_cell_rows_planes` for images of at least :data:`PLANES_MIN_CELLS` cells across,
    else by :func:`_cell_row_interleaved`. ``max_channel=True``: per pixel the channel with
    the largest gradient magnitude (first on ties) votes into ``ht[ci, 0]`` (skimage's
    multichannel HOG). ``bin_lut``, ``mag_lut``: :func:`fastdet.features._hog._luts`.
    """
    if max_channel:
        for ci in range(ci0, ci1):
            _cell_row_max_channel(img, chans, ci, c_row, c_col, bin_lut, mag_lut, ht)
    elif ht.shape[2] >= PLANES_MIN_CELLS:
        _cell_rows_planes(img, chans, ci0, ci1, c_row, c_col, bin_lut, mag_lut, ht)
    else:
        for ci in range(ci0, ci1):
            _cell_row_interleaved(img, chans, ci, c_row, c_col, bin_lut, mag_lut, ht)


# --------------------------------------------------------------------------------------
# the detector's block map: the same cell histograms, blocks normalised to within an ulp
# --------------------------------------------------------------------------------------
# The detector needs every block value to ~1e-15 relative, not to the last bit: NumPy's
# pairwise order and the lane transposes of _normalize_range cost 60% of its HOG time. Here
# the same cell histograms (skimage's exact float32 sums, channel-major within a cell row,
# ``ht[r, k, c, o]``: a block row of one channel, ``b_col`` cells of ``n_or`` bins, is one
# contiguous run) are normalised block by block: a block is ``b_row`` runs, read in place,
# summed in any order and scaled by a reciprocal (5x faster than the exact path).
@njit(**REASSOC)
def normalize_blocks_fast(ht, bi0, bi1, b_row, b_col, method, out):
    """Normalise block rows ``bi0 <= bi < bi1`` of ``ht (rows, n_ch, cols, n_or)`` into
    ``out (n_blocks_row, n_blocks_col, n_ch, b_row * b_col * n_or)`` (C-contiguous).

    Each cell's sum (of ``|h|`` for L1, ``h²`` for L2) is taken once and a block's sum
    is the sum of its cells'; per block row and channel the reciprocals of all blocks are
    computed first, into an array: with the reciprocal in a register LLVM rewrites
    ``a * (1 / d)`` as ``a / d`` (allowed by ``reassoc``), and a vector division costs
    several multiplications. Indices are unsigned (no wraparound checks) so that the runs
    vectorise. 1.47 -> 0.69 ms for the detector's bands (L2-Hys).
    """
    n_ch = ht.shape[1]
    n_c = ht.shape[2]
    n_or = ht.shape[3]
    n_bc = out.shape[1]
    size = out.shape[3]
    if bi1 <= bi0 or n_bc <= 0:
        return
    l1 = method == NORM_L1 or method == NORM_L1_SQRT
    run = np.uint64(b_col * n_or)
    src = ht.reshape(ht.size)
    dst = out.reshape(out.size)
    row_len = n_c * n_or  # one channel's cell row
    n_r = bi1 - bi0 + b_row - 1  # cell rows the blocks cover
    cell_sum = np.empty(n_r * n_ch * n_c)
    for r in range(n_r):
        for k in range(n_ch):
            base = ((bi0 + r) * n_ch + k) * row_len
            for c in range(n_c):
                q = np.uint64(base + c * n_or)
                s = 0.0
                if l1:
                    for o in range(np.uint64(n_or)):
                        s += abs(src[q + o])
                else:
                    for o in range(np.uint64(n_or)):
                        s += src[q + o] * src[q + o]
                cell_sum[np.uint64((r * n_ch + k) * n_c + c)] = s
    inv = np.empty(n_bc)
    inv2 = np.empty(n_bc)
    for bi in range(bi0, bi1):
        for k in range(n_ch):
            for bj in range(n_bc):
                s = 0.0
                for i in range(b_row):
                    c0 = ((bi - bi0 + i) * n_ch + k) * n_c + bj
                    for j in range(b_col):
                        s += cell_sum[np.uint64(c0 + j)]
                inv[bj] = s
            if l1:
                for bj in range(n_bc):
                    inv[bj] = 1.0 / (inv[bj] + EPS)
            else:
                for bj in range(n_bc):
                    inv[bj] = 1.0 / np.sqrt(inv[bj] + EPS2)
            if method == NORM_L2_HYS:  # clip at 0.2, renormalise
                for bj in range(n_bc):
                    iv = inv[bj]
                    s = 0.0
                    for i in range(b_row):
                        q = np.uint64(((bi + i) * n_ch + k) * row_len + bj * n_or)
                        for p in range(run):
                            x = min(src[q + p] * iv, HYS_CLIP)
                            s += x * x
                    inv2[bj] = s
                for bj in range(n_bc):
                    inv2[bj] = 1.0 / np.sqrt(inv2[bj] + EPS2)
            for bj in range(n_bc):
                iv = inv[bj]
                iv2 = inv2[bj]
                d0 = ((bi * n_bc + bj) * n_ch + k) * size
                for i in range(b_row):
                    q = np.uint64(((bi + i) * n_ch + k) * row_len + bj * n_or)
                    d = np.uint64(d0) + np.uint64(i) * run
                    if method == NORM_L2_HYS:
                        for p in range(run):
                            dst[d + p] = min(src[q + p] * iv, HYS_CLIP) * iv2
                    elif method == NORM_L1_SQRT:
                        for p in range(run):
                            dst[d + p] = np.sqrt(src[q + p] * iv)
                    else:
                        for p in range(run):
                            dst[d + p] = src[q + p] * iv


# --------------------------------------------------------------------------------------
# float images: magnitude and orientation come from NumPy (bit-identical to skimage);
# the kernels bin, accumulate and normalise
# --------------------------------------------------------------------------------------
@njit(**_JIT)
def cell_hist_float(mag, orient, c_row, c_col, k, ht):
    """Hard-binned cell histograms of one channel into ``ht[:, k]``.

    ``mag`` and ``orient`` (degrees in [0, 180]) are float64 maps covering at least the
    whole cells. A pixel votes into bin ``i`` when ``180/n*i <= orient < 180/n*(i+1)``;
    like skimage, a NaN orientation votes into every bin and an orientation at or above
    the last edge into none.
    """
    n_cells_row = ht.shape[0]
    n_cells_col = ht.shape[2]
    n_or = ht.shape[3]
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
                ht[ci, k, cx, o2] = np.float64(acc[cx, o2] / area)


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
def draw_hog_image(ht, c_row, c_col, dr_arr, dc_arr, out):
    """skimage's HOG picture: per cell and bin, a line through the cell centre
    perpendicular to the bin's mid angle, brightness = the cell's histogram value
    (``ht[:, 0]``, the one channel of skimage's HOG)."""
    n_or = ht.shape[3]
    for r in range(ht.shape[0]):
        for c in range(ht.shape[2]):
            centre_r = r * c_row + c_row // 2
            centre_c = c * c_col + c_col // 2
            for o in range(n_or):
                dr = dr_arr[o]
                dc = dc_arr[o]
                _add_line(out, int(centre_r - dc), int(centre_c + dr),
                          int(centre_r + dc), int(centre_c - dr), ht[r, 0, c, o])


# --------------------------------------------------------------------------------------
# what the package calls, compiled ahead of time (fastdet._numba.ensure_compiled)
# --------------------------------------------------------------------------------------
#: argument types of every call the package makes to each kernel: exactly the types of the
#: calls (C-contiguous arrays, Python ints as int64), so a call finds its machine code
SIGNATURES: dict[str, tuple[str, ...]] = {
    "cell_hists_u8": ("uint8[:, :, ::1], int64[::1], boolean, int64, int64, int64, int64, int8[::1], float64[::1], "
                      "float64[:, :, :, ::1]",),
    "normalize_blocks": ("float64[:, :, :, ::1], int64, int64, int64, int64, int64, float64[:, :, :, ::1]",),
    "normalize_blocks_fast": ("float64[:, :, :, ::1], int64, int64, int64, int64, int64, float64[:, :, :, ::1]",),
    "cell_hist_float": ("float64[:, ::1], float64[:, ::1], int64, int64, int64, float64[:, :, :, ::1]",),
    "draw_hog_image": ("float64[:, :, :, ::1], int64, int64, float64[::1], float64[::1], float64[:, ::1]",
                       "float64[:, :, :, ::1], int64, int64, float64[::1], float64[::1], float32[:, ::1]"),
}
#: CPU seconds to compile each (all its signatures), reference machine (docs/benchmarks.md)
COMPILE_SECONDS: dict[str, float] = {
    "cell_hists_u8": 8.1, "normalize_blocks": 6.9, "normalize_blocks_fast": 2.0, "cell_hist_float": 1.4,
    "draw_hog_image": 1.6,
}
