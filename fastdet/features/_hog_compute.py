"""The HOG block maps of an already checked image: the look-up tables of the uint8 path,
the uint8 (LUT) and float (skimage's steps) computation paths, rows spread over threads,
and the visualisation image. Called by the wrappers of :mod:`fastdet.features._hog`; the
kernels live in :mod:`fastdet.features._hog_kernels`."""
from __future__ import annotations

import threading

import numba
import numpy as np

from .._numba import split_range
from . import _hog_kernels as _k
from ._hog_args import _float_dtype, _geometry

# Below this many pixel-channels per image the uint8 kernel runs on one thread: waking the
# thread pool costs more than it saves on a small image.
_PARALLEL_MIN_SAMPLES = 32_768

_lut_lock = threading.Lock()
_mag_lut: np.ndarray | None = None
_bin_luts: dict[int, np.ndarray] = {}


# --------------------------------------------------------------------------------------
# look-up tables for uint8 images
# --------------------------------------------------------------------------------------
def _integer_gradients() -> tuple[np.ndarray, np.ndarray]:
    g = np.arange(-_k.LUT_OFFSET, _k.LUT_OFFSET + 1, dtype=np.float64)
    g_row, g_col = np.meshgrid(g, g, indexing="ij")
    return g_row, g_col


def _luts(orientations: int) -> tuple[np.ndarray, np.ndarray]:
    """(bin_lut, mag_lut) over every uint8 gradient pair ``(g_row, g_col)`` in
    [-255, 255]², flattened with index ``(g_row + 255) * 511 + (g_col + 255)``.

    Both are computed with the very NumPy calls skimage makes (``np.hypot(g_col, g_row)``
    and ``np.rad2deg(np.arctan2(g_row, g_col)) % 180`` with its bin tests), so a table
    look-up returns exactly the value skimage computes for that pixel.
    """
    global _mag_lut
    bins = _bin_luts.get(orientations)
    if bins is not None and _mag_lut is not None:
        return bins, _mag_lut
    with _lut_lock:
        g_row, g_col = _integer_gradients()
        if _mag_lut is None:
            mag = np.hypot(g_col, g_row)
            # skimage's multichannel selection uses np.hypot(g_row, g_col); the kernel
            # compares these table values, so the two must agree bit for bit
            if not np.array_equal(mag, np.hypot(g_row, g_col)):
                raise RuntimeError("np.hypot is not symmetric on this platform")
            _mag_lut = np.ascontiguousarray(mag.ravel())
        if orientations not in _bin_luts:
            orient = np.rad2deg(np.arctan2(g_row, g_col)) % 180
            per180 = 180.0 / orientations
            lut = np.full(orient.shape, -1, dtype=np.int16)
            for i in range(orientations):
                inside = (orient < per180 * (i + 1)) & (orient >= per180 * i)
                lut[inside] = i
            if (lut < 0).any():  # an integer gradient always falls in a bin
                raise RuntimeError(f"orientation LUT has unbinned entries for {orientations}")
            dtype = np.int8 if orientations <= 127 else np.int16
            _bin_luts[orientations] = np.ascontiguousarray(lut.ravel().astype(dtype))
        return _bin_luts[orientations], _mag_lut




# --------------------------------------------------------------------------------------
# the two computation paths
# --------------------------------------------------------------------------------------
def _cells_u8(img, chans, max_channel, ppc, orientations, n_cells, n_out_ch):
    """Cell histograms ``ht (n_cells_row, n_out_ch, n_cells_col, orientations)`` of a uint8
    ``(rows, cols, C)`` C-contiguous image; cell rows spread over threads for a big image."""
    bin_lut, mag_lut = _luts(orientations)
    ht = np.empty((n_cells[0], n_out_ch, n_cells[1], orientations))
    parts = _parts(img.shape[0] * img.shape[1] * len(chans), n_cells[0])
    split_range(lambda lo, hi: _k.cell_hists_u8(img, chans, max_channel, lo, hi, ppc[0], ppc[1], bin_lut, mag_lut,
                                                ht), n_cells[0], parts)
    return ht


def _parts(samples: int, rows: int) -> int:
    """Threads worth using for ``samples`` pixel-channels in ``rows`` rows: one below
    :data:`_PARALLEL_MIN_SAMPLES` (waking threads costs more than it saves), else Numba's
    thread count (1 in a band thread of the detector)."""
    if samples < _PARALLEL_MIN_SAMPLES or rows < 2:
        return 1
    return min(numba.get_num_threads(), rows)


def _normalize(kernel, ht, cpb, method, n_blocks, n_out_ch, orientations, parts):
    """Block map ``(n_blocks_row, n_blocks_col, n_out_ch, block size)`` of ``ht`` by ``kernel``
    (:func:`~._hog_kernels.normalize_blocks` or ``normalize_blocks_fast``), block rows spread
    over ``parts`` threads."""
    out = np.empty((n_blocks[0], n_blocks[1], n_out_ch, cpb[0] * cpb[1] * orientations))
    split_range(lambda lo, hi: kernel(ht, lo, hi, cpb[0], cpb[1], method, out), n_blocks[0],
                min(parts, n_blocks[0]))
    return out


