"""Read MOTChallenge box files (and the JSON-lines box format of ``fastdet video``) into
the one box table, :class:`~fastdet.detections.Detections`.

A file is a table of many frames: ground truth has ``frames``, ``ids``, ``boxes`` and
``consider`` (no scores), predictions ``frames``, ``ids``, ``boxes`` and ``scores``; both
keep the file's continuous coordinates (``float64`` boxes) and name the file in ``source``.
The writers live in :mod:`fastdet.io.boxwriters` and are re-exported here.

Formats
-------
Ground truth (``gt.txt``), one box per line::

    frame,id,left,top,width,height,consider,class,visibility

Predictions (``det.txt`` / tracker output), one box per line::

    frame,id,left,top,width,height,conf,-1,-1,-1

``frame`` is 1-based. A prediction's ``id`` is ``-1`` when the detector gives no identity.
Ground-truth lines may have 6 to 10 columns (a 6-column line has ``consider`` = 1);
prediction lines 7 to 10 (column 7 is the confidence). Columns past those are read as
numbers and otherwise ignored (``class``, ``visibility``, the 3-D world coordinates).
Blank lines are skipped. Anything else wrong -- a wrong column count, a field that is not a
finite number, a fractional frame or id, a negative width or height, a frame < 1, a
``consider`` other than 0/1, a frame or id out of range, a coordinate, width or height
beyond :data:`~fastdet.boxes.MAX_COORD` pixels -- raises :class:`~fastdet.errors.DataError` whose message
names the file and the line.

JSON lines (written by :class:`JsonLinesWriter`, also read by :func:`read_predictions` for
files ending in ``.jsonl`` / ``.json``), one object per frame::

    {"frame": 3, "boxes": [[x1, y1, x2, y2], ...], "scores": [...], "ids": [...]}

Boxes inside fastdet are ``x1, y1, x2, y2`` with ``x2 = left + width`` and
``y2 = top + height`` (continuous coordinates; for the integer boxes of
:class:`~fastdet.detections.Detections` that is "x2 exclusive").
"""
from __future__ import annotations

import math
import os
from typing import Any

import numpy as np

from ..boxes import MAX_COORD, ltwh_to_xyxy
from ..detections import Detections
from ..errors import DataError
from .boxwriters import JsonLinesWriter, MotWriter, PathLike
from .files import JsonError, parse_json, read_input_text

__all__ = [
    "GT_COLUMNS", "PRED_COLUMNS", "MIN_GT_COLUMNS", "MIN_PRED_COLUMNS", "MAX_COLUMNS", "MAX_FRAME", "MAX_ID",
    "PathLike", "MotWriter", "JsonLinesWriter",
    "parse_gt", "parse_predictions", "parse_jsonl_predictions", "read_gt", "read_predictions",
]

GT_COLUMNS = ("frame", "id", "left", "top", "width", "height", "consider", "class", "visibility")
PRED_COLUMNS = ("frame", "id", "left", "top", "width", "height", "conf", "x", "y", "z")
MIN_GT_COLUMNS = 6
MIN_PRED_COLUMNS = 7
MAX_COLUMNS = 10


# ---------------------------------------------------------------------------------------
# reading


def _read_text(path: PathLike) -> tuple[str, str]:
    """The text of a box file: one bounded read of a regular file
    (:func:`fastdet.io.files.read_input_text`: a FIFO, ``/dev/zero``, a symlink loop, a binary
    or a file past :data:`~fastdet.io.files.MAX_TEXT_BYTES` are refused in one line)."""
    name = os.fspath(path)
    return read_input_text(name, "box file"), name


#: largest frame number and largest id magnitude a box file may hold (int32: a video of
#: 2**31 frames runs 2.7 years at 25 fps; larger numbers are a damaged file)
MAX_FRAME = 2**31 - 1
MAX_ID = 2**31 - 1


