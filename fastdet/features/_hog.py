"""Histogram of Oriented Gradients, compatible with scikit-image, on Numba kernels.

Public functions (exported as ``fastdet.hog`` and ``fastdet.hog_channels``):

* :func:`hog` -- drop-in replacement for ``skimage.feature.hog``: same arguments, same
  output shape, dtype and values (to floating-point rounding; in practice bit-identical).
* :func:`hog_channels` -- the per-channel HOG the vehicle pipeline uses: the HOG of each
  channel computed separately, as one contiguous block map.
* :func:`hog_channels_batch` -- :func:`hog_channels` of a stack of equally sized crops,
  threaded over the stack.

The kernels live in :mod:`fastdet.features._hog_kernels`; this module is the public wrappers,
:mod:`fastdet.features._hog_args` checks their arguments and :mod:`fastdet.features._hog_compute`
computes the block maps (look-up tables, the uint8 and float paths).
"""
from __future__ import annotations

import operator
from collections.abc import Sequence
from typing import Literal

import numba
import numpy as np
from numpy.typing import ArrayLike

from .._numba import split_range
from . import _hog_kernels as _k
from ._hog_args import (  # noqa: F401  (re-exported: the checks' old home)
    BLOCK_NORMS,
    _as_array,
    _block_norm_code,
    _float_dtype,
    _geometry,
    _hog_params,
    _pair,
    _positive_int,
)
from ._hog_compute import (  # noqa: F401  (re-exported: the computation paths' old home)
    _PARALLEL_MIN_SAMPLES,
    _blocks_float,
    _blocks_u8,
    _blocks_u8_fast,
    _cells_u8,
    _compute,
    _gradients,
    _hog_image,
    _integer_gradients,
    _luts,
    _normalize,
    _parts,
)

__all__ = ["hog", "hog_channels", "hog_channels_batch"]

#: block normalisations, as scikit-image names them
BlockNorm = Literal["L1", "L1-sqrt", "L2", "L2-Hys"]
IntPair = tuple[int, int]


# --------------------------------------------------------------------------------------
# public API
# --------------------------------------------------------------------------------------
def hog(image: ArrayLike, orientations: int = 9, pixels_per_cell: IntPair = (8, 8),
        cells_per_block: IntPair = (3, 3), block_norm: BlockNorm = "L2-Hys", visualize: bool = False,
        transform_sqrt: bool = False, feature_vector: bool = True,
        *, channel_axis: int | None = None) -> np.ndarray | tuple[np.ndarray, np.ndarray]:
    """Histogram of Oriented Gradients (HOG) of an image, as ``skimage.feature.hog``.

    Same arguments, defaults, output shape, dtype and values as scikit-image's ``hog``
    (Dalal & Triggs 2005, scikit-image variant), computed by Numba kernels:

    1. optional power-law compression: ``image = sqrt(image)`` (``transform_sqrt``);
    2. gradients by central differences **without** the 1/2 factor,
       ``g_row[r, c] = I[r+1, c] - I[r-1, c]`` and ``g_col[r, c] = I[r, c+1] - I[r, c-1]``,
       zero on the image's first/last rows (``g_row``) and columns (``g_col``); for a
       multichannel image each pixel keeps the gradient of the channel with the largest
       magnitude (the first such channel on ties);
    3. magnitude ``hypot(g_col, g_row)`` and unsigned orientation
       ``rad2deg(arctan2(g_row, g_col)) % 180`` in degrees; hard binning (no interpolation):
       bin ``i`` holds ``180/n*i <= theta < 180/n*(i+1)``;
    4. cell histograms: magnitudes summed per cell and bin (in float32, as skimage does),
       divided by the cell area in pixels; pixels beyond the last whole cell are dropped
       (they still enter the gradients of their neighbours);
    5. blocks of ``cells_per_block`` cells at a one-cell stride, each normalised with
       ``block_norm`` (``eps = 1e-5``): ``'L1'`` ``v / (sum|v| + eps)``; ``'L1-sqrt'``
       ``sqrt(v / (sum|v| + eps))``; ``'L2'`` ``v / sqrt(sum v² + eps²)``; ``'L2-Hys'`` L2,
       clipped at 0.2, then L2 again.

    For ``uint8`` input (without ``transform_sqrt``) the gradients are integers in
    [-255, 255], so bin and magnitude come from exact look-up tables built with the
    same NumPy calls skimage uses (no ``atan2``/``sqrt`` per pixel).

    Parameters
    ----------
    image : (M, N) or (M, N, C) array_like
        Image; real numeric dtype. Must hold at least one block of cells.
    orientations : int
        Number of orientation bins over [0, 180) degrees.
    pixels_per_cell : (int, int) or int
        Cell size in pixels (rows, cols).
    cells_per_block : (int, int) or int
        Block size in cells (rows, cols).
    block_norm : {'L1', 'L1-sqrt', 'L2', 'L2-Hys'}
        Block normalisation (see above).
    visualize : bool
        Also return skimage's HOG picture: per cell and bin, a line segment through the
        cell centre perpendicular to the bin's mid angle, of intensity the cell's
        histogram value.
    transform_sqrt : bool
        Square-root the image first (needs non-negative values).
    feature_vector : bool
        Return ``out.ravel()`` instead of the 5-D block array.
    channel_axis : int or None
        ``None`` for a 2-D (grey) image, else the axis of the channels of a 3-D image.

    Returns
    -------
    out : (n_blocks_row, n_blocks_col, b_row, b_col, orientations) ndarray, or its ravel
        Normalised blocks, ``n_blocks_row = M // p_row - b_row + 1`` (and likewise for
        columns). dtype float32 for float16/float32 input, else float64.
    hog_image : (M, N) ndarray
        Only if ``visualize``.

    Raises
    ------
    ValueError
        Wrong ``image`` ndim, empty or too small ``image``, negative values with
        ``transform_sqrt``, unknown ``block_norm``, bad ``channel_axis``,
        ``orientations``, ``pixels_per_cell`` or ``cells_per_block``; the message names
        the argument.

    References
    ----------
    .. [1] N. Dalal and B. Triggs, "Histograms of Oriented Gradients for Human
           Detection", CVPR 2005, :DOI:`10.1109/CVPR.2005.177`.
    .. [2] scikit-image, ``skimage/feature/_hog.py`` and ``_hoghistogram.pyx``.
    """
    arr = _as_array(image)
    orientations, ppc, cpb, method = _hog_params(orientations, pixels_per_cell, cells_per_block, block_norm)
    if channel_axis is None:
        if arr.ndim != 2:
            raise ValueError(
                f"image must be 2-D when channel_axis is None, got shape {arr.shape}; "
                "for a multichannel image pass channel_axis")
        img3 = arr[:, :, None]
        chans = [0]
        max_channel = False
    else:
        if arr.ndim != 3:
            raise ValueError(
                f"image must be 3-D (two spatial axes and channel_axis), got shape {arr.shape}")
        try:
            axis = operator.index(channel_axis)
        except TypeError:
            raise ValueError(f"channel_axis must be an int or None, got {channel_axis!r}") from None
        if not -arr.ndim <= axis < arr.ndim:
            raise ValueError(f"channel_axis={channel_axis} is out of range for a 3-D image")
        img3 = np.moveaxis(arr, axis, -1)
        chans = list(range(img3.shape[2]))
        max_channel = True
    ht, out, float_dtype = _compute(img3, chans, max_channel, ppc, cpb, orientations,
                                    method, bool(transform_sqrt))
    blocks = out.reshape(out.shape[0], out.shape[1], cpb[0], cpb[1], orientations)
    if float_dtype is not np.float64:
        blocks = blocks.astype(float_dtype)
    if feature_vector:
        blocks = blocks.ravel()
    if visualize:
        return blocks, _hog_image(ht, ppc, orientations, img3.shape[:2], float_dtype)
    return blocks


