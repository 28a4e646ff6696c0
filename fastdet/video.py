"""Video: decode → detect (positive windows) → heat map → boxes → draw → encode.

Python API
----------
:class:`VideoDetector` turns a stream of frames into one box per vehicle per frame::

    vd = VideoDetector()                # bundled model, default SearchConfig / HeatConfig
    for frame in frames:                # (H, W, 3) uint8 BGR
        dets = vd.update(frame)         # Detections: boxes (N, 4) x1, y1, x2, y2; scores
    vd.last_windows, vd.last_heat, vd.last_mask, vd.last_labels   # debug of the last frame

:func:`iter_video_detections` runs it over a file and yields ``(frame number, Detections)``
with 1-based frame numbers of the file (``start`` frames skipped keep their numbers).

Command line (``python -m fastdet video``)
------------------------------------------
``python -m fastdet video INPUT -o OUT.mp4 [--boxes B.txt] [--json B.jsonl] [--model M.npz]
[--oncoming-model W.npz | --no-oncoming] [--debug] [--profile] [--no-progress] [--start S] [--frames N]``

- The bundled oncoming-traffic model runs beside the main one (see :class:`VideoDetector`);
  ``--no-oncoming`` leaves it out, ``--oncoming-model`` replaces it.

- Decoding runs in a reader thread and drawing + encoding in a writer thread, connected to
  the detecting main thread by bounded queues: OpenCV and the numba kernels release the
  GIL, so the three overlap on two cores.
- ``--boxes`` writes MOTChallenge lines ``frame,-1,left,top,width,height,conf,-1,-1,-1``
  and ``--json`` one JSON object per frame (:mod:`fastdet.motio`); both are flushed after
  every frame. ``frame`` is the 1-based frame number in INPUT, so with ``--start S`` the
  first line is frame ``S + 1``, aligned with the ground truth of the whole clip.
- The video is written as ``.OUT.partial.mp4`` in the output folder (the extension is kept:
  it picks the container) and renamed to ``OUT.mp4`` when the run ends -- also when it ends
  early on Ctrl-C or on a frame that fails to decode, because the file is then a complete,
  playable video of the frames done, matching the boxes file line for line. A run that
  ends before its first frame leaves no video.
- Bad input (missing file, not a video, no frames, an output folder that does not exist,
  a model that does not load) raises :class:`~fastdet.errors.FastdetError`; the dispatcher
  prints one line and exits with status 2. Inputs and outputs are all checked before any
  output file is created.
"""
from __future__ import annotations

import argparse
import math
import os
import queue
import sys
import threading
import time
from pathlib import Path
from typing import Any, Iterator

import numpy as np

from .config import HeatConfig, MotionGate
from .detections import Detections
from ._cliargs import add_oncoming_arguments, nonneg_int, oncoming_arg, positive_int
from .errors import DataError, FastdetError

_QUEUE_SIZE = 8
_END = object()


# ---------------------------------------------------------------------------------------
# detector plumbing


def _passive_omp() -> None:
    """Make idle OpenMP workers sleep instead of spinning (``OMP_WAIT_POLICY=PASSIVE``)
    unless the user chose otherwise; must run before numba's OpenMP layer starts.

    The numba kernels run parallel regions on numba's OpenMP layer, many per frame. With
    GNU OpenMP's default spin-waiting, a thread waiting at a region's barrier burns the core
    its partner needs whenever the reader / writer threads (or any other program) also want
    the CPU: 10 fps instead of 65 with ``--boxes`` on 2 cores while other jobs ran.
    """
    os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")


def make_detector(model: Any = None, oncoming: Any = True) -> Any:
    """The video pipeline's :class:`fastdet.detector.Detector`: ``model`` (a Model, a path,
    or ``None`` for the bundled model) and, as its wide-window model, ``oncoming``: ``True``
    for the bundled oncoming-traffic model, a Model or path for another, ``False`` / ``None``
    for none. Raises :class:`~fastdet.errors.ModelError` when a model does not load."""
    try:
        from .detector import Detector
    except ImportError as exc:  # pragma: no cover - only while the detector is missing
        raise FastdetError(f"the detector is not available in this build ({exc})") from None
    if oncoming is True:
        from .model import ONCOMING_MODEL_PATH

        oncoming = ONCOMING_MODEL_PATH
    return Detector(model=model, wide=oncoming or None)