def _blocks_u8(img, chans, max_channel, ppc, cpb, orientations, method, n_cells, n_blocks):
    """uint8 ``(rows, cols, C)`` C-contiguous image -> (ht, blocks) via the LUT kernel."""
    n_out_ch = 1 if max_channel else len(chans)
    ht = _cells_u8(img, chans, max_channel, ppc, orientations, n_cells, n_out_ch)
    parts = _parts(img.shape[0] * img.shape[1] * len(chans), n_cells[0])
    return ht, _normalize(_k.normalize_blocks, ht, cpb, method, n_blocks, n_out_ch, orientations, parts)


def _blocks_u8_fast(img, chans, ppc, cpb, orientations, method, n_cells, n_blocks):
    """uint8 ``(rows, cols, C)`` C-contiguous image -> per-channel blocks, normalised to
    within an ulp of skimage (:func:`hog_channels` ``exact=False``)."""
    ht = _cells_u8(img, chans, False, ppc, orientations, n_cells, len(chans))
    parts = _parts(img.shape[0] * img.shape[1] * len(chans), n_cells[0])
    return _normalize(_k.normalize_blocks_fast, ht, cpb, method, n_blocks, len(chans), orientations, parts)


def _gradients(channel: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Central differences without the 1/2, zero on the outer rows / columns, in the
    channel's dtype (skimage's ``_hog_channel_gradient``)."""
    g_row = np.zeros(channel.shape, dtype=channel.dtype)
    g_row[1:-1, :] = channel[2:, :] - channel[:-2, :]
    g_col = np.zeros(channel.shape, dtype=channel.dtype)
    g_col[:, 1:-1] = channel[:, 2:] - channel[:, :-2]
    return g_row, g_col


def _blocks_float(img, chans, max_channel, ppc, cpb, orientations, method, n_cells,
                  n_blocks):
    """Float ``(rows, cols, C)`` image (already in skimage's working dtype, already
    square-rooted if asked) -> (cell histograms, blocks).

    Gradient magnitude and orientation use NumPy's ``hypot``/``arctan2`` exactly as
    skimage does (NumPy's SIMD versions differ from libm's by an ulp now and then, which
    could flip a bin), then the kernels bin, accumulate and normalise.
    """
    n_out_ch = 1 if max_channel else len(chans)
    ht = np.empty((n_cells[0], n_out_ch, n_cells[1], orientations))
    if max_channel:
        # skimage's steps verbatim: per-channel gradients and magnitudes in an
        # (rows, cols, C) array, argmax over channels (first on ties), then gather
        shape = img.shape[:2] + (len(chans),)
        g_row_by_ch = np.empty(shape, dtype=img.dtype)
        g_col_by_ch = np.empty(shape, dtype=img.dtype)
        g_magn = np.empty(shape, dtype=img.dtype)
        for i, ch in enumerate(chans):
            g_row_by_ch[:, :, i], g_col_by_ch[:, :, i] = _gradients(img[:, :, ch])
            g_magn[:, :, i] = np.hypot(g_row_by_ch[:, :, i], g_col_by_ch[:, :, i])
        pick = g_magn.argmax(axis=2)[:, :, None]
        pairs = [(np.take_along_axis(g_row_by_ch, pick, axis=2)[:, :, 0],
                  np.take_along_axis(g_col_by_ch, pick, axis=2)[:, :, 0])]
    else:
        pairs = (_gradients(img[:, :, ch]) for ch in chans)
    for k, (g_row, g_col) in enumerate(pairs):
        g_row = np.ascontiguousarray(g_row, dtype=np.float64)
        g_col = np.ascontiguousarray(g_col, dtype=np.float64)
        magnitude = np.hypot(g_col, g_row)
        orientation = np.rad2deg(np.arctan2(g_row, g_col)) % 180
        _k.cell_hist_float(magnitude, orientation, ppc[0], ppc[1], k, ht)
    return ht, _normalize(_k.normalize_blocks, ht, cpb, method, n_blocks, n_out_ch, orientations, 1)


def _compute(img3, chans, max_channel, ppc, cpb, orientations, method, transform_sqrt):
    """Dispatch on dtype. ``img3`` is ``(rows, cols, C)``; returns (cell histograms ``(rows,
    channels, cols, orientations)``, blocks, dtype)."""
    float_dtype = _float_dtype(img3.dtype)
    n_cells, n_blocks = _geometry(img3.shape[:2], ppc, cpb)
    if transform_sqrt:
        if img3.dtype.kind != "u" and bool(np.any(img3 < 0)):
            raise ValueError("transform_sqrt=True needs a non-negative image: "
                             "image has negative values")
    chans = np.asarray(chans, dtype=np.int64)
    if img3.dtype == np.uint8 and not transform_sqrt:
        ht, out = _blocks_u8(np.ascontiguousarray(img3), chans, max_channel, ppc, cpb,
                             orientations, method, n_cells, n_blocks)
    else:
        work = img3.astype(float_dtype, copy=False)
        if transform_sqrt:
            work = np.sqrt(work)
        ht, out = _blocks_float(work, chans, max_channel, ppc, cpb, orientations, method,
                                n_cells, n_blocks)
    return ht, out, float_dtype


def _hog_image(ht, ppc, orientations, shape, float_dtype):
    radius = min(ppc) // 2 - 1
    midpoints = np.pi * (np.arange(orientations) + 0.5) / orientations
    dr_arr = np.ascontiguousarray(radius * np.sin(midpoints), dtype=np.float64)
    dc_arr = np.ascontiguousarray(radius * np.cos(midpoints), dtype=np.float64)
    image = np.zeros(shape, dtype=float_dtype)
    _k.draw_hog_image(ht, ppc[0], ppc[1], dr_arr, dc_arr, image)
    return image

