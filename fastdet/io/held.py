"""A stretch of a video file's frames decoded once and held, for runs that read it several
times (:class:`HeldFrames`, made by :func:`hold_frames`).

``fastdet adapt`` runs the pipeline three times over the stretch it kept aside at the end of
each video. Opening a file at frame S decodes every frame before it (:class:`FrameReader
<fastdet.io.reader.FrameReader>` grabs them: exact, where a seek may land beside the frame),
41 s into 10 minutes of 1280x720 footage. :func:`hold_frames` does that once and keeps the
frames -- in memory, or in a raw file of ``(N, H, W, 3) uint8`` (read back as a read-only
``np.memmap``) when they would take more than the caller's byte budget -- and a
:class:`~fastdet.io.reader.FrameReader` of a :class:`HeldFrames` yields them again, the same
frames with the same numbers, each time without decoding.
"""
from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from ..errors import DataError
from .atomic import discard_partial, partial_name


class HeldFrames:
    """Frames of a video file decoded once (:func:`hold_frames`): pass it as the source of a
    :class:`~fastdet.io.reader.FrameReader` (and so of
    :func:`~fastdet.video.run.iter_video_detections`,
    :func:`~fastdet.video.replay.iter_offset_detections`) to read them again.

    path: the video file (names and messages); fps, frame_count: the file's, as its reader
        gave them. start: the frames skipped before the first held one (so the first held
        frame is ``start + 1``). numbers: ``(N,)`` int64, the 1-based frame number of each
        held frame, increasing (a gap is a damaged frame the reading skipped). frames: the
        frames, ``N`` arrays ``(H, W, 3) uint8`` BGR (a list in memory, or a read-only
        ``np.memmap`` of ``(N, H, W, 3)``). decode_seconds: ``(N,)`` float, each frame's
        decoding time in the reading. ended: the stream ended after the last held frame (the
        video's end; else the reading stopped at its frame limit and nothing past it is held).
        error: the message of a decoding error that ended the reading (raised again as a
        :class:`~fastdet.errors.DataError` after the frames, as the file's reader raises it).
        spill: the raw file holding the frames (``None``: in memory); :meth:`close` removes it.
    """

    def __init__(self, path: str, fps: float, frame_count: int | None, start: int, numbers: np.ndarray,
                 frames: Sequence[np.ndarray], decode_seconds: np.ndarray, ended: bool, error: str | None = None,
                 spill: Path | None = None) -> None:
        if len(numbers) != len(frames) or len(numbers) != len(decode_seconds) or not len(numbers):
            raise ValueError(f"{len(numbers)} numbers, {len(frames)} frames, {len(decode_seconds)} times: "
                             "one of each a frame, at least one")
        self.path = path
        self.fps = float(fps)
        self.frame_count = frame_count
        self.start = int(start)
        self.numbers = np.asarray(numbers, np.int64)
        self.frames = frames
        self.decode_seconds = np.asarray(decode_seconds, np.float64)
        self.ended = bool(ended)
        self.error = error
        self.spill = spill
        self.shape: tuple[int, ...] = tuple(frames[0].shape)

    def __len__(self) -> int:
        return len(self.numbers)

    @property
    def nbytes(self) -> int:
        """Bytes of the held frames (in memory or in the spill file)."""
        return len(self) * int(np.prod(self.shape))

    def index(self, number: int) -> int | None:
        """The position of frame ``number`` (1-based) among the held ones; ``None``: not held."""
        i = int(np.searchsorted(self.numbers, number))
        return i if i < len(self.numbers) and self.numbers[i] == number else None

    def frame(self, i: int) -> np.ndarray:
        """A copy of the ``i``-th held frame, ``(H, W, 3) uint8`` C-contiguous and writable (what a
        file's reader gives: the held frames themselves are never handed out)."""
        return np.array(self.frames[i], dtype=np.uint8, order="C", copy=True)

    def close(self) -> None:
        """Drop the frames and remove the spill file (if any). Idempotent."""
        self.frames = []
        if self.spill is not None:
            discard_partial(self.spill)
            self.spill = None

    def __enter__(self) -> HeldFrames:  # noqa: PYI034
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _spill_name(folder: Path, path: str) -> Path:
    return partial_name(folder / f"frames-{Path(path).stem}.raw")


