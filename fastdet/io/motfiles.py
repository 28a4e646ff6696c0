"""Read and write MOTChallenge box files (and the JSON-lines box format of ``fastdet video``).

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
``consider`` other than 0/1 -- raises :class:`~fastdet.errors.DataError` whose message
names the file and the line.

JSON lines (written by :class:`JsonLinesWriter`, also read by :func:`read_predictions` for
files ending in ``.jsonl`` / ``.json``), one object per frame::

    {"frame": 3, "boxes": [[x1, y1, x2, y2], ...], "scores": [...], "ids": [...]}

Boxes inside fastdet are ``x1, y1, x2, y2`` with ``x2 = left + width`` and
``y2 = top + height`` (continuous coordinates; for the integer boxes of
:class:`~fastdet.detections.Detections` that is "x2 exclusive").
"""
from __future__ import annotations

import io
import json
import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any, Iterable, Iterator, Sequence, Union

import numpy as np

from ..boxes import ltwh_to_xyxy, xyxy_to_ltwh
from ..errors import DataError, WriteError
from .atomic import commit, partial_name

PathLike = Union[str, "os.PathLike[str]"]

GT_COLUMNS = ("frame", "id", "left", "top", "width", "height", "consider", "class", "visibility")
PRED_COLUMNS = ("frame", "id", "left", "top", "width", "height", "conf", "x", "y", "z")
MIN_GT_COLUMNS = 6
MIN_PRED_COLUMNS = 7
MAX_COLUMNS = 10


# ---------------------------------------------------------------------------------------
# box conversions


# ---------------------------------------------------------------------------------------
# containers


def _as_1d(name: str, a, dtype, n: int | None) -> np.ndarray:
    arr = np.ascontiguousarray(np.asarray(a, dtype=dtype).reshape(-1))
    if n is not None and arr.shape[0] != n:
        raise ValueError(f"{name} has {arr.shape[0]} entries, expected {n}")
    return arr


def _as_boxes(a) -> np.ndarray:
    arr = np.asarray(a, dtype=np.float64)
    if arr.size == 0:
        return np.zeros((0, 4), np.float64)
    if arr.ndim != 2 or arr.shape[1] != 4:
        raise ValueError(f"boxes must have shape (N, 4), got {arr.shape}")
    return np.ascontiguousarray(arr)


def _normalise_rows(table: Any, last: str, dtype: Any) -> None:
    """Check and convert the columns of a frozen box table in place: ``boxes`` to ``(N, 4)
    float64``, ``frames`` and ``ids`` to ``(N,) int64`` and the column ``last`` to ``(N,)
    dtype``."""
    boxes = _as_boxes(table.boxes)
    n = boxes.shape[0]
    object.__setattr__(table, "boxes", boxes)
    for name, dt in (("frames", np.int64), ("ids", np.int64), (last, dtype)):
        object.__setattr__(table, name, _as_1d(name, getattr(table, name), dt, n))


@dataclass(frozen=True, eq=False)
class GroundTruth:
    """Ground-truth boxes of one clip, one row per box, in file order.

    frames: ``(N,) int64`` 1-based frame numbers.
    ids: ``(N,) int64`` object identities.
    boxes: ``(N, 4) float64`` x1, y1, x2, y2.
    consider: ``(N,) bool``: True for a box a detector must find, False for an ignore region.
    source: where it came from (file name), for messages.
    """

    frames: np.ndarray
    ids: np.ndarray
    boxes: np.ndarray
    consider: np.ndarray
    source: str = "<memory>"

    def __post_init__(self) -> None:
        _normalise_rows(self, "consider", bool)

    def __len__(self) -> int:
        return int(self.boxes.shape[0])

    @property
    def num_frames(self) -> int:
        """The last annotated frame number (0 when there are no boxes)."""
        return int(self.frames.max()) if len(self) else 0

    @property
    def num_considered(self) -> int:
        return int(self.consider.sum())