class VideoDetector:
    """Vehicle boxes for a stream of frames: a :class:`~fastdet.detector.Detector` for the
    positive windows of each frame, then a :class:`~fastdet.heatmap.HeatMap` over recent
    frames for one box per vehicle.

    detector: anything with ``detect(frame, rgb=False) -> Detections``, ``score_kind``,
        ``timings`` and ``last_scales`` (as :class:`~fastdet.detector.Detector`); default the
        Detector with the bundled model and the bundled oncoming-traffic model
        (:func:`make_detector`), created on first use.
    heat: :class:`~fastdet.config.HeatConfig` (default ``HeatConfig()``).
    wide_heat: heat map of the wide-window model's windows, when the detector has one
        (default :data:`fastdet.config.WIDE_HEAT`); its boxes are added where the main heat
        map found nothing (:func:`fastdet.fusion.merge_wide`).
    motion: :class:`~fastdet.config.MotionGate` for the wide-window model (default
        ``MotionGate()``): it searches only where the picture moved since the previous frame
        and keeps only its windows that moved enough (:mod:`fastdet.motion`); so it finds
        nothing on the first frame.

    After :meth:`update`, for debugging the last frame: ``last_windows`` (the positive
    windows, :class:`Detections`), ``last_scales`` (scale of each window), ``last_heat``
    (heat grid, float64, one cell = ``heat.cell`` pixels), ``last_mask`` (heat > threshold),
    ``last_labels`` (blob labels), ``last_boxes`` (the result) and ``timings`` (seconds per
    stage: the detector's ``resize_colour``, ``hog``, ``score`` and the heat map's
    ``heat``, ``label``). These arrays are new objects every frame, so a consumer may keep
    them (e.g. a writer thread) while the next frame is processed.

    The heat map is sized on the first frame; a frame of another size starts a new heat map
    (as :meth:`reset`).
    """

    def __init__(self, detector: Any = None, heat: HeatConfig | None = None,
                 wide_heat: HeatConfig | None = None, motion: MotionGate | None = None) -> None:
        from .motion import FrameMotion

        self._detector = detector
        self.wide_heat_config = wide_heat
        self.wide_heatmap = None
        self.motion_gate = motion if motion is not None else MotionGate()
        if not isinstance(self.motion_gate, MotionGate):
            raise TypeError(f"motion must be a MotionGate, got {type(self.motion_gate).__name__}")
        self._motion = FrameMotion()
        self.heat_config = heat if heat is not None else HeatConfig()
        if not isinstance(self.heat_config, HeatConfig):
            raise TypeError(f"heat must be a HeatConfig, got {type(self.heat_config).__name__}")
        self.heatmap = None
        self.timings: dict[str, float] = {}
        self._clear()

    @property
    def detector(self) -> Any:
        if self._detector is None:
            self._detector = make_detector()
        return self._detector

    def _clear(self) -> None:
        self.last_windows = Detections.empty()
        self.last_scales = np.zeros(0, np.float32)
        self.last_heat = np.zeros((0, 0), np.float64)
        self.last_mask = np.zeros((0, 0), bool)
        self.last_labels = np.zeros((0, 0), np.int32)
        self.last_boxes = Detections.empty()

    def reset(self) -> None:
        """Forget the previous frames (a new video, or a cut)."""
        if self.heatmap is not None:
            self.heatmap.reset()
        if self.wide_heatmap is not None:
            self.wide_heatmap.reset()
        self._motion.reset()
        self._clear()

    def warmup(self) -> None:
        """Compile / load the numba kernels now, not on the first frame."""
        det = self.detector
        if hasattr(det, "warmup"):
            det.warmup()
        from .heatmap import HeatMap

        HeatMap((8, 8), self.heat_config).warmup()

    def _heatmap_for(self, shape: tuple[int, ...]):
        hw = (int(shape[0]), int(shape[1]))
        if self.heatmap is None or self.heatmap.frame_shape != hw:
            from .heatmap import HeatMap

            kind = getattr(self.detector, "score_kind", "decision")
            self.heatmap = HeatMap(hw, self.heat_config, score_kind=kind)
        return self.heatmap

    def _wide_heatmap_for(self, shape: tuple[int, ...]):
        from .config import WIDE_HEAT
        from .heatmap import HeatMap

        hw = (int(shape[0]), int(shape[1]))
        if self.wide_heatmap is None or self.wide_heatmap.frame_shape != hw:
            self.wide_heatmap = HeatMap(hw, self.wide_heat_config or WIDE_HEAT,
                                        score_kind=getattr(self.detector, "score_kind", "decision"))
        return self.wide_heatmap

    def _moving_wide_bands(self, det: Any, frame: np.ndarray, rgb: bool, gate: float):
        """``(MotionMap or None, bands)``: this frame's motion over the wide search's region
        and the parts of the wide bands where some window moves at least ``gate``."""
        from .motion import moving_bands

        geos = det.geometries(frame.shape[:2], part=1)
        roi = (min(g.x0 for g in geos), min(g.y0 for g in geos), max(g.x1 for g in geos), max(g.y1 for g in geos))
        motion = self._motion.update(frame[:, :, ::-1] if rgb else frame, roi)
        if motion is None:
            return None, []
        return motion, [b for g in geos for b in moving_bands(g, det.wide_model.config, motion, gate)]

    @staticmethod
    def _gate_wide(windows: Detections, scales: np.ndarray, wide: np.ndarray, motion, gate: float):
        """Drop the wide windows whose motion is below ``gate``."""
        from .motion import window_motion

        idx = np.flatnonzero(wide)
        still = idx[window_motion(motion, windows.boxes[idx]) < gate]
        if not len(still):
            return windows, scales, wide
        keep = np.ones(len(scales), bool)
        keep[still] = False
        return Detections(windows.boxes[keep], windows.scores[keep]), scales[keep], wide[keep]

    def update(self, frame: np.ndarray, rgb: bool = False) -> Detections:
        """Boxes of the vehicles in ``frame`` (``(H, W, 3) uint8``, BGR or RGB with ``rgb=True``).

        Each box's score is the peak heat of its blob (:mod:`fastdet.heatmap`)."""
        frame = np.asarray(frame)
        if frame.ndim != 3 or frame.shape[2] != 3 or frame.dtype != np.uint8:
            raise ValueError(f"frame must be an (H, W, 3) uint8 array, got {frame.dtype} {frame.shape}")
        det = self.detector
        has_wide = getattr(det, "wide_model", None) is not None
        gate = self.motion_gate.min_motion if has_wide else 0.0
        t0 = time.perf_counter()
        motion = None
        if gate > 0:
            motion, wide_bands = self._moving_wide_bands(det, frame, rgb, gate)
            t_motion = time.perf_counter() - t0
            windows = det.detect(frame, rgb=rgb, wide_bands=wide_bands)
        else:
            windows = det.detect(frame, rgb=rgb)
        hm = self._heatmap_for(frame.shape)
        scales = np.asarray(getattr(det, "last_scales", np.zeros(0)), np.float32).reshape(-1)
        scales = scales.copy() if len(scales) == len(windows.boxes) else np.ones(len(windows.boxes), np.float32)
        wide = scales < 0  # windows of a wide-window model (Detector(wide=...)): own heat map
        if has_wide:
            from .fusion import merge_wide

            if motion is not None and wide.any():
                t1 = time.perf_counter()
                windows, scales, wide = self._gate_wide(windows, scales, wide, motion, gate)
                t_motion += time.perf_counter() - t1
            main_boxes = hm.update(Detections(windows.boxes[~wide], windows.scores[~wide]))
            hw = self._wide_heatmap_for(frame.shape)
            if not wide.any() and hw.config.n_frames == 1:
                hw.reset()  # no memory and no windows: no heat, no boxes
                boxes = main_boxes
            else:
                boxes = merge_wide(main_boxes, hw.update(Detections(windows.boxes[wide], windows.scores[wide])))
        else:
            boxes = hm.update(windows)
        self.last_windows = windows
        self.last_scales = scales
        self.last_heat = hm.heat
        self.last_mask = hm.mask
        self.last_labels = hm.labels
        self.last_boxes = boxes
        self.timings = {**dict(getattr(det, "timings", {}) or {}), **hm.timings}
        if gate > 0:
            self.timings["motion"] = t_motion
        return boxes