def hold_frames(path: str | os.PathLike, start: int = 0, frames: int | None = None, *, max_bytes: int | None = None,
                spill_dir: str | os.PathLike | None = None, notify: Callable[[str], None] | None = None
                ) -> HeldFrames:
    """Decode frames ``start + 1 ...`` of the video file ``path`` (at most ``frames`` of them)
    once, as :class:`~fastdet.io.reader.FrameReader` (``notify``: its notes, delivered here
    once) yields them, and hold them.

    max_bytes: when the frames would take more than this (a frame's bytes times ``frames``,
        or the frames left by the file header's count when fewer; ``None``: no limit), they go
        to a raw file in ``spill_dir`` (made when missing) instead of memory
        (``.frames-NAME.partial.PID-TOKEN.raw``, a temporary name of
        :mod:`fastdet.io.atomic`: removed by :meth:`HeldFrames.close` and, failing that, when
        the process ends; every write checked), read back as a read-only ``np.memmap``.
    Raises :class:`~fastdet.errors.DataError` as the reader does for a video that does not
    open or a ``start`` past its end, and :class:`~fastdet.errors.WriteError` (a
    ``DataError``; the file removed) when the spill file cannot be written (a full disk);
    ``ValueError`` when spilling is needed and ``spill_dir`` is not given. A decoding error
    midway is held (:attr:`HeldFrames.error`) and raised by each reading of the held frames.
    """
    from ..errors import WriteError
    from .reader import FrameReader

    name = os.fspath(path)
    with FrameReader(name, start, frames, notify=notify) as reader:
        if reader.live:
            raise DataError(f"{name}: only a video file's frames can be held, not a live source's")
        per_frame = reader.first_frame.nbytes
        most = reader.expected if reader.expected is not None else frames  # the header's count, at most frames
        spill = max_bytes is not None and (most is None or most * per_frame > max_bytes)
        if spill and spill_dir is None:
            raise ValueError("the frames exceed max_bytes: give spill_dir")
        numbers: list[int] = []
        held: list[np.ndarray] = []
        secs: list[float] = []
        error: str | None = None
        tmp = _spill_name(Path(os.fspath(spill_dir)), name) if spill else None
        try:
            if tmp is not None:
                tmp.parent.mkdir(parents=True, exist_ok=True)
            fh = open(tmp, "wb") if tmp is not None else None  # noqa: SIM115 - closed below, checked
            try:
                try:
                    for fno, frame, dt in reader:
                        numbers.append(fno)
                        secs.append(dt)
                        if fh is None:
                            held.append(frame)
                        elif fh.write(memoryview(np.ascontiguousarray(frame)).cast("B")) != frame.nbytes:
                            raise OSError(f"short write to {tmp}")
                except DataError as exc:
                    if not numbers:
                        raise
                    error = str(exc)
                if fh is not None:
                    fh.flush()
            finally:
                if fh is not None:
                    fh.close()
            limit = reader.limit
            ended = error is not None or limit is None or len(numbers) < limit
            shape = reader.shape
            if tmp is not None:
                stack: Sequence[np.ndarray] = np.memmap(tmp, dtype=np.uint8, mode="r",
                                                        shape=(len(numbers), *shape))
            else:
                stack = held
        except OSError as exc:
            if tmp is not None:
                discard_partial(tmp)
            raise WriteError(f"{spill_dir}: cannot hold the frames of {name} there "
                             f"({exc.strerror or exc})") from None
        except BaseException:
            if tmp is not None:
                discard_partial(tmp)
            raise
        return HeldFrames(name, reader.fps, reader.frame_count, start, np.array(numbers, np.int64), stack,
                          np.array(secs), ended, error, tmp)

