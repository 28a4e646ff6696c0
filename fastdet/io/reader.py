"""Frames of a video, decoded in a background thread (:class:`FrameReader`).

One reader for every command that reads video (``video``, ``eval --video``, ``bench``,
``mine-negatives``, ``batch``): what it yields is what decodes.

Sources (:func:`source_kind`): a video file; an image sequence (``frames/img%04d.jpg``);
a URL (``rtsp://``, ``http://``, ...) or a camera index (``0``) -- *live* sources, which
have no frame count and end when the stream ends (or on Ctrl-C). Also a file's frames decoded
once and held (:class:`~fastdet.io.held.HeldFrames`): read again without decoding, the same
frames, numbers and end as the file's reader gives.

The end of a stream is where decoding ends. The frame count in a file's header is an
estimate (edit lists of ``ffmpeg -ss ... -c copy`` cuts, pre-roll and durations make it
exceed the decodable frames: 91 for the 88 frames of ``test_small1.mp4``, 91 for the 65 of
a cut), so it is used only for progress and, when decoding ends elsewhere, for one note.
Damage in the middle of a file -- a frame that fails to decode while later ones still do
-- is reported in one note and skipped: the frames after it are processed and keep their
numbers in the file, because every failed read consumed the packet of the frame it could
not decode (exact for one frame per packet, as in MP4, MOV, AVI and MKV files). A run of
more than :data:`MAX_BAD_READS` failed reads (or every failed read on a live source)
ends the stream.
"""
from __future__ import annotations

import math
import os
import queue
import re
import threading
import time
from collections import deque
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from .. import exiting, signals
from ..console import note, quiet_opencv
from ..errors import DataError, FastdetError
from .files import not_found
from .held import HeldFrames

QUEUE_SIZE = 8
#: seconds a live source (pipe, stream, camera) may take to open
OPEN_TIMEOUT_S = 30.0
#: seconds :meth:`FrameReader.close` waits for the decoding thread
CLOSE_TIMEOUT_S = 10.0
#: failed reads in a row after which a file's stream counts as ended (damage in the middle
#: is reported when a frame decodes again within this many reads; reads at the true end
#: of a file fail at once, so trying costs nothing there)
MAX_BAD_READS = 256
#: frames after the first that :meth:`FrameReader.colour_sample` decodes ahead (about 2 s)
COLOUR_AHEAD = 50
#: at most this many bytes of frames decoded ahead for that look
COLOUR_AHEAD_BYTES = 128 * 2**20
#: frames at even positions through a file that :meth:`FrameReader.colour_sample` then reads
COLOUR_SPREAD = 8
_END = object()
_URL = re.compile(r"^[A-Za-z][A-Za-z0-9+.-]*://")


#: extensions FFmpeg (OpenCV's backend) reads as an image sequence when the name holds a
#: ``%d`` pattern (its image2 demuxer); any other name -- ``a%d.mp4`` -- it opens literally
SEQUENCE_EXTENSIONS = frozenset({
    ".bmp", ".dib", ".dpx", ".exr", ".jp2", ".j2k", ".jpe", ".jpeg", ".jpg", ".pam", ".pbm", ".pcx", ".pgm",
    ".png", ".pnm", ".ppm", ".ras", ".sgi", ".sr", ".sun", ".tga", ".tif", ".tiff", ".webp", ".xbm", ".xwd",
})
#: the frame numbers FFmpeg tries for a sequence's first frame (``start_number_range``)
SEQUENCE_FIRST = range(5)
# FFmpeg's pattern syntax (av_get_frame_filename): %d with an optional zero-padded width; %%
_SEQ_TOKEN = re.compile(r"%(%|0?\d*d)")


def sequence_regex(name: str) -> re.Pattern[str] | None:
    """A regex of the file names (not folders) that the image-sequence pattern ``name``'s last
    part gives (``img%04d.jpg``: ``img0003.jpg``, ``img12345.jpg``); ``None`` when the name
    holds no ``%d`` or a ``%`` that FFmpeg does not take."""
    base = os.path.basename(name)
    out, pos, numbered = [], 0, False
    for m in _SEQ_TOKEN.finditer(base):
        if "%" in base[pos:m.start()]:
            return None
        out.append(re.escape(base[pos:m.start()]))
        if m.group(1) == "%":
            out.append("%")
        else:
            numbered = True
            width = m.group(1)[:-1]
            digits = int(width) if width.lstrip("0") else 0
            out.append(rf"\d{{{max(digits, 1)},}}" if width.startswith("0") else r" *\d+")
        pos = m.end()
    if "%" in base[pos:] or not numbered or "%" in os.path.dirname(name):
        return None
    out.append(re.escape(base[pos:]))
    return re.compile("".join(out))


