"""Every setting of fastdet, one module per pipeline stage, as frozen dataclasses (hashable,
comparable, JSON round-trip through one :meth:`~fastdet.config.Config.to_dict` /
:meth:`~fastdet.config.Config.from_dict`, a stable :meth:`~fastdet.config.Config.digest`):

- :mod:`.features`: what a model computes of a window (:class:`FeatureConfig`);
- :mod:`.search`: where to search (:class:`SearchBand`, :class:`SearchConfig`, the
  oncoming-traffic search by traffic side, :func:`oncoming_search`);
- :mod:`.heat`: how the heat map makes boxes (:class:`HeatConfig`, :data:`ONCOMING_HEAT`);
- :mod:`.motion`: the oncoming model's motion gate (:class:`MotionGate`);
- :mod:`.ownvehicle`: the own vehicle's region and the windows dropped there (:class:`OwnVehicleConfig`);
- :mod:`.split`: heat blobs over vehicles side by side split (:class:`NeighbourSplit`);
- :mod:`.plausible`: returned boxes that cannot be vehicles dropped (:class:`PlausibleConfig`);
- :mod:`.track`: the tracker (:class:`TrackerConfig`);
- :mod:`.guided`: the search between full scans (:class:`GuidedSearch`);
- :mod:`.refine`: the box refinement (:class:`RefineConfig`) and its training boxes
  (:class:`JitterConfig`);
- :mod:`.picture`: how a single picture is searched, the whole of it at every scale
  (:class:`PictureSearch`);
- :mod:`.models`: the bundled model files;
- :mod:`.pipeline`: all of the video pipeline's settings in one value (:class:`PipelineConfig`);
- :mod:`.teacher`: a teacher CNN that labels frames (:class:`TeacherConfig`);
- :mod:`.batch`: a batch's settings and options (:class:`Settings`, :class:`BatchOptions`).

A new setting goes into its stage's dataclass (a field with a default and a check in
``__post_init__``); a new stage gets a module here with its dataclass and a field of
:class:`PipelineConfig`.
"""
import warnings
from typing import Any

from ._base import Config
from .features import CELL, COLOR_SPACES, WINDOW, ColorSpace, FeatureConfig
from .guided import GuidedSearch
from .heat import ONCOMING_HEAT, BoxMode, HeatConfig, ScoreKind
from .models import (
    DEFAULT_MODEL_PATH,
    ONCOMING_MODEL_PATH,
    REFINE_MODEL_PATH,
)
from .motion import MotionGate
from .ownvehicle import OwnVehicleConfig
from .picture import PICTURE_SEARCH, PictureSearch
from .pipeline import BOXES, Boxes, Horizon, PipelineConfig
from .plausible import PlausibleConfig
from .refine import JitterConfig, RefineConfig
from .search import (
    ONCOMING_SEARCH,
    REFERENCE_HORIZON,
    REFERENCE_SHAPE,
    TRAFFIC_SIDES,
    SearchBand,
    SearchConfig,
    Traffic,
    check_traffic,
    oncoming_search,
)
from .split import NeighbourSplit
from .teacher import COCO_VEHICLES, TeacherConfig
from .track import TrackerConfig

__all__ = ["BoxMode", "CELL", "COCO_VEHICLES", "COLOR_SPACES", "ColorSpace", "Config", "DEFAULT_MODEL_PATH",
           "BOXES", "Boxes", "FeatureConfig", "GuidedSearch", "HeatConfig", "Horizon", "JitterConfig", "MotionGate",
           "NeighbourSplit", "ONCOMING_HEAT", "ONCOMING_MODEL_PATH", "ONCOMING_SEARCH", "OwnVehicleConfig",
           "PICTURE_SEARCH", "PictureSearch",
           "PipelineConfig", "PlausibleConfig", "REFERENCE_HORIZON", "REFERENCE_SHAPE", "REFINE_MODEL_PATH",
           "RefineConfig", "ScoreKind", "SearchBand", "SearchConfig",
           "TRAFFIC_SIDES", "TeacherConfig", "TrackerConfig", "Traffic", "WINDOW", "check_traffic", "oncoming_search"]

#: former names, kept for code written against them: ``WIDE_HEAT``, ``WIDE_SEARCH``, ``wide_search``
_RENAMED = {"WIDE_HEAT": "ONCOMING_HEAT", "WIDE_SEARCH": "ONCOMING_SEARCH", "wide_search": "oncoming_search"}


def __getattr__(name: str) -> Any:
    if name in _RENAMED:
        new = _RENAMED[name]
        warnings.warn(f"fastdet.config.{name} is deprecated; use fastdet.config.{new}", DeprecationWarning,
                      stacklevel=2)
        return globals()[new]
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
