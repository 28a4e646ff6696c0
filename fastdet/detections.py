"""The one box table of fastdet: :class:`Detections`, boxes with per-box columns.

Every stage's result is one (a frame's windows, a frame's vehicles), and so is a whole
clip's: the boxes of many frames with a ``frames`` column, as the MOTChallenge and
JSON-lines readers of :mod:`fastdet.io.motfiles` return them and the evaluation scores them.
Predictions have ``scores``; ground truth has none, and a ``consider`` column instead.
Iterating over a table gives its rows, one :class:`Box` each; ``repr`` prints them as a
small aligned table.
"""
from __future__ import annotations

import itertools
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass, fields, replace
from typing import Any, NamedTuple

import numpy as np

#: ``Detections.part`` values: which model a window came from.
MAIN_PART = 0
ONCOMING_PART = 1
#: component ``i`` of a :class:`fastdet.Detector` (``components=``) tags its windows ``FIRST_COMPONENT_PART + i``
FIRST_COMPONENT_PART = 2

#: the per-box columns besides ``boxes``, in field order (each ``None`` when absent)
COLUMNS = ("scores", "scale", "part", "ids", "frames", "consider")
_DTYPES = {"scale": np.float32, "part": np.int8, "ids": np.int64, "frames": np.int64, "consider": np.bool_}
#: what :meth:`Detections.concat` puts in a column for the rows of a part without it
_FILL = {"scale": np.nan, "part": MAIN_PART, "ids": -1, "consider": True}
_INT32 = np.iinfo(np.int32)
#: the :class:`Box` field of each column, in :data:`COLUMNS` order
ROW_FIELDS = {"scores": "score", "scale": "scale", "part": "part", "ids": "id", "frames": "frame",
              "consider": "consider"}
#: rows :meth:`Detections.__repr__` prints before ``... N more``
REPR_ROWS = 10


class Box(NamedTuple):
    """One row of a :class:`Detections` table, as iterating over the table yields them
    (``for box in d``): frozen, compared and unpacked as a tuple, fields by name.

    x1, y1, x2, y2: the box (Python ``int`` for the pipeline's ``int32`` pixel boxes, ``x2, y2``
        exclusive; ``float`` for a box file's continuous coordinates).
    score, scale, part, id, frame, consider: the row's value of the table's ``scores``,
        ``scale``, ``part``, ``ids``, ``frames`` and ``consider`` columns as Python scalars;
        ``None`` where the table has no such column (ground truth has no ``score``, a
        single frame's table no ``frame``). What ``score`` means depends on the stage: see
        :class:`Detections`.
    """

    x1: float
    y1: float
    x2: float
    y2: float
    score: float | None = None
    scale: float | None = None
    part: int | None = None
    id: int | None = None
    frame: int | None = None
    consider: bool | None = None


def _boxes(value: Any) -> np.ndarray:
    b = np.asarray(value)
    if b.size == 0:
        return np.zeros((0, 4), np.int32)
    if b.ndim == 1 and b.shape[0] == 4:
        b = b.reshape(1, 4)  # one box, flat
    if b.ndim != 2 or b.shape[1] != 4:
        raise ValueError(f"Detections: boxes must have shape (N, 4), got {b.shape}")
    if b.dtype.kind == "f":
        return np.ascontiguousarray(b, dtype=np.float64)
    if b.dtype.kind not in "iub":
        raise ValueError(f"Detections: boxes must be numbers, got {b.dtype}")
    if b.dtype.itemsize > 4 and (b.min() < _INT32.min or b.max() > _INT32.max):
        raise ValueError(f"Detections: integer boxes must fit int32, got {b.min()} .. {b.max()}")
    return np.ascontiguousarray(b, dtype=np.int32)


def _column(name: str, value: Any, n: int) -> np.ndarray:
    a = np.asarray(value)
    if name == "scores":
        dtype: Any = np.float64 if a.dtype == np.float64 and a.size else np.float32
    else:
        dtype = _DTYPES[name]
    a = np.ascontiguousarray(a.reshape(-1), dtype=dtype)
    if len(a) != n:
        raise ValueError(f"Detections: {n} boxes but {len(a)} {name}")
    return a


def _cell(name: str, v: Any) -> str:
    """One value of :meth:`Detections.__repr__`'s table."""
    if isinstance(v, int):  # bool too
        return str(v)
    if name == "score":
        return f"{v:.4g}"
    if name == "scale":
        return f"{v:.3g}"
    return f"{v:.6g}"  # a float box coordinate


