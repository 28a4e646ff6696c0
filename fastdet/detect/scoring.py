"""The dense window scores of one band: a checked front for the numba kernels of
:mod:`fastdet.detect._score_kernels` (which index without bounds checks)."""
from __future__ import annotations

import numba
import numpy as np

from .._numba import split_range
from ._score_kernels import dense_scores as _dense
from ._score_kernels import hist_weight_integral as _hist_integral


def _f64_rows(name: str, a: np.ndarray) -> None:
    if not isinstance(a, np.ndarray) or a.dtype != np.float64 or a.ndim != 2 or not a.flags.c_contiguous:
        raise ValueError(f"{name} must be a C-contiguous 2-D float64 array, got "
                         f"{getattr(a, 'dtype', type(a).__name__)} {getattr(a, 'shape', '')}")


def dense_scores(block_rows: np.ndarray, w_hog: np.ndarray, k: int, out: np.ndarray, *, step: int, cell: int,
                 win_h: int, win_w: int, bias: float = 0.0, spat_rows: np.ndarray | None = None,
                 w_sp: np.ndarray | None = None, sp_off: int = 1, integ: np.ndarray | None = None,
                 hist_step: int = 1, parallel: bool = False) -> np.ndarray:
    """Decision value of every window of a band into ``out (ny, nx) float64``; returns ``out``.

    ``out[i, j] = bias + HOG term + spatial term + histogram term`` of the window whose
    top-left block is ``(i*step, j*step)``:

    - HOG: ``sum_dr block_rows[i*step + dr, j*step*k : j*step*k + nbx*k] @ w_hog[dr]``
      (``block_rows (R, Cb*k)``: the block map, one row of blocks of ``k`` values each;
      ``w_hog (nby, nbx*k)``);
    - spatial (``spat_rows (Hs, Ws*3)``, ``w_sp (Sh, Sw*3)``, both or neither):
      ``sum_dr spat_rows[y + dr, x*3 : x*3 + Sw*3] @ w_sp[dr]`` at ``y, x = (i, j)*step*cell /
      sp_off`` (``sp_off``: pixels per spatial-map pixel, a divisor of ``cell``);
    - histogram (``integ``: integral image of the per-pixel weights at every ``hist_step``-th
      row and column, ``(H/hist_step + 1, W/hist_step + 1)``, see :func:`hist_weight_integral`;
      ``hist_step`` divides ``cell``, ``win_h`` and ``win_w``): the sum over the
      ``win_h x win_w`` pixels at ``(i, j)*step*cell``.

    ``parallel``: spread the window rows over Numba's thread count of threads (else the
    calling thread only; the scores are the same to the last bit).
    ``ValueError`` when an array has the wrong type or is too small for ``out``'s windows.
    """
    _f64_rows("block_rows", block_rows)
    _f64_rows("w_hog", w_hog)
    _f64_rows("out", out)
    k, step, cell, win_h, win_w, sp_off, hg = (int(v) for v in (k, step, cell, win_h, win_w, sp_off, hist_step))
    if min(k, step, cell, win_h, win_w, sp_off, hg) < 1:
        raise ValueError("k, step, cell, win_h, win_w, sp_off and hist_step must be >= 1")
    nby, lw = w_hog.shape
    if lw % k or nby < 1:
        raise ValueError(f"w_hog {w_hog.shape}: rows of whole blocks of k={k} values expected")
    nbx = lw // k
    ny, nx = out.shape
    if ny and nx and (block_rows.shape[0] < (ny - 1) * step + nby
                      or block_rows.shape[1] < ((nx - 1) * step + nbx) * k):
        raise ValueError(f"block_rows {block_rows.shape} too small for {ny}x{nx} windows of {nby}x{nbx} "
                             f"blocks at step {step} (k={k})")
    if (spat_rows is None) != (w_sp is None):
        raise ValueError("spat_rows and w_sp go together")
    if spat_rows is None:
        spat_rows = w_sp = np.zeros((0, 0))
    else:
        _f64_rows("spat_rows", spat_rows)
        _f64_rows("w_sp", w_sp)
        if cell % sp_off or w_sp.shape[1] % 3:
            raise ValueError(f"sp_off {sp_off} must divide cell {cell}; w_sp rows hold 3 channels")
        if ny and nx and (spat_rows.shape[0] < ((ny - 1) * step * cell) // sp_off + w_sp.shape[0]
                          or spat_rows.shape[1] < ((nx - 1) * step * cell) // sp_off * 3 + w_sp.shape[1]):
            raise ValueError(f"spat_rows {spat_rows.shape} too small for {ny}x{nx} windows of w_sp {w_sp.shape}")
    if integ is None:
        integ = np.zeros((1, 1))
    else:
        _f64_rows("integ", integ)
        if integ.shape[0] < 2:
            raise ValueError(f"integ {integ.shape}: an integral image has at least 2 rows")
        if cell % hg or win_h % hg or win_w % hg:
            raise ValueError(f"hist_step {hg} must divide cell {cell}, win_h {win_h} and win_w {win_w}")
        if ny and nx and (integ.shape[0] < ((ny - 1) * step * cell + win_h) // hg + 1
                          or integ.shape[1] < ((nx - 1) * step * cell + win_w) // hg + 1):
            raise ValueError(f"integ {integ.shape} too small for {ny}x{nx} windows of {win_h}x{win_w} px "
                             f"(hist_step {hg})")
    if ny and nx:
        bias = float(bias)
        split_range(lambda i0, i1: _dense(block_rows, w_hog, k, spat_rows, w_sp, sp_off, integ, hg, win_h, win_w,
                                          cell, step, bias, i0, i1, out),
                    ny, numba.get_num_threads() if parallel else 1)
    return out


def weight_table(w_hist: np.ndarray, shift: int) -> np.ndarray:
    """Each channel's histogram weight of every byte value: ``(C, 256) float64``,
    ``table[c, v] = w_hist[c, v >> shift]`` (``w_hist (C, bins)``, ``bins << shift >= 256``)."""
    _f64_rows("w_hist", w_hist)
    shift = int(shift)
    if shift < 0 or w_hist.shape[0] < 1 or w_hist.shape[1] << shift < 256:
        raise ValueError(f"w_hist {w_hist.shape} does not cover 256 >> {shift} bins")
    return np.ascontiguousarray(w_hist[:, np.arange(256) >> shift])


def hist_weight_integral(image: np.ndarray, table: np.ndarray, step: int = 1,
                         out: np.ndarray | None = None) -> np.ndarray:
    """Integral image of the per-pixel histogram weight ``sum_c table[c, image[y, x, c]]``
    (``table``: :func:`weight_table`) of an ``(H, W, C) uint8`` image at every ``step``-th row
    and column: ``(H // step + 1, W // step + 1) float64``, ``out[r, q]`` = the sum over
    ``image[:r*step, :q*step]`` (pass ``step`` = the cell size, and ``hist_step=step`` to
    :func:`dense_scores`)."""
    if image.dtype != np.uint8 or image.ndim != 3 or image.shape[2] < 1:
        raise ValueError(f"image must be (H, W, C) uint8, got {image.dtype} {image.shape}")
    _f64_rows("table", table)
    if table.shape != (image.shape[2], 256):
        raise ValueError(f"table must be ({image.shape[2]}, 256) for {image.shape[2]} channels, got {table.shape}")
    step = int(step)
    if step < 1:
        raise ValueError(f"step must be >= 1, got {step}")
    shape = (image.shape[0] // step + 1, image.shape[1] // step + 1)
    if out is None:
        out = np.empty(shape, np.float64)
    elif out.shape != shape:
        raise ValueError(f"out must be {shape}, got {out.shape}")
    else:
        _f64_rows("out", out)
    _hist_integral(np.ascontiguousarray(image), table, step, out)
    return out