# ---------------------------------------------------------------------------------------
# reading frames in a thread


class _Reader:
    """Frames of a video file, decoded in a background thread.

    Opening checks the file and decodes the first frame (after skipping ``start``), so a
    missing file, a non-video or a zero-frame video fail here, before any output exists.
    Iterating yields ``(frame_number, frame, decode_seconds)`` with 1-based frame numbers;
    a frame that fails to decode midway (:meth:`_decode_failed`) raises DataError after
    the frames before it were yielded.
    """

    def __init__(self, path: str | os.PathLike, start: int = 0, frames: int | None = None,
                 queue_size: int = _QUEUE_SIZE) -> None:
        import cv2

        self.path = name = os.fspath(path)
        if start < 0:
            raise FastdetError(f"start must be >= 0, got {start}")
        if frames is not None and frames < 1:
            raise FastdetError(f"frames must be >= 1, got {frames}")
        if not os.path.exists(name):
            raise DataError(f"{name}: file not found")
        if os.path.isdir(name):
            raise DataError(f"{name}: is a folder, not a video")
        # FFmpeg prints its own complaints ("moov atom not found") on stderr; we report errors
        # ourselves, in one line. A user's own setting wins.
        os.environ.setdefault("OPENCV_FFMPEG_LOGLEVEL", "-8")
        cap = cv2.VideoCapture(name)
        if not cap.isOpened():
            cap.release()
            raise DataError(f"{name}: not a video OpenCV can read (not a video file, damaged, or no frames)")
        n = cap.get(cv2.CAP_PROP_FRAME_COUNT)
        self.frame_count = int(n) if math.isfinite(n) and n > 0 else None
        fps = cap.get(cv2.CAP_PROP_FPS)
        self.fps = float(fps) if math.isfinite(fps) and fps > 0 else 25.0
        for i in range(start):
            if not cap.grab():
                cap.release()
                raise DataError(f"{name}: start {start} is past the end of the video ({i} frames)")
        t0 = time.perf_counter()
        ok, frame = cap.read()
        dt = time.perf_counter() - t0
        if not ok or frame is None:
            cap.release()
            if start:
                raise DataError(f"{name}: start {start} is past the end of the video ({start} frames)")
            raise DataError(f"{name}: the video has no frames")
        if frame.ndim != 3 or frame.shape[2] != 3 or frame.dtype != np.uint8:
            cap.release()
            raise DataError(f"{name}: frames are {frame.dtype} {frame.shape}, expected 8-bit colour")
        self.shape = frame.shape
        self.start = start
        self.limit = frames
        remaining = None if self.frame_count is None else max(self.frame_count - start, 1)
        self.expected = remaining if frames is None else (frames if remaining is None else min(frames, remaining))
        self._cap = cap
        self._first = (start + 1, frame, dt)
        self._q: queue.Queue = queue.Queue(maxsize=queue_size)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="fastdet-decode", daemon=True)
        self._started = False

    def _put(self, item: Any) -> bool:
        while not self._stop.is_set():
            try:
                self._q.put(item, timeout=0.1)
                return True
            except queue.Full:
                continue
        return False

    def _run(self) -> None:
        cap = self._cap
        try:
            if not self._put(self._first):
                return
            k = 1
            while not self._stop.is_set() and (self.limit is None or k < self.limit):
                t0 = time.perf_counter()
                ok, frame = cap.read()
                dt = time.perf_counter() - t0
                if not ok or frame is None:
                    idx = self.start + k  # frames consumed before the failing one
                    if self._decode_failed(idx):
                        total = f" of {self.frame_count}" if self.frame_count else ""
                        self._put(("error", f"{self.path}: frame {idx + 1}{total} could not be decoded; "
                                            f"stopped after frame {idx}"))
                    break
                if frame.shape != self.shape:
                    self._put(("error", f"{self.path}: frame {self.start + k + 1} is {frame.shape}, "
                                        f"the first frame was {self.shape}; stopped"))
                    break
                if not self._put((self.start + k + 1, frame, dt)):
                    return
                k += 1
            self._put(_END)
        except BaseException as exc:  # pragma: no cover - defensive
            self._put(("error", f"{self.path}: decoding failed: {exc}"))
            self._put(_END)
        finally:
            cap.release()

    def _decode_failed(self, idx: int) -> bool:
        """After a failed read at 0-based frame ``idx``: a decode failure, or the end?

        A failure is a decode error when a further frame can still be read (damage in the
        middle), or when it comes well before the container's frame count. That count is
        only an estimate (edit lists, pre-roll and durations make it exceed the decodable
        frames by a few: 91 for the 88 frames of test_small1.mp4), so a failure within
        ``max(5, 5%)`` frames of it counts as the end of the video.
        """
        if self._cap.grab():
            return True
        if self.frame_count is None:
            return False
        slack = max(5, int(math.ceil(0.05 * self.frame_count)))
        return idx < self.frame_count - slack

    def __iter__(self) -> Iterator[tuple[int, np.ndarray, float]]:
        if not self._started:
            self._started = True
            self._thread.start()
        while True:
            try:
                item = self._q.get(timeout=0.1)
            except queue.Empty:
                if not self._thread.is_alive() and self._q.empty():
                    return
                continue
            if item is _END:
                return
            if isinstance(item[0], str):
                raise DataError(item[1])
            yield item

    def close(self) -> None:
        self._stop.set()
        if self._started:
            while self._thread.is_alive():
                try:
                    self._q.get(timeout=0.05)
                except queue.Empty:
                    pass
            self._thread.join()
        else:
            self._cap.release()