def is_image_sequence(path: str | os.PathLike) -> bool:
    """``path`` is what OpenCV reads as a printf-style image sequence (``test%d.jpg``): a
    ``%d`` pattern, an image extension (:data:`SEQUENCE_EXTENSIONS`: FFmpeg opens ``a%d.mp4``
    as the file of that very name, even with ``a1.mp4`` beside it) and one of its first
    frames (:data:`SEQUENCE_FIRST`) exists."""
    name = os.fspath(path)
    if "%" not in name or Path(name).suffix.lower() not in SEQUENCE_EXTENSIONS or sequence_regex(name) is None:
        return False
    try:
        return any(Path(name % i).exists() for i in SEQUENCE_FIRST)
    except (TypeError, ValueError):
        return False


def source_kind(source: str | os.PathLike | int) -> str:
    """``'camera'`` (an int, or a string of digits that is not a file), ``'url'`` (``scheme://...``),
    ``'sequence'`` (an image sequence, :func:`is_image_sequence`) or ``'file'``."""
    if isinstance(source, int) or (isinstance(source, str) and source.isdigit() and not os.path.exists(source)):
        return "camera"
    name = os.fspath(source)
    if _URL.match(name):
        return "url"
    if is_image_sequence(name):
        return "sequence"
    return "file"


def check_source(source: str | os.PathLike | int) -> str:
    """Refuse a file source that does not exist or is a folder (``DataError``); returns
    :func:`source_kind`. Live sources are only checked by opening them."""
    kind = source_kind(source)
    if kind == "file":
        name = os.fspath(source)
        if not os.path.exists(name):
            raise not_found(name, f"{name}: file not found")
        if os.path.isdir(name):
            raise DataError(f"{name}: is a folder, not a video")
    return kind


def _open_capture(name: str, kind: str, timeout: float | None = None) -> Any:
    """``cv2.VideoCapture`` of a live source, opened in a helper thread: a pipe nobody writes
    to or a stream that does not answer blocks inside OpenCV, where no signal reaches. The
    wait is bounded by ``timeout`` (default :data:`OPEN_TIMEOUT_S`) and a stop signal ends
    it (:mod:`fastdet.signals`); the helper is then left behind (a daemon thread)."""
    limit = OPEN_TIMEOUT_S if timeout is None else timeout
    box: dict[str, Any] = {}

    def open_it() -> None:
        try:
            box["cap"] = cv2.VideoCapture(int(name)) if kind == "camera" else cv2.VideoCapture(name)
        except BaseException as exc:  # noqa: BLE001 - reported by the waiting thread
            box["error"] = exc

    t = threading.Thread(target=open_it, name="fastdet-open", daemon=True)
    t.start()
    if not signals.wait(lambda: not t.is_alive(), limit):
        exiting.leave_behind(t)  # still inside OpenCV: the process must not wait for it at exit
        signals.check()  # a stop signal: Stopped
        raise DataError(f"{name}: the source did not open within {limit:g} s (a pipe nobody writes to, "
                        f"a stream that does not answer?)")
    if "error" in box:
        raise DataError(f"{name}: cannot open ({box['error']})")
    return box["cap"]


