"""Numba kernels: the decision value of every window position of a band, at once.

A window's score is a sum of three correlations with the folded linear weights (see
DESIGN.md, "score all windows at once"): its 7x7 blocks of the band's HOG block map, its
crop of the band's spatial-bin map, and the window sum of the per-pixel histogram-weight
map (four look-ups in an integral image). Call them through :mod:`fastdet.detect.scoring`,
which checks the shapes (these kernels do not: an index out of range reads other memory).

How the HOG and spatial terms are laid out for the hardware: a window's HOG term is a sum
over its ``nby`` rows of blocks of one contiguous dot product — ``block_rows[yb + dr]``
from column ``xb * k`` on, ``nbx * k`` values (1344 for 7 blocks of 192) — with that row of
the weights. So the kernel takes one weight row at a time (10.7 kB, it stays in L1) and
runs it along the block row for every window of the window row, eight windows at a time:
each weight is loaded once for eight fused multiply-adds into eight vector accumulators.
The innermost loop indexes slices from 0 (no negative-index wraparound test, which made
LLVM emit gathers for the old per-window loop), so it compiles to packed AVX2 / AVX-512
``vfmadd231pd`` with memory operands (checked with ``inspect_asm``). float64 throughout:
float32 products summed in float32 miss the classic reference by up to 3e-6 on the test
frames, above the 1e-6 the exactness test demands. What this layout gained, and why not BLAS:
docs/benchmarks.md (*Where a frame's detection time goes*).
"""
from __future__ import annotations

import numpy as np
from numba import njit

from .._numba import REASSOC

# fastmath: only "reassoc" and "contract", so LLVM may vectorise the dot products (split
# them into SIMD lanes and fuse multiply-adds). That changes the rounding of a sum of ~12k
# products by ~1e-13, far inside the 1e-6 the exactness tests demand; no nan/inf assumptions.
# (fastdet._numba.REASSOC)

@njit(**REASSOC)
def _dots4(r, wr, sk, n, out):
    """``out[j] += r[j*sk : j*sk + len(wr)] @ wr`` for ``j < n``, four windows at a time."""
    L = wr.shape[0]
    j = 0
    while j + 4 <= n:
        o = j * sk
        x0 = r[o: o + L]
        x1 = r[o + sk: o + sk + L]
        x2 = r[o + 2 * sk: o + 2 * sk + L]
        x3 = r[o + 3 * sk: o + 3 * sk + L]
        a0 = a1 = a2 = a3 = 0.0
        for t in range(L):
            wt = wr[t]
            a0 += x0[t] * wt
            a1 += x1[t] * wt
            a2 += x2[t] * wt
            a3 += x3[t] * wt
        out[j] += a0
        out[j + 1] += a1
        out[j + 2] += a2
        out[j + 3] += a3
        j += 4
    while j < n:
        o = j * sk
        x0 = r[o: o + L]
        a0 = 0.0
        for t in range(L):
            a0 += x0[t] * wr[t]
        out[j] += a0
        j += 1


@njit(**REASSOC)
def _dots(r, wr, sk, n, out):
    """``out[j] += r[j*sk : j*sk + len(wr)] @ wr`` for ``j < n``: eight windows at a time
    (one load of each weight, eight packed FMAs), the rest four and one at a time."""
    L = wr.shape[0]
    j = 0
    while j + 8 <= n:
        o = j * sk
        x0 = r[o: o + L]
        x1 = r[o + sk: o + sk + L]
        x2 = r[o + 2 * sk: o + 2 * sk + L]
        x3 = r[o + 3 * sk: o + 3 * sk + L]
        x4 = r[o + 4 * sk: o + 4 * sk + L]
        x5 = r[o + 5 * sk: o + 5 * sk + L]
        x6 = r[o + 6 * sk: o + 6 * sk + L]
        x7 = r[o + 7 * sk: o + 7 * sk + L]
        a0 = a1 = a2 = a3 = a4 = a5 = a6 = a7 = 0.0
        for t in range(L):
            wt = wr[t]
            a0 += x0[t] * wt
            a1 += x1[t] * wt
            a2 += x2[t] * wt
            a3 += x3[t] * wt
            a4 += x4[t] * wt
            a5 += x5[t] * wt
            a6 += x6[t] * wt
            a7 += x7[t] * wt
        out[j] += a0
        out[j + 1] += a1
        out[j + 2] += a2
        out[j + 3] += a3
        out[j + 4] += a4
        out[j + 5] += a5
        out[j + 6] += a6
        out[j + 7] += a7
        j += 8
    if j < n:
        _dots4(r[j * sk:], wr, sk, n - j, out[j:])


