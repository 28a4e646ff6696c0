"""VideoDetector: positive windows of each frame → heat map over recent frames → one box per vehicle.

Python API
----------
:class:`VideoDetector` turns a stream of frames into one box per vehicle per frame::

    vd = VideoDetector()                # bundled models, PipelineConfig() (fastdet.config)
    for frame in frames:                # (H, W, 3) uint8 BGR
        dets = vd.update(frame)         # Detections: boxes (N, 4) x1, y1, x2, y2; scores; ids
    vd.debug.windows, vd.debug.heat, vd.debug.boxes, vd.debug.tracks   # the last frame (FrameDebug)
    vd.timings                                                         # seconds per stage

``update`` runs a fixed sequence of stages (:mod:`fastdet.video.stages`); running a file as
``python -m fastdet video`` does is :func:`fastdet.detect_video` (:mod:`fastdet.video.run`),
which also reads the first seconds ahead for the horizon and uses the file's frame rate: a
loop like the one above gives other boxes and ids unless it does both
(``VideoDetector(fps=fps)``, :meth:`VideoDetector.prime_horizon` before the first ``update``).
"""
from __future__ import annotations

import threading
import time
import weakref
from collections.abc import Iterable, Iterator
from concurrent.futures import Future, ThreadPoolExecutor, wait
from typing import Any

import numba
import numpy as np

from .._numba import ensure_compiled, serial_thread
from ..config import PipelineConfig
from ..detections import Detections
from ..model import Model
from .blobsplit import KERNELS as SPLIT_KERNELS
from .blobsplit import window_modes
from .detector import MovableHorizon, WindowDetector, detector_kernels, make_detector
from .heatmap import KERNELS as HEAT_KERNELS
from .heatmap import HeatMap
from .motion import KERNELS as MOTION_KERNELS
from .motion import warmup_motion
from .refine import KERNELS as REFINE_KERNELS
from .refine import BoxRegressor, regressor_for
from .stages import (
    FrameDebug,
    FrameState,
    FusionStage,
    HeatStage,
    HorizonStage,
    OwnVehicleStage,
    PlanStage,
    Stage,
    build_stages,
    split_tail,
)
from .track import Tracker


class PendingFrame:
    """A frame :meth:`VideoDetector.start` has begun: :meth:`result` gives its boxes (what
    :meth:`VideoDetector.update` would have returned), waiting for its last stages if they
    still run. ``debug``: the frame's :class:`~fastdet.video.stages.FrameDebug`; ``timings``:
    seconds per stage, complete once :meth:`result` has returned."""

    def __init__(self, vd: VideoDetector, debug: FrameDebug, timings: dict[str, float],
                 tail: Future[tuple[FrameState, dict[str, float]]]) -> None:
        self._vd, self.debug, self.timings, self._tail = vd, debug, timings, tail
        self._out: Detections | None = None

    def result(self) -> Detections:
        """The frame's boxes; also makes them the detector's last frame (its ``debug`` and
        ``timings``)."""
        if self._out is None:
            s, tail_timings = self._tail.result()
            self.timings = {**s.timings, **self.timings, **tail_timings}
            self._out = s.out
        self._vd.debug, self._vd.timings = self.debug, self.timings
        return self._out

    def wait(self) -> None:
        """Wait until the frame's last stages are done, without taking the result (an error
        they raised stays for :meth:`result`)."""
        wait([self._tail])


