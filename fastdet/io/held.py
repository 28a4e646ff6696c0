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

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from .atomic import discard_partial


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