@dataclass(frozen=True, eq=False)
class Predictions:
    """Predicted boxes, one row per box, in file order.

    frames: ``(N,) int64`` 1-based frame numbers.
    ids: ``(N,) int64`` track ids, ``-1`` for "no id".
    boxes: ``(N, 4) float64`` x1, y1, x2, y2.
    scores: ``(N,) float64`` confidences, higher is more certain.
    source: where it came from (file name), for messages.
    """

    frames: np.ndarray
    ids: np.ndarray
    boxes: np.ndarray
    scores: np.ndarray
    source: str = "<memory>"

    def __post_init__(self) -> None:
        _normalise_rows(self, "scores", np.float64)

    def __len__(self) -> int:
        return int(self.boxes.shape[0])

    @property
    def has_ids(self) -> bool:
        """True when some prediction carries a track id (not all ``-1``)."""
        return bool(np.any(self.ids != -1))

    @classmethod
    def empty(cls, source: str = "<memory>") -> "Predictions":
        return cls(np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros((0, 4)), np.zeros(0), source)

    @classmethod
    def from_frames(
        cls,
        frames: Iterable[tuple],
        source: str = "<memory>",
    ) -> "Predictions":
        """Collect ``(frame, detections)`` pairs, e.g. from
        ``fastdet.video.iter_video_detections``.

        ``detections`` is a :class:`~fastdet.detections.Detections` (``boxes`` x1, y1, x2, y2,
        ``scores``, and ``ids`` if it has them) or a tuple ``(boxes, scores[, ids])``.
        """
        fr: list[np.ndarray] = []
        ids: list[np.ndarray] = []
        bx: list[np.ndarray] = []
        sc: list[np.ndarray] = []
        for frame, det in frames:
            if hasattr(det, "boxes"):
                boxes, scores, tid = det.boxes, det.scores, getattr(det, "ids", None)
            else:
                boxes, scores = det[0], det[1]
                tid = det[2] if len(det) > 2 else None
            b = _as_boxes(boxes)
            n = b.shape[0]
            s = _as_1d("scores", scores, np.float64, n)
            i = np.full(n, -1, np.int64) if tid is None else _as_1d("ids", tid, np.int64, n)
            fr.append(np.full(n, int(frame), np.int64))
            ids.append(i)
            bx.append(b)
            sc.append(s)
        if not fr:
            return cls.empty(source)
        return cls(np.concatenate(fr), np.concatenate(ids), np.concatenate(bx), np.concatenate(sc), source)


# ---------------------------------------------------------------------------------------
# reading


def _read_text(path: PathLike) -> tuple[str, str]:
    name = os.fspath(path)
    p = Path(name)
    if not p.exists():
        raise DataError(f"{name}: file not found")
    if p.is_dir():
        raise DataError(f"{name}: is a directory, expected a box file")
    try:
        with open(p, "r", encoding="utf-8-sig", newline=None) as f:
            return f.read(), name
    except UnicodeDecodeError as exc:
        raise DataError(f"{name}: not a text file ({exc.reason} at byte {exc.start})") from None
    except OSError as exc:
        raise DataError(f"{name}: cannot read ({exc.strerror or exc})") from None


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
        vals.extend([math.nan] * (MAX_COLUMNS - len(vals)))
        rows.append(vals)
        linenos.append(lineno)
    arr = np.array(rows, dtype=np.float64) if rows else np.zeros((0, MAX_COLUMNS), np.float64)
    return arr, linenos


def parse_gt(text: str, source: str = "<string>") -> GroundTruth:
    """Ground truth from the text of a MOTChallenge ``gt.txt`` (see module docstring)."""
    arr, linenos = _parse_rows(text, source, MIN_GT_COLUMNS, "ground truth")
    consider = arr[:, 6].copy()
    consider[np.isnan(consider)] = 1.0
    bad = np.flatnonzero((consider != 0) & (consider != 1))
    if bad.size:
        k = int(bad[0])
        raise DataError(f"{source}: line {linenos[k]}: consider must be 0 or 1, got {arr[k, 6]:g}")
    return GroundTruth(
        frames=arr[:, 0].astype(np.int64),
        ids=arr[:, 1].astype(np.int64),
        boxes=ltwh_to_xyxy(arr[:, 2:6]),
        consider=consider.astype(bool),
        source=source,
    )


def parse_predictions(text: str, source: str = "<string>") -> Predictions:
    """Predictions from the text of a MOTChallenge detection / tracker file."""
    arr, _ = _parse_rows(text, source, MIN_PRED_COLUMNS, "predictions")
    return Predictions(
        frames=arr[:, 0].astype(np.int64),
        ids=arr[:, 1].astype(np.int64),
        boxes=ltwh_to_xyxy(arr[:, 2:6]),
        scores=arr[:, 6].copy(),
        source=source,
    )


