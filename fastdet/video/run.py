"""Running the pipeline over a video: the :class:`~fastdet.VideoDetector` every command
builds for a reader (:func:`video_detector_for`), the boxes of every frame of a file
(:func:`detect_video`, the public one, ``fastdet.detect_video``; :func:`iter_video_detections`,
the same as ``(frame, Detections)`` pairs), priming the horizon from a file's first seconds
and the progress bar of a run (:func:`progress_bar`)."""
from __future__ import annotations

import os
import sys
from collections.abc import Iterator
from dataclasses import replace
from typing import Any

import numpy as np
from tqdm import tqdm

from ..config import PipelineConfig
from ..detect.checks import check_frame
from ..detections import Detections
from ..errors import FastdetError
from ..io.held import HeldFrames
from ..io.reader import FrameReader
from .detector import WindowDetector, camera_horizon, make_detector
from .horizon import HORIZON_FRAMES, estimate_horizon, search_horizon
from .offline import offline_pass
from .pipeline import VideoDetector, run_frames
from .plausible import PlausibleStage

#: most bytes of frames :func:`video_detector_for` keeps to estimate the horizon from the
#: run's own reader (75 frames of 1280x720: 207 MB); for larger frames the first seconds are
#: decoded a second time instead
PRIME_BUFFER_BYTES = 256 * 2**20


def progress_bar(total: int | None, enabled: bool, desc: str) -> tqdm:
    """A tqdm bar of frames on stderr, shown only when ``enabled`` and stderr is a terminal."""
    return tqdm(total=total, unit="frame", desc=desc, file=sys.stderr, dynamic_ncols=True,
                disable=not (enabled and sys.stderr.isatty()))


def _first_frames(path: str | os.PathLike | HeldFrames, start: int) -> Iterator[np.ndarray]:
    """The first HORIZON_FRAMES frames of a file from ``start`` (a reader of their own, quiet:
    the reader of the run itself says what there is to say about the file)."""
    reader = FrameReader(path if isinstance(path, HeldFrames) else os.fspath(path), start, HORIZON_FRAMES,
                         notify=lambda _note: None)
    try:
        for _, frame, _ in reader:
            yield frame
    finally:
        reader.close()


def _primes(vd: VideoDetector) -> bool:
    """Whether a file's first seconds are read ahead: for the horizon (``'auto'``, and no horizon
    the main model records for its camera: :func:`~fastdet.video.detector.camera_horizon`)."""
    return camera_horizon(vd.config, vd.detector) == "auto"


def prime_horizon_from_file(vd: VideoDetector, path: str | os.PathLike | HeldFrames, start: int = 0) -> None:
    """For a file (not a live source) or its held frames (:class:`~fastdet.io.held.HeldFrames`):
    give ``vd`` the first seconds of the video ahead of time
    (:meth:`VideoDetector.prime_horizon`), so every frame, the first ones too, is searched at the
    estimated horizon. Every command that reads a file does this, so ``video``, ``batch`` and
    ``eval --video`` give the same boxes."""
    if _primes(vd) and (isinstance(path, HeldFrames) or os.path.isfile(os.fspath(path))):
        vd.prime_horizon(_first_frames(path, start))


def file_horizon(path: str | os.PathLike | HeldFrames, start: int = 0) -> float | None:
    """The horizon a ``video`` run of the file from frame ``start`` searches at (``horizon='auto'``,
    :func:`prime_horizon_from_file`): estimated from its first seconds, as a fraction of the frame
    height; ``None`` when there is no estimate or it is the reference's (the bands as written).
    ``PipelineConfig(horizon=file_horizon(path))`` searches every frame there, the frames it is
    given being any stretch of the file: ``fastdet adapt`` runs the pipeline over a stretch of a
    video as a run of the whole video would, not at a horizon read from the stretch's own first
    frames (8 frames of a short clip can give none where 40 give one)."""
    return search_horizon(estimate_horizon(_first_frames(path, start)))