def _check_range(where: str, frame: float, tid: float) -> None:
    """``DataError`` for a frame past :data:`MAX_FRAME` or an id beyond +-:data:`MAX_ID`."""
    if frame > MAX_FRAME:
        raise DataError(f"{where}: frame {frame:.15g} is out of range (at most {MAX_FRAME})")
    if abs(tid) > MAX_ID:
        raise DataError(f"{where}: id {tid:.15g} is out of range (-{MAX_ID} to {MAX_ID})")


def _whole(name: str, v: Any) -> int:
    """A JSON number that is a whole number (``777.0`` yes, ``777.5`` no, ``true`` no)."""
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise ValueError(f"{name} must be a whole number, got {v!r}")
    if isinstance(v, float) and not (math.isfinite(v) and v.is_integer()):
        raise ValueError(f"{name} must be a whole number, got {v!r}")
    return int(v)


def _parse_rows(text: str, source: str, min_cols: int, kind: str) -> tuple[np.ndarray, list[int]]:
    """Numeric rows of a MOT file -> ``(N, 10)`` float64 (missing columns NaN), line numbers."""
    rows: list[list[float]] = []
    linenos: list[int] = []
    for lineno, raw in enumerate(text.splitlines(), start=1):
        line = raw.strip()
        if not line:
            continue
        fields = [f.strip() for f in line.split(",")]
        where = f"{source}: line {lineno}"
        if not (min_cols <= len(fields) <= MAX_COLUMNS):
            want = f"{min_cols} to {MAX_COLUMNS}"
            raise DataError(
                f"{where}: expected {want} comma-separated columns for {kind}, got {len(fields)}: {line[:80]!r}"
            )
        vals: list[float] = []
        names = GT_COLUMNS if kind == "ground truth" else PRED_COLUMNS
        for k, f in enumerate(fields):
            col = names[k] if k < len(names) else f"column {k + 1}"
            try:
                v = float(f)
            except ValueError:
                raise DataError(f"{where}: {col} is not a number: {f!r}") from None
            if not math.isfinite(v):
                raise DataError(f"{where}: {col} is not a finite number: {f!r}")
            vals.append(v)
        frame, tid, _, _, w, h = vals[:6]
        if frame != int(frame) or tid != int(tid):
            raise DataError(f"{where}: frame and id must be whole numbers, got {fields[0]!r}, {fields[1]!r}")
        if frame < 1:
            raise DataError(f"{where}: frame must be >= 1 (frames are 1-based), got {fields[0]}")
        _check_range(where, frame, tid)
        if w < 0 or h < 0:
            raise DataError(f"{where}: negative box size width={fields[4]} height={fields[5]}")
        for k in range(2, 6):
            if abs(vals[k]) > MAX_COORD:
                raise DataError(f"{where}: {names[k]} {fields[k]} is out of range (at most {MAX_COORD:.0f} px)")
        vals.extend([math.nan] * (MAX_COLUMNS - len(vals)))
        rows.append(vals)
        linenos.append(lineno)
    arr = np.array(rows, dtype=np.float64) if rows else np.zeros((0, MAX_COLUMNS), np.float64)
    return arr, linenos


def parse_gt(text: str, source: str = "<string>") -> Detections:
    """Ground truth from the text of a MOTChallenge ``gt.txt`` (see module docstring): a
    table with ``frames``, ``ids``, ``boxes`` and ``consider``, no scores."""
    arr, linenos = _parse_rows(text, source, MIN_GT_COLUMNS, "ground truth")
    consider = arr[:, 6].copy()
    consider[np.isnan(consider)] = 1.0
    bad = np.flatnonzero((consider != 0) & (consider != 1))
    if bad.size:
        k = int(bad[0])
        raise DataError(f"{source}: line {linenos[k]}: consider must be 0 or 1, got {arr[k, 6]:g}")
    return Detections(
        ltwh_to_xyxy(arr[:, 2:6]),
        frames=arr[:, 0].astype(np.int64),
        ids=arr[:, 1].astype(np.int64),
        consider=consider.astype(bool),
        source=source,
    )


