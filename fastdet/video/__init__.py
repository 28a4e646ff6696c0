"""A stream of frames: :class:`VideoDetector` (positive windows → heat map over recent frames →
one box per vehicle), the heat map, the motion gate of the wide model and the fusion of the
two models' boxes."""
from .heatmap import HeatMap
from .pipeline import VideoDetector, WindowDetector, detect_image, iter_video_detections, make_detector

__all__ = ["HeatMap", "VideoDetector", "WindowDetector", "detect_image", "iter_video_detections", "make_detector"]
