"""VideoDetector: positive windows of each frame → heat map over recent frames → one box per vehicle.

Python API
----------
:class:`VideoDetector` turns a stream of frames into one box per vehicle per frame::

    vd = VideoDetector()                # bundled model, default SearchConfig / HeatConfig / TrackerConfig
    for frame in frames:                # (H, W, 3) uint8 BGR
        dets = vd.update(frame)         # Detections: boxes (N, 4) x1, y1, x2, y2; scores; ids
    vd.last_windows, vd.last_heat, vd.last_mask, vd.last_labels   # debug of the last frame
    vd.last_boxes, vd.last_low, vd.tracker.tracks                 # heat-map boxes, weak boxes, tracks

:func:`iter_video_detections` runs it over a file and yields ``(frame number, Detections)``
with 1-based frame numbers of the file (``start`` frames skipped keep their numbers);
``offline=True`` adds the offline pass (:mod:`fastdet.video.offline`).
"""
from __future__ import annotations

import os
import sys
import time
from collections.abc import Iterable, Iterator, Sequence
from typing import Any, Literal, Protocol, runtime_checkable

import numpy as np
from tqdm import tqdm

from .._numba import ensure_compiled
from ..boxes import clip, overlap_fraction
from ..config import WIDE_HEAT, GuidedSearch, HeatConfig, MotionGate, SearchBand, TrackerConfig, wide_search
from ..detect import BandGeometry, Detector, DetectStats
from ..detect.checks import check_frame
from ..detections import Detections
from ..io.reader import FrameReader
from ..model import ONCOMING_MODEL_PATH, Model
from .fusion import merge_wide
from .guided import SearchPlanner
from .heatmap import KERNELS as HEAT_KERNELS
from .heatmap import HeatMap
from .horizon import HORIZON_FRAMES, TOLERANCE, HorizonEstimator, search_horizon
from .motion import KERNELS as MOTION_KERNELS
from .motion import FrameMotion, MotionMap, moving_bands, warmup_motion, window_motion
from .offline import offline_pass
from .refine import KERNELS as REFINE_KERNELS
from .refine import BoxRegressor, RefineConfig, load_regressor, refine
from .track import LOST, Tracker

ModelLike = Model | str | os.PathLike | None

#: most bytes of frames :func:`video_detector_for` keeps to estimate the horizon from the
#: run's own reader (75 frames of 1280x720: 207 MB); for larger frames the first seconds are
#: decoded a second time instead
PRIME_BUFFER_BYTES = 256 * 2**20


@runtime_checkable
class WindowDetector(Protocol):
    """What :class:`VideoDetector` needs of a detector (:class:`fastdet.Detector` is one).

    ``score_kind``: ``"probability"`` or ``"decision"`` (how the heat map scales scores);
    ``wide_model``: the wide-window model or ``None``; ``detect`` returns the positive
    windows with the ``part`` column set (or no ``part``: all main-model windows);
    ``geometries(shape, part=1)`` the wide model's bands (used only when ``wide_model``
    is not ``None``, for the motion gate)."""

    score_kind: str
    wide_model: Model | None

    def detect(self, frame: np.ndarray, rgb: bool = False, wide_bands: Sequence[SearchBand] | None = None,
               stats: DetectStats | None = None) -> Detections: ...

    def warmup(self) -> None: ...

    def geometries(self, frame_shape: tuple[int, int], part: int = 0) -> list[BandGeometry]: ...


def make_detector(model: ModelLike = None, oncoming: ModelLike | bool = True,
                  traffic: Literal["right", "left", "both"] = "right") -> Detector:
    """The video pipeline's :class:`fastdet.Detector`: ``model`` (a Model, a path, or
    ``None`` for the bundled model) and, as its wide-window model, ``oncoming``: ``True``
    for the bundled oncoming-traffic model, a Model or path for another, ``False`` / ``None``
    for none; ``traffic``: the side of the road traffic drives on, which decides where the
    wide model looks for oncoming cars (:func:`fastdet.config.wide_search`). Raises
    :class:`~fastdet.errors.ModelError` when a model does not load."""
    if oncoming is True:
        oncoming = ONCOMING_MODEL_PATH
    return Detector(model=model, wide=oncoming or None, wide_search=wide_search(traffic))