# ---------------------------------------------------------------------------------------
# writing the video in a thread


def partial_name(path: str | os.PathLike) -> Path:
    """Temporary name of an output while it is written: ``dir/.NAME.partial.EXT``."""
    p = Path(path)
    return p.with_name(f".{p.stem}.partial{p.suffix}")


def _check_output(path: str, what: str, inp: str) -> None:
    parent = os.path.dirname(os.path.abspath(path))
    if not os.path.isdir(parent):
        raise DataError(f"{path}: output folder {parent} does not exist")
    if not os.access(parent, os.W_OK):
        raise DataError(f"{path}: output folder {parent} is not writable")
    if os.path.isdir(path):
        raise DataError(f"{path}: is a folder, expected a {what} file name")
    if os.path.exists(path) and os.path.samefile(path, inp):
        raise DataError(f"{path}: the {what} would overwrite the input")


class _VideoSink:
    """Draws and encodes frames in a background thread; see the module docstring for the
    temporary name. ``put((frame, boxes, debug))`` then ``close()``."""

    def __init__(self, path: str, fps: float, size: tuple[int, int], debug: bool = False,
                 threshold: float | None = None) -> None:
        import cv2

        self.path = Path(path)
        self.tmp = partial_name(path)
        self.debug = debug
        self.threshold = threshold
        self._writer = cv2.VideoWriter(str(self.tmp), cv2.VideoWriter_fourcc(*"mp4v"), fps, size)
        if not self._writer.isOpened():
            self._writer.release()
            self.tmp.unlink(missing_ok=True)
            raise DataError(f"{path}: cannot write a video there (unknown extension "
                            f"{self.path.suffix or '(none)'!r}? use .mp4 or .avi; or no permission)")
        self.frames = 0
        self.draw_s = 0.0
        self.encode_s = 0.0
        self.error: BaseException | None = None
        self._q: queue.Queue = queue.Queue(maxsize=_QUEUE_SIZE)
        self._thread = threading.Thread(target=self._run, name="fastdet-encode", daemon=True)
        self._thread.start()
        self._closed = False

    def put(self, item: tuple) -> None:
        while True:
            if self.error is not None or not self._thread.is_alive():
                raise RuntimeError(f"video writer thread failed: {self.error!r}")
            try:
                self._q.put(item, timeout=0.1)
                return
            except queue.Full:
                continue

    def _run(self) -> None:
        from . import draw

        try:
            while True:
                item = self._q.get()
                if item is None:
                    return
                frame, boxes, dbg = item
                t0 = time.perf_counter()
                if dbg is not None:
                    draw.paste_panels(frame, draw.debug_panels(frame, *dbg, threshold=self.threshold,
                                                               boxes=boxes.boxes))
                draw.draw_boxes(frame, boxes.boxes, boxes.scores)
                t1 = time.perf_counter()
                self._writer.write(frame)
                t2 = time.perf_counter()
                self.draw_s += t1 - t0
                self.encode_s += t2 - t1
                self.frames += 1
        except BaseException as exc:  # reported by put() / close()
            self.error = exc

    def close(self) -> Path | None:
        """Finish the queued frames, close the file and give it its final name (``None``
        and no file when no frame was written)."""
        if self._closed:
            return self.path if self.frames else None
        self._closed = True
        if self._thread.is_alive():
            while True:
                try:
                    self._q.put(None, timeout=0.1)
                    break
                except queue.Full:
                    if not self._thread.is_alive():
                        break
            self._thread.join()
        self._writer.release()
        if self.frames:
            os.replace(self.tmp, self.path)
            return self.path
        self.tmp.unlink(missing_ok=True)
        return None