def parse_predictions(text: str, source: str = "<string>") -> Detections:
    """Predictions from the text of a MOTChallenge detection / tracker file: a table with
    ``frames``, ``ids``, ``boxes`` and ``scores``."""
    arr, _ = _parse_rows(text, source, MIN_PRED_COLUMNS, "predictions")
    return Detections(
        ltwh_to_xyxy(arr[:, 2:6]),
        arr[:, 6].copy(),
        frames=arr[:, 0].astype(np.int64),
        ids=arr[:, 1].astype(np.int64),
        source=source,
    )


def parse_jsonl_predictions(text: str, source: str = "<string>") -> Detections:
    """Predictions from JSON lines as written by :class:`JsonLinesWriter` (a table as
    :func:`parse_predictions` gives)."""
    frames: list[tuple[int, Detections]] = []
    for lineno, raw in enumerate(text.splitlines(), start=1):
        line = raw.strip()
        if not line:
            continue
        where = f"{source}: line {lineno}"
        try:
            obj = parse_json(line)
        except JsonError as exc:
            raise DataError(f"{where}: not a box line (JSON: {exc})") from None
        if not isinstance(obj, dict) or "frame" not in obj or "boxes" not in obj:
            raise DataError(f"{where}: expected an object with 'frame', 'boxes', 'scores'")
        try:
            frame = obj["frame"]
            if isinstance(frame, bool) or not isinstance(frame, int) or frame < 1:
                raise ValueError(f"frame must be an integer >= 1, got {frame!r}")
            if frame > MAX_FRAME:
                raise ValueError(f"frame {frame} is out of range (at most {MAX_FRAME})")
            boxes = np.asarray(obj["boxes"], dtype=np.float64)
            if boxes.size == 0:
                boxes = np.zeros((0, 4))
            if boxes.ndim != 2 or boxes.shape[1] != 4:
                raise ValueError("boxes must be a list of [x1, y1, x2, y2]")
            n = boxes.shape[0]
            scores = np.asarray(obj.get("scores", [math.nan] * n), dtype=np.float64).reshape(-1)
            if scores.shape[0] != n:
                raise ValueError(f"{n} boxes but {scores.shape[0]} scores")
            ids_raw = obj.get("ids")
            if ids_raw is None:
                ids = np.full(n, -1, np.int64)
            else:
                if not isinstance(ids_raw, list):
                    raise ValueError(f"ids must be a list of whole numbers, got {ids_raw!r}"[:120])
                ids = np.array([_whole("an id", v) for v in ids_raw], dtype=object)
                if ids.size and np.any(np.abs(ids) > MAX_ID):
                    raise ValueError(f"an id is out of range (-{MAX_ID} to {MAX_ID})")
                ids = ids.astype(np.int64).reshape(-1)
            if ids.shape[0] != n:
                raise ValueError(f"{n} boxes but {ids.shape[0]} ids")
            if not (np.isfinite(boxes).all() and np.isfinite(scores).all()):
                raise ValueError("boxes and scores must be finite numbers")
            if boxes.size and np.abs(boxes).max() > MAX_COORD:
                raise ValueError(f"a box coordinate is out of range (at most {MAX_COORD:.0f} px)")
            if np.any(boxes[:, 2] < boxes[:, 0]) or np.any(boxes[:, 3] < boxes[:, 1]):
                raise ValueError("negative box size (x2 < x1 or y2 < y1)")
        except (TypeError, ValueError) as exc:
            raise DataError(f"{where}: {exc}") from None
        frames.append((frame, Detections(boxes, scores, ids=ids)))
    return Detections.from_frames(frames, source=source)


def read_gt(path: PathLike) -> Detections:
    """Read a MOTChallenge ground-truth file. An empty file is an error."""
    text, name = _read_text(path)
    gt = parse_gt(text, name)
    if len(gt) == 0:
        raise DataError(f"{name}: no ground-truth boxes in the file")
    return gt


def read_predictions(path: PathLike) -> Detections:
    """Read predictions: MOTChallenge text, or JSON lines when the name ends in ``.jsonl``/``.json``.

    An empty file is valid (the detector found nothing).
    """
    text, name = _read_text(path)
    if name.lower().endswith((".jsonl", ".json")):
        return parse_jsonl_predictions(text, name)
    return parse_predictions(text, name)
