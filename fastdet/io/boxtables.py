"""The in-memory box tables of a clip: :class:`GroundTruth` and :class:`Predictions`.

One row per box, in file order: 1-based ``frames``, ``ids``, ``boxes`` x1, y1, x2, y2
(``x2 = left + width``, ``y2 = top + height``, continuous coordinates) and a last column
(``consider`` / ``scores``). Read and written by :mod:`fastdet.io.motfiles` and
:mod:`fastdet.io.boxwriters`.
"""
from __future__ import annotations

import os
from dataclasses import dataclass
from typing import Any, Iterable, Iterator, Union

import numpy as np

PathLike = Union[str, "os.PathLike[str]"]


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


def iter_frames(preds: Predictions) -> Iterator[tuple[int, np.ndarray]]:
    """``(frame, row indices)`` of ``preds`` (or a :class:`GroundTruth`) by ascending frame."""
    if len(preds) == 0:
        return
    order = np.argsort(preds.frames, kind="stable")
    f = preds.frames[order]
    cuts = np.flatnonzero(np.diff(f)) + 1
    for idx in np.split(order, cuts):
        yield int(preds.frames[idx[0]]), idx