# ---------------------------------------------------------------------------------------
# iterating over a file


def _progress(total: int | None, enabled: bool, desc: str):
    from tqdm import tqdm

    return tqdm(total=total, unit="frame", desc=desc, file=sys.stderr, dynamic_ncols=True,
                disable=not (enabled and sys.stderr.isatty()))


def iter_video_detections(path: str | os.PathLike, model: Any = None, start: int = 0,
                          frames: int | None = None, progress: bool = True, detector: Any = None,
                          heat: HeatConfig | None = None, oncoming: Any = True) -> Iterator[tuple[int, Detections]]:
    """Vehicle boxes of every frame of a video file: yields ``(frame, Detections)``.

    frame: 1-based frame number in the file (``start`` frames are skipped, so the first one
        yielded is ``start + 1``). frames: at most this many frames.
    model: model for the default Detector (Model, path, or ``None`` for the bundled one);
        oncoming: its wide-window model (see :func:`make_detector`);
        ``detector``: use this detector instead (see :class:`VideoDetector`).
    progress: a tqdm bar on stderr when it is a terminal.
    Raises :class:`~fastdet.errors.DataError` / :class:`~fastdet.errors.ModelError` for bad
    input (a decode failure midway raises after the frames before it were yielded).
    """
    if detector is not None and model is not None:
        raise ValueError("give a model or a detector, not both")
    _passive_omp()
    reader = _Reader(path, start, frames)
    try:
        vd = VideoDetector(detector if detector is not None else make_detector(model, oncoming), heat)
        vd.warmup()
        with _progress(reader.expected, progress, os.path.basename(reader.path)) as bar:
            for fno, frame, _ in reader:
                yield fno, vd.update(frame)
                bar.update(1)
    finally:
        reader.close()


