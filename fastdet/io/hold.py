"""Decoding a stretch of a video file once and holding its frames (:func:`hold_frames`): in
memory, or in a raw file beside the work when they would take too much; the frames are then
read again as a :class:`~fastdet.io.held.HeldFrames` source of
:class:`~fastdet.io.reader.FrameReader` (kept apart from :mod:`fastdet.io.held`, which the
reader imports)."""
from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from ..errors import DataError, WriteError
from .atomic import discard_partial, partial_name
from .held import HeldFrames
from .reader import FrameReader


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