def video_detector_for(reader: FrameReader, detector: WindowDetector,
                       config: PipelineConfig | None = None) -> VideoDetector:
    """The :class:`VideoDetector` for the video ``reader`` reads, built the one way every command
    (``video``, ``eval --video``, ``batch``) builds it, so they all give the same boxes: the
    first frame checked against the detector's search (size, colour) before any output exists,
    the motion gate at the video's frame rate, and for a file the horizon primed from its first
    seconds (:func:`prime_horizon_from_file`; the frames come from ``reader`` itself,
    :meth:`FrameReader.peek <fastdet.io.reader.FrameReader.peek>`, when they fit in
    :data:`PRIME_BUFFER_BYTES` and the run reads at least that many)."""
    config = config if config is not None else PipelineConfig()
    horizon = camera_horizon(config, detector)
    given_as = ("--horizon" if horizon == config.horizon
                else "the camera's horizon the main model records (--horizon F or off to search elsewhere)")
    check_frame(detector, reader.first_frame, reader.path, horizon=horizon, more=reader.colour_sample,
                horizon_given_as=given_as)
    vd = VideoDetector(detector, config, fps=reader.fps)
    if (_primes(vd) and reader.kind == "file" and os.path.isfile(reader.path)
            and (reader.limit is None or reader.limit >= HORIZON_FRAMES)
            and HORIZON_FRAMES * reader.first_frame.nbytes <= PRIME_BUFFER_BYTES):
        # the run's own reader decodes the first seconds ahead and yields them again: the
        # same frames as a second reader of the file would give, decoded once
        vd.prime_horizon(reader.peek(HORIZON_FRAMES))
    else:
        prime_horizon_from_file(vd, reader.held or reader.path, reader.start)
    return vd


def defer_plausible(vd: VideoDetector) -> None:
    """Before the first frame of a run with the offline pass: the plausibility stage lets every
    box through, so that :func:`offline_boxes` applies its rules after the pass."""
    st = vd.stage(PlausibleStage)
    if isinstance(st, PlausibleStage):
        st.deferred = True


def offline_boxes(vd: VideoDetector, done: list[tuple[int, Detections]],
                  frame_shape: tuple[int, ...]) -> list[tuple[int, Detections]]:
    """The offline pass (:func:`~fastdet.video.offline.offline_pass`) over the boxes ``vd``
    returned for every frame (``done``), then the rules of its plausibility stage when
    :func:`defer_plausible` deferred them (a box they drop before the pass leaves a gap in its
    track that the pass fills again). Needs the tracker."""
    if vd.tracker is None:
        raise ValueError("the offline pass needs the tracker")
    final = offline_pass(done, frame_shape, vd.tracker.config)
    st = vd.stage(PlausibleStage)
    if isinstance(st, PlausibleStage) and st.deferred:
        final = [(fno, st.filter(d)) for fno, d in final]
    return final


def iter_video_detections(path: str | os.PathLike | int | HeldFrames, config: PipelineConfig | None = None, *,
                          start: int = 0, frames: int | None = None, progress: bool = True,
                          detector: WindowDetector | None = None,
                          offline: bool = False) -> Iterator[tuple[int, Detections]]:
    """Vehicle boxes of every frame of a video file: yields ``(frame, Detections)``, the
    tables as ``VideoDetector.update`` returns them (no ``frames`` column; ``ids`` only with
    the tracker). The package's own runs use it; the public form is :func:`detect_video`
    (``fastdet.detect_video``: one table a frame with ``frames`` and ``ids`` columns).

    frame: 1-based frame number in the file (``start`` frames are skipped, so the first one
        yielded is ``start + 1``). frames: at most this many frames. path: a video source as
        :class:`~fastdet.io.reader.FrameReader` takes it, held frames of a file
        (:class:`~fastdet.io.held.HeldFrames`) included: the same boxes as the file gives.
    config: the pipeline's settings (:class:`~fastdet.config.PipelineConfig`; default
        ``PipelineConfig()``: the bundled models, tracking on, ``ids`` filled).
    detector: use this detector instead of the one ``config`` names (see :class:`VideoDetector`).
    offline: run the offline pass over the whole file's tracks first
        (:func:`fastdet.video.offline.offline_pass`: gap interpolation); the
        first frame is then yielded only after the last one was read. Needs the tracker.
    progress: a tqdm bar on stderr when it is a terminal.
    Raises :class:`~fastdet.errors.DataError` / :class:`~fastdet.errors.ModelError` for bad
    input (a decode failure midway raises after the frames before it were yielded).
    """
    config = config if config is not None else PipelineConfig()
    if offline and config.tracker is None:
        raise ValueError("offline needs the tracker")
    reader = FrameReader(path, start, frames)
    vd: VideoDetector | None = None
    try:
        if offline and reader.live:
            raise FastdetError(f"{reader.path}: the offline pass needs a video file, not a live source")
        if detector is None:
            detector = make_detector(config)
        vd = video_detector_for(reader, detector, config)
        if offline:
            defer_plausible(vd)
        vd.warmup()
        done: list[tuple[int, Detections]] = []
        with progress_bar(reader.expected, progress, os.path.basename(reader.path)) as bar:
            for fno, _, _, dets in run_frames(vd, reader):
                if offline:
                    done.append((fno, dets))
                else:
                    yield fno, dets
                bar.update(1)
        shape = reader.shape
    finally:
        reader.close()
        if vd is not None:
            vd.close()  # its background thread (VideoDetector.start)
    if offline:
        assert vd is not None
        yield from offline_boxes(vd, done, shape)