# ---------------------------------------------------------------------------------------
# command line




def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("input", metavar="INPUT", help="video file (anything OpenCV reads)")
    parser.add_argument("-o", "--output", metavar="OUTPUT.mp4",
                        help="annotated video (mp4v); written as .OUTPUT.partial.mp4, renamed when done")
    parser.add_argument("--boxes", metavar="BOXES.txt",
                        help="boxes per frame, MOTChallenge: frame,-1,left,top,width,height,conf,-1,-1,-1")
    parser.add_argument("--json", metavar="BOXES.jsonl", help="boxes per frame as JSON lines")
    parser.add_argument("--model", metavar="MODEL.npz", help="model file (default: the bundled model)")
    add_oncoming_arguments(parser)
    parser.add_argument("--debug", action="store_true",
                        help="add panels along the top: windows by scale, heat map, thresholded blobs")
    parser.add_argument("--profile", action="store_true", help="print a table of ms per frame per stage")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    parser.add_argument("--start", type=nonneg_int, default=0, metavar="S",
                        help="skip the first S frames (frame numbers stay those of the file)")
    parser.add_argument("--frames", type=positive_int, default=None, metavar="N",
                        help="process at most N frames")
    d = HeatConfig()
    parser.add_argument("--heat-frames", type=positive_int, default=d.n_frames, metavar="N",
                        help=f"frames the heat map remembers (default {d.n_frames})")
    parser.add_argument("--heat-decay", type=float, default=d.decay, metavar="D",
                        help=f"weight of a frame k frames old is D**k (default {d.decay})")
    parser.add_argument("--heat-threshold", type=float, default=d.threshold, metavar="T",
                        help=f"heat a pixel needs to be part of a vehicle (default {d.threshold})")


def _heat_config(args: argparse.Namespace) -> HeatConfig:
    try:
        return HeatConfig(n_frames=getattr(args, "heat_frames", HeatConfig.n_frames),
                          decay=getattr(args, "heat_decay", HeatConfig.decay),
                          threshold=getattr(args, "heat_threshold", HeatConfig.threshold))
    except ValueError as exc:
        raise FastdetError(f"heat map: {exc}") from None


_STAGES = (
    ("decode", "decode", "reader"),
    ("resize/colour", "resize_colour", "main"),
    ("HOG", "hog", "main"),
    ("scoring", "score", "main"),
    ("heat", "heat", "main"),
    ("label", "label", "main"),
    ("motion", "motion", "main"),
    ("boxes out", "boxes_out", "main"),
    ("draw", "draw", "writer"),
    ("encode", "encode", "writer"),
)


