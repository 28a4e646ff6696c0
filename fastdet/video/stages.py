"""The stages of :meth:`VideoDetector.update <fastdet.VideoDetector.update>`: small objects
that each take the per-frame :class:`FrameState`, do one step and return it.

In the order they run (:func:`build_stages`; a stage whose setting is off is left out):

=============  ===========================================================================
``horizon``    feed the horizon estimate, move the bands (:class:`HorizonStage`)
``plan``       which windows of the main bands to score (guided search, :class:`PlanStage`)
``motion``     where the picture moves: the oncoming bands to search (:class:`MotionStage`)
``detect``     the positive windows of both models (:class:`DetectStage`)
``motion``     drop the oncoming windows that did not move enough (:class:`GateStage`)
``heatmap``    the main heat map's boxes (:class:`HeatStage`)
``fusion``     the oncoming heat map's boxes where the main one found none (:class:`FusionStage`)
``weak``       the weak blobs the tracker may keep a track alive with (:class:`WeakStage`)
``track``      track ids (:class:`TrackStage`)
``clip``       the tracker's filtered boxes clipped to the frame (:class:`ClipStage`)
``refine``     the learned box refinement (:class:`RefineStage`)
``observe``    tell the guided search what this frame found (:class:`ObserveStage`)
=============  ===========================================================================

Each stage's seconds go to ``VideoDetector.timings`` under its name; a stage may report
finer parts of its work (``detect``: ``resize_colour``, ``hog``, ``score``; ``heatmap``:
``heat``, ``label``), which are then not counted in its own figure, so the figures add up.

A new stage: a class with ``name``, ``__call__(state) -> state`` and ``reset()``, put into
the list :func:`build_stages` returns; what it needs from earlier stages or gives to later
ones is a field of :class:`FrameState`.
"""
from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass, field

import numpy as np

from ..boxes import clip, overlap_fraction
from ..config import (
    GuidedSearch,
    HeatConfig,
    MotionGate,
    PipelineConfig,
    RefineConfig,
    SearchBand,
)
from ..detect import DetectStats
from ..detections import Detections
from .detector import ColumnSearch, MovableHorizon, WindowDetector
from .fusion import merge_wide
from .guided import SearchPlanner
from .heatmap import HeatMap
from .horizon import HORIZON_FRAMES, TOLERANCE, HorizonEstimator, search_horizon
from .motion import FrameMotion, MotionMap, moving_bands, window_motion
from .refine import BoxRegressor, refine
from .track import LOST, Tracker

#: one live track: ``(id, state, predicted box)``, id -1 while tentative
TrackView = tuple[int, str, np.ndarray]


@dataclass
class FrameState:
    """One frame on its way through the stages.

    frame: the frame as given, ``(H, W, 3) uint8``; rgb: its channels are RGB (else BGR).
    columns: the guided search's window columns per main band (``None``: every window).
    motion, gate, oncoming_bands: this frame's motion over the oncoming search, the gate in
        grey levels and the parts of the oncoming bands that move (``None``: not gated).
    windows: the positive windows (:class:`Detections` with ``scale`` and ``part``).
    boxes: the heat maps' boxes; low: the weak boxes given to the tracker.
    out: what :meth:`~fastdet.VideoDetector.update` returns.
    tracks: every live track after the tracker.
    timings: seconds of the finer parts of a stage's work (see the module docstring).
    """

    frame: np.ndarray
    rgb: bool = False
    columns: list | None = None
    motion: MotionMap | None = None
    gate: float = 0.0
    oncoming_bands: list[SearchBand] | None = None
    windows: Detections = field(default_factory=Detections.empty)
    boxes: Detections = field(default_factory=Detections.empty)
    low: Detections = field(default_factory=Detections.empty)
    out: Detections = field(default_factory=Detections.empty)
    heatmap: HeatMap | None = None
    tracks: list[TrackView] = field(default_factory=list)
    timings: dict[str, float] = field(default_factory=dict)

    @property
    def shape(self) -> tuple[int, int]:
        return int(self.frame.shape[0]), int(self.frame.shape[1])

    @property
    def bgr(self) -> np.ndarray:
        """The frame in BGR order (a contiguous copy for an RGB frame)."""
        return np.ascontiguousarray(self.frame[..., ::-1]) if self.rgb else self.frame