def _channel_list(channels, n_channels: int) -> list[int]:
    if channels is None:
        return list(range(n_channels))
    if isinstance(channels, (int, np.integer)):
        channels = [channels]
    try:
        chans = [operator.index(c) for c in channels]
    except TypeError:
        raise ValueError(f"channels must be None or a sequence of ints, got {channels!r}") from None
    if not chans:
        raise ValueError("channels must not be empty")
    for c in chans:
        if not -n_channels <= c < n_channels:
            raise ValueError(f"channels: index {c} is out of range for {n_channels} channels")
    return [c % n_channels for c in chans]


def hog_channels(image: ArrayLike, orientations: int = 9, pixels_per_cell: int | IntPair = 8,
                 cells_per_block: int | IntPair = 2, block_norm: BlockNorm = "L2-Hys",
                 transform_sqrt: bool = False, channels: Sequence[int] | None = None,
                 exact: bool = True) -> np.ndarray:
    """Per-channel HOG block map of an ``(H, W, C)`` (or ``(H, W)``) image.

    Each selected channel gets its own HOG, exactly
    ``skimage.feature.hog(image[..., ch], orientations, pixels_per_cell, cells_per_block,
    block_norm, transform_sqrt=transform_sqrt, feature_vector=False)`` (see :func:`hog`
    for the algorithm), and the results are interleaved into one block map::

        out[r, c, k] == skimage.feature.hog(image[..., channels[k]], ...,
                                            feature_vector=False)[r, c]

    so that a row of blocks (all channels) is contiguous in memory. This is the hot path
    of the detector: for uint8 input the gradients, look-up-table binning and float32 cell
    sums are fused in one pass, threaded over cell rows (NUMBA_NUM_THREADS /
    ``numba.set_num_threads``), and the GIL is released.

    Parameters
    ----------
    image : (H, W, C) or (H, W) array_like
        Channels last; a 2-D image is one channel.
    orientations : int
        Orientation bins over [0, 180) degrees.
    pixels_per_cell, cells_per_block : int or (int, int)
        Cell size in pixels, block size in cells.
    block_norm : {'L1', 'L1-sqrt', 'L2', 'L2-Hys'}
    transform_sqrt : bool
        Square-root the image first (non-negative values only).
    channels : sequence of int or None
        Channels to use, in output order (``None``: all).
    exact : bool
        ``True``: skimage's values to the last bit. ``False`` (what the detector uses): the
        same cell histograms, but each block is summed in any order and scaled by a
        reciprocal, so values may differ from skimage's by an ulp or two (~1e-16, relative);
        5x faster block normalisation for uint8 images without ``transform_sqrt`` (other
        inputs take the exact path).

    Returns
    -------
    out : (n_blocks_row, n_blocks_col, n_channels, b_row, b_col, orientations) ndarray
        C-contiguous float64 (values of float32 input are rounded to float32, as
        skimage returns them).
    """
    arr = _as_array(image)
    if arr.ndim == 2:
        arr = arr[:, :, None]
    elif arr.ndim != 3:
        raise ValueError(f"image must be (H, W) or (H, W, C), got shape {arr.shape}")
    orientations, ppc, cpb, method = _hog_params(orientations, pixels_per_cell, cells_per_block, block_norm)
    chans = _channel_list(channels, arr.shape[2])
    if not exact and arr.dtype == np.uint8 and not transform_sqrt:
        n_cells, n_blocks = _geometry(arr.shape[:2], ppc, cpb)
        out = _blocks_u8_fast(np.ascontiguousarray(arr), np.asarray(chans, dtype=np.int64), ppc, cpb,
                              orientations, method, n_cells, n_blocks)
        return out.reshape(out.shape[0], out.shape[1], out.shape[2], cpb[0], cpb[1], orientations)
    _, out, float_dtype = _compute(arr, chans, False, ppc, cpb, orientations, method,
                                   bool(transform_sqrt))
    if float_dtype is not np.float64:
        out[...] = out.astype(float_dtype)
    return out.reshape(out.shape[0], out.shape[1], out.shape[2], cpb[0], cpb[1], orientations)


