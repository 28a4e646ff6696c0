"""The stages of :class:`~fastdet.VideoDetector` from the positive windows to the boxes
returned: heat maps, fusion, weak boxes, tracker, clipping, refinement, and what the guided
search learns of the frame (:mod:`fastdet.video.stages`)."""
from __future__ import annotations

from collections.abc import Callable

from ..boxes import clip, overlap_fraction
from ..config import HeatConfig, RefineConfig
from ..detections import MAIN_PART, Detections
from .detector import WindowDetector
from .fusion import merge_oncoming
from .guided import SearchPlanner
from .heatmap import HeatMap
from .refine import BoxRegressor, refine
from .state import FrameState, Stage
from .track import LOST, Tracker


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
        w = s.windows
        s.boxes = s.out = hm.update(w[w.part == MAIN_PART] if w.part is not None else w)
        s.timings.update(hm.timings)
        return s

    def reset(self) -> None:
        if self.heatmap is not None:
            self.heatmap.reset()


class _ExtraHeatStage(Stage):
    """A heat map of its own for windows other than the main model's, sized to the frame
    (a frame of another size starts a new one); its boxes go where the main heat map found
    nothing (:func:`fastdet.video.fusion.merge_oncoming`)."""

    def __init__(self, detector: WindowDetector, config: HeatConfig) -> None:
        self.detector, self.config = detector, config
        self.heatmap: HeatMap | None = None

    def _heatmap_for(self, s: FrameState) -> HeatMap:
        if self.heatmap is None or self.heatmap.frame_shape != s.shape:
            self.heatmap = HeatMap(s.shape, self.config, score_kind=self.detector.score_kind)
        return self.heatmap

    def reset(self) -> None:
        if self.heatmap is not None:
            self.heatmap.reset()


class FusionStage(_ExtraHeatStage):
    """The oncoming model's heat map; its boxes are added where the main heat map found
    nothing (:func:`fastdet.video.fusion.merge_oncoming`)."""

    name = "fusion"

    def __call__(self, s: FrameState) -> FrameState:
        hw = self._heatmap_for(s)
        oncoming = s.windows.is_oncoming
        if not oncoming.any() and hw.config.n_frames == 1:
            hw.reset()  # no memory and no windows: no heat, no boxes
        else:
            s.boxes = s.out = merge_oncoming(s.boxes, hw.update(s.windows[oncoming]))
        return s


class WeakStage(Stage):
    """The tracker's low-confidence boxes: the weak blobs of the heat maps above ``low_heat``
    x their thresholds (:meth:`HeatMap.weak_boxes`), less those with more than 0.2 of their
    area inside a heat-map box (as :func:`merge_oncoming`)."""

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
    """Track ids (:class:`~fastdet.video.track.Tracker`): the tracked vehicles of this frame.
    ``split``: a box over two tracks is split between them (heat-map blobs may hold two
    vehicles; the windows of :class:`~fastdet.video.nmsboxes.NmsStage` do not)."""

    name = "track"

    def __init__(self, tracker: Tracker, split: bool = True) -> None:
        self.tracker, self.split = tracker, split

    def __call__(self, s: FrameState) -> FrameState:
        s.out = self.tracker.update(s.boxes, s.low, frame_shape=s.shape, split=self.split)
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
    """Tell the search planner what this frame found: its windows of the main model (and of a
    side-view component it carries; not the oncoming model's), the live tracks and whether a
    confirmed vehicle's track was lost."""

    name = "observe"

    def __init__(self, planner: SearchPlanner, tracker: Tracker | None) -> None:
        self.planner, self.tracker = planner, tracker

    def __call__(self, s: FrameState) -> FrameState:
        w = s.windows
        main = w[~w.is_oncoming] if w.part is not None else w
        tracks, lost = [], False
        if self.tracker is not None:
            frame = self.tracker.frame
            for t in self.tracker.tracks:
                pred = t.predicted if t.predicted is not None else t.box
                tracks.append((t.box, pred, frame - t.last_frame))
                lost |= t.state == LOST and t.id > 0 and t.last_frame == frame - 1
        self.planner.observe(main, tracks, lost)
        return s
