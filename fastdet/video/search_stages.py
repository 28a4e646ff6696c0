"""The stages of :class:`~fastdet.VideoDetector` up to the positive windows: the horizon,
the guided search's plan, the motion gate and the detector (:mod:`fastdet.video.stages`)."""
from __future__ import annotations

from collections.abc import Iterable

import numpy as np

from ..config import MotionGate
from ..detect import DetectStats
from .detector import ColumnSearch, MovableHorizon, WindowDetector
from .guided import SearchPlanner
from .horizon import HORIZON_FRAMES, TOLERANCE, HorizonEstimator, estimate_horizon, search_horizon
from .motion import FrameMotion, moving_bands, window_motion
from .state import FrameState, Stage


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
        if self.estimator is None:
            return self.detector.horizon
        self.estimator = None
        self.detector.set_horizon(search_horizon(estimate_horizon(np.asarray(f) for f in frames)))
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
        assert det.oncoming_model is not None
        gate = self.gate.threshold(motion.noise)
        s.motion, s.gate = motion, gate
        s.oncoming_bands = [b for g in geos for b in moving_bands(g, det.oncoming_model.config, motion, gate)]
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
            kw["oncoming_bands"] = s.oncoming_bands
        if s.columns is not None:
            kw["columns"] = s.columns
        s.windows = self.detector.detect(s.frame, rgb=s.rgb, stats=stats, **kw)
        s.timings.update(stats.timings)
        s.bands = stats.bands
        return s


class GateStage(Stage):
    """Drop the oncoming windows whose motion is below the gate."""

    name = "motion"

    def __call__(self, s: FrameState) -> FrameState:
        windows = s.windows
        if s.motion is None:
            return s
        oncoming = windows.is_oncoming
        if not oncoming.any():
            return s
        keep = np.ones(len(windows), bool)
        idx = np.flatnonzero(oncoming)
        keep[idx[window_motion(s.motion, windows.boxes[idx]) < s.gate]] = False
        if not keep.all():
            s.windows = windows[keep]
        return s
