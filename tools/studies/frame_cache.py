"""The boxes of every frame of a clip in one ``.npz``: the record-and-replay caches of the
studies (detector windows, pipeline boxes), so a rerun skips the detector.

The file holds ``n`` (``(F,) int64``, the boxes of each frame), ``boxes`` and every column
the frames' :class:`~fastdet.detections.Detections` have (``scores``, ``scale``, ``part``,
``ids``, ...), all frames' rows in order. It is written under a temporary name and renamed
(:func:`fastdet.io.atomic.atomic_path`), so a stopped run leaves no half a cache.
"""
from __future__ import annotations

from collections.abc import Sequence
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
