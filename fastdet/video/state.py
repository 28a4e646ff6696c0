"""The per-frame state the stages of :class:`~fastdet.VideoDetector` pass on
(:class:`FrameState`), the debug record of a frame (:class:`FrameDebug`) and the base of a
stage (:class:`Stage`); the stages themselves: :mod:`fastdet.video.stages`."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..config import SearchBand
from ..detections import Detections
from .heatmap import HeatMap
from .motion import MotionMap

#: one live track: ``(id, state, predicted box)``, id -1 while tentative
TrackView = tuple[int, str, np.ndarray | None]


@dataclass
class FrameState:
    """One frame on its way through the stages.

    frame: the frame as given, ``(H, W, 3) uint8``; rgb: its channels are RGB (else BGR).
    columns: the guided search's window columns per main band (``None``: every window).
    motion, gate, oncoming_bands: this frame's motion over the oncoming search, the gate in
        grey levels and the parts of the oncoming bands that move (``None``: not gated).
    windows: the positive windows (:class:`Detections` with ``scale`` and ``part``).
    bands: the detector's decision values of every band it scored, ``(part, geometry, (ny, nx))``
        (windows not scored -inf; ``None``: a detector that does not give them).
    boxes: the heat maps' boxes; low: the weak boxes given to the tracker.
    out: what :meth:`~fastdet.VideoDetector.update` returns.
    tracks: every live track after the tracker.
    timings: seconds of the finer parts of a stage's work (:mod:`fastdet.video.stages`).
    """

    frame: np.ndarray
    rgb: bool = False
    columns: list | None = None
    motion: MotionMap | None = None
    gate: float = 0.0
    oncoming_bands: list[SearchBand] | None = None
    windows: Detections = field(default_factory=Detections.empty)
    bands: list | None = None
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
        """The record of a frame that went through the stages (no main heat map: boxes made by
        non-maximum suppression; its grids are then empty)."""
        hm = s.heatmap
        if hm is None:
            return cls(s.windows, boxes=s.boxes, low=s.low, tracks=s.tracks)
        return cls(s.windows, hm.heat, hm.mask, hm.labels, s.boxes, s.low, s.tracks)


class Stage:
    """One step of :meth:`~fastdet.VideoDetector.update` (:mod:`fastdet.video.stages`)."""

    name = "stage"

    def __call__(self, s: FrameState) -> FrameState:
        raise NotImplementedError

    def reset(self) -> None:
        """Forget the previous frames (a new video or a cut)."""