def _profile_table(totals: dict[str, float], n: int, wall: float, main_busy: float) -> str:
    import numba

    # with 2+ Numba threads the Detector runs its bands in that many threads: its stage
    # times add up their work, which can exceed the main thread's busy time
    band = numba.get_num_threads() > 1
    lines = [f"{'stage':<16}{'ms/frame':>10}  thread"]
    for label, key, thread in _STAGES:
        if key in totals:
            if band and key in ("resize_colour", "hog", "score"):
                thread = f"{numba.get_num_threads()} band threads (work summed)"
            lines.append(f"{label:<16}{1e3 * totals[key] / n:>10.2f}  {thread}")
    lines.append(f"{'main thread busy':<16}{1e3 * main_busy / n:>10.2f}  main (detect + heat + boxes out)")
    lines.append(f"{'wall':<16}{1e3 * wall / n:>10.2f}  ({n / wall:.1f} fps)")
    return "\n".join(lines)


def run(args: argparse.Namespace, detector: Any = None) -> int:
    """The ``video`` subcommand. ``detector`` replaces the model's Detector (tests)."""
    _passive_omp()
    out, boxes_path, json_path = args.output, args.boxes, args.json
    if not (out or boxes_path or json_path):
        raise FastdetError("nothing to write: give -o OUTPUT.mp4, --boxes BOXES.txt and/or --json BOXES.jsonl")
    named = [p for p in (out, boxes_path, json_path) if p]
    if len({os.path.abspath(p) for p in named}) != len(named):
        raise FastdetError("the outputs must be different files")
    heat = _heat_config(args)
    if not os.path.exists(args.input):
        raise DataError(f"{args.input}: file not found")
    for p, what in ((out, "video"), (boxes_path, "boxes"), (json_path, "JSON")):
        if p:
            _check_output(p, what, args.input)

    reader = _Reader(args.input, args.start, args.frames)
    sink = mot = jsl = None
    try:
        if detector is None:
            detector = make_detector(args.model, oncoming_arg(args))
        elif args.model is not None:
            raise FastdetError("--model cannot be used with an injected detector")
        vd = VideoDetector(detector, heat)
        vd.warmup()

        from .motio import JsonLinesWriter, MotWriter

        h, w = reader.shape[:2]
        if out:
            sink = _VideoSink(out, reader.fps, (w, h), debug=args.debug, threshold=heat.threshold)
        if boxes_path:
            mot = MotWriter(boxes_path)
        if json_path:
            jsl = JsonLinesWriter(json_path)

        totals: dict[str, float] = {}
        n = 0
        main_busy = 0.0
        t_start = time.perf_counter()
        bar = _progress(reader.expected, not args.no_progress, os.path.basename(args.input))
        try:
            for fno, frame, t_dec in reader:
                t0 = time.perf_counter()
                dets = vd.update(frame)
                t1 = time.perf_counter()
                if mot is not None:
                    mot.write(fno, dets.boxes, dets.scores)
                if jsl is not None:
                    jsl.write(fno, dets.boxes, dets.scores)
                t2 = time.perf_counter()
                if sink is not None:
                    dbg = None
                    if args.debug:
                        dbg = (vd.last_windows.boxes, vd.last_scales, vd.last_heat, vd.last_labels, vd.last_mask)
                    sink.put((frame, dets, dbg))
                for k, v in vd.timings.items():
                    totals[k] = totals.get(k, 0.0) + v
                totals["decode"] = totals.get("decode", 0.0) + t_dec
                totals["boxes_out"] = totals.get("boxes_out", 0.0) + (t2 - t1)
                main_busy += t2 - t0
                n += 1
                bar.update(1)
        finally:
            bar.close()
            written = sink.close() if sink is not None else None
            wall = time.perf_counter() - t_start
            if sink is not None:
                totals["draw"], totals["encode"] = sink.draw_s, sink.encode_s
            outs = [str(p) for p in (written, boxes_path, json_path) if p]
            if n:
                print(f"fastdet video: {n} frames in {wall:.2f} s, {n / wall:.1f} fps"
                      + (f"; wrote {', '.join(outs)}" if outs else ""), flush=True)
                if args.profile:
                    print(_profile_table(totals, n, wall, main_busy), flush=True)
    finally:
        reader.close()
        if sink is not None:
            sink.close()
        for wr in (mot, jsl):
            if wr is not None:
                wr.close()
    return 0
