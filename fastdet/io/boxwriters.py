"""Write box files frame by frame: MOTChallenge lines (:class:`MotWriter`) and JSON lines
(:class:`JsonLinesWriter`); the formats are described in :mod:`fastdet.io.motfiles`. What
they write is a :class:`~fastdet.detections.Detections` with scores: one frame's
(:meth:`~_FrameWriter.write_detections`) or a whole table of many frames
(:meth:`~_FrameWriter.write_table`).

Each writer takes a path (written under a temporary name, renamed on close) or a text
stream, and flushes after every frame so the file can be followed while a video runs.
"""
from __future__ import annotations

import io
import json
import os
from pathlib import Path
from typing import IO, Sequence, Union

import numpy as np

from ..boxes import xyxy_to_ltwh
from ..detections import Detections
from ..errors import WriteError
from .atomic import commit, partial_name

PathLike = Union[str, "os.PathLike[str]"]


def _fmt_score(s: float) -> str:
    # shortest text that reads back to the same float32 (detector scores are float32)
    s32 = np.float32(s)
    if not np.isfinite(s32):
        raise ValueError(f"score must be finite, got {s}")
    return np.format_float_positional(s32, unique=True, trim="-")


def _fmt_coord(v) -> str:
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    f = float(v)
    return str(int(f)) if f.is_integer() else repr(f)


def _json_coord(v):
    if isinstance(v, (int, np.integer)):
        return int(v)
    f = float(v)
    return int(f) if f.is_integer() else f


class _FrameWriter:
    """Shared plumbing: open a path (or take a text stream), validate, flush per frame.

    A path is written under its temporary name (:func:`fastdet.io.atomic.partial_name`,
    ``.NAME.partial.txt``; flushed after every frame, so it can be followed while a video
    runs) and renamed to its final name by :meth:`close`: a run that is killed never
    leaves a file under the final name that looks complete. A failed write (disk full)
    raises :class:`~fastdet.errors.DataError` naming the final file, and the temporary
    file is removed; so does ``close(discard=True)``.
    """

    def __init__(self, target: PathLike | IO[str]) -> None:
        self._tmp: Path | None = None
        if hasattr(target, "write"):
            self._f = target  # type: ignore[assignment]
            self._owns = False
            self.name = getattr(target, "name", "<stream>")
        else:
            self.name = os.fspath(target)  # type: ignore[arg-type]
            self._tmp = partial_name(self.name)
            try:
                self._f = open(self._tmp, "w", encoding="utf-8", newline="\n")
            except OSError as exc:
                raise WriteError(f"{self.name}: cannot write ({exc.strerror or exc})") from None
            self._owns = True
        self.frames_written = 0
        self._failed = False
        self._result: Path | None = None

    def write(self, frame: int, boxes, scores, ids: Sequence[int] | np.ndarray | None = None) -> None:
        """Write one frame's boxes (``(N, 4)`` x1, y1, x2, y2) and scores; ids default to -1."""
        self.write_detections(frame, Detections(boxes, scores, ids=ids))

    def write_detections(self, frame: int, det: Detections) -> None:
        """Write one frame's :class:`~fastdet.detections.Detections` (its ``ids`` if it has
        them, else -1); it needs scores, and a ``frames`` column, if it has one, must say
        ``frame``."""
        frame = int(frame)
        if frame < 1:
            raise ValueError(f"frame must be >= 1 (1-based), got {frame}")
        if det.scores is None:
            raise ValueError("these boxes have no scores (ground truth?): a box file holds predictions")
        if det.frames is not None and np.any(det.frames != frame):
            raise ValueError(f"frame {frame}, but the rows say frames {sorted(set(det.frames.tolist()))}")
        ids = det.ids if det.ids is not None else np.full(len(det), -1, np.int64)
        try:
            self._f.write(self._format(frame, det.boxes, det.scores, ids))
            self._f.flush()
        except OSError as exc:
            self._failed = True
            raise WriteError(f"{self.name}: cannot write ({exc.strerror or exc}); "
                            f"{self.frames_written} frames were written before it") from None
        self.frames_written += 1

    def write_table(self, table: Detections) -> None:
        """Write a table of many frames (a ``frames`` column, e.g. from
        :meth:`Detections.from_frames <fastdet.detections.Detections.from_frames>` or
        :func:`~fastdet.io.motfiles.read_predictions`): each frame that has rows, by ascending
        frame, its rows in table order."""
        for frame, rows in table.by_frame():
            self.write_detections(frame, rows)

    def _format(self, frame: int, b: np.ndarray, s: np.ndarray, i: np.ndarray) -> str:
        raise NotImplementedError

    @property
    def tmp(self) -> Path | None:
        """The temporary file written (``None`` for a stream)."""
        return self._tmp

    def close(self, discard: bool = False, rename: bool = True) -> Path | None:
        """Close the file and give it its final name (the path); with ``discard`` (or after
        a failed write) remove it instead (``None``). With ``rename=False`` the closed
        temporary file is left for the caller to rename (:class:`~fastdet.io.atomic.OutputSet`)
        and its path returned. A stream is only flushed."""
        if not self._owns:
            self._f.flush()
            return None
        if self._f.closed:
            if discard and self._result is not None and self._result == self._tmp:
                self._tmp.unlink(missing_ok=True)
                self._result = None
            return self._result
        tmp = self._tmp
        assert tmp is not None
        try:
            self._f.close()
        except OSError as exc:
            self._failed = True
            if not discard:
                tmp.unlink(missing_ok=True)
                raise WriteError(f"{self.name}: cannot write ({exc.strerror or exc})") from None
        if discard or self._failed:
            tmp.unlink(missing_ok=True)
            return None
        self._result = commit(tmp, self.name) if rename else tmp
        return self._result

    def __enter__(self):
        return self

    def __exit__(self, exc_type, *exc) -> None:
        # an exception that is a stop (Ctrl-C, SIGTERM) keeps the frames written so far
        self.close(discard=exc_type is not None and not issubclass(exc_type, KeyboardInterrupt))