def detect_video(source: str | os.PathLike | int | HeldFrames, config: PipelineConfig | None = None, *, start: int = 0,
                 frames: int | None = None, offline: bool = False, progress: bool = False,
                 **settings: Any) -> Iterator[Detections]:
    """The vehicles of every frame of a video, exactly as ``python -m fastdet video SOURCE``
    finds them (the same boxes, scores and track ids as its ``--boxes`` / ``--json`` files):
    yields one :class:`~fastdet.Detections` per frame read, in order.

    Each table has a ``frames`` column (the 1-based frame number in ``source``, so with
    ``start=S`` the first frame is ``S + 1``) and an ``ids`` column (track ids from 1; ``-1``
    with ``tracker=None``); its ``scores`` are each box's peak heat (:class:`~fastdet.Detections`).
    A frame without vehicles is an empty table. ``Detections.concat(list(detect_video(path)))``
    is the whole clip as one table (``MotWriter(path).write_table(clip)`` writes the same
    bytes as ``video --boxes``).

    source: a video file, an image sequence (``frames/img%04d.jpg``), a URL or a camera
        index, as ``video`` reads them (:class:`~fastdet.io.reader.FrameReader`); or a file's
        frames held by :func:`fastdet.io.hold.hold_frames` (the same boxes, without decoding).
    config: the settings (:class:`~fastdet.config.PipelineConfig`; default ``PipelineConfig()``,
        which is what ``video`` runs without options); ``**settings`` replace fields of it,
        e.g. ``detect_video(path, oncoming=False, horizon=0.55)`` (``video --no-oncoming
        --horizon 0.55``), ``tracker=None`` (``--no-track``), ``refine=None`` (``--no-refine``).
    start, frames: skip the first ``start`` frames, read at most ``frames`` (``--start``, ``--frames``).
    offline: the offline pass over the whole file's tracks (``--offline``: short gaps filled);
        the first frame is then yielded after the last one was read.
    progress: a progress bar on stderr when it is a terminal.

    What a hand-written loop over :meth:`VideoDetector.update <fastdet.VideoDetector.update>`
    lacks, and why its boxes and ids differ (466 boxes against ``video``'s 472 on the
    960x540 ``akin_highway.mp4``, other ids from the first frame on):

    - the horizon read ahead: for a file, the first seconds (``HORIZON_FRAMES``, 75 frames)
      are decoded before the first frame is searched and the horizon is estimated from
      them (:meth:`VideoDetector.prime_horizon <fastdet.VideoDetector.prime_horizon>`; the
      same frames give the own vehicle's region).
      A bare ``VideoDetector().update(frame)`` loop estimates the horizon as the frames come,
      so its first frames (until the estimate settles, one to three seconds) are searched
      at the reference horizon, 0.585 of the height (``akin_highway``'s is 0.485): it misses
      the vehicles there (frames 1-17 of ``akin_highway``), and its heat map and tracker
      start from other boxes, so the ids differ for the rest of the clip. This is the whole
      difference on that clip;
    - the file's frame rate (``VideoDetector(fps=None)`` assumes 25): the frames the motion
      gate compares (a lag of 2 frames from 38 fps up) and the own-vehicle estimate's pairs;
    - the reader: a damaged frame in the middle is skipped with a note and the frames keep
      their numbers in the file (a ``while cap.read()[0]`` loop stops at the first failed
      read); the first frame is checked (size, colour) before any work.

    The same loop by hand: ``vd = VideoDetector(fps=fps)``, ``vd.prime_horizon(first_75_frames)``,
    then ``vd.update(frame)`` for every frame from the first.

    Raises :class:`~fastdet.errors.DataError` / :class:`~fastdet.errors.ModelError` for bad
    input (a decode failure midway raises after the frames before it were yielded),
    ``TypeError`` for a setting that is not a ``PipelineConfig`` field, ``ValueError`` for
    ``offline`` without the tracker.
    """
    config = config if config is not None else PipelineConfig()
    if settings:
        config = replace(config, **settings)
    for fno, dets in iter_video_detections(source, config, start=start, frames=frames, progress=progress,
                                           offline=offline):
        yield dets.with_frames(np.full(len(dets), fno, np.int64)).with_ids(
            dets.ids if dets.ids is not None else np.full(len(dets), -1, np.int64))
