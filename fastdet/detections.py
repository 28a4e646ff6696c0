"""The result type of every stage: :class:`Detections`, boxes with per-box columns."""
from __future__ import annotations

import warnings
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, fields, replace
from typing import Any

import numpy as np

#: ``Detections.part`` values: which model a window came from.
MAIN_PART = 0
ONCOMING_PART = 1
#: component ``i`` of a :class:`fastdet.Detector` (``components=``) tags its windows ``FIRST_COMPONENT_PART + i``
FIRST_COMPONENT_PART = 2

_OPTIONAL = ("scale", "part", "ids")
_DTYPES = {"boxes": np.int32, "scores": np.float32, "scale": np.float32, "part": np.int8, "ids": np.int64}


@dataclass(frozen=True, eq=False)
class Detections:
    """Boxes found in one frame, one row per box (in the manner of supervision's ``Detections``).

    boxes: ``(N, 4) int32`` ``x1, y1, x2, y2`` in frame pixels (``x2, y2`` exclusive).
    scores: ``(N,) float32``, higher is more certain. What a score means depends on the
        stage: for :meth:`fastdet.Detector.detect` windows, the probability of "vehicle"
        (logistic-regression model) or the decision value (LinearSVC); for
        :meth:`fastdet.VideoDetector.update` boxes, the peak heat of the box's blob.
    scale: ``(N,) float32`` or ``None``: the search band's scale of each window (a window
        is ``64 * scale`` frame pixels for 64-px windows).
    part: ``(N,) int8`` or ``None``: which model found each window: ``MAIN_PART`` (0) for
        the main (square-window) model, ``ONCOMING_PART`` (1) for the oncoming-traffic
        (wide-window) model, ``FIRST_COMPONENT_PART + i`` (2, 3, ...) for the detector's
        component ``i``.
    ids: ``(N,) int64`` or ``None``: track ids (>= 1) from the tracker, -1 for none.

    ``len(d)`` is the number of boxes, ``d[mask]`` / ``d[indices]`` / ``d[i:j]`` select rows
    of every column, :meth:`concat` joins frames' worth of rows, :meth:`empty` has none.
    ``boxes, scores = d`` (the old tuple form) still works but is deprecated: use
    ``d.boxes`` and ``d.scores``.
    """

    boxes: np.ndarray
    scores: np.ndarray
    scale: np.ndarray | None = None
    part: np.ndarray | None = None
    ids: np.ndarray | None = None

    def __post_init__(self) -> None:
        b = np.asarray(self.boxes)
        b = (b if b.size else np.zeros((0, 4))).reshape(-1, 4)
        object.__setattr__(self, "boxes", np.ascontiguousarray(b, dtype=np.int32))
        n = len(self.boxes)
        for name in ("scores", *_OPTIONAL):
            v = getattr(self, name)
            if v is None:
                continue
            a = np.ascontiguousarray(np.asarray(v).reshape(-1), dtype=_DTYPES[name])
            if len(a) != n:
                raise ValueError(f"Detections: {n} boxes but {len(a)} {name}")
            object.__setattr__(self, name, a)

    # ---- construction ----------------------------------------------------------------
    @classmethod
    def empty(cls) -> "Detections":
        """No boxes."""
        return cls(np.zeros((0, 4), np.int32), np.zeros((0,), np.float32))

    @classmethod
    def concat(cls, parts: Sequence["Detections"]) -> "Detections":
        """Rows of all ``parts`` in order. A column present in some parts only is filled
        with its missing value (``scale`` NaN, ``part`` 0, ``ids`` -1) elsewhere."""
        parts = list(parts)
        if not parts:
            return cls.empty()
        if len(parts) == 1:
            return parts[0]
        cols: dict[str, Any] = {
            "boxes": np.concatenate([p.boxes for p in parts]),
            "scores": np.concatenate([p.scores for p in parts]),
        }
        fill = {"scale": np.nan, "part": MAIN_PART, "ids": -1}
        for name in _OPTIONAL:
            if any(getattr(p, name) is not None for p in parts):
                cols[name] = np.concatenate([
                    getattr(p, name) if getattr(p, name) is not None
                    else np.full(len(p), fill[name], _DTYPES[name]) for p in parts])
        return cls(**cols)

    def with_ids(self, ids: np.ndarray) -> "Detections":
        """The same rows with track ids ``(N,)``."""
        return replace(self, ids=ids)

    # ---- rows ------------------------------------------------------------------------
    def __len__(self) -> int:
        return len(self.boxes)

    def __getitem__(self, index: Any) -> "Detections":
        """Rows selected by a boolean mask, an index array or a slice (an int gives one row)."""
        if isinstance(index, (int, np.integer)):
            index = [int(index)]
        cols: dict[str, Any] = {f.name: getattr(self, f.name) for f in fields(self)}
        rows: dict[str, Any] = {k: (v[index] if v is not None else None) for k, v in cols.items()}
        return Detections(**rows)

    def __iter__(self) -> Iterator[np.ndarray]:
        warnings.warn("unpacking Detections as (boxes, scores) is deprecated; use .boxes and .scores",
                      DeprecationWarning, stacklevel=2)
        return iter((self.boxes, self.scores))

    def __repr__(self) -> str:
        extra = [n for n in _OPTIONAL if getattr(self, n) is not None]
        return f"Detections({len(self)} boxes{', with ' + ', '.join(extra) if extra else ''})"

    @property
    def is_oncoming(self) -> np.ndarray:
        """``(N,) bool``: rows found by the oncoming-traffic model (all False without ``part``)."""
        if self.part is None:
            return np.zeros(len(self), bool)
        return self.part == ONCOMING_PART
