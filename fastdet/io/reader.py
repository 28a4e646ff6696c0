"""Frames of a video, decoded in a background thread (:class:`FrameReader`).

One reader for every command that reads video (``video``, ``eval --video``, ``bench``,
``batch``): what it yields is what decodes.
"""
from __future__ import annotations

import math
import os
import queue
import threading
import time
from typing import Any, Iterator

import cv2
import numpy as np

from ..errors import DataError, FastdetError

QUEUE_SIZE = 8
_END = object()


class FrameReader:
    """Frames of a video file, decoded in a background thread.

    Opening checks the file and decodes the first frame (after skipping ``start``), so a
    missing file, a non-video or a zero-frame video fail here, before any output exists.
    Iterating yields ``(frame_number, frame, decode_seconds)`` with 1-based frame numbers;
    a frame that fails to decode midway (:meth:`_decode_failed`) raises DataError after
    the frames before it were yielded.
    """

    def __init__(self, path: str | os.PathLike, start: int = 0, frames: int | None = None,
                 queue_size: int = QUEUE_SIZE) -> None:
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