@dataclass(frozen=True)
class FrameDebug:
    """What :meth:`~fastdet.VideoDetector.update` saw on the last frame, for debugging and
    drawing: windows (the positive windows), heat (the main heat grid, float64, one cell =
    ``HeatConfig.cell`` pixels), mask (heat > threshold), labels (blob labels), boxes (the heat
    maps' boxes, before the tracker), low (the weak boxes given to the tracker), tracks (every
    live track: ``(id, state, predicted box)``, id -1 while tentative). New objects every
    frame, so a consumer may keep them while the next frame is processed."""

    windows: Detections = field(default_factory=Detections.empty)
    heat: np.ndarray = field(default_factory=lambda: np.zeros((0, 0), np.float64))
    mask: np.ndarray = field(default_factory=lambda: np.zeros((0, 0), bool))
    labels: np.ndarray = field(default_factory=lambda: np.zeros((0, 0), np.int32))
    boxes: Detections = field(default_factory=Detections.empty)
    low: Detections = field(default_factory=Detections.empty)
    tracks: list[TrackView] = field(default_factory=list)

    @classmethod
    def of(cls, s: FrameState) -> FrameDebug:
        """The record of a frame that went through the stages."""
        hm = s.heatmap
        assert hm is not None
        return cls(s.windows, hm.heat, hm.mask, hm.labels, s.boxes, s.low, s.tracks)


class Stage:
    """One step of :meth:`~fastdet.VideoDetector.update` (module docstring)."""

    name = "stage"

    def __call__(self, s: FrameState) -> FrameState:
        raise NotImplementedError

    def reset(self) -> None:
        """Forget the previous frames (a new video or a cut)."""


class HorizonStage(Stage):
    """Put the detector's bands at the configured horizon (``'auto'``: at the reference until
    there is an estimate, then where the first frames' optical flow puts it)."""

    name = "horizon"

    def __init__(self, detector: MovableHorizon, horizon: float | str) -> None:
        self.detector = detector
        self.horizon = horizon
        self.estimator: HorizonEstimator | None = None
        self.started = False

    def start(self) -> None:
        """Set the bands and start a new estimate (``'auto'``)."""
        self.started = True
        self.estimator = None
        if self.horizon == "auto":
            self.detector.set_horizon(None)
            self.estimator = HorizonEstimator()
        else:
            self.detector.set_horizon(float(self.horizon))

    def prime(self, frames: Iterable[np.ndarray]) -> float | None:
        """Estimate the horizon from ``frames`` (at most HORIZON_FRAMES) now; the bands go there."""
        self.start()
        est = self.estimator
        if est is None:
            return self.detector.horizon
        for i, f in enumerate(frames):
            if i >= HORIZON_FRAMES or est.done:
                break
            est.update(np.asarray(f))
        self.detector.set_horizon(search_horizon(est.estimate))
        self.estimator = None
        return self.detector.horizon

    def __call__(self, s: FrameState) -> FrameState:
        if not self.started:
            self.start()
        est = self.estimator
        if est is None:
            return s
        est.update(s.frame)
        h = search_horizon(est.estimate)
        cur = self.detector.horizon
        if (h is None) != (cur is None) or (h is not None and cur is not None and abs(h - cur) > 0.5 * TOLERANCE):
            self.detector.set_horizon(h)
        if est.done or est.frames >= HORIZON_FRAMES:
            self.estimator = None  # settled: no more flow to compute
        return s

    def reset(self) -> None:
        if self.estimator is not None:
            self.estimator.cut()  # the camera stays: keep the estimate, pair no frames across the cut


class PlanStage(Stage):
    """Which windows of the main model's bands this frame scores (:mod:`fastdet.video.guided`)."""

    name = "plan"

    def __init__(self, detector: ColumnSearch, planner: SearchPlanner) -> None:
        self.detector = detector
        self.planner = planner

    def __call__(self, s: FrameState) -> FrameState:
        det, cfg = self.detector, self.detector.config  # type: ignore[attr-defined]
        s.columns = self.planner.plan(det.geometries(s.shape, 0), cfg.win_w, cfg.pixels_per_cell,  # type: ignore[attr-defined]
                                      s.shape)
        return s

    def reset(self) -> None:
        self.planner.reset()  # a full scan next


class MotionStage(Stage):
    """This frame's motion over the oncoming search's region (against the frame
    :meth:`MotionGate.lag` back at ``fps``), the gate for it (:meth:`MotionGate.threshold` of
    its noise) and the parts of the oncoming bands where some window moves at least that much."""

    name = "motion"

    def __init__(self, detector: WindowDetector, gate: MotionGate, fps: float | None) -> None:
        self.detector, self.gate, self.fps = detector, gate, fps
        self.motion = FrameMotion()

    def __call__(self, s: FrameState) -> FrameState:
        det = self.detector
        geos = det.geometries(s.shape, part=1)
        roi = (min(g.x0 for g in geos), min(g.y0 for g in geos), max(g.x1 for g in geos), max(g.y1 for g in geos))
        motion = self.motion.update(s.frame[:, :, ::-1] if s.rgb else s.frame, roi, lag=self.gate.lag(self.fps))
        if motion is None:
            s.motion, s.oncoming_bands, s.gate = None, [], 0.0
            return s
        assert det.wide_model is not None
        gate = self.gate.threshold(motion.noise)
        s.motion, s.gate = motion, gate
        s.oncoming_bands = [b for g in geos for b in moving_bands(g, det.wide_model.config, motion, gate)]
        return s

    def reset(self) -> None:
        self.motion.reset()


