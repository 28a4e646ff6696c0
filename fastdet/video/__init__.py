"""A stream of frames: :class:`VideoDetector` (positive windows → heat map over recent frames →
one box per vehicle → a track id for each) as a sequence of stages (:mod:`.stages`), the heat
map, the motion gate of the oncoming model, the fusion of the two models' boxes, the tracker
(:class:`Tracker`), single pictures (:func:`detect_picture`), running a file (:func:`detect_video`, :mod:`.run`), the
offline pass over a file's tracks (:func:`offline_pass`) and counting (:class:`VehicleCounter`)."""
from .count import CountLine, VehicleCounter
from .detector import ColumnSearch, HasKernels, MovableHorizon, WindowDetector, make_detector
from .heatmap import HeatMap, detect_image
from .offline import offline_pass
from .picture import PictureDetector, detect_picture
from .pipeline import PendingFrame, VideoDetector, run_frames
from .run import detect_video, iter_video_detections, prime_horizon_from_file, progress_bar, video_detector_for
from .stages import FrameDebug
from .track import Tracker

__all__ = ["ColumnSearch", "CountLine", "FrameDebug", "HasKernels", "HeatMap", "MovableHorizon", "PendingFrame",
           "PictureDetector", "Tracker", "VehicleCounter", "VideoDetector", "WindowDetector", "detect_image",
           "detect_picture", "detect_video", "iter_video_detections", "make_detector", "offline_pass",
           "prime_horizon_from_file", "progress_bar", "run_frames", "video_detector_for"]