class VideoDetector:
    """Vehicle boxes for a stream of frames: a :class:`~fastdet.Detector` for the positive
    windows of each frame, then a :class:`~fastdet.video.heatmap.HeatMap` over recent
    frames for one box per vehicle.

    detector: a :class:`WindowDetector` (default: the Detector with the bundled model and
        the bundled oncoming-traffic model, :func:`make_detector`, created on first use).
        ``TypeError`` for an object that is not one.
    heat: :class:`~fastdet.config.HeatConfig` (default ``HeatConfig()``).
    wide_heat: heat map of the wide-window model's windows, when the detector has one
        (default :data:`fastdet.config.WIDE_HEAT`); its boxes are added where the main heat
        map found nothing (:func:`fastdet.video.fusion.merge_wide`).
    motion: :class:`~fastdet.config.MotionGate` for the wide-window model (default
        ``MotionGate()``): it searches only where the picture moved since the previous frame
        (at 25 fps; ``fps``) and keeps only its windows that moved enough
        (:mod:`fastdet.video.motion`); so it finds nothing on the first frame.
    tracker: :class:`~fastdet.config.TrackerConfig` of the tracker that gives each vehicle
        an id (:mod:`fastdet.video.track`; default ``TrackerConfig()``), or ``False`` for no
        tracking (every box from the heat maps, ``ids`` ``None``). Ids start at 1 for a new
        VideoDetector and after :meth:`reset`, so they are the same run after run.
    fps: frames per second of the video (``None``: 25): the motion gate compares frames
        :meth:`MotionGate.lag <fastdet.config.MotionGate.lag>` apart.
    horizon: where the search bands go (:attr:`SearchConfig.horizon
        <fastdet.config.SearchConfig>`): ``'auto'`` (default) estimates the horizon from the
        optical flow of the first :data:`~fastdet.video.horizon.HORIZON_FRAMES` frames
        (:mod:`fastdet.video.horizon`; until there is an estimate, and when it is within the
        estimate's precision of the reference, the bands stay where they are written) --
        :meth:`prime_horizon` gives it those frames ahead of time; :meth:`reset` keeps it (a
        cut, same camera; another camera wants a new VideoDetector); a number: the horizon row
        as a fraction of the frame height (a camera whose horizon is known); ``None``: the
        detector's search as it is. Needs a detector with ``set_horizon`` (a
        :class:`~fastdet.Detector`); others are left alone.
    guided: how the main model's bands are searched between full scans
        (:class:`~fastdet.config.GuidedSearch`, default ``GuidedSearch()``: every window
        every few frames and after a cut or a lost track, near the tracked vehicles and the
        recent positive windows plus a rotating strip in between; :mod:`fastdet.video.guided`),
        or ``False`` for the full search on every frame; ``None`` (default): ``GuidedSearch()``
        with the tracker, the full search without it. Needs a detector whose ``detect``
        takes ``columns`` (a :class:`~fastdet.Detector`); others search in full.
    refine: learned box refinement of the boxes returned (:mod:`fastdet.video.refine`: a
        regressor from each box's context crop to its offsets, DPM-style): ``True`` / ``None``
        (default) with ``RefineConfig()``, a :class:`~fastdet.video.refine.RefineConfig`, or
        ``False`` for the heat map's (or tracker's) boxes as they are. Only the returned boxes
        move; the heat map, the tracker's state and the guided search see the unrefined ones.
    refine_model: the regressor (a :class:`~fastdet.video.refine.BoxRegressor` or a path;
        ``None``: the bundled ``fastdet/models/refine.npz``).

    What :meth:`update` returns, with the tracker: the tracked vehicles of this frame (the
    confirmed tracks that found a box), each with its id and, as its score, the peak heat of
    the blob it was matched to -- above the heat map's threshold for a heat-map box, at or
    below it for a weak blob that kept the vehicle's track alive. Without the tracker: the
    heat maps' boxes, scored by peak heat.

    After :meth:`update`, for debugging the last frame: ``last_windows`` (the positive
    windows, :class:`Detections` with ``scale`` and ``part``), ``last_heat`` (heat grid,
    float64, one cell = ``heat.cell`` pixels), ``last_mask`` (heat > threshold),
    ``last_labels`` (blob labels), ``last_boxes`` (the result) and ``timings`` (seconds per
    stage: the detector's ``resize_colour``, ``hog``, ``score``, the heat map's ``heat``,
    ``label``, ``motion``, ``weak`` (the weak blobs) and ``track``), ``last_low`` (the weak boxes given to the tracker)
    and ``last_tracks`` (every live track: ``(id, state, predicted box)``, id -1 while
    tentative). ``last_boxes`` is the heat maps' boxes before the tracker. These are new
    objects every frame, so a consumer may keep them (e.g. a writer thread) while the next
    frame is processed.

    The heat map is sized on the first frame; a frame of another size starts a new heat map
    (as :meth:`reset`).
    """

    def __init__(self, detector: WindowDetector | None = None, heat: HeatConfig | None = None,
                 wide_heat: HeatConfig | None = None, motion: MotionGate | None = None,
                 tracker: TrackerConfig | bool | None = None, fps: float | None = None,
                 horizon: float | str | None = "auto", guided: GuidedSearch | bool | None = None,
                 refine: RefineConfig | bool | None = None,
                 refine_model: BoxRegressor | str | os.PathLike | None = None) -> None:
        if detector is not None and not isinstance(detector, WindowDetector):
            raise TypeError(f"detector must provide detect(), warmup(), geometries(), score_kind and "
                            f"wide_model (a WindowDetector), got {type(detector).__name__}")
        self._detector = detector
        self.wide_heat_config = wide_heat if wide_heat is not None else WIDE_HEAT
        self.wide_heatmap: HeatMap | None = None
        self.motion_gate = motion if motion is not None else MotionGate()
        if not isinstance(self.motion_gate, MotionGate):
            raise TypeError(f"motion must be a MotionGate, got {type(self.motion_gate).__name__}")
        self._motion = FrameMotion()
        self.fps = fps  # frames per second of the video, for the motion gate (None: 25)
        self.heat_config = heat if heat is not None else HeatConfig()
        if not isinstance(self.heat_config, HeatConfig):
            raise TypeError(f"heat must be a HeatConfig, got {type(self.heat_config).__name__}")
        self.heatmap: HeatMap | None = None
        if tracker is None or tracker is True:
            tracker = TrackerConfig()
        if tracker is not False and not isinstance(tracker, TrackerConfig):
            raise TypeError(f"tracker must be a TrackerConfig or False, got {type(tracker).__name__}")
        self.tracker: Tracker | None = Tracker(tracker) if tracker is not False else None
        if not (horizon is None or horizon == "auto" or (isinstance(horizon, (int, float)) and 0 <= horizon <= 1)):
            raise ValueError(f"horizon must be 'auto', a fraction of the frame height in [0, 1] or None, "
                             f"got {horizon!r}")
        self.horizon = horizon
        if guided is None:  # guided by the tracks: without a tracker, the full search
            guided = GuidedSearch() if self.tracker is not None else False
        elif guided is True:
            guided = GuidedSearch()
        if guided is not False and not isinstance(guided, GuidedSearch):
            raise TypeError(f"guided must be a GuidedSearch or False, got {type(guided).__name__}")
        self.guided: GuidedSearch | None = None if guided is False or guided.full else guided
        self._planner = SearchPlanner(self.guided) if self.guided is not None else None
        if refine is None or refine is True:
            refine = RefineConfig()
        if refine is not False and not isinstance(refine, RefineConfig):
            raise TypeError(f"refine must be a RefineConfig or a bool, got {type(refine).__name__}")
        self.refine: RefineConfig | None = None if refine is False else refine
        self.refiner: BoxRegressor | None = None
        if self.refine is not None:
            self.refiner = (refine_model if isinstance(refine_model, BoxRegressor)
                            else load_regressor(refine_model))
        self._horizon_est: HorizonEstimator | None = None
        self._horizon_started = False
        self.timings: dict[str, float] = {}
        self._clear()

    @property
    def detector(self) -> WindowDetector:
        if self._detector is None:
            self._detector = make_detector()
        return self._detector

    def _clear(self) -> None:
        self.last_windows = Detections.empty()
        self.last_heat = np.zeros((0, 0), np.float64)
        self.last_mask = np.zeros((0, 0), bool)
        self.last_labels = np.zeros((0, 0), np.int32)
        self.last_boxes = Detections.empty()
        self.last_low = Detections.empty()
        self.last_tracks: list[tuple[int, str, np.ndarray]] = []

    def reset(self) -> None:
        """Forget the previous frames (a new video, or a cut); track ids start again at 1."""
        if self.tracker is not None:
            self.tracker.reset()
        if self.heatmap is not None:
            self.heatmap.reset()
        if self.wide_heatmap is not None:
            self.wide_heatmap.reset()
        self._motion.reset()
        if self._planner is not None:
            self._planner.reset()  # a full scan next
        if self._horizon_est is not None:
            self._horizon_est.cut()  # the camera stays: keep the estimate, pair no frames across the cut
        self._clear()

    def _start_horizon(self, det: WindowDetector) -> None:
        """Put the detector's bands at the configured horizon (``'auto'``: at the reference
        until there is an estimate) and start a new estimate."""
        self._horizon_started = True
        self._horizon_est = None
        if self.horizon is None or not hasattr(det, "set_horizon"):
            return
        if self.horizon == "auto":
            det.set_horizon(None)
            self._horizon_est = HorizonEstimator()
        else:
            det.set_horizon(float(self.horizon))

    def _feed_horizon(self, det: WindowDetector, frame: np.ndarray) -> None:
        """One more frame for the horizon estimate (``'auto'``, the first HORIZON_FRAMES
        frames); the bands move when the estimate moves by more than its precision."""
        est = self._horizon_est
        if est is None:
            return
        est.update(frame)
        h = search_horizon(est.estimate)
        cur = det.horizon
        if (h is None) != (cur is None) or (h is not None and abs(h - cur) > 0.5 * TOLERANCE):
            det.set_horizon(h)
        if est.done or est.frames >= HORIZON_FRAMES:
            self._horizon_est = None  # settled: no more flow to compute

    def prime_horizon(self, frames: Iterable[np.ndarray]) -> float | None:
        """With ``horizon='auto'``: estimate the horizon from ``frames`` (the first frames of
        the video, BGR or RGB alike; at most HORIZON_FRAMES are used) before :meth:`update`
        sees them, so the first frames are searched at it too. Returns the horizon the bands
        are now at (``None``: the reference)."""
        det = self.detector
        self._start_horizon(det)
        est = self._horizon_est
        if est is None:
            return getattr(det, "horizon", None)
        for i, f in enumerate(frames):
            if i >= HORIZON_FRAMES or est.done:
                break
            est.update(np.asarray(f))
        det.set_horizon(search_horizon(est.estimate))  # type: ignore[attr-defined]
        self._horizon_est = None
        return det.horizon  # type: ignore[attr-defined]

    def warmup(self) -> None:
        """Compile / load the numba kernels now, not on the first frame: every kernel the
        frames will run, at once (on a first run on every core, after saying so), then each
        run once."""
        ensure_compiled((*getattr(self.detector, "kernels", ()), *HEAT_KERNELS, *MOTION_KERNELS,
                         *(REFINE_KERNELS if self.refiner is not None else ())))
        self.detector.warmup()
        HeatMap((8, 8), self.heat_config).warmup()
        warmup_motion()

    def _heatmap_for(self, shape: tuple[int, ...]) -> HeatMap:
        hw = (int(shape[0]), int(shape[1]))
        if self.heatmap is None or self.heatmap.frame_shape != hw:
            if self.heatmap is not None and self.tracker is not None:
                self.tracker.reset()  # another picture: its tracks do not continue
            if self._planner is not None:
                self._planner.reset()
            self.heatmap = HeatMap(hw, self.heat_config, score_kind=self.detector.score_kind)
        return self.heatmap

    def _wide_heatmap_for(self, shape: tuple[int, ...]) -> HeatMap:
        hw = (int(shape[0]), int(shape[1]))
        if self.wide_heatmap is None or self.wide_heatmap.frame_shape != hw:
            self.wide_heatmap = HeatMap(hw, self.wide_heat_config, score_kind=self.detector.score_kind)
        return self.wide_heatmap

    def _moving_wide_bands(self, det: WindowDetector, frame: np.ndarray,
                           rgb: bool) -> tuple[MotionMap | None, list[SearchBand], float]:
        """``(MotionMap or None, bands, gate)``: this frame's motion over the wide search's
        region (against the frame :meth:`MotionGate.lag` back at ``fps``), the gate for it
        (:meth:`MotionGate.threshold` of its noise) and the parts of the wide bands where
        some window moves at least that much."""
        geos = det.geometries(frame.shape[:2], part=1)
        roi = (min(g.x0 for g in geos), min(g.y0 for g in geos), max(g.x1 for g in geos), max(g.y1 for g in geos))
        motion = self._motion.update(frame[:, :, ::-1] if rgb else frame, roi, lag=self.motion_gate.lag(self.fps))
        if motion is None:
            return None, [], 0.0
        assert det.wide_model is not None
        gate = self.motion_gate.threshold(motion.noise)
        return motion, [b for g in geos for b in moving_bands(g, det.wide_model.config, motion, gate)], gate

    @staticmethod
    def _gate_wide(windows: Detections, motion: MotionMap, gate: float) -> Detections:
        """Drop the wide windows whose motion is below ``gate``."""
        wide = windows.is_wide
        if not wide.any():
            return windows
        keep = np.ones(len(windows), bool)
        idx = np.flatnonzero(wide)
        keep[idx[window_motion(motion, windows.boxes[idx]) < gate]] = False
        return windows if keep.all() else windows[keep]

    def update(self, frame: np.ndarray, rgb: bool = False) -> Detections:
        """Boxes of the vehicles in ``frame`` (``(H, W, 3) uint8``, BGR or RGB with ``rgb=True``).

        Each box's score is the peak heat of its blob (:mod:`fastdet.video.heatmap`); with
        the tracker, the boxes are those of the tracked vehicles, with ``ids`` (class
        docstring). Causal: uses this and earlier frames only."""
        frame = np.asarray(frame)
        if frame.ndim != 3 or frame.shape[2] != 3 or frame.dtype != np.uint8:
            raise ValueError(f"frame must be an (H, W, 3) uint8 array, got {frame.dtype} {frame.shape}")
        det = self.detector
        if not self._horizon_started:
            self._start_horizon(det)
        if self._horizon_est is not None:
            self._feed_horizon(det, frame)
        has_wide = det.wide_model is not None
        gated = has_wide and self.motion_gate.min_motion > 0
        stats = DetectStats()
        guide = self._plan(det, frame.shape)
        t0 = time.perf_counter()
        motion = None
        t_motion = gate = 0.0
        if gated:
            motion, wide_bands, gate = self._moving_wide_bands(det, frame, rgb)
            t_motion = time.perf_counter() - t0
            windows = det.detect(frame, rgb=rgb, wide_bands=wide_bands, stats=stats, **guide)
        else:
            windows = det.detect(frame, rgb=rgb, stats=stats, **guide)
        hm = self._heatmap_for(frame.shape)
        if has_wide:
            wide = windows.is_wide
            if motion is not None and wide.any():
                t1 = time.perf_counter()
                windows = self._gate_wide(windows, motion, gate)
                wide = windows.is_wide
                t_motion += time.perf_counter() - t1
            main_boxes = hm.update(windows[~wide])
            hw = self._wide_heatmap_for(frame.shape)
            if not wide.any() and hw.config.n_frames == 1:
                hw.reset()  # no memory and no windows: no heat, no boxes
                boxes = main_boxes
            else:
                boxes = merge_wide(main_boxes, hw.update(windows[wide]))
        else:
            boxes = hm.update(windows)
        out = boxes
        t_weak = t_track = 0.0
        if self.tracker is not None:
            t1 = time.perf_counter()
            low = self._weak_boxes(boxes)
            t2 = time.perf_counter()
            out = self.tracker.update(boxes, low)
            if self.tracker.config.output == "filtered" and len(out):
                out = Detections(clip(out.boxes, frame.shape), out.scores, ids=out.ids)
            t_weak, t_track = t2 - t1, time.perf_counter() - t2
            self.last_low = low
            self.last_tracks = [(t.id, t.state, t.predicted) for t in self.tracker.tracks]
        t_refine = 0.0
        if self.refiner is not None and len(out):
            t1 = time.perf_counter()
            bgr = np.ascontiguousarray(frame[..., ::-1]) if rgb else frame
            out = refine(bgr, out, self.refiner, self.refine)
            t_refine = time.perf_counter() - t1
        if self._planner is not None:
            self._observe(windows)
        self.last_windows = windows
        self.last_heat = hm.heat
        self.last_mask = hm.mask
        self.last_labels = hm.labels
        self.last_boxes = boxes
        self.timings = {**stats.timings, **hm.timings}
        if gated:
            self.timings["motion"] = t_motion
        if self.tracker is not None:
            self.timings["weak"] = t_weak
            self.timings["track"] = t_track
        if self.refiner is not None:
            self.timings["refine"] = t_refine
        return out

    def _plan(self, det: WindowDetector, shape: tuple[int, ...]) -> dict[str, Any]:
        """``{"columns": ...}`` for this frame's ``detect`` (guided search), or ``{}`` (full)."""
        if self._planner is None or not isinstance(det, Detector):
            return {}
        cfg = det.config
        columns = self._planner.plan(det.geometries(shape[:2], 0), cfg.win_w, cfg.pixels_per_cell, shape[:2])
        return {} if columns is None else {"columns": columns}

    def _observe(self, windows: Detections) -> None:
        """Tell the planner what this frame found: its main-model windows, the live tracks
        and whether a confirmed vehicle's track was lost."""
        assert self._planner is not None
        main = windows[~windows.is_wide] if windows.part is not None else windows
        tracks, lost = [], False
        if self.tracker is not None:
            frame = self.tracker.frame
            for t in self.tracker.tracks:
                pred = t.predicted if t.predicted is not None else t.box
                tracks.append((t.box, pred, frame - t.last_frame))
                lost |= t.state == LOST and t.id > 0 and t.last_frame == frame - 1
        self._planner.observe(main, tracks, lost)

    def _weak_boxes(self, boxes: Detections) -> Detections:
        """The tracker's low-confidence boxes: the weak blobs of the heat maps above
        ``low_heat`` x their thresholds (:meth:`HeatMap.weak_boxes`), less those with more
        than 0.2 of their area inside a box of ``boxes`` (as :func:`merge_wide`)."""
        assert self.tracker is not None
        f = self.tracker.config.low_heat
        if f <= 0:
            return Detections.empty()
        parts = [hm.weak_boxes(f * hm.config.threshold) for hm in (self.heatmap, self.wide_heatmap)
                 if hm is not None and hm.n_seen]
        low = Detections.concat(parts) if parts else Detections.empty()
        if len(low) and len(boxes):
            low = low[overlap_fraction(low.boxes, boxes.boxes).max(axis=1) <= 0.2]
        return low