def hog_channels_batch(images: ArrayLike, orientations: int = 9, pixels_per_cell: int | IntPair = 8,
                       cells_per_block: int | IntPair = 2, block_norm: BlockNorm = "L2-Hys",
                       channels: Sequence[int] | None = None, *, threads: int | None = None) -> np.ndarray:
    """:func:`hog_channels` of every image of an ``(N, H, W, C)`` stack (or ``(N, H, W)``).

    For a uint8 stack (e.g. 64x64 training crops) the uint8 kernels run image after image,
    the images spread over ``threads`` Python threads (``None``: Numba's thread count); other
    dtypes fall back to one :func:`hog_channels` call per image.

    Returns
    -------
    out : (N, n_blocks_row, n_blocks_col, n_channels, b_row, b_col, orientations) ndarray
        C-contiguous float64; ``out[i] == hog_channels(images[i], ...)``.
    """
    try:
        arr = np.asarray(images)
    except Exception as exc:  # noqa: BLE001
        raise ValueError(f"images must be array-like: {exc}") from None
    if arr.ndim == 3:
        arr = arr[..., None]
    elif arr.ndim != 4:
        raise ValueError(f"images must be (N, H, W, C) or (N, H, W), got shape {arr.shape}")
    if arr.shape[1] == 0 or arr.shape[2] == 0 or arr.shape[3] == 0:
        raise ValueError(f"images are empty (shape {arr.shape})")
    orientations, ppc, cpb, method = _hog_params(orientations, pixels_per_cell, cells_per_block, block_norm)
    chans = _channel_list(channels, arr.shape[3])
    _float_dtype(arr.dtype)
    n_cells, n_blocks = _geometry(arr.shape[1:3], ppc, cpb, name="images")
    shape = (arr.shape[0], n_blocks[0], n_blocks[1], len(chans), cpb[0], cpb[1],
             orientations)
    if arr.dtype != np.uint8:
        out = np.empty(shape)
        for i in range(arr.shape[0]):
            out[i] = hog_channels(arr[i], orientations, ppc, cpb, block_norm, False, chans)
        return out
    bin_lut, mag_lut = _luts(orientations)
    out = np.empty((shape[0], n_blocks[0], n_blocks[1], len(chans),
                    cpb[0] * cpb[1] * orientations))
    imgs = np.ascontiguousarray(arr)
    chans_arr = np.asarray(chans, dtype=np.int64)

    ncr, nbr = n_cells[0], n_blocks[0]

    def run(lo: int, hi: int) -> None:
        """Images ``lo <= i < hi``, on this thread: two kernel calls per image (a few µs of
        dispatch against ~0.1 ms of work) -- a kernel looping over the images would be one
        more kernel to compile, with copies of both."""
        ht = np.empty((ncr, len(chans), n_cells[1], orientations))  # scratch, one per thread
        for i in range(lo, hi):
            _k.cell_hists_u8(imgs[i], chans_arr, False, 0, ncr, ppc[0], ppc[1], bin_lut, mag_lut, ht)
            _k.normalize_blocks(ht, 0, nbr, cpb[0], cpb[1], method, out[i])

    n_threads = numba.get_num_threads() if threads is None else int(threads)
    split_range(run, arr.shape[0], min(n_threads, arr.shape[0] // 4 + 1))
    return out.reshape(shape)