def parse_jsonl_predictions(text: str, source: str = "<string>") -> Predictions:
    """Predictions from JSON lines as written by :class:`JsonLinesWriter`."""
    frames: list[tuple[int, tuple]] = []
    for lineno, raw in enumerate(text.splitlines(), start=1):
        line = raw.strip()
        if not line:
            continue
        where = f"{source}: line {lineno}"
        try:
            obj = json.loads(line)
        except json.JSONDecodeError as exc:
            raise DataError(f"{where}: not JSON ({exc.msg})") from None
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
            if np.any(boxes[:, 2] < boxes[:, 0]) or np.any(boxes[:, 3] < boxes[:, 1]):
                raise ValueError("negative box size (x2 < x1 or y2 < y1)")
        except (TypeError, ValueError) as exc:
            raise DataError(f"{where}: {exc}") from None
        frames.append((frame, (boxes, scores, ids)))
    return Predictions.from_frames(frames, source=source)


def read_gt(path: PathLike) -> GroundTruth:
    """Read a MOTChallenge ground-truth file. An empty file is an error."""
    text, name = _read_text(path)
    gt = parse_gt(text, name)
    if len(gt) == 0:
        raise DataError(f"{name}: no ground-truth boxes in the file")
    return gt


def read_predictions(path: PathLike) -> Predictions:
    """Read predictions: MOTChallenge text, or JSON lines when the name ends in ``.jsonl``/``.json``.

    An empty file is valid (the detector found nothing).
    """
    text, name = _read_text(path)
    if name.lower().endswith((".jsonl", ".json")):
        return parse_jsonl_predictions(text, name)
    return parse_predictions(text, name)


# ---------------------------------------------------------------------------------------
# writing


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

    @staticmethod
    def _check(frame: int, boxes, scores, ids) -> tuple[int, np.ndarray, np.ndarray, np.ndarray]:
        frame = int(frame)
        if frame < 1:
            raise ValueError(f"frame must be >= 1 (1-based), got {frame}")
        b = np.asarray(boxes)
        if b.size == 0:
            b = np.zeros((0, 4), b.dtype if b.dtype.kind in "iuf" else np.int32)
        if b.ndim != 2 or b.shape[1] != 4:
            raise ValueError(f"boxes must have shape (N, 4), got {b.shape}")
        n = b.shape[0]
        s = np.asarray(scores, dtype=np.float64).reshape(-1)
        if s.shape[0] != n:
            raise ValueError(f"{n} boxes but {s.shape[0]} scores")
        i = np.full(n, -1, np.int64) if ids is None else np.asarray(ids, dtype=np.int64).reshape(-1)
        if i.shape[0] != n:
            raise ValueError(f"{n} boxes but {i.shape[0]} ids")
        return frame, b, s, i

    def write(self, frame: int, boxes, scores, ids: Sequence[int] | np.ndarray | None = None) -> None:
        """Write one frame's boxes (``(N, 4)`` x1, y1, x2, y2) and scores; ids default to -1."""
        frame, b, s, i = self._check(frame, boxes, scores, ids)
        try:
            self._f.write(self._format(frame, b, s, i))
            self._f.flush()
        except OSError as exc:
            self._failed = True
            raise WriteError(f"{self.name}: cannot write ({exc.strerror or exc}); "
                            f"{self.frames_written} frames were written before it") from None
        self.frames_written += 1

    def write_detections(self, frame: int, det) -> None:
        """Write a :class:`~fastdet.detections.Detections` (uses its ``ids`` if it has them)."""
        self.write(frame, det.boxes, det.scores, getattr(det, "ids", None))

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


def iter_frames(preds: Predictions) -> Iterator[tuple[int, np.ndarray]]:
    """``(frame, row indices)`` of ``preds`` (or a :class:`GroundTruth`) by ascending frame."""
    if len(preds) == 0:
        return
    order = np.argsort(preds.frames, kind="stable")
    f = preds.frames[order]
    cuts = np.flatnonzero(np.diff(f)) + 1
    for idx in np.split(order, cuts):
        yield int(preds.frames[idx[0]]), idx
