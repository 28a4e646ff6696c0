"""A stream of frames: :class:`VideoDetector` (positive windows → heat map over recent frames →
one box per vehicle → a track id for each), the heat map, the motion gate of the wide model,
the fusion of the two models' boxes, the tracker (:class:`Tracker`), the offline pass over a
file's tracks (:func:`offline_pass`) and counting (:class:`VehicleCounter`)."""
from .count import CountLine, VehicleCounter
from .heatmap import HeatMap
from .offline import offline_pass
from .pipeline import VideoDetector, WindowDetector, detect_image, iter_video_detections, make_detector
from .track import Tracker

__all__ = ["CountLine", "HeatMap", "Tracker", "VehicleCounter", "VideoDetector", "WindowDetector", "detect_image",
           "iter_video_detections", "make_detector", "offline_pass"]