@njit(**REASSOC)
def _score_span(block_rows, w_hog, k, spat_rows, w_sp, sp_off, integ, hg, win_h, win_w, cell, step, bias,
                i, j0, j1, out):
    """``out[i, j0:j1]``: the windows of window row ``i``, columns ``j0 .. j1-1``."""
    yb = i * step
    sk = step * k
    orow = out[i, j0:j1]
    n = j1 - j0
    for j in range(n):
        orow[j] = bias
    for dr in range(w_hog.shape[0]):
        _dots(block_rows[yb + dr, j0 * sk:], w_hog[dr], sk, n, orow)
    if spat_rows.shape[0] > 0:
        ssp = (step * cell) // sp_off * 3  # spatial-map values between window columns
        ys = (yb * cell) // sp_off
        for dr in range(w_sp.shape[0]):
            _dots(spat_rows[ys + dr, j0 * ssp:], w_sp[dr], ssp, n, orow)
    if integ.shape[0] > 1:
        y0 = yb * cell // hg
        top = integ[y0]
        bot = integ[y0 + win_h // hg]
        ww = win_w // hg
        for j in range(n):
            x0 = (j0 + j) * step * cell // hg
            orow[j] += bot[x0 + ww] - top[x0 + ww] - bot[x0] + top[x0]


@njit(**REASSOC)
def dense_scores(block_rows, w_hog, k, spat_rows, w_sp, sp_off, integ, hg, win_h, win_w, cell, step, bias, i0, i1,
                 out):
    """Scores of the windows of window rows ``i0 <= i < i1`` of one band into ``out[i0:i1]``,
    on the calling thread: a whole window row per weight-row pass (the wrapper spreads the
    rows over threads when asked).

    block_rows: (R, Cb*k) float64, the HOG block map with one row of blocks contiguous
        (k = values per block position, all channels).
    w_hog: (nby, nbx*k) float64, HOG weights laid out like nby consecutive rows of nbx blocks.
    spat_rows: (Hs, Ws*3) float64 spatial-bin map (Hs = 0 when unused); w_sp: (Sh, Sw*3).
    sp_off: pixels per spatial-map pixel (the spatial factor; divides ``cell``).
    integ: (H/hg+1, W/hg+1) float64 integral image of the histogram-weight map sampled every
        ``hg`` pixels (``hg`` divides cell, win_h, win_w); (1, 1) when unused.
    win_h, win_w, cell, step: window and cell size in pixels, stride in cells.
    out: (ny, nx) float64: out[i, j] is the window at block (i*step, j*step).
    """
    nx = out.shape[1]
    for i in range(i0, i1):
        _score_span(block_rows, w_hog, k, spat_rows, w_sp, sp_off, integ, hg, win_h, win_w, cell, step, bias,
                    i, 0, nx, out)


@njit(**REASSOC)
def hist_weight_integral(image, lut, g, out):
    """Integral image of the per-pixel histogram weight ``sum_c lut[c, image[y, x, c]]`` at
    every ``g``-th row and column: ``out[r, q]`` = the sum over ``image[:r*g, :q*g]``.

    image: (H, W, C) uint8; lut: (C, 256) float64, each channel's histogram weight of every
    value (``w_hist[c, v >> shift]``); out: (H//g + 1, W//g + 1) float64, overwritten.
    The windows sit on the cell grid, so ``g`` = the cell size serves them: the per-pixel
    weights of a row of cells are summed column by column into one buffer (look-ups by an
    unsigned byte, no chain between pixels; three channels in one pass), then each cell's
    ``g`` columns once, and the running sum along the row (the sums are reordered, ~1e-15
    apart; the measurements: docs/benchmarks.md, *Kernel notes*).
    """
    nr, nq = out.shape[0] - 1, out.shape[1] - 1
    c = image.shape[2]
    w = nq * g
    v = np.empty(w)
    for q in range(nq + 1):
        out[0, q] = 0.0
    l0 = lut[0]
    for r in range(nr):
        for x in range(w):
            v[x] = 0.0
        for y in range(r * g, r * g + g):
            px = image[y]
            if c == 3:
                l1 = lut[1]
                l2 = lut[2]
                for x in range(w):
                    v[x] += (l0[px[x, 0]] + l1[px[x, 1]]) + l2[px[x, 2]]
            else:
                for ch in range(c):
                    lc = lut[ch]
                    for x in range(w):
                        v[x] += lc[px[x, ch]]
        row = out[r + 1]
        prev = out[r]
        row[0] = prev[0]
        run = 0.0
        for q in range(nq):
            t = v[q * g: q * g + g]
            acc = 0.0
            for x in range(g):
                acc += t[x]
            run += acc
            row[q + 1] = prev[q + 1] + run


# --------------------------------------------------------------------------------------
# what the package calls, compiled ahead of time (fastdet._numba.ensure_compiled)
# --------------------------------------------------------------------------------------
#: argument types of every call the package makes to each kernel: exactly the types of the
#: calls (C-contiguous arrays, Python ints as int64), so a call finds its machine code
SIGNATURES: dict[str, tuple[str, ...]] = {
    "dense_scores": ("float64[:, ::1], float64[:, ::1], int64, float64[:, ::1], float64[:, ::1], int64, "
                     "float64[:, ::1], int64, int64, int64, int64, int64, float64, int64, int64, float64[:, ::1]",),
    "hist_weight_integral": ("uint8[:, :, ::1], float64[:, ::1], int64, float64[:, ::1]",),
}
#: CPU seconds to compile each, reference machine (docs/benchmarks.md)
COMPILE_SECONDS: dict[str, float] = {"dense_scores": 3.6, "hist_weight_integral": 0.85}
