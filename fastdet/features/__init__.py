"""Features of an image or window: scikit-image-compatible HOG (:func:`hog`), per-channel HOG,
colour conversion, spatial bins and colour histograms; numba kernels beside their wrappers."""
from ._hog import hog, hog_channels, hog_channels_batch
from .window import convert_color, extract_features, hist_bin_shift, spatial_factor, spatial_map

__all__ = ["hog", "hog_channels", "hog_channels_batch", "convert_color", "extract_features",
           "hist_bin_shift", "spatial_factor", "spatial_map"]