class FrameReader:
    """Frames of a video, decoded in a background thread.

    source: a file, an image sequence, a URL or a camera index (see the module docstring);
        or a file's frames held by :func:`~fastdet.io.hold.hold_frames`: its frames from
        ``start + 1`` on, yielded again without decoding (copies; ``kind`` ``'file'``,
        ``path``, ``fps`` and ``frame_count`` the file's; the notes were the reading's, none
        are repeated; a decoding error it met is raised at the same place). Frames it does
        not hold (before its ``start``, past the frames it read) raise ``ValueError``.
    start: frames to skip (their numbers are kept: the first frame yielded is ``start + 1``).
    frames: at most this many frames.
    notify: called with each note for the user (a frame count that differs from the
        header's, damaged frames skipped); default :func:`fastdet.console.note`. Notes are
        delivered in the iterating thread, in stream order.

    Opening checks the source and decodes the first frame (after skipping ``start``), so a
    missing file, a non-video or a zero-frame video fail here, before any output exists.
    Iterating yields ``(frame_number, frame (H, W, 3) uint8 BGR, decode_seconds)`` with
    1-based frame numbers; :meth:`peek` decodes the next frames ahead and iterating then
    yields them as well (each frame is decoded once). Afterwards ``decoded`` is the number of frames yielded and
    ``skipped`` the list of ``(first, last)`` frame numbers that were damaged.
    """

    def __init__(self, source: str | os.PathLike | int | HeldFrames, start: int = 0, frames: int | None = None,
                 queue_size: int = QUEUE_SIZE, notify: Callable[[str], None] | None = None) -> None:
        if start < 0:
            raise FastdetError(f"start must be >= 0, got {start}")
        if frames is not None and frames < 1:
            raise FastdetError(f"frames must be >= 1, got {frames}")
        self._store: HeldFrames | None = None
        self._i0 = 0
        if isinstance(source, HeldFrames):
            self._open_held(source, start, frames, notify)
            return
        self.kind = check_source(source)
        self.path = name = str(source) if self.kind == "camera" else os.fspath(source)
        # a named pipe or a device is a stream too: read once, never reopened
        self.live = self.kind in ("url", "camera") or (self.kind == "file" and not os.path.isfile(name))
        self.notify = notify if notify is not None else note
        quiet_opencv()
        cap = _open_capture(name, self.kind) if self.live else cv2.VideoCapture(name)
        if not cap.isOpened():
            cap.release()
            what = {"camera": "camera that can be opened", "url": "stream OpenCV can open (check the address)"}
            default = "video OpenCV can read (not a video file, damaged, or no frames)"
            raise DataError(f"{name}: not a {what.get(self.kind, default)}")
        n = cap.get(cv2.CAP_PROP_FRAME_COUNT)
        self.frame_count = int(n) if math.isfinite(n) and n > 0 and not self.live else None
        fps = cap.get(cv2.CAP_PROP_FPS)
        self.fps = float(fps) if math.isfinite(fps) and 0 < fps < 1000 else 25.0
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
            raise DataError(f"{name}: the video has no frames" if not self.live
                            else f"{name}: the stream gave no frame")
        if frame.ndim != 3 or frame.shape[2] != 3 or frame.dtype != np.uint8:
            cap.release()
            raise DataError(f"{name}: frames are {frame.dtype} {frame.shape}, expected 8-bit colour")
        self.shape = frame.shape
        self.start = start
        self.limit = frames
        remaining = None if self.frame_count is None else max(self.frame_count - start, 1)
        self.expected = remaining if frames is None else (frames if remaining is None else min(frames, remaining))
        self.decoded = 0
        self.skipped: list[tuple[int, int]] = []
        self._cap = cap
        self._first = (start + 1, frame, dt)
        self._q: queue.Queue = queue.Queue(maxsize=queue_size)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="fastdet-decode", daemon=True)
        self._started = False
        self._held: deque[tuple[int, np.ndarray, float]] = deque()  # peeked, not yet yielded
        self._held_error: DataError | None = None  # raised after the held frames
        self._items: Iterator[tuple[int, np.ndarray, float]] | None = None

    def _open_held(self, held: HeldFrames, start: int, frames: int | None,
                   notify: Callable[[str], None] | None) -> None:
        """The reader of held frames (``source`` in the class docstring)."""
        if start < held.start:
            raise ValueError(f"{held.path}: frames from {held.start + 1} are held, not frame {start + 1}")
        i0 = held.index(start + 1)
        if i0 is None:
            if held.ended and start + 1 > int(held.numbers[-1]):
                raise DataError(f"{held.path}: start {start} is past the end of the video")
            raise ValueError(f"{held.path}: frame {start + 1} is not held")
        self.kind, self.path, self.live = "file", held.path, False
        self.notify = notify if notify is not None else note
        self.frame_count, self.fps, self.shape = held.frame_count, held.fps, held.shape
        self.start, self.limit = start, frames
        remaining = None if self.frame_count is None else max(self.frame_count - start, 1)
        self.expected = remaining if frames is None else (frames if remaining is None else min(frames, remaining))
        self.decoded = 0
        self.skipped = []
        self._store, self._i0, self._cap = held, i0, None
        t0 = time.perf_counter()
        frame = held.frame(i0)
        self._first = (start + 1, frame, time.perf_counter() - t0)
        self._stop = threading.Event()
        self._started = False
        self._held = deque()
        self._held_error = None
        self._items = None

    def _replay(self) -> Iterator[tuple[int, np.ndarray, float]]:
        """The held frames from ``start + 1``, as :meth:`_pull` gives a file's (at most
        ``limit``; damaged frames the reading skipped recorded in ``skipped``; its decoding
        error raised after the frames before it)."""
        held = self._store
        assert held is not None
        yield self._first
        last, i, k = self._first[0], self._i0 + 1, 1
        while self.limit is None or k < self.limit:
            if i >= len(held):
                if held.error is not None:
                    raise DataError(held.error)
                if not held.ended:
                    raise ValueError(f"{self.path}: the frames after {last} are not held")
                return
            fno = int(held.numbers[i])
            if fno > last + 1:
                self.skipped.append((last + 1, fno - 1))
            t0 = time.perf_counter()
            frame = held.frame(i)
            yield fno, frame, time.perf_counter() - t0
            last, i, k = fno, i + 1, k + 1

    @property
    def held(self) -> HeldFrames | None:
        """The held frames this reader reads (``None``: it decodes its source)."""
        return self._store

    @property
    def first_frame(self) -> np.ndarray:
        """The first frame (decoded when the reader was opened), for checks before any output."""
        return self._first[1]

    def colour_sample(self) -> Iterator[np.ndarray]:
        """More frames than the first to judge the picture by (a video whose first frames are
        grey, a faded intro, is still colour footage): the next :data:`COLOUR_AHEAD` frames
        (at most :data:`COLOUR_AHEAD_BYTES`; decoded ahead with :meth:`peek`, so iterating yields
        them and each is decoded once), then, for a file with a frame count,
        :data:`COLOUR_SPREAD` frames at even positions through the rest of it (a second
        capture that seeks). Lazy: a caller that stops at the first colour frame decodes no
        more; nothing is read unless it is asked for (the first frame alone usually
        answers)."""
        ahead = max(1, min(COLOUR_AHEAD, COLOUR_AHEAD_BYTES // max(1, self.first_frame.nbytes)))
        if self.limit is not None:
            ahead = min(ahead, self.limit - 1)
        for k in range(1, ahead + 1):  # one more frame a time: stop as soon as one is colour
            got = self.peek(k)
            if len(got) < k:
                break
            yield got[-1]
        if self.live or self.kind != "file" or self.frame_count is None:
            return
        first = self.start + ahead + 1
        end = self.frame_count if self.limit is None else min(self.frame_count, self.start + self.limit)
        if end <= first:
            return
        if self._store is not None:  # the held frames at those positions (no seek needed)
            for k in range(COLOUR_SPREAD):
                i = self._store.index(first + (end - first) * k // COLOUR_SPREAD + 1)
                if i is not None:
                    yield self._store.frame(i)
            return
        cap = cv2.VideoCapture(self.path)
        try:
            for k in range(COLOUR_SPREAD):
                cap.set(cv2.CAP_PROP_POS_FRAMES, first + (end - first) * k // COLOUR_SPREAD)
                ok, frame = cap.read()
                if ok and frame is not None and frame.shape == self.shape:
                    yield frame
        finally:
            cap.release()

    def _put(self, item: Any) -> bool:
        while not self._stop.is_set():
            try:
                self._q.put(item, timeout=0.1)
                return True
            except queue.Full:
                continue
        return False

    def _read(self) -> tuple[np.ndarray | None, float]:
        t0 = time.perf_counter()
        ok, frame = self._cap.read()
        return (frame if ok else None), time.perf_counter() - t0

    def _run(self) -> None:
        try:
            self._decode()
        except BaseException as exc:  # noqa: BLE001 - reported in the iterating thread
            self._put(("error", f"{self.path}: decoding failed: {exc}"))
        finally:
            self._cap.release()  # before _END: the process may exit as soon as it is seen
            self._put(_END)

    def _decode(self) -> None:
        if not self._put(self._first):
            return
        fno, k = self.start + 1, 1  # last frame number yielded, frames yielded
        while not self._stop.is_set() and (self.limit is None or k < self.limit):
            frame, dt = self._read()
            bad = 0
            while frame is None and not self.live and bad < MAX_BAD_READS and not self._stop.is_set():
                bad += 1
                frame, dt = self._read()
            if frame is None:
                self._ended(fno)
                return
            if bad:
                frames = f"frames {fno + 1}-{fno + bad}" if bad > 1 else f"frame {fno + 1}"
                msg = (f"{self.path}: {frames} could not be decoded (damaged); skipped, "
                       "the frames after keep their numbers")
                self._put(("note", msg))
                self._put(("skipped", (fno + 1, fno + bad)))
                fno += bad
            if frame.shape != self.shape:
                msg = f"{self.path}: frame {fno + 1} is {frame.shape}, the first frame was {self.shape}; stopped"
                self._put(("error", msg))
                return
            fno += 1
            if not self._put((fno, frame, dt)):
                return
            k += 1

    def _ended(self, last: int) -> None:
        """The stream ended after frame ``last``: a note when the header counted otherwise."""
        if self.frame_count is not None and last != self.frame_count:
            msg = (f"{self.path}: {last} frames decoded; the file's header estimated "
                   f"{self.frame_count} (the end is where decoding ends)")
            self._put(("note", msg))

    def _pull(self) -> Iterator[tuple[int, np.ndarray, float]]:
        """The decoded frames from the thread (notes delivered, damage recorded on the way)."""
        if not self._started:
            self._started = True
            self._thread.start()
            exiting.leave_behind(self._thread)  # inside OpenCV while it runs: an exit before close() must not wait
        while True:
            try:
                item = self._q.get(timeout=0.1)
            except queue.Empty:
                if not self._thread.is_alive() and self._q.empty():
                    return
                if signals.stop_requested():  # a stalled stream: the stop ends it
                    return
                continue
            if item is _END:
                self._thread.join()
                return
            tag = item[0]
            if tag == "note":
                self.notify(item[1])
                continue
            if tag == "skipped":
                self.skipped.append(item[1])
                continue
            if tag == "error":
                raise DataError(item[1])
            yield item

    def _source(self) -> Iterator[tuple[int, np.ndarray, float]]:
        if self._items is None:
            self._items = self._pull() if self._store is None else self._replay()
        return self._items

    def peek(self, n: int) -> list[np.ndarray]:
        """The next ``n`` frames (fewer when the stream ends first), decoded now and kept:
        iterating yields them (with their numbers and decode times) before the frames after
        them, so a caller can look ahead (e.g. the horizon estimate of the first seconds)
        without decoding them twice. A decoding error among them is raised by the iteration
        once it reaches it, as without the look-ahead."""
        src = self._source()
        while len(self._held) < n and self._held_error is None:
            try:
                item = next(src, None)
            except DataError as exc:
                self._held_error = exc
                break
            if item is None:
                break
            self._held.append(item)
        return [item[1] for item in list(self._held)[:n]]

    def __iter__(self) -> Iterator[tuple[int, np.ndarray, float]]:
        while self._held:
            item = self._held.popleft()
            self.decoded += 1
            yield item
        if self._held_error is not None:
            exc, self._held_error = self._held_error, None
            raise exc
        for item in self._source():
            self.decoded += 1
            yield item

    @property
    def n_skipped(self) -> int:
        """Damaged frames skipped so far."""
        return sum(b - a + 1 for a, b in self.skipped)

    def close(self) -> None:
        self._held.clear()
        self._stop.set()
        if self._started:
            end = time.monotonic() + CLOSE_TIMEOUT_S
            while self._thread.is_alive() and time.monotonic() < end:
                try:
                    self._q.get(timeout=0.05)
                except queue.Empty:
                    pass
            # a decoder blocked in a read of a stalled stream is left behind (a daemon thread)
            self._thread.join(timeout=0.1)
        elif self._cap is not None:
            self._cap.release()

    def __enter__(self) -> FrameReader:  # noqa: PYI034
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def read_frames(source: str | os.PathLike | int, start: int = 0, frames: int | None = None,
                notify: Callable[[str], None] | None = None) -> list[np.ndarray]:
    """Every frame of ``source`` that decodes (after skipping ``start``, at most ``frames``),
    in order: what a :class:`FrameReader` yields, ``(H, W, 3) uint8`` BGR each, for the
    studies and tests that hold a whole clip in memory. ``notify`` as :class:`FrameReader`'s
    (default :func:`fastdet.console.note`). Raises :class:`~fastdet.errors.DataError` for a
    source that does not open or has no frames."""
    with FrameReader(source, start, frames, notify=notify) as reader:
        return [frame for _, frame, _ in reader]


def read_frames_at(source: str | os.PathLike, numbers: Iterable[int],
                   notify: Callable[[str], None] | None = None) -> dict[int, np.ndarray]:
    """The frames of ``source`` with the 1-based ``numbers`` (a keyframe list, frames to test
    on), ``{number: (H, W, 3) uint8 BGR}``, decoding no further than the largest; a number past
    the end of the video is missing from the result. ``notify`` as :class:`FrameReader`'s."""
    want = {int(n) for n in numbers}
    out: dict[int, np.ndarray] = {}
    if not want:
        return out
    last = max(want)
    with FrameReader(source, notify=notify) as reader:
        for number, frame, _ in reader:
            if number in want:
                out[number] = frame
            if number >= last:
                break
    return out
