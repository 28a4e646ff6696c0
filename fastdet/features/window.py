"""Window features: HOG of each selected channel + spatial bins + colour histogram.

The feature vector of one ``win_h x win_w`` crop (default 64x64) in the colour space of a
:class:`~fastdet.config.FeatureConfig`, concatenated in this order:

1. HOG, channel after channel, each as ``skimage.feature.hog(crop[..., c], orientations,
   (ppc, ppc), (cpb, cpb), 'L2-Hys', feature_vector=True)``;
2. spatial bins: ``cv2.resize(crop, (w, h), interpolation=cv2.INTER_LINEAR).ravel()`` with
   ``(h, w) = config.spatial_shape`` (row, column, channel order), as float;
3. colour histogram: ``np.histogram(crop[..., c], bins, range=(0, 256))[0]`` for c = 0, 1, 2.

:func:`extract_features` computes all of it for a stack of crops at once; the spatial bins
come from :func:`spatial_map` (which the detector also uses on whole bands), and the tests
check every part against the plain reference above.
"""
from __future__ import annotations

import cv2
import numba
import numpy as np

from .._numba import split_range
from ..config import FeatureConfig
from . import _hog_kernels
from ._hog import hog_channels_batch
from ._window_kernels import color_hist_batch, hog_to_features, spatial_batch

#: the numba kernels of :func:`extract_features` (compiled ahead of time: fastdet._numba.ensure_compiled)
KERNELS = (_hog_kernels.cell_hists_u8, _hog_kernels.normalize_blocks, hog_to_features, spatial_batch,
           color_hist_batch)

_CONVERSIONS = {
    "RGB": cv2.COLOR_BGR2RGB,
    "HSV": cv2.COLOR_BGR2HSV,
    "HLS": cv2.COLOR_BGR2HLS,
    "LUV": cv2.COLOR_BGR2LUV,
    "YCrCb": cv2.COLOR_BGR2YCrCb,
    "YUV": cv2.COLOR_BGR2YUV,
}


def convert_color(image_bgr: np.ndarray, color_space: str) -> np.ndarray:
    """``(H, W, 3) uint8`` BGR → ``(H, W, 3) uint8`` in ``color_space`` (OpenCV's 8-bit ranges)."""
    if image_bgr.dtype != np.uint8 or image_bgr.ndim != 3 or image_bgr.shape[2] != 3:
        raise ValueError(f"expected an (H, W, 3) uint8 BGR image, got {image_bgr.dtype} {image_bgr.shape}")
    try:
        code = _CONVERSIONS[color_space]
    except KeyError:
        raise ValueError(f"unknown color_space {color_space!r}; expected one of {sorted(_CONVERSIONS)}") from None
    return cv2.cvtColor(image_bgr, code)


def spatial_factor(config: FeatureConfig) -> int:
    """Downscale factor of the spatial bins (``window // spatial_size``)."""
    return config.window // config.spatial_size


def spatial_map(image: np.ndarray, factor: int) -> np.ndarray:
    """What ``cv2.resize(.., INTER_LINEAR)`` by an integer ``factor`` makes of every
    ``factor``-aligned tile: ``(H // factor, W // factor, C) uint8``.

    For an integer shrink, OpenCV's bilinear sample of output pixel ``i`` sits at input
    ``factor*i + factor/2 - 0.5``: the rounded mean of the 2x2 pixels at offsets
    ``factor/2 - 1`` and ``factor/2`` (factor 1: the pixel itself). Because windows start on
    the 8-px cell grid (a multiple of ``factor``), a window's spatial bins are a crop of
    this map, so the detector computes it once per band: ``cv2.resize`` of the aligned part
    (faster than the same sum in NumPy: docs/benchmarks.md, *Kernel notes*).
    """
    if factor == 1:
        return np.ascontiguousarray(image)
    if factor % 2:
        raise ValueError(f"spatial factor must be 1 or even, got {factor}")
    h, w = image.shape[0] // factor, image.shape[1] // factor
    if h and w and image.dtype == np.uint8:
        out = cv2.resize(image[: h * factor, : w * factor], (w, h), interpolation=cv2.INTER_LINEAR)
        return out.reshape((h, w) + image.shape[2:])  # cv2 drops a last axis of 1
    o = factor // 2 - 1
    im = image[: h * factor, : w * factor].astype(np.uint16)
    s = (im[o::factor, o::factor] + im[o + 1::factor, o::factor]
         + im[o::factor, o + 1::factor] + im[o + 1::factor, o + 1::factor])
    return ((s + 2) >> 2).astype(np.uint8)


