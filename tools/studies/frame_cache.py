"""The boxes of every frame of a clip in one ``.npz``: the record-and-replay caches of the
studies (detector windows, pipeline boxes), so a rerun skips the detector.

The file holds ``n`` (``(F,) int64``, the boxes of each frame), ``boxes`` and every column
the frames' :class:`~fastdet.detections.Detections` have (``scores``, ``scale``, ``part``,
``ids``, ...), all frames' rows in order. It is written under a temporary name and renamed
(:func:`fastdet.io.atomic.atomic_path`), so a stopped run leaves no half a cache.

:func:`pack_detections` / :func:`unpack_detections` lay any list of :class:`Detections` (each
with its own columns) out as plain arrays under a prefix, for caches holding several such
lists in one ``.npz`` (read with ``allow_pickle=False``).
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from fastdet.detections import COLUMNS, Detections
from fastdet.io.atomic import atomic_path


def save_frame_detections(path: Path, frames: Sequence[Detections]) -> None:
    """Write the boxes of each of ``frames`` (one :class:`Detections` a frame) to ``path``."""
    cat = Detections.concat(frames)
    arrays = {"n": np.array([len(d) for d in frames], np.int64), "boxes": cat.boxes}
    arrays.update({name: getattr(cat, name) for name in COLUMNS if getattr(cat, name) is not None})
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(path) as tmp, open(tmp, "wb") as fh:
        np.savez_compressed(fh, **arrays)


def load_frame_detections(path: Path) -> list[Detections]:
    """The frames written by :func:`save_frame_detections`, one :class:`Detections` each."""
    with np.load(path, allow_pickle=False) as z:
        counts = z["n"]
        columns = {k: z[k] for k in z.files if k != "n"}
    out, start = [], 0
    for count in counts:
        stop = start + int(count)
        out.append(Detections(**{name: col[start:stop] for name, col in columns.items()}))
        start = stop
    return out


def pack_detections(items: Sequence[Detections], prefix: str) -> dict[str, np.ndarray]:
    """Arrays holding ``items`` (any :class:`Detections`, each with its own columns) for an
    ``.npz``, under keys starting with ``prefix``: ``n`` ``(F,) int64`` their lengths, ``has``
    ``(F, C) bool`` which of :data:`~fastdet.detections.COLUMNS` each has, then ``boxes`` and
    each column some item has, those items' rows in order (``source`` is not kept).
    :func:`unpack_detections` reads them back; a column whose dtype differs between items is
    a ``ValueError`` (it would come back converted)."""
    out = {prefix + "n": np.array([len(d) for d in items], np.int64),
           prefix + "has": np.array([[getattr(d, c) is not None for c in COLUMNS] for d in items],
                                    bool).reshape(len(items), len(COLUMNS))}
    for name in ("boxes", *COLUMNS):
        cols = [getattr(d, name) for d in items if getattr(d, name) is not None]
        if not cols:
            continue
        dtypes = sorted({str(c.dtype) for c in cols})
        if len(dtypes) > 1:
            raise ValueError(f"{prefix}{name}: items of dtypes {', '.join(dtypes)}")
        out[prefix + name] = np.concatenate(cols)
    return out


def unpack_detections(arrays: Mapping[str, np.ndarray], prefix: str) -> list[Detections]:
    """The :class:`Detections` that :func:`pack_detections` stored under ``prefix``."""
    counts, has = arrays[prefix + "n"], arrays[prefix + "has"]
    start = dict.fromkeys(("boxes", *COLUMNS), 0)
    out = []
    for count, row in zip(counts.tolist(), has):
        kw = {}
        for name, present in zip(("boxes", *COLUMNS), (True, *row.tolist())):
            if present:
                kw[name] = arrays[prefix + name][start[name]: start[name] + count]
                start[name] += count
        out.append(Detections(**kw))
    return out
