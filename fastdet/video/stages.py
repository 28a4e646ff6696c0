"""The stages of :meth:`VideoDetector.update <fastdet.VideoDetector.update>`: small objects
that each take the per-frame :class:`FrameState`, do one step and return it.

In the order they run (:func:`build_stages`; a stage whose setting is off is left out):

===============  ===========================================================================
``horizon``      feed the horizon estimate, move the bands (:class:`HorizonStage`)
``plan``         which windows of the main bands to score (guided search, :class:`PlanStage`)
``motion``       where the picture moves: the oncoming bands to search (:class:`MotionStage`)
``detect``       the positive windows of both models (:class:`DetectStage`)
``motion``       drop the oncoming windows that did not move enough (:class:`GateStage`)
``ownvehicle``   drop the windows on the own vehicle (:class:`OwnVehicleStage`; on by default)
``heatmap``      the main heat map's boxes (:class:`HeatStage`)
``split``        wide boxes split between vehicles side by side (:class:`SplitStage`; on by default)
``nms``          with ``boxes='nms'``, in place of the two above: the frame's windows after
                 non-maximum suppression (:class:`NmsStage`)
``fusion``       the oncoming heat map's boxes where the main one found none (:class:`FusionStage`)
``weak``         the weak blobs the tracker may keep a track alive with (:class:`WeakStage`)
``track``        track ids (:class:`TrackStage`)
``clip``         the tracker's filtered boxes clipped to the frame (:class:`ClipStage`)
``observe``      tell the guided search what this frame found (:class:`ObserveStage`)
``refine``       the learned box refinement (:class:`RefineStage`)
``plausible``    drop the returned boxes that cannot be vehicles (:class:`PlausibleStage`)
===============  ===========================================================================

The last two (:data:`TAIL_STAGES`) change only the boxes returned for the frame: nothing a
later frame reads. :meth:`VideoDetector.start <fastdet.VideoDetector.start>` runs them beside
the next frame's first stages.

Each stage's seconds go to ``VideoDetector.timings`` under its name; a stage may report
finer parts of its work (``detect``: ``resize_colour``, ``hog``, ``score``; ``heatmap``:
``heat``, ``label``), which are then not counted in its own figure, so the figures add up.

A new stage: a class with ``name``, ``__call__(state) -> state`` and ``reset()``, put into
the list :func:`build_stages` returns; what it needs from earlier stages or gives to later
ones is a field of :class:`FrameState`.
"""
from __future__ import annotations

from ..config import GuidedSearch, PipelineConfig
from .blobsplit import SplitStage
from .box_stages import (
    ClipStage,
    FusionStage,
    HeatStage,
    ObserveStage,
    RefineStage,
    TrackStage,
    WeakStage,
)
from .detector import ColumnSearch, MovableHorizon, WindowDetector, box_formation, camera_horizon
from .guided import SearchPlanner
from .nmsboxes import NmsStage
from .ownvehicle import OwnVehicleStage
from .plausible import PlausibleStage
from .refine import BoxRegressor
from .search_stages import DetectStage, GateStage, HorizonStage, MotionStage, PlanStage
from .state import FrameDebug, FrameState, Stage, TrackView
from .track import Tracker

__all__ = ["ClipStage", "DetectStage", "FrameDebug", "FrameState", "FusionStage", "GateStage",
           "HeatStage", "HorizonStage", "MotionStage", "NmsStage", "ObserveStage", "OwnVehicleStage", "PlausibleStage",
            "PlanStage", "RefineStage", "SplitStage", "Stage", "TrackStage",
           "TAIL_STAGES", "TrackView", "WeakStage", "build_stages", "planner_for", "split_tail"]


#: the stages at the end of the list that change only the boxes returned for the frame (no
#: later frame reads what they do): :meth:`fastdet.VideoDetector.start` may run them beside the
#: next frame
TAIL_STAGES: tuple[type[Stage], ...] = (RefineStage, PlausibleStage)


def split_tail(stages: list[Stage]) -> tuple[list[Stage], list[Stage]]:
    """``(head, tail)`` of ``stages``: the tail is the run of :data:`TAIL_STAGES` at the end."""
    cut = len(stages)
    while cut > 0 and isinstance(stages[cut - 1], TAIL_STAGES):
        cut -= 1
    return stages[:cut], stages[cut:]


def planner_for(config: PipelineConfig, detector: WindowDetector) -> SearchPlanner | None:
    """The guided search's planner, when the config plans (:attr:`PipelineConfig.planned`)
    and the detector can score columns."""
    guided: GuidedSearch | None = config.planned
    if guided is None or not isinstance(detector, ColumnSearch):
        return None
    return SearchPlanner(guided)


def build_stages(config: PipelineConfig, detector: WindowDetector, fps: float | None, tracker: Tracker | None,
                 regressor: BoxRegressor | None) -> list[Stage]:
    """The stages for ``config`` and ``detector``, in the order they run (this module's docstring)."""
    stages: list[Stage] = []
    horizon = camera_horizon(config, detector)
    if horizon is not None and isinstance(detector, MovableHorizon):
        stages.append(HorizonStage(detector, horizon))
    planner = planner_for(config, detector)
    if planner is not None:
        stages.append(PlanStage(detector, planner))  # type: ignore[arg-type]
    oncoming = detector.oncoming_model is not None
    gated = oncoming and config.motion.min_motion > 0
    if gated:
        stages.append(MotionStage(detector, config.motion, fps))
    stages.append(DetectStage(detector))
    if gated:
        stages.append(GateStage())
    if config.own_vehicle is not None:
        stages.append(OwnVehicleStage(config.own_vehicle, fps))

    def new_size(first: bool) -> None:  # another picture: its tracks and search plan do not continue
        if tracker is not None and not first:
            tracker.reset()
        if planner is not None:  # on the first frame too: a full scan on the second frame
            planner.reset()

    by_heat = box_formation(config, detector) == "heat"
    heat: list[HeatStage | FusionStage] = []
    if by_heat:
        heat.append(HeatStage(detector, config.heat, oncoming, new_size))
        stages.append(heat[0])
        if config.split is not None:  # on the main heat map's boxes, before the others are added
            stages.append(SplitStage(config.split))
    else:
        stages.append(NmsStage(new_size))
    if oncoming:
        fusion = FusionStage(detector, config.oncoming_heat)
        heat.append(fusion)
        stages.append(fusion)
    if tracker is not None:
        stages += [WeakStage(tracker.config.low_heat, heat), TrackStage(tracker, split=by_heat)]
        if tracker.config.output == "filtered":
            stages.append(ClipStage())
    if planner is not None:
        stages.append(ObserveStage(planner, tracker))
    # the tail (TAIL_STAGES): only the boxes returned for this frame, which no later frame reads
    if regressor is not None and config.refine is not None:
        stages.append(RefineStage(regressor, config.refine))
    if config.plausible is not None:
        stages.append(PlausibleStage(config.plausible))
    return stages