def run_frames(vd: VideoDetector, frames: Iterable[tuple[int, np.ndarray, float]], *, beside: bool | None = None
               ) -> Iterator[tuple[int, np.ndarray, float, Detections]]:
    """``vd.update`` of every frame of ``frames`` (``(frame number, frame, seconds to decode
    it)``, as a :class:`~fastdet.io.reader.FrameReader` yields them), in order: yields ``(frame
    number, frame, seconds, boxes)``, the boxes those ``update`` returns. Each frame is begun
    with :meth:`VideoDetector.start` (``beside`` is its option), so its last stages run beside
    the next frame's first and the boxes come one frame behind the reading. An error in
    reading a frame or in beginning it is raised after the frame before it was yielded, as a
    loop of ``update`` would; closed early (a ``break``), it waits for the frame in flight
    before it returns."""
    it = iter(frames)
    ahead: tuple[int, np.ndarray, float, PendingFrame] | None = None
    begun: tuple[int, np.ndarray, float, PendingFrame] | None
    try:
        while True:
            try:
                item = next(it, None)
                begun = None if item is None else (*item, vd.start(item[1], beside=beside))
            except BaseException:
                if ahead is not None:
                    last, ahead = ahead, None
                    yield last[0], last[1], last[2], last[3].result()
                raise
            done, ahead = ahead, begun
            if done is not None:
                yield done[0], done[1], done[2], done[3].result()
            if ahead is None:
                return
    finally:
        if ahead is not None:
            ahead[3].wait()


def _given_components(detector: object) -> list[Any]:
    """The components of ``detector`` besides the side-view one its main model carries."""
    comps = list(getattr(detector, "components", None) or [])
    model = getattr(detector, "model", None)
    if comps and isinstance(model, Model) and model.side is not None and comps[0] is model.side:
        comps = comps[1:]
    return comps


