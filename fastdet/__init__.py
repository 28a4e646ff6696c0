"""fastdet: real-time HOG + linear-classifier vehicle detection for dashcam video.

Public API (the heavy parts are imported lazily, so ``import fastdet`` is cheap)::

    from fastdet import hog, hog_channels            # skimage-compatible HOG, per-channel HOG
    from fastdet import hog_channels_batch           # per-channel HOG of a stack of crops
    from fastdet import Detector, VideoDetector      # one frame / a stream of frames
    from fastdet import detect_video                 # a video file, as `python -m fastdet video` runs it
    from fastdet import load_model, Model            # the bundled or a trained model
    from fastdet import Detections, Box              # the box table (boxes + scores, ids, frames ...), one row
    from fastdet import sample_video                 # the path of the sample clip that ships with fastdet
    from fastdet import PipelineConfig               # every setting of the video pipeline (fastdet.config)
    from fastdet import FeatureConfig, SearchConfig, SearchBand, HeatConfig, MotionGate, TrackerConfig

Sub-packages, one per pipeline stage (layers point down): ``features`` (HOG, colour
features) → ``detect`` (search bands, Detector) → ``video`` (heat map, motion gate, fusion,
VideoDetector) → ``cli`` (commands); beside them ``io`` (reader, sink, box files, atomic
writes), ``eval`` (metrics, report) and ``train`` (datasets, fitting, mining).
"""
from __future__ import annotations

import importlib
import os
from typing import TYPE_CHECKING, Any

# numba's OpenMP workers busy-wait between parallel regions by default; on 2 cores shared with
# the video reader/writer threads (or anything else) that spinning takes the cores the others
# need, so the workers sleep instead (docs/benchmarks.md, *OpenMP wait policy*). Set here,
# before any submodule can load numba's OpenMP layer; a user's own setting wins.
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

from ._version import __version__
from .errors import DataError, FastdetError, ModelError

if TYPE_CHECKING:  # what the lazy names below resolve to, for type checkers and IDEs
    from .config import FeatureConfig as FeatureConfig
    from .config import HeatConfig as HeatConfig
    from .config import MotionGate as MotionGate
    from .config import PipelineConfig as PipelineConfig
    from .config import SearchBand as SearchBand
    from .config import SearchConfig as SearchConfig
    from .config import TrackerConfig as TrackerConfig
    from .data import sample_video as sample_video
    from .detect import Detector as Detector
    from .detections import Box as Box
    from .detections import Detections as Detections
    from .features import extract_features as extract_features
    from .features import hog as hog
    from .features import hog_channels as hog_channels
    from .features import hog_channels_batch as hog_channels_batch
    from .model import Model as Model
    from .model import load_model as load_model
    from .video import HeatMap as HeatMap
    from .video import VideoDetector as VideoDetector
    from .video import detect_video as detect_video

# everything that imports NumPy is lazy: ``python -m fastdet`` imports this package before
# its first line of its own runs, and installs its stop-signal handlers right after
_LAZY = {
    "FeatureConfig": "fastdet.config",
    "HeatConfig": "fastdet.config",
    "MotionGate": "fastdet.config",
    "PipelineConfig": "fastdet.config",
    "SearchBand": "fastdet.config",
    "SearchConfig": "fastdet.config",
    "TrackerConfig": "fastdet.config",
    "Detections": "fastdet.detections",
    "Box": "fastdet.detections",
    "hog": "fastdet.features",
    "hog_channels": "fastdet.features",
    "hog_channels_batch": "fastdet.features",
    "extract_features": "fastdet.features",
    "Detector": "fastdet.detect",
    "VideoDetector": "fastdet.video",
    "detect_video": "fastdet.video",
    "HeatMap": "fastdet.video",
    "load_model": "fastdet.model",
    "Model": "fastdet.model",
    "sample_video": "fastdet.data",
}

__all__ = ["__version__", "FastdetError", "ModelError", "DataError", *_LAZY]


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        value = getattr(importlib.import_module(_LAZY[name]), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'fastdet' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