def detect_image(frame: np.ndarray, detector: WindowDetector, heat: HeatConfig) -> tuple[Detections, HeatMap, Detections]:
    """One image: the positive windows of ``detector``, a single-frame heat map (``heat``,
    e.g. ``HeatConfig().single_frame()``) and its boxes: ``(windows, heatmap, boxes)``."""
    windows = detector.detect(frame)
    hm = HeatMap(frame.shape, heat, score_kind=detector.score_kind)
    return windows, hm, hm.update(windows)


def _progress(total: int | None, enabled: bool, desc: str) -> tqdm:
    return tqdm(total=total, unit="frame", desc=desc, file=sys.stderr, dynamic_ncols=True,
                disable=not (enabled and sys.stderr.isatty()))


def _first_frames(path: str, start: int) -> Iterator[np.ndarray]:
    """The first HORIZON_FRAMES frames of a file from ``start`` (a reader of their own, quiet:
    the reader of the run itself says what there is to say about the file)."""
    reader = FrameReader(path, start, HORIZON_FRAMES, notify=lambda _note: None)
    try:
        for _, frame, _ in reader:
            yield frame
    finally:
        reader.close()


def prime_horizon_from_file(vd: VideoDetector, path: str | os.PathLike, start: int = 0) -> None:
    """For a file (not a live source): give ``vd`` the first seconds of the video ahead of time
    (:meth:`VideoDetector.prime_horizon`), so every frame, the first ones too, is searched at the
    estimated horizon. Every command that reads a file does this, so ``video``, ``batch`` and
    ``eval --video`` give the same boxes."""
    if vd.horizon == "auto" and os.path.isfile(os.fspath(path)):
        vd.prime_horizon(_first_frames(os.fspath(path), start))


