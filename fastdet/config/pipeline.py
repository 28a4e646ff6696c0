"""Every setting of the video pipeline in one frozen value (:class:`PipelineConfig`)."""
from __future__ import annotations

import os
from dataclasses import dataclass, replace
from types import MappingProxyType
from typing import Literal, get_args

from ._base import Config
from .guided import GuidedSearch
from .heat import ONCOMING_HEAT, HeatConfig
from .motion import MotionGate
from .ownvehicle import OwnVehicleConfig
from .plausible import PlausibleConfig
from .refine import RefineConfig
from .search import SearchBand, SearchConfig, Traffic, check_traffic
from .split import NeighbourSplit
from .track import TrackerConfig


def _retired() -> dict[str, object]:
    """The dict values the deleted stages' fields had while off (:attr:`PipelineConfig._RETIRED`;
    docs/accuracy.md, "Deleted stages")."""
    def bands(*rows: tuple[float, int, int]) -> tuple[SearchBand, ...]:
        return tuple(SearchBand(*r) for r in rows)

    return {"side": False,
            "side_search": SearchConfig(bands=bands((1.25, 367, 503), (1.75, 360, 521), (2.5, 349, 549),
                                                    (3.5, 334, 586), (5.0, 313, 641), (7.0, 284, 714)),
                                        cells_per_step=2, threshold=0.0).to_dict(),
            "side_heat": HeatConfig(max_aspect=1.0, min_height=10).to_dict(),
            "small": False,
            "small_search": SearchConfig(bands=bands((1.25, 383, 492), (1.5, 378, 503), (1.75, 373, 514),
                                                     (2.0, 368, 525)),
                                         cells_per_step=1, threshold=0.0, shrink="area").to_dict(),
            "small_heat": HeatConfig(threshold=3.5, split_gap=0.5).to_dict(),
            "small_check": -4.6,
            "selfcal": None,
            "perspective": None}


#: how the pipeline makes one box per vehicle of the positive windows: ``'heat'`` (the heat map
#: over frames, a box per blob) or ``'nms'`` (each frame's windows after non-maximum suppression)
Boxes = Literal["heat", "nms"]
BOXES: tuple[str, ...] = get_args(Boxes)

#: where the search bands go: ``'auto'`` (estimated from the video), a fraction of the frame
#: height, or ``None`` (the bands as the search writes them)
Horizon = float | Literal["auto"] | None


def _path(value: object, name: str) -> str | None:
    if value is None:
        return None
    if isinstance(value, (str, os.PathLike)):
        return os.fspath(value)
    raise TypeError(f"{name} must be a path or None, got {type(value).__name__}")


