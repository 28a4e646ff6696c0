"""The annotated output video, drawn and encoded in a background thread (:class:`VideoSink`).

The video is written under a temporary name (:func:`fastdet.io.atomic.partial_name`) and
renamed when closed. OpenCV's ``VideoWriter.write`` fails silently (a full disk, a file
size limit), so the sink checks what reached the disk: while writing, a file that stops
growing on a full file system (or at the process's file-size limit) stops the run; when
closing, the file must open and hold the frames written. Otherwise :class:`DataError`
(one line) and no file under the final name.

No wait for the encoder is unbounded: an encoder thread stuck inside OpenCV (a write to a
network disk that stopped answering) cannot be interrupted, so :meth:`VideoSink.put` (the
queue full) and :meth:`VideoSink.close` (finishing the queued frames) wait only while it makes
progress. Once it has written nothing for ``stall_s`` seconds (:data:`STALL_S`; after a stop
signal :data:`STOP_STALL_S`) with frames to write, the sink gives up on it: ``WriteError``
(one line), the temporary file removed, no file under the final name, and the thread left
behind (a daemon, :func:`fastdet.exiting.leave_behind`; if it ever wakes it closes the file and
ends). ``close(discard=True)`` has nothing to finish: it waits at most :data:`DISCARD_WAIT_S`.
"""
from __future__ import annotations

import contextlib
import os
import queue
import resource
import threading
import time
from collections.abc import Callable
from pathlib import Path

import cv2

from .. import exiting, signals
from ..console import note, quiet_native_stderr, quiet_opencv
from ..errors import DataError, WriteError
from . import draw
from .atomic import commit, partial_name
from .reader import QUEUE_SIZE

FOURCC = "mp4v"
#: containers OpenCV's FFmpeg writes mp4v video into
CONTAINERS = (".mp4", ".m4v", ".mov", ".avi", ".mkv")
#: frames between two looks at the file's size while writing
CHECK_EVERY = 10
#: free bytes below which a file system counts as full
FULL_BYTES = 1 << 20
#: seconds the encoder may write no frame while it has frames to write before the sink gives up
#: on it (stuck inside OpenCV: a disk that stopped answering). Generous: a slow encoder on a
#: loaded machine writes a frame in well under a second
STALL_S = 60.0
#: the same once a stop signal came (the user is waiting for the run to end; ``put`` waits in
#: the frame loop's patient block, where no further signal stops it)
STOP_STALL_S = 5.0
#: seconds ``close(discard=True)`` waits for the encoder thread to end (nothing to finish)
DISCARD_WAIT_S = 1.0


def _disk_full(path: Path) -> str | None:
    """Why ``path`` cannot grow (a full file system, the file-size limit), or ``None``."""
    try:
        size = path.stat().st_size
        st = os.statvfs(path.parent)
    except OSError:
        return None
    soft, _ = resource.getrlimit(resource.RLIMIT_FSIZE)
    if soft != resource.RLIM_INFINITY and size >= soft - 65536:
        return f"the file reached the process's file-size limit ({soft} bytes)"
    if st.f_bavail * st.f_frsize < FULL_BYTES:
        return "the disk is full"
    return None


def check_video_path(path: str | os.PathLike) -> None:
    """``DataError`` before any work when ``path``'s extension is not a container fastdet's
    ``mp4v`` video can be written into (``.webm`` takes only VP8/VP9/AV1)."""
    ext = Path(path).suffix.lower()
    if ext not in CONTAINERS:
        what = f"a {ext!r} file" if ext else "a file without an extension"
        raise DataError(f"{path}: cannot write a video there (fastdet writes {FOURCC} (MPEG-4) video, "
                        f"which OpenCV cannot put in {what}); use {', '.join(CONTAINERS)}")


