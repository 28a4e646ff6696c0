"""Detection in one frame: search bands, :class:`Detector` (every window of every band scored
at once) and its scoring kernels."""
from .bands import BandGeometry, band_geometry, scaled_band, window_boxes
from .detector import Detector, DetectStats

__all__ = ["BandGeometry", "band_geometry", "scaled_band", "window_boxes", "DetectStats", "Detector"]