class DetectStage(Stage):
    """The positive windows of this frame (both models; the oncoming model only where
    :class:`MotionStage` found motion, the main model only in the planned columns)."""

    name = "detect"

    def __init__(self, detector: WindowDetector) -> None:
        self.detector = detector

    def __call__(self, s: FrameState) -> FrameState:
        stats = DetectStats()
        kw: dict = {}
        if s.oncoming_bands is not None:
            kw["wide_bands"] = s.oncoming_bands
        if s.columns is not None:
            kw["columns"] = s.columns
        s.windows = self.detector.detect(s.frame, rgb=s.rgb, stats=stats, **kw)
        s.timings.update(stats.timings)
        return s


class GateStage(Stage):
    """Drop the oncoming windows whose motion is below the gate."""

    name = "motion"

    def __call__(self, s: FrameState) -> FrameState:
        windows = s.windows
        if s.motion is None:
            return s
        wide = windows.is_wide
        if not wide.any():
            return s
        keep = np.ones(len(windows), bool)
        idx = np.flatnonzero(wide)
        keep[idx[window_motion(s.motion, windows.boxes[idx]) < s.gate]] = False
        if not keep.all():
            s.windows = windows[keep]
        return s


class HeatStage(Stage):
    """The main model's heat map over recent frames and its boxes. A frame of another size
    starts a new heat map, and ``on_new_size(first)`` is called (``first``: the first heat
    map; the tracks and the search plan do not continue into another picture)."""

    name = "heatmap"

    def __init__(self, detector: WindowDetector, config: HeatConfig, oncoming: bool,
                 on_new_size: Callable[[bool], None]) -> None:
        self.detector, self.config, self.oncoming = detector, config, oncoming
        self.on_new_size = on_new_size
        self.heatmap: HeatMap | None = None

    def __call__(self, s: FrameState) -> FrameState:
        hw = s.shape
        if self.heatmap is None or self.heatmap.frame_shape != hw:
            self.on_new_size(self.heatmap is None)
            self.heatmap = HeatMap(hw, self.config, score_kind=self.detector.score_kind)
        hm = self.heatmap
        s.heatmap = hm
        s.boxes = s.out = hm.update(s.windows[~s.windows.is_wide] if self.oncoming else s.windows)
        s.timings.update(hm.timings)
        return s

    def reset(self) -> None:
        if self.heatmap is not None:
            self.heatmap.reset()


class FusionStage(Stage):
    """The oncoming model's heat map; its boxes are added where the main heat map found
    nothing (:func:`fastdet.video.fusion.merge_wide`)."""

    name = "fusion"

    def __init__(self, detector: WindowDetector, config: HeatConfig) -> None:
        self.detector, self.config = detector, config
        self.heatmap: HeatMap | None = None

    def __call__(self, s: FrameState) -> FrameState:
        if self.heatmap is None or self.heatmap.frame_shape != s.shape:
            self.heatmap = HeatMap(s.shape, self.config, score_kind=self.detector.score_kind)
        hw = self.heatmap
        wide = s.windows.is_wide
        if not wide.any() and hw.config.n_frames == 1:
            hw.reset()  # no memory and no windows: no heat, no boxes
        else:
            s.boxes = s.out = merge_wide(s.boxes, hw.update(s.windows[wide]))
        return s

    def reset(self) -> None:
        if self.heatmap is not None:
            self.heatmap.reset()


class WeakStage(Stage):
    """The tracker's low-confidence boxes: the weak blobs of the heat maps above ``low_heat``
    x their thresholds (:meth:`HeatMap.weak_boxes`), less those with more than 0.2 of their
    area inside a heat-map box (as :func:`merge_wide`)."""

    name = "weak"

    def __init__(self, low_heat: float, heat_stages: list[HeatStage | FusionStage]) -> None:
        self.low_heat, self.heat_stages = low_heat, heat_stages

    def __call__(self, s: FrameState) -> FrameState:
        f = self.low_heat
        if f <= 0:
            s.low = Detections.empty()
            return s
        parts = [hm.weak_boxes(f * hm.config.threshold) for hm in (st.heatmap for st in self.heat_stages)
                 if hm is not None and hm.n_seen]
        low = Detections.concat(parts) if parts else Detections.empty()
        if len(low) and len(s.boxes):
            low = low[overlap_fraction(low.boxes, s.boxes.boxes).max(axis=1) <= 0.2]
        s.low = low
        return s