class MotWriter(_FrameWriter):
    """Write predictions as MOTChallenge lines ``frame,id,left,top,width,height,conf,-1,-1,-1``.

    ``MotWriter(path_or_text_stream)``; call :meth:`write` once per frame (a frame with no
    boxes writes nothing); each call flushes, so the file is readable while a video runs.
    A path is opened for writing (truncated); a stream is left open by :meth:`close`.
    """

    def _format(self, frame: int, b: np.ndarray, s: np.ndarray, i: np.ndarray) -> str:
        ltwh = xyxy_to_ltwh(b)
        out = io.StringIO()
        for k in range(b.shape[0]):
            l, t, w, h = (_fmt_coord(v) for v in ltwh[k])
            out.write(f"{frame},{int(i[k])},{l},{t},{w},{h},{_fmt_score(s[k])},-1,-1,-1\n")
        return out.getvalue()


class JsonLinesWriter(_FrameWriter):
    """Write one JSON object per frame:
    ``{"frame": n, "boxes": [[x1, y1, x2, y2], ...], "scores": [...], "ids": [...]}``.

    Every call of :meth:`write` writes a line (also for a frame with no boxes) and flushes.
    """

    def _format(self, frame: int, b: np.ndarray, s: np.ndarray, i: np.ndarray) -> str:
        obj = {
            "frame": frame,
            "boxes": [[_json_coord(v) for v in row] for row in b.tolist()] if b.dtype.kind == "f"
            else b.astype(np.int64).tolist(),
            "scores": [float(_fmt_score(v)) for v in s],
            "ids": [int(v) for v in i],
        }
        return json.dumps(obj, separators=(",", ":")) + "\n"
