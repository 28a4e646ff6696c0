"""The video pipeline for one main model moved by several decision offsets, over one pass of the
frames: each frame decoded and scored once, the rest of the pipeline once per offset (and per
box formation: :func:`iter_lane_detections`).

``fastdet adapt`` chooses a model's operating point by running the pipeline over a stretch of
video with the model moved by each of a few decision offsets (:func:`fastdet.train.blend.offset`
subtracts a constant from every decision value). What the offset changes is which of the main
model's windows are positive and their scores; the frames, the horizon, the own vehicle's
region, the motion gate and the oncoming model's windows do not depend on it. So
:func:`iter_offset_detections` runs, per frame:

- once (``front``): the horizon, the motion gate, the detector over every window of every band
  (the full search) and the gate, as :class:`~fastdet.VideoDetector`'s own stages
  (:func:`~fastdet.video.stages.build_stages` of the config without the guided search), and the
  own vehicle's estimate;
- for each offset (a *lane*): the stages of :func:`~fastdet.video.stages.build_stages` for the
  config as given, the guided search's plan included, with a :class:`ReplayDetector` in place of
  the detector -- it scores nothing, its windows are those of the recorded decision values moved
  by the offset, in the columns the lane's plan asks for (-inf elsewhere, as the guided search
  leaves them) -- and the own vehicle's region read from the shared estimate
  (:class:`~fastdet.video.ownvehicle.OwnVehicleFollower`); the horizon, motion and gate stages,
  done in front, are left out.

A lane's boxes are those of :func:`~fastdet.video.run.iter_video_detections` with the moved
model (``tests/video/test_replay.py`` compares them), to the rounding of the decision values:
the detector adds the moved model's intercept in its kernel, the lane subtracts the offset
from the recorded value, and the guided search scores a column slice of the band (both
~1e-15 decision units).
"""
from __future__ import annotations

import os
from collections.abc import Iterator, Sequence
from dataclasses import replace

import numpy as np

from ..config import Boxes, FeatureConfig, PipelineConfig, RefineConfig, SearchBand
from ..detect import BandGeometry, Detector, DetectStats
from ..detections import MAIN_PART, ONCOMING_PART, Detections
from ..io.held import HeldFrames
from ..io.reader import FrameReader
from ..model import Model
from .detector import make_detector
from .ownvehicle import OwnVehicleFollower, OwnVehicleStage
from .refine import BoxRegressor
from .run import progress_bar, video_detector_for
from .search_stages import GateStage, HorizonStage, MotionStage
from .stages import HeatStage, NmsStage, RefineStage, build_stages
from .state import FrameState, Stage
from .track import Tracker

#: one band's recorded decision values: ``(part, geometry, (geo.ny, geo.nx) float64)``
Band = tuple[int, BandGeometry, np.ndarray]