@dataclass(frozen=True)
class PipelineConfig(Config):
    """The settings of :class:`~fastdet.VideoDetector` and of every command that runs it
    (``video``, ``eval --video``, ``bench``, ``batch``), stage by stage.

    model: the main model file; ``None``: the bundled one (:data:`~fastdet.config.models.DEFAULT_MODEL_PATH`).
    oncoming: the oncoming-traffic (wide-window) model: ``True`` the bundled one, a path for
        another, ``False`` none.
    refine_model: the box regressor file; ``None``: the one the main model file carries (a model
        ``fastdet adapt`` made), else the bundled one.
    traffic: the side of the road traffic drives on (:data:`~fastdet.config.TRAFFIC_SIDES`),
        which decides where the oncoming model searches (:func:`~fastdet.config.oncoming_search`).
    search: the main model's search bands (:class:`SearchConfig`).
    horizon: where the search bands go: ``'auto'`` estimates the horizon from the optical flow
        of the first seconds (:mod:`fastdet.video.horizon`), unless the main model records its
        camera's horizon (``fastdet adapt``: :func:`~fastdet.video.detector.camera_horizon`); a
        number is the horizon row as a fraction of the frame height in [0, 1], ``None`` leaves
        the bands where they are written.
    boxes: how one box per vehicle is made of the main model's positive windows: ``'heat'``, the
        heat map over recent frames (:attr:`heat`, a box per blob, the split); ``'nms'``, each
        frame's windows -- and those of the side-view component an adapted model may carry --
        after non-maximum suppression (:mod:`fastdet.video.nmsboxes`; the tracker then splits no
        box); ``None``: what the main model file records (a model ``fastdet adapt``
        made keeps the one that agreed best with its teacher), else ``'heat'``.
    heat: the main model's heat map; oncoming_heat: the oncoming model's.
    motion: the motion gate of the oncoming model.
    tracker: the tracker that gives every vehicle an id; ``None``: no tracking (boxes
        without ids).
    guided: the search between full scans, guided by the tracks; ``None``: the full search
        on every frame. Needs the tracker: without it the search is full (:attr:`planned`).
    refine: the learned box refinement; ``None``: the boxes as the heat map (or the tracker)
        gives them.
    own_vehicle: drop the positive windows lying on the own vehicle (hood, dashboard,
        mirrors, letterbox bars) found in the first seconds (:mod:`fastdet.video.ownvehicle`);
        on by default (:class:`OwnVehicleConfig`: a camera with nothing of its vehicle in
        view gets an empty region and loses no window), ``None``: off.
    split: split the main heat map's wide boxes between the modes of their windows, one box
        per vehicle side by side (:mod:`fastdet.video.blobsplit`); on by default
        (:class:`NeighbourSplit`), ``None``: off.
    plausible: drop the returned boxes that cannot be vehicles (:mod:`fastdet.video.plausible`):
        a second box on one vehicle (IoU above 0.5 with a higher-scored box). ``None``: every box
        the tracker (and the refinement) gives.
    """

    #: the deleted stages' fields at their off values (docs/accuracy.md, "Deleted stages"): an
    #: older config's dict still loads, and today's default config keeps its digest
    _RETIRED = MappingProxyType(_retired())
    #: of those, the ones left out of the dict while off (``None``); ``perspective: null`` was written
    _OMIT_NONE = ("selfcal", "boxes")

    model: str | None = None
    oncoming: str | bool = True
    refine_model: str | None = None
    traffic: Traffic = "right"
    search: SearchConfig = SearchConfig()
    horizon: Horizon = "auto"
    boxes: Boxes | None = None
    heat: HeatConfig = HeatConfig()
    oncoming_heat: HeatConfig = ONCOMING_HEAT
    motion: MotionGate = MotionGate()
    tracker: TrackerConfig | None = TrackerConfig()
    guided: GuidedSearch | None = GuidedSearch()
    refine: RefineConfig | None = RefineConfig()
    own_vehicle: OwnVehicleConfig | None = OwnVehicleConfig()
    split: NeighbourSplit | None = NeighbourSplit()
    plausible: PlausibleConfig | None = PlausibleConfig()

    def __post_init__(self) -> None:
        object.__setattr__(self, "model", _path(self.model, "model"))
        object.__setattr__(self, "refine_model", _path(self.refine_model, "refine_model"))
        if not isinstance(self.oncoming, bool):
            object.__setattr__(self, "oncoming", _path(self.oncoming, "oncoming"))
            if self.oncoming is None:
                raise TypeError("oncoming must be True, False or a path, got None")
        check_traffic(self.traffic)
        h = self.horizon
        if not (h is None or h == "auto" or (isinstance(h, (int, float)) and not isinstance(h, bool) and 0 <= h <= 1)):
            raise ValueError(f"horizon must be 'auto', a fraction of the frame height in [0, 1] or None, got {h!r}")
        if self.boxes is not None and self.boxes not in BOXES:
            raise ValueError(f"boxes must be one of {', '.join(BOXES)} or None, got {self.boxes!r}")
        for name, cls, optional in (("search", SearchConfig, False), ("heat", HeatConfig, False),
                                    ("oncoming_heat", HeatConfig, False), ("motion", MotionGate, False),
                                    ("tracker", TrackerConfig, True), ("guided", GuidedSearch, True),
                                    ("refine", RefineConfig, True),
                                    ("own_vehicle", OwnVehicleConfig, True), ("split", NeighbourSplit, True),
                                    ("plausible", PlausibleConfig, True)):
            v = getattr(self, name)
            if not (isinstance(v, cls) or (optional and v is None)):
                allowed = f"a {cls.__name__}" + (" or None" if optional else "")
                raise TypeError(f"{name} must be {allowed}, got {type(v).__name__}")

    @property
    def planned(self) -> GuidedSearch | None:
        """The guided search that runs: :attr:`guided` with the tracker and when it is not a
        full scan on every frame; ``None``: the full search."""
        if self.tracker is None or self.guided is None or self.guided.full:
            return None
        return self.guided

    def without(self, *stages: Literal["tracker", "guided", "refine", "oncoming"]) -> PipelineConfig:
        """This config with the named optional stages off (``tracker``, ``guided``: the full
        search, ``refine``, ``oncoming``: no oncoming model)."""
        return replace(self, tracker=None if "tracker" in stages else self.tracker,
                       guided=None if "guided" in stages else self.guided,
                       refine=None if "refine" in stages else self.refine,
                       oncoming=False if "oncoming" in stages else self.oncoming)