def video_detector_for(reader: FrameReader, detector: WindowDetector, heat: HeatConfig | None = None,
                       tracker: TrackerConfig | bool | None = None, horizon: float | str | None = "auto",
                       guided: GuidedSearch | bool | None = None,
                       refine: RefineConfig | bool | None = None) -> VideoDetector:
    """The :class:`VideoDetector` for the video ``reader`` reads, built the one way every command
    (``video``, ``eval --video``, ``batch``) builds it, so they all give the same boxes: the
    first frame checked against the detector's search (size, colour) before any output exists,
    the motion gate at the video's frame rate, and for a file the horizon primed from its first
    seconds (:func:`prime_horizon_from_file`; the frames come from ``reader`` itself,
    :meth:`FrameReader.peek <fastdet.io.reader.FrameReader.peek>`, when they fit in
    :data:`PRIME_BUFFER_BYTES` and the run reads at least that many)."""
    check_frame(detector, reader.first_frame, reader.path, horizon=horizon)
    vd = VideoDetector(detector, heat, tracker=tracker, fps=reader.fps, horizon=horizon, guided=guided,
                       refine=refine)
    if (vd.horizon == "auto" and reader.kind == "file" and os.path.isfile(reader.path)
            and (reader.limit is None or reader.limit >= HORIZON_FRAMES)
            and HORIZON_FRAMES * reader.first_frame.nbytes <= PRIME_BUFFER_BYTES):
        # the run's own reader decodes the first seconds ahead and yields them again: the
        # same frames as a second reader of the file would give, decoded once
        vd.prime_horizon(reader.peek(HORIZON_FRAMES))
    else:
        prime_horizon_from_file(vd, reader.path, reader.start)
    return vd