class VideoSink:
    """Draws and encodes frames in a background thread; see the module docstring for the
    temporary name. ``put((frame, boxes, debug))`` then ``close()``.

    ``boxes`` is the frame's :class:`~fastdet.detections.Detections`; with ``ids`` they are
    drawn as tracks (id label, colour and trail, :func:`fastdet.io.draw.draw_tracks`; with
    ``debug`` the label is ``#id heat``, the box's score: its blob's peak heat).
    ``debug`` is ``None`` or ``(windows, heat, labels, mask[, tracks])`` for the debug
    panels (:func:`fastdet.io.draw.debug_panels`) and, with ``tracks``, every live track's
    predicted box (:func:`fastdet.io.draw.draw_track_states`).

    ``stall_s``: seconds without a frame written (with frames to write) after which
    :meth:`put` and :meth:`close` give up on the encoder (see the module docstring)."""

    def __init__(self, path: str, fps: float, size: tuple[int, int], debug: bool = False,
                 threshold: float | None = None, notify: Callable[[str], None] | None = None,
                 stall_s: float = STALL_S) -> None:
        self.path = Path(path)
        self.stall_s = stall_s
        self.tmp = partial_name(path)
        self.debug = debug
        self.threshold = threshold
        w, h = int(size[0]), int(size[1])
        # MPEG-4 takes even sizes only: FFmpeg would silently cut an odd one by a pixel
        self._pad = (w % 2, h % 2)
        if any(self._pad):
            (notify or note)(f"{path}: frames of {w}x{h} are written as {w + w % 2}x{h + h % 2} "
                             f"(one black column / row added: MPEG-4 video has even sizes)")
        quiet_opencv()
        with quiet_native_stderr():  # FFmpeg lists what a container takes: we say it in one line
            self._writer = cv2.VideoWriter(str(self.tmp), cv2.VideoWriter_fourcc(*FOURCC), fps,
                                           (w + w % 2, h + h % 2))
        if not self._writer.isOpened():
            self._writer.release()
            self.tmp.unlink(missing_ok=True)
            ext = self.path.suffix.lower()
            why = ("no permission, or the codec is missing" if ext in CONTAINERS else
                   f"fastdet writes {FOURCC} (MPEG-4) video, which OpenCV cannot put in "
                   f"{'a ' + repr(ext) + ' file' if ext else 'a file without an extension'}")
            raise DataError(f"{path}: cannot write a video there ({why}); use {', '.join(CONTAINERS)}")
        self.frames = 0
        self._size = 0  # the file's size at the last look
        self.draw_s = 0.0
        self.encode_s = 0.0
        self.error: BaseException | None = None
        self._trails = draw.Trails()
        self._q: queue.Queue = queue.Queue(maxsize=QUEUE_SIZE)
        self._progress = time.monotonic()  # when the encoder last took a frame or wrote one
        self._abandoned = False  # given up on: the thread ends (closing the file) when it wakes
        self._thread = threading.Thread(target=self._run, name="fastdet-encode", daemon=True)
        self._thread.start()
        exiting.leave_behind(self._thread)  # inside OpenCV while it runs: an exit before close() must not wait
        self._closed = False
        self._result: Path | None = None

    def put(self, item: tuple) -> None:
        """Queue a frame; while the queue is full, wait as long as the encoder makes progress
        (``WriteError`` once it has written nothing for the stall limit, :meth:`_stalled`)."""
        since = time.monotonic()
        while True:
            if isinstance(self.error, DataError):
                raise self.error
            if self.error is not None or not self._thread.is_alive():
                raise RuntimeError(f"video writer thread failed: {self.error!r}")
            try:
                self._q.put(item, timeout=0.1)
                return
            except queue.Full:
                self._stalled(since)

    def _stalled(self, since: float) -> None:
        """Give up on the encoder (:meth:`_abandon`, ``WriteError``) when it has written nothing
        for ``stall_s`` seconds -- :data:`STOP_STALL_S` once a stop signal came -- while the
        caller waited for it since ``since`` (the time before counts not: the encoder may have
        been idle, without frames to write, until just before)."""
        limit = min(self.stall_s, STOP_STALL_S) if signals.stop_requested() else self.stall_s
        idle = time.monotonic() - max(self._progress, since)
        if idle < limit:
            return
        self._abandon()
        self.error = WriteError(f"{self.path}: writing the video failed after {self.frames} frames: the encoder "
                                f"has written nothing for {limit:g} s (the disk stopped answering?); no video was kept")
        raise self.error

    def _abandon(self) -> None:
        """Stop waiting for the encoder thread: it ends (and closes the file) when it next
        looks, and the queued frames are dropped."""
        self._abandoned = True
        with contextlib.suppress(queue.Empty):
            while True:
                self._q.get_nowait()

    def _run(self) -> None:
        try:
            while not self._abandoned:
                item = self._q.get()
                self._progress = time.monotonic()
                if item is None or self._abandoned:
                    return
                frame, boxes, dbg = item
                t0 = time.perf_counter()
                if dbg is not None:
                    draw.paste_panels(frame, draw.debug_panels(frame, *dbg[:4], threshold=self.threshold,
                                                               boxes=boxes.boxes))
                    if len(dbg) > 4:
                        draw.draw_track_states(frame, dbg[4])
                if boxes.ids is not None:
                    self._trails.update(boxes)
                    draw.draw_tracks(frame, boxes, self._trails, scores=dbg is not None)
                else:
                    draw.draw_boxes(frame, boxes.boxes, boxes.scores)
                t1 = time.perf_counter()
                if any(self._pad):
                    frame = cv2.copyMakeBorder(frame, 0, self._pad[1], 0, self._pad[0], cv2.BORDER_CONSTANT, value=0)
                self._writer.write(frame)
                self._progress = time.monotonic()
                t2 = time.perf_counter()
                self.draw_s += t1 - t0
                self.encode_s += t2 - t1
                self.frames += 1
                if self.frames % CHECK_EVERY == 0:
                    self._check_growing()
        except BaseException as exc:  # reported by put() / close()
            if self.error is None:  # not after put() / close() gave up on this thread
                self.error = exc
        finally:
            if self._abandoned:  # given up on while inside OpenCV: the file is closed here
                self._writer.release()

    def _check_growing(self) -> None:
        """``DataError`` when the file stopped growing because it cannot (disk full)."""
        try:
            size = self.tmp.stat().st_size
        except OSError:
            size = -1
        if size == self._size or size < 0:
            why = _disk_full(self.tmp) if size >= 0 else "the file disappeared"
            if why:
                raise WriteError(f"{self.path}: writing the video failed after {self.frames} frames: {why}")
        self._size = size

    def _verify(self) -> None:
        """The closed temporary file opens and holds the frames written (``DataError``)."""
        quiet_opencv()
        with quiet_native_stderr():
            cap = cv2.VideoCapture(str(self.tmp))
        try:
            n = cap.get(cv2.CAP_PROP_FRAME_COUNT) if cap.isOpened() else None
            ok = n is not None and cap.read()[0]
        finally:
            cap.release()
        if not ok:
            why = _disk_full(self.tmp) or "the written file does not open"
            raise WriteError(f"{self.path}: writing the video failed: {why}; no video was kept")
        if n and n > 0 and int(n) != self.frames:
            why = _disk_full(self.tmp) or "the file was cut short"
            raise WriteError(f"{self.path}: writing the video failed: it holds {int(n)} of the "
                            f"{self.frames} frames written ({why}); no video was kept")

    def close(self, discard: bool = False, rename: bool = True) -> Path | None:
        """Finish the queued frames, close the file, check it (:meth:`_verify`) and give it
        its final name (``None`` and no file when no frame was written, or with
        ``discard``). ``DataError`` (and no file) when the writes failed, or when the encoder
        wrote nothing for the stall limit while finishing (:meth:`_finish`: it is then left
        behind). With ``discard`` the queued frames are dropped and the encoder is waited for at
        most :data:`DISCARD_WAIT_S`. With ``rename=False`` the checked temporary file is left
        for the caller to rename and its path returned."""
        if self._closed:
            if discard and self._result is not None and self._result == self.tmp:
                self.tmp.unlink(missing_ok=True)
                self._result = None
            return self._result
        self._closed = True
        if discard:  # nothing to finish: the queued frames are dropped
            self._abandon()
            with contextlib.suppress(queue.Full):
                self._q.put_nowait(None)  # an idle thread ends at once
            self._thread.join(DISCARD_WAIT_S)
        elif not self._abandoned:
            try:
                self._finish()
            except WriteError:
                pass  # the thread is given up on: below
        if self._thread.is_alive():  # given up on (stuck inside OpenCV): left behind
            with contextlib.suppress(OSError):  # else removed at exit (fastdet.io.atomic)
                self.tmp.unlink(missing_ok=True)
            if discard:
                return None
            # only a stall (_stalled) gives the thread up, and it sets a WriteError
            assert isinstance(self.error, DataError), f"encoder given up on without a WriteError: {self.error!r}"
            raise self.error
        self._writer.release()
        if not self.frames or discard or self.error is not None:
            self.tmp.unlink(missing_ok=True)
            if isinstance(self.error, DataError) and not discard:
                raise self.error
            return None
        try:
            self._verify()
        except DataError as exc:
            self.error = exc
            self.tmp.unlink(missing_ok=True)
            raise
        self._result = commit(self.tmp, self.path) if rename else self.tmp
        return self._result

    def _finish(self) -> None:
        """Queue the end and wait for the encoder to write the queued frames and end, as long
        as it makes progress (``WriteError`` when it stalls, :meth:`_stalled`)."""
        since = time.monotonic()
        while self._thread.is_alive():
            try:
                self._q.put(None, timeout=0.1)
                break
            except queue.Full:
                self._stalled(since)
        while self._thread.is_alive():
            self._thread.join(0.1)
            if self._thread.is_alive():
                self._stalled(since)