@dataclass(frozen=True, eq=False)
class Detections:
    """Boxes, one row per box, with per-box columns (in the manner of supervision's ``Detections``).

    boxes: ``(N, 4)`` ``x1, y1, x2, y2``: ``int32`` frame pixels (``x2, y2`` exclusive) as
        every stage of the pipeline gives them, or ``float64`` continuous coordinates
        (``x2 = left + width``) as box files may hold them: integer boxes are kept as
        ``int32``, floating-point ones as ``float64`` (an empty table is ``int32``).
    scores: ``(N,) float32`` (``float64`` when given as ``float64``, e.g. read from a file),
        higher is more certain, or ``None`` (ground truth). What a score means depends on
        the stage:

        - a vehicle box in video -- :meth:`fastdet.VideoDetector.update`,
          :func:`fastdet.detect_video`, ``python -m fastdet video`` (the ``conf`` of its box
          files) -- scores the *peak heat* of the heat-map blob it came from: at its hottest
          cell, the heat of the windows covering it over the recent frames (each window's heat
          grows with its score; older frames decay), above the heat threshold
          (``HeatConfig.threshold``, 4): typically about 6 to 100. A weak blob that kept a track
          alive is at or below the threshold, a box the offline pass added is 0;
        - a vehicle box in a single picture -- :func:`fastdet.detect_picture`, ``python -m
          fastdet image`` -- scores the box verifier's decision value (above its threshold,
          about -6; :mod:`fastdet.detect.verifier`); without the verifier
          (``PictureSearch(verify=False)``), the kept window's decision value;
        - a window -- :meth:`fastdet.Detector.detect` -- scores the model's own value: the
          probability of "vehicle" (0.5 to 1) for a logistic-regression model (the bundled
          models), the decision value (> 0) for a LinearSVC one
          (:attr:`Model.score_kind <fastdet.model.Model.score_kind>`).
    scale: ``(N,) float32`` or ``None``: the search band's scale of each window (a window
        is ``64 * scale`` frame pixels for 64-px windows).
    part: ``(N,) int8`` or ``None``: which model found each window: ``MAIN_PART`` (0) for
        the main (square-window) model, ``ONCOMING_PART`` (1) for the oncoming-traffic
        (wide-window) model, ``FIRST_COMPONENT_PART + i`` (2, 3, ...) for the detector's
        component ``i``.
    ids: ``(N,) int64`` or ``None``: track (or ground-truth object) ids, -1 for none.
    frames: ``(N,) int64`` or ``None``: 1-based frame numbers, for a table of many frames
        (a clip's predictions or ground truth, :meth:`from_frames`).
    consider: ``(N,) bool`` or ``None``: ground truth's flag, True for a box a detector
        must find, False for an ignore region.
    source: where the rows came from (a file name), for messages; not a column.

    ``len(d)`` is the number of boxes, ``d[mask]`` / ``d[indices]`` / ``d[i:j]`` select rows
    of every column (``d[i]`` is a one-row table), :meth:`concat` joins tables, :meth:`empty`
    has none, :meth:`by_frame` splits a table of many frames. ``for box in d`` yields the
    rows one :class:`Box` at a time (``box.x1 ... box.y2``, ``box.score``, ``box.id``,
    ``box.frame``, ...; ``None`` for a column the table lacks); the columns themselves are
    ``d.boxes``, ``d.scores``, ... ``repr(d)`` (and ``print(d)``) shows the rows as an aligned
    table, the first :data:`REPR_ROWS` of them, then ``... N more``.
    """

    boxes: np.ndarray
    scores: np.ndarray | None = None
    scale: np.ndarray | None = None
    part: np.ndarray | None = None
    ids: np.ndarray | None = None
    frames: np.ndarray | None = None
    consider: np.ndarray | None = None
    source: str = "<memory>"

    def __post_init__(self) -> None:
        boxes = _boxes(self.boxes)
        object.__setattr__(self, "boxes", boxes)
        n = len(boxes)
        for name in COLUMNS:
            v = getattr(self, name)
            if v is not None:
                object.__setattr__(self, name, _column(name, v, n))

    # ---- construction ----------------------------------------------------------------
    @classmethod
    def empty(cls, source: str = "<memory>") -> Detections:
        """No boxes (an empty score column)."""
        return cls(np.zeros((0, 4), np.int32), np.zeros((0,), np.float32), source=source)

    @classmethod
    def concat(cls, parts: Sequence[Detections]) -> Detections:
        """Rows of all ``parts`` in order (``source`` of the first). A column present in some
        parts only is filled with its missing value (``scale`` NaN, ``part`` 0, ``ids`` -1,
        ``consider`` True) elsewhere; ``scores`` and ``frames`` have none: parts with and
        without them do not join (``ValueError``)."""
        parts = list(parts)
        if not parts:
            return cls.empty()
        if len(parts) == 1:
            return parts[0]
        cols: dict[str, Any] = {"boxes": np.concatenate([p.boxes for p in parts])}
        for name in COLUMNS:
            have = [getattr(p, name) is not None for p in parts]
            if not any(have):
                continue
            if not all(have) and name not in _FILL:
                raise ValueError(f"Detections.concat: some parts have {name} and some do not")
            cols[name] = np.concatenate([
                getattr(p, name) if getattr(p, name) is not None
                else np.full(len(p), _FILL[name], _DTYPES[name]) for p in parts])
        return cls(**cols, source=parts[0].source)

    @classmethod
    def from_frames(cls, frames: Iterable[tuple[int, Detections]], source: str = "<memory>") -> Detections:
        """One table of ``(frame number, detections)`` pairs (e.g. from
        :func:`fastdet.video.iter_video_detections`), in the order given: their rows with a
        ``frames`` column and an ``ids`` column (-1 for the rows of frames without ids).
        (The tables :func:`fastdet.detect_video` yields have both already: :meth:`concat` them.)"""
        rows = [d.with_frames(np.full(len(d), int(f), np.int64)) for f, d in frames]
        if not rows:
            e = cls.empty(source)
            return replace(e, frames=np.zeros(0, np.int64), ids=np.zeros(0, np.int64))
        out = cls.concat(rows)
        if out.ids is None:
            out = out.with_ids(np.full(len(out), -1, np.int64))
        return replace(out, source=source)

    def with_ids(self, ids: np.ndarray) -> Detections:
        """The same rows with track ids ``(N,)``."""
        return replace(self, ids=ids)

    def with_frames(self, frames: np.ndarray) -> Detections:
        """The same rows with frame numbers ``(N,)``."""
        return replace(self, frames=frames)

    # ---- rows ------------------------------------------------------------------------
    def __len__(self) -> int:
        return len(self.boxes)

    def __getitem__(self, index: Any) -> Detections:
        """Rows selected by a boolean mask, an index array or a slice (an int gives one row)."""
        if isinstance(index, (int, np.integer)):
            index = [int(index)]
        rows: dict[str, Any] = {f.name: getattr(self, f.name) for f in fields(self)}
        for name in ("boxes", *COLUMNS):
            if rows[name] is not None:
                rows[name] = rows[name][index]
        return Detections(**rows)

    def __iter__(self) -> Iterator[Box]:
        """The rows, one :class:`Box` at a time (Python scalars; ``None`` for absent columns)."""
        n = len(self)
        cols: list[Iterable[Any]] = [self.boxes[:, k].tolist() for k in range(4)]
        for name in COLUMNS:
            v = getattr(self, name)
            cols.append(v.tolist() if v is not None else itertools.repeat(None, n))
        return map(Box._make, zip(*cols))

    def __repr__(self) -> str:
        n = len(self)
        head = f"Detections({n} box{'' if n == 1 else 'es'}"
        head += (f" from {self.source}" if self.source != "<memory>" else "") + ")"
        if n == 0:
            return head
        names = ["x1", "y1", "x2", "y2", *(ROW_FIELDS[c] for c in COLUMNS if getattr(self, c) is not None)]
        shown = self[:REPR_ROWS]
        table = [names] + [[_cell(name, v) for name, v in zip(Box._fields, row) if name in names]
                           for row in shown]
        widths = [max(len(r[k]) for r in table) for k in range(len(names))]
        lines = [head, *("  ".join(c.rjust(w) for c, w in zip(r, widths)) for r in table)]
        if n > REPR_ROWS:
            lines.append(f"... {n - REPR_ROWS} more")
        return "\n".join(lines)

    def by_frame(self) -> Iterator[tuple[int, Detections]]:
        """``(frame number, that frame's rows in table order)`` by ascending frame, for a
        table with a ``frames`` column."""
        if self.frames is None:
            raise ValueError("Detections.by_frame: the table has no frames column")
        if len(self) == 0:
            return
        order = np.argsort(self.frames, kind="stable")
        cuts = np.flatnonzero(np.diff(self.frames[order])) + 1
        for idx in np.split(order, cuts):
            yield int(self.frames[idx[0]]), self[idx]

    # ---- derived -----------------------------------------------------------------------
    @property
    def is_oncoming(self) -> np.ndarray:
        """``(N,) bool``: rows found by the oncoming-traffic model (all False without ``part``)."""
        if self.part is None:
            return np.zeros(len(self), bool)
        return self.part == ONCOMING_PART

    @property
    def num_frames(self) -> int:
        """The last frame number of a table with a ``frames`` column (0 when it has no rows)."""
        if self.frames is None:
            raise ValueError("Detections.num_frames: the table has no frames column")
        return int(self.frames.max()) if len(self) else 0

    @property
    def num_considered(self) -> int:
        """Boxes a detector must find: ``consider`` True (every box without that column)."""
        return len(self) if self.consider is None else int(self.consider.sum())

    @property
    def has_ids(self) -> bool:
        """True when some row carries an id (not all ``-1``, or no ``ids`` column)."""
        return self.ids is not None and bool(np.any(self.ids != -1))

    @property
    def targets(self) -> np.ndarray:
        """``(N,) bool``: the rows a detector must find (``consider``; all of them without it)."""
        return np.ones(len(self), bool) if self.consider is None else self.consider