class ReplayDetector:
    """A :class:`~fastdet.video.detector.WindowDetector` (with the guided search's
    :class:`~fastdet.video.detector.ColumnSearch` and a
    :class:`~fastdet.video.detector.MovableHorizon` that follows ``source``) that scores
    nothing: :meth:`detect` gives the positive windows of the main model's decision values
    ``source`` recorded on the frame (:meth:`feed`), less ``delta`` (the model moved as
    :func:`fastdet.train.blend.offset` moves it), only in the columns asked for, followed by the
    oncoming model's windows as fed (they do not depend on the main model).

    source: the :class:`~fastdet.Detector` that scored the frames (its bands, thresholds and
        score kind are used). delta: the offset, decision units (+ is stricter).
    component_delta: the offset of the components' windows (a camera's side-view component,
        :func:`fastdet.train.blend.side_offset`); +inf: none of them.
    """

    column_search = True

    def __init__(self, source: Detector, delta: float, component_delta: float = 0.0) -> None:
        self.source = source
        self.delta = float(delta)
        self.component_delta = float(component_delta)
        self._main: list[Band] = []
        self._oncoming = Detections.empty()

    @property
    def score_kind(self) -> str:
        return self.source.score_kind

    @property
    def oncoming_model(self) -> Model | None:
        return self.source.oncoming_model

    @property
    def model(self) -> Model:
        """The source's main model (what it records, such as its box formation, holds for the
        moved model too)."""
        return self.source.model

    @property
    def config(self) -> FeatureConfig:
        """The main model's features (window and cell size), as :attr:`fastdet.Detector.config`."""
        return self.source.config

    @property
    def horizon(self) -> float | None:
        return self.source.horizon

    def set_horizon(self, horizon: float | None) -> None:
        """The source's horizon is set where the frames are scored, not here."""
        raise RuntimeError("a ReplayDetector's bands are the source detector's: set its horizon")

    def feed(self, bands: Sequence[Band], oncoming: Detections) -> None:
        """The next frame's recorded decision values of every band (``DetectStats.bands`` of a
        full search: no -inf in the main model's) and its oncoming windows after the motion gate."""
        self._main = [b for b in bands if b[0] != ONCOMING_PART]
        self._oncoming = oncoming

    def detect(self, frame: np.ndarray, rgb: bool = False, oncoming_bands: Sequence[SearchBand] | None = None,
               stats: DetectStats | None = None,
               columns: Sequence[Sequence[tuple[int, int]] | None] | None = None) -> Detections:
        """The fed frame's positive windows (``frame`` is not looked at): the main model's
        decision values less ``delta`` in ``columns`` (as :meth:`fastdet.Detector.detect` takes
        them; the other windows -inf), then the fed oncoming windows. ``stats`` gets the main
        bands' values."""
        if columns is not None and len(columns) > len(self._main):
            raise ValueError(f"columns: {len(columns)} entries for {len(self._main)} bands")
        columns = self.source.band_columns(columns, frame.shape[:2])
        bands: list[Band] = []
        for i, (part, geo, dec) in enumerate(self._main):
            delta = self.delta if part == MAIN_PART else self.component_delta
            d = dec - delta if delta else dec
            spans = columns[i] if columns is not None and i < len(columns) else None
            if spans is not None:
                d2 = np.full_like(d, -np.inf)
                for j0, j1 in spans:
                    j0, j1 = max(int(j0), 0), min(int(j1), geo.nx)
                    if j0 < j1:
                        d2[:, j0:j1] = d[:, j0:j1]
                d = d2
            bands.append((part, geo, d))
        if stats is not None:
            stats.bands.extend(bands)
        main = self.source.windows(bands)
        return Detections.concat([main, self._oncoming]) if len(self._oncoming) else main

    def warmup(self) -> None:
        """Nothing to compile: the source scores."""

    def geometries(self, frame_shape: tuple[int, int], part: int = 0) -> list[BandGeometry]:
        return self.source.geometries(frame_shape, part)


class SharedRefineStage(RefineStage):
    """:class:`~fastdet.video.box_stages.RefineStage` whose results the lanes of one frame share:
    a lane whose boxes (and parts) are those another lane refined on this frame takes that
    lane's refined boxes (the same arithmetic on the same input). ``memo``: one dict for all
    lanes, emptied before every frame."""

    def __init__(self, regressor: BoxRegressor, config: RefineConfig, memo: dict[bytes, np.ndarray]) -> None:
        super().__init__(regressor, config)
        self.memo = memo

    def __call__(self, s: FrameState) -> FrameState:
        out = s.out
        if not len(out):
            return s
        key = out.boxes.tobytes() + (b"" if out.part is None else b"|" + out.part.tobytes())
        boxes = self.memo.get(key)
        if boxes is None:
            s = super().__call__(s)
            self.memo[key] = s.out.boxes
        else:
            s.out = replace(out, boxes=boxes)
        return s


def lane_stages(config: PipelineConfig, replay: ReplayDetector, fps: float | None, regressor: BoxRegressor | None,
                own: OwnVehicleStage | None, memo: dict[bytes, np.ndarray]) -> list[Stage]:
    """One offset's stages: :func:`~fastdet.video.stages.build_stages` for ``config`` with
    ``replay`` as the detector, a tracker of its own and ``regressor`` (read-only: one serves
    every lane), less what :func:`iter_offset_detections` does in front (horizon, motion, gate),
    the own-vehicle stage following ``own``, the refinement sharing ``memo``
    (:class:`SharedRefineStage`)."""
    tracker = Tracker(config.tracker) if config.tracker is not None else None
    out: list[Stage] = []
    for st in build_stages(config, replay, fps, tracker, regressor):
        if isinstance(st, (HorizonStage, MotionStage, GateStage)):
            continue
        if isinstance(st, RefineStage):
            out.append(SharedRefineStage(st.regressor, st.config, memo))
        elif isinstance(st, OwnVehicleStage):
            if own is None:
                raise ValueError("the config drops windows on the own vehicle: give its shared stage")
            out.append(OwnVehicleFollower(own))
        else:
            out.append(st)
    return out