class VideoDetector:
    """Vehicle boxes for a stream of frames: a detector's positive windows of each frame, a
    heat map over recent frames for one box per vehicle, a tracker for its id.

    detector: a :class:`~fastdet.video.detector.WindowDetector` (default: the one
        :func:`~fastdet.video.detector.make_detector` makes of ``config``, on first use).
        ``TypeError`` for an object that is not one.
    config: every setting (:class:`~fastdet.config.PipelineConfig`; default
        ``PipelineConfig()``): heat maps, motion gate, horizon, tracker, guided search,
        refinement (its model files are used only when ``detector`` / ``refiner`` are not given).
    fps: frames per second of the video (``None``: 25): the motion gate compares frames
        :meth:`MotionGate.lag <fastdet.config.MotionGate.lag>` apart.
    refiner: the box regressor (default: the one ``config.refine_model`` names, else the one the
        main model file carries, else the bundled one -- :func:`~fastdet.video.refine.regressor_for`
        --, loaded now when the refinement is on).

    With ``horizon='auto'`` the bands follow the horizon estimated from the optical flow of
    the first frames (:mod:`fastdet.video.horizon`); :meth:`prime_horizon` gives it those
    frames ahead of time (as :func:`fastdet.detect_video` and every command do for a file:
    without it the first frames are searched at the reference horizon, and the boxes and ids
    differ from theirs); :meth:`reset` keeps it (a cut, same camera; another camera wants a
    new VideoDetector). This needs a detector that can move its bands
    (:class:`~fastdet.video.detector.MovableHorizon`); the guided search needs one that scores
    only some columns (:class:`~fastdet.video.detector.ColumnSearch`); others search in full.

    What :meth:`update` returns, with the tracker: the tracked vehicles of this frame (the
    confirmed tracks that found a box), each with its id and, as its score, the peak heat of
    the blob it was matched to -- above the heat map's threshold for a heat-map box, at or
    below it for a weak blob that kept the vehicle's track alive. Without the tracker: the
    heat maps' boxes, scored by peak heat. Ids start at 1 for a new VideoDetector and after
    :meth:`reset`, so they are the same run after run.

    After :meth:`update`: ``debug`` (:class:`~fastdet.video.stages.FrameDebug` of the last
    frame) and ``timings`` (seconds per stage, :mod:`fastdet.video.stages`). The heat map is
    sized on the first frame; a frame of another size starts a new heat map (as :meth:`reset`).
    """

    def __init__(self, detector: WindowDetector | None = None, config: PipelineConfig | None = None, *,
                 fps: float | None = None, refiner: BoxRegressor | None = None) -> None:
        if detector is not None and not isinstance(detector, WindowDetector):
            raise TypeError(f"detector must provide detect(), warmup(), geometries(), score_kind and "
                            f"oncoming_model (a WindowDetector), got {type(detector).__name__}")
        if config is not None and not isinstance(config, PipelineConfig):
            raise TypeError(f"config must be a PipelineConfig, got {type(config).__name__}")
        if detector is not None and _given_components(detector):
            raise ValueError("the video pipeline runs the main model (and the side-view component it carries) and "
                             "the oncoming model only, not a Detector's components=: pass a Detector without them "
                             "(a component of the main model's features can ride in the model file: Model.side)")
        self.config = config if config is not None else PipelineConfig()
        self._detector = detector
        self.fps = fps
        self.tracker: Tracker | None = Tracker(self.config.tracker) if self.config.tracker is not None else None
        self.refiner: BoxRegressor | None = None
        if self.config.refine is not None:
            if refiner is not None and not isinstance(refiner, BoxRegressor):
                raise TypeError(f"refiner must be a BoxRegressor, got {type(refiner).__name__}")
            if refiner is None:
                model: Model | str | None = self.config.model
                if detector is None and model is not None and self.config.refine_model is None:
                    made = make_detector(self.config)  # the main model file read once, by the detector
                    self._detector, model = made, made.model
                refiner = regressor_for(model, self.config.refine_model, name=self.config.model)
            self.refiner = refiner
        self._stages: list[Stage] | None = None
        self.timings: dict[str, float] = {}
        self.debug = FrameDebug()
        self._tail_pool: ThreadPoolExecutor | None = None  # made by the first start() that runs a tail beside
        self._last_tail: Future | None = None
        self._tail_lock = threading.Lock()

    @property
    def detector(self) -> WindowDetector:
        if self._detector is None:
            self._detector = make_detector(self.config)
        return self._detector

    @property
    def stages(self) -> list[Stage]:
        """The stages :meth:`update` runs, in order (made on first use, for the detector)."""
        if self._stages is None:
            self._stages = build_stages(self.config, self.detector, self.fps, self.tracker, self.refiner)
        return self._stages

    def stage(self, kind: type[Stage]) -> Stage | None:
        """The first stage of class ``kind`` that runs (``None``: none)."""
        return next((s for s in self.stages if isinstance(s, kind)), None)

    @property
    def heatmap(self) -> HeatMap | None:
        """The main model's heat map (``None`` before the first frame)."""
        st = self.stage(HeatStage)
        return st.heatmap if isinstance(st, HeatStage) else None

    @property
    def oncoming_heatmap(self) -> HeatMap | None:
        """The oncoming model's heat map (``None`` without that model or before the first frame)."""
        st = self.stage(FusionStage)
        return st.heatmap if isinstance(st, FusionStage) else None

    def reset(self) -> None:
        """Forget the previous frames (a new video, or a cut); track ids start again at 1."""
        self._settle()
        if self.tracker is not None:
            self.tracker.reset()
        for st in self._stages or ():
            st.reset()
        self.debug = FrameDebug()

    def prime_horizon(self, frames: Iterable[np.ndarray]) -> float | None:
        """With ``horizon='auto'``: estimate the horizon from ``frames`` (the first frames of
        the video, BGR or RGB alike; at most HORIZON_FRAMES are used) before :meth:`update`
        sees them, so the first frames are searched at it too; with ``own_vehicle``, the same
        frames (as many as its estimate takes) give the own vehicle's region. Returns the horizon
        the bands are now at (``None``: the reference)."""
        st = self.stage(HorizonStage)
        own = self.stage(OwnVehicleStage)
        it = iter(frames)
        if isinstance(own, OwnVehicleStage):
            it = own.tee(it)
        try:
            if isinstance(st, HorizonStage):
                return st.prime(it)
            det = self.detector
            return det.horizon if isinstance(det, MovableHorizon) else None
        finally:
            if isinstance(own, OwnVehicleStage):
                own.prime(it)  # the frames the horizon did not need

    def warmup(self) -> None:
        """Compile / load the numba kernels now, not on the first frame: every kernel the
        frames will run, at once (on a first run on every core, after saying so), then each
        run once."""
        split = self.config.split is not None
        ensure_compiled((*detector_kernels(self.detector), *HEAT_KERNELS, *MOTION_KERNELS,
                         *(REFINE_KERNELS if self.refiner is not None else ()),
                         *(SPLIT_KERNELS if split else ())))
        self.detector.warmup()
        HeatMap((8, 8), self.config.heat).warmup()
        warmup_motion()
        if split:
            window_modes(np.array([[0.0, 0.0, 64.0, 64.0], [8.0, 0.0, 72.0, 64.0]]), np.ones(2))

    def update(self, frame: np.ndarray, rgb: bool = False) -> Detections:
        """Boxes of the vehicles in ``frame`` (``(H, W, 3) uint8``, BGR or RGB with ``rgb=True``).

        Each box's score is the peak heat of its blob (:mod:`fastdet.video.heatmap`; with
        ``boxes='nms'``, its window's score, :mod:`fastdet.video.nmsboxes`); with
        the tracker, the boxes are those of the tracked vehicles, with ``ids`` (class
        docstring). Causal: uses this and earlier frames only."""
        return self.start(frame, rgb, beside=False).result()

    def start(self, frame: np.ndarray, rgb: bool = False, *, beside: bool | None = None) -> PendingFrame:
        """Begin ``frame`` (as :meth:`update`): every stage a later frame reads runs now; the
        last ones, which change only this frame's boxes (the refinement and the plausibility
        rules: :data:`~fastdet.video.stages.TAIL_STAGES`), run on a background thread when
        ``beside`` (default: when Numba has two threads or more), beside the next frame's
        first stages. :meth:`PendingFrame.result` gives the boxes: the same as :meth:`update`'s.
        Frames are started in order, one after the other (not from several threads at once);
        their last stages run in the order started. :func:`fastdet.video.run.iter_video_detections`
        runs a file this way, one frame ahead."""
        frame = np.asarray(frame)
        if frame.ndim != 3 or frame.shape[2] != 3 or frame.dtype != np.uint8:
            raise ValueError(f"frame must be an (H, W, 3) uint8 array, got {frame.dtype} {frame.shape}")
        head, rest = split_tail(self.stages)  # each frame: the list is open to stages added to it
        s = FrameState(frame, rgb)
        timings = self._run(head, s)
        debug = FrameDebug.of(s)
        if beside is None:
            beside = numba.get_num_threads() > 1
        tail: Future[tuple[FrameState, dict[str, float]]]
        if beside and rest:
            with self._tail_lock:
                if self._tail_pool is None:
                    self._tail_pool = ThreadPoolExecutor(1, thread_name_prefix="fastdet-tail",
                                                         initializer=serial_thread)
                    weakref.finalize(self, self._tail_pool.shutdown, wait=False)
                tail = self._last_tail = self._tail_pool.submit(self._finish, rest, s)
        else:
            self._settle()  # an earlier frame's last stages first: they run in order
            tail = Future()
            tail.set_result(self._finish(rest, s))
        return PendingFrame(self, debug, timings, tail)

    @staticmethod
    def _run(stages: list[Stage], s: FrameState) -> dict[str, float]:
        timings: dict[str, float] = {}
        for stage in stages:  # each stage's time, less the parts it reports itself
            parts = sum(s.timings.values())
            t0 = time.perf_counter()
            s = stage(s)
            own = time.perf_counter() - t0 - (sum(s.timings.values()) - parts)
            timings[stage.name] = timings.get(stage.name, 0.0) + max(own, 0.0)
        return timings

    def _finish(self, stages: list[Stage], s: FrameState) -> tuple[FrameState, dict[str, float]]:
        return s, self._run(stages, s)

    def _settle(self) -> None:
        """Wait for the last frame's stages running beside (their errors are its result's)."""
        last = self._last_tail
        if last is not None:
            wait([last])
            self._last_tail = None

    def close(self) -> None:
        """Stop the background thread of :meth:`start` (also done when the VideoDetector is
        garbage-collected), after the frames it works on."""
        self._settle()
        with self._tail_lock:
            if self._tail_pool is not None:
                self._tail_pool.shutdown(wait=True)
                self._tail_pool = None

    @property
    def planning(self) -> bool:
        """The guided search runs (:attr:`PipelineConfig.planned` and a detector that can)."""
        return self.stage(PlanStage) is not None
