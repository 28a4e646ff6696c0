"""fastdet: real-time HOG + linear-classifier vehicle detection for dashcam video.

Public API (imported lazily, so ``import fastdet`` is cheap)::

    from fastdet import hog, hog_channels            # skimage-compatible HOG, per-channel HOG
    from fastdet import hog_channels_batch           # per-channel HOG of a stack of crops
    from fastdet import Detector, VideoDetector      # one frame / a stream of frames
    from fastdet import load_model, Model            # the bundled or a trained model
    from fastdet import FeatureConfig, SearchConfig, SearchBand, HeatConfig, MotionGate, Detections
"""
from __future__ import annotations

import importlib
import os
from typing import Any

# numba's OpenMP workers busy-wait between parallel regions by default; on 2 cores shared with
# the video reader/writer threads (or anything else) that spinning cost 5-8x in throughput.
# Sleeping workers fix it. Set before numba loads OpenMP; a user's own setting wins.
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

from ._version import __version__
from .config import FeatureConfig, HeatConfig, MotionGate, SearchBand, SearchConfig
from .detections import Detections
from .errors import DataError, FastdetError, ModelError

_LAZY = {
    "hog": "fastdet._hog",
    "hog_channels": "fastdet._hog",
    "hog_channels_batch": "fastdet._hog",
    "Detector": "fastdet.detector",
    "VideoDetector": "fastdet.video",
    "HeatMap": "fastdet.heatmap",
    "load_model": "fastdet.model",
    "Model": "fastdet.model",
    "extract_features": "fastdet.features",
}

__all__ = [
    "__version__", "FeatureConfig", "HeatConfig", "MotionGate", "SearchBand", "SearchConfig", "Detections",
    "FastdetError", "ModelError", "DataError", *_LAZY,
]


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        value = getattr(importlib.import_module(_LAZY[name]), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'fastdet' has no attribute {name!r}")