def iter_video_detections(path: str | os.PathLike, model: Any = None, start: int = 0,
                          frames: int | None = None, progress: bool = True, detector: Any = None,
                          heat: HeatConfig | None = None, oncoming: Any = True,
                          tracker: TrackerConfig | bool | None = None,
                          offline: bool = False, horizon: float | str | None = "auto",
                          guided: GuidedSearch | bool | None = None,
                          refine: RefineConfig | bool | None = None,
                          traffic: Literal["right", "left", "both"] = "right") -> Iterator[tuple[int, Detections]]:
    """Vehicle boxes of every frame of a video file: yields ``(frame, Detections)``.

    frame: 1-based frame number in the file (``start`` frames are skipped, so the first one
        yielded is ``start + 1``). frames: at most this many frames.
    model: model for the default Detector (Model, path, or ``None`` for the bundled one);
        oncoming: its wide-window model and traffic: the side of the road traffic drives on
        (see :func:`make_detector`);
        ``detector``: use this detector instead (see :class:`VideoDetector`).
    tracker: as :class:`VideoDetector` (default: tracking on, ``ids`` filled); guided,
        horizon, refine: as :class:`VideoDetector` (``guided=False``: the full search on every
        frame; ``refine=False``: the boxes unrefined).
    offline: run the offline pass over the whole file's tracks first
        (:func:`fastdet.video.offline.offline_pass`: gap interpolation, extension back); the
        first frame is then yielded only after the last one was read. Needs the tracker.
    progress: a tqdm bar on stderr when it is a terminal.
    Raises :class:`~fastdet.errors.DataError` / :class:`~fastdet.errors.ModelError` for bad
    input (a decode failure midway raises after the frames before it were yielded).
    """
    if detector is not None and model is not None:
        raise ValueError("give a model or a detector, not both")
    if offline and tracker is False:
        raise ValueError("offline needs the tracker")
    reader = FrameReader(path, start, frames)
    try:
        if detector is None:
            detector = make_detector(model, oncoming, traffic)
        vd = video_detector_for(reader, detector, heat, tracker, horizon, guided, refine)
        vd.warmup()
        done: list[tuple[int, Detections]] = []
        with _progress(reader.expected, progress, os.path.basename(reader.path)) as bar:
            for fno, frame, _ in reader:
                dets = vd.update(frame)
                if offline:
                    done.append((fno, dets))
                else:
                    yield fno, dets
                bar.update(1)
        shape = reader.shape
    finally:
        reader.close()
    if offline:
        assert vd.tracker is not None
        yield from offline_pass(done, shape, vd.tracker.config)