class TrackStage(Stage):
    """Track ids (:class:`~fastdet.video.track.Tracker`): the tracked vehicles of this frame."""

    name = "track"

    def __init__(self, tracker: Tracker) -> None:
        self.tracker = tracker

    def __call__(self, s: FrameState) -> FrameState:
        s.out = self.tracker.update(s.boxes, s.low)
        s.tracks = [(t.id, t.state, t.predicted) for t in self.tracker.tracks]
        return s

    def reset(self) -> None:
        self.tracker.reset()


class ClipStage(Stage):
    """The tracker's filtered boxes (``TrackerConfig.output='filtered'``) clipped to the frame."""

    name = "clip"

    def __call__(self, s: FrameState) -> FrameState:
        out = s.out
        if len(out):
            s.out = Detections(clip(out.boxes, s.frame.shape), out.scores, ids=out.ids)
        return s


class RefineStage(Stage):
    """The learned box refinement of the boxes returned (:func:`fastdet.video.refine.refine`);
    the heat maps, the tracker and the guided search keep the unrefined ones."""

    name = "refine"

    def __init__(self, regressor: BoxRegressor, config: RefineConfig) -> None:
        self.regressor, self.config = regressor, config

    def __call__(self, s: FrameState) -> FrameState:
        if len(s.out):
            s.out = refine(s.bgr, s.out, self.regressor, self.config)
        return s


class ObserveStage(Stage):
    """Tell the search planner what this frame found: its main-model windows, the live
    tracks and whether a confirmed vehicle's track was lost."""

    name = "observe"

    def __init__(self, planner: SearchPlanner, tracker: Tracker | None) -> None:
        self.planner, self.tracker = planner, tracker

    def __call__(self, s: FrameState) -> FrameState:
        w = s.windows
        main = w[~w.is_wide] if w.part is not None else w
        tracks, lost = [], False
        if self.tracker is not None:
            frame = self.tracker.frame
            for t in self.tracker.tracks:
                pred = t.predicted if t.predicted is not None else t.box
                tracks.append((t.box, pred, frame - t.last_frame))
                lost |= t.state == LOST and t.id > 0 and t.last_frame == frame - 1
        self.planner.observe(main, tracks, lost)
        return s


def planner_for(config: PipelineConfig, detector: WindowDetector) -> SearchPlanner | None:
    """The guided search's planner, when the config plans (:attr:`PipelineConfig.planned`)
    and the detector can score columns."""
    guided: GuidedSearch | None = config.planned
    if guided is None or not isinstance(detector, ColumnSearch):
        return None
    return SearchPlanner(guided)


def build_stages(config: PipelineConfig, detector: WindowDetector, fps: float | None, tracker: Tracker | None,
                 regressor: BoxRegressor | None) -> list[Stage]:
    """The stages for ``config`` and ``detector``, in the order they run (module docstring)."""
    stages: list[Stage] = []
    if config.horizon is not None and isinstance(detector, MovableHorizon):
        stages.append(HorizonStage(detector, config.horizon))
    planner = planner_for(config, detector)
    if planner is not None:
        stages.append(PlanStage(detector, planner))  # type: ignore[arg-type]
    oncoming = detector.wide_model is not None
    gated = oncoming and config.motion.min_motion > 0
    if gated:
        stages.append(MotionStage(detector, config.motion, fps))
    stages.append(DetectStage(detector))
    if gated:
        stages.append(GateStage())

    def new_size(first: bool) -> None:  # another picture: its tracks and search plan do not continue
        if tracker is not None and not first:
            tracker.reset()
        if planner is not None:  # on the first frame too: a full scan on the second frame
            planner.reset()

    heat: list[HeatStage | FusionStage] = [HeatStage(detector, config.heat, oncoming, new_size)]
    if oncoming:
        heat.append(FusionStage(detector, config.oncoming_heat))
    stages += heat
    if tracker is not None:
        stages += [WeakStage(tracker.config.low_heat, heat), TrackStage(tracker)]
        if tracker.config.output == "filtered":
            stages.append(ClipStage())
    if regressor is not None and config.refine is not None:
        stages.append(RefineStage(regressor, config.refine))
    if planner is not None:
        stages.append(ObserveStage(planner, tracker))
    return stages