def iter_offset_detections(path: str | os.PathLike | HeldFrames, offsets: Sequence[float],
                           config: PipelineConfig | None = None, *, start: int = 0, frames: int | None = None,
                           progress: bool = False) -> Iterator[tuple[int, dict[float, Detections]]]:
    """The boxes of every frame of a video file for ``config``'s main model moved by each of
    ``offsets`` (decision units, + is stricter; :func:`fastdet.train.blend.offset`), in one pass
    (module docstring): yields ``(frame, {offset: Detections})``, each table as
    :func:`~fastdet.video.run.iter_video_detections` yields it with the moved model (to the
    rounding of the decision values, ~1e-15).

    path, start, frames, progress: as :func:`~fastdet.video.run.iter_video_detections` (a file,
    or its frames held by :func:`~fastdet.io.hold.hold_frames`: the horizon is read ahead as
    there). config: the pipeline (default ``PipelineConfig()``);
    the offline pass is not offered.
    """
    config = config if config is not None else PipelineConfig()
    offs = [float(o) for o in offsets]
    if not offs or len(set(offs)) != len(offs):
        raise ValueError(f"offsets must be distinct and at least one, got {list(offsets)!r}")
    lanes = [(config.boxes, o) for o in offs]
    for fno, tables in iter_lane_detections(path, lanes, config, start=start, frames=frames, progress=progress):
        yield fno, dict(zip(offs, tables))


#: one lane of :func:`iter_lane_detections`: ``(boxes, offset)`` or ``(boxes, offset, component offset)``
Lane = tuple[Boxes | None, float] | tuple[Boxes | None, float, float]


def iter_lane_detections(path: str | os.PathLike | HeldFrames, lanes: Sequence[Lane],
                         config: PipelineConfig | None = None, *, start: int = 0, frames: int | None = None,
                         progress: bool = False) -> Iterator[tuple[int, list[Detections]]]:
    """As :func:`iter_offset_detections`, for lanes that may also differ in their box formation:
    each lane ``(boxes, offset)`` is ``config`` with :attr:`PipelineConfig.boxes
    <fastdet.config.PipelineConfig>` set to ``boxes`` and its main model moved by ``offset``;
    a third entry moves the main model's side-view component
    (:func:`~fastdet.train.blend.side_offset`: +inf, without it) by that much (default 0).
    Yields ``(frame, [Detections of each lane, in order])``; the frames are read and scored once
    for all of them."""
    config = config if config is not None else PipelineConfig()
    keys = [(lane[0], float(lane[1]), float(lane[2]) if len(lane) > 2 else 0.0) for lane in lanes]
    if not keys or len(set(keys)) != len(keys):
        raise ValueError(f"lanes must be distinct and at least one, got {list(lanes)!r}")
    reader = FrameReader(path, start, frames)
    try:
        # a side-view component is searched whenever a lane makes window boxes (make_detector leaves
        # it out for the heat map alone)
        window_lanes = any(b == "nms" or (b is None and config.boxes == "nms") for b, _, _ in keys)
        detector = make_detector(replace(config, boxes="nms") if window_lanes else config)
        # in front: every window scored on every frame, with the stages of a full-search run
        vd = video_detector_for(reader, detector, config.without("guided"))
        vd.warmup()
        front: list[Stage] = []
        for st in vd.stages:
            if isinstance(st, (HeatStage, NmsStage)):
                break
            if not isinstance(st, OwnVehicleStage):
                front.append(st)
        own = vd.stage(OwnVehicleStage)
        assert own is None or isinstance(own, OwnVehicleStage)
        replays = [ReplayDetector(detector, o, c) for _, o, c in keys]
        memo: dict[bytes, np.ndarray] = {}
        stages = [lane_stages(replace(config, boxes=b), r, reader.fps, vd.refiner, own, memo)
                  for (b, _, _), r in zip(keys, replays)]
        with progress_bar(reader.expected, progress, os.path.basename(reader.path)) as bar:
            for fno, frame, _ in reader:
                s = FrameState(frame)
                for st in front:
                    s = st(s)
                if own is not None:
                    own(FrameState(frame))  # its estimate fed once; each lane drops its own windows
                bands = s.bands or []
                oncoming = s.windows[s.windows.is_oncoming]
                result: list[Detections] = []
                memo.clear()
                for r, lane in zip(replays, stages):
                    r.feed(bands, oncoming)
                    ls = FrameState(frame)
                    for st in lane:
                        ls = st(ls)
                    result.append(ls.out)
                yield fno, result
                bar.update(1)
    finally:
        reader.close()