def hist_bin_shift(config: FeatureConfig) -> int:
    """Colour-histogram bin of a uint8 value v is ``v >> shift`` (bins divide 256)."""
    return int(np.log2(256 // config.hist_bins))


_CHUNK = 64  # crops per HOG call in extract_features (a few MB of block maps)
_MIN_CHUNK = 8  # ... and at least this many (fewer crops than this a thread: one thread)


def extract_features(crops: np.ndarray, config: FeatureConfig | None = None) -> np.ndarray:
    """Feature vectors of a stack of crops.

    crops: ``(N, win_h, win_w, 3) uint8`` BGR (or a single ``(win_h, win_w, 3)`` crop).
    Returns ``(N, config.n_features) float64`` (``(n_features,)`` for a single crop), in the
    order documented in this module. Chunks of the stack are spread over Numba's thread count
    of threads (the kernels release the GIL).
    """

    config = config or FeatureConfig()
    crops = np.asarray(crops)
    single = crops.ndim == 3
    if single:
        crops = crops[None]
    wh, ww = config.win_h, config.win_w
    if crops.dtype != np.uint8 or crops.ndim != 4 or crops.shape[1:] != (wh, ww, 3):
        raise ValueError(f"crops must be (N, {wh}, {ww}, 3) uint8 BGR, got {crops.dtype} {crops.shape}")
    n = crops.shape[0]
    out = np.empty((n, config.n_features), np.float64)
    if n == 0:
        return out[0] if single else out
    # colour conversion of the whole stack at once: (N*wh, ww, 3) is one image to OpenCV
    conv = convert_color(np.ascontiguousarray(crops).reshape(n * wh, ww, 3), config.color_space)
    conv = conv.reshape(n, wh, ww, 3)
    hist_shift = hist_bin_shift(config) if config.hist_bins else 0
    sp_factor = spatial_factor(config) if config.spatial_size else 1
    sp_pos = config.n_hog
    hist_pos = sp_pos + (config.n_spatial if config.spatial_size else 0)

    threads = numba.get_num_threads()
    # chunks of at most _CHUNK crops, small enough that every thread gets one (a few dozen
    # crops, as the box regressor's, on two threads: two chunks); each crop's row is its own
    chunk = max(_MIN_CHUNK, min(_CHUNK, -(-n // threads)))

    def chunks(c0: int, c1: int) -> None:
        """Feature rows of chunks ``c0 <= c < c1`` of ``chunk`` crops, on this thread."""
        for s in range(c0 * chunk, min(c1 * chunk, n), chunk):
            e = min(s + chunk, n)
            part, rows = conv[s:e], out[s:e]
            # 1. HOG: (n, br, bc, nch, cpb, cpb, o) -> channel-major feature order, a chunk small
            #    enough that the kernel's output is still in cache when it is reordered
            hog = hog_channels_batch(part, config.orientations, config.pixels_per_cell,
                                     config.cells_per_block, channels=list(config.hog_channels), threads=1)
            hog_to_features(hog.reshape(hog.shape[:4] + (-1,)), rows)
            # 2. spatial bins (the same pixels as spatial_map / cv2.resize; tested)
            if config.spatial_size:
                spatial_batch(part, sp_factor, rows, sp_pos)
            # 3. colour histograms
            if config.hist_bins:
                hist = np.empty((e - s, config.n_hist), np.float64)
                color_hist_batch(part, hist_shift, config.hist_bins, hist)
                rows[:, hist_pos: hist_pos + config.n_hist] = hist

    split_range(chunks, -(-n // chunk), threads)
    return out[0] if single else out
