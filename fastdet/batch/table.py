"""The combined box table of a batch (``--table boxes.parquet`` or ``boxes.csv``).

One row per box of every finished video: ``video`` (its output name, as in the manifest),
``frame`` (1-based), ``id`` (track id, -1 for none), ``x1, y1, x2, y2`` (pixels) and
``score`` (the detector's float32 score). It is built at the end of the batch from the
per-video MOTChallenge files, one video at a time (memory stays bounded for any number of
videos), written under a temporary name and renamed when complete.

Parquet goes through pyarrow (in the ``cluster`` extra), one row group per video; CSV
through the standard library, with coordinates written as in the boxes files.
"""
from __future__ import annotations

import csv
import os
from collections.abc import Iterable
from pathlib import Path

import numpy as np

from ..detections import Detections
from ..errors import FastdetError
from ..io.atomic import atomic_path
from ..io.motfiles import read_predictions

try:  # Parquet only; the CSV table needs nothing
    import pyarrow as pa
    import pyarrow.parquet as pq
except ImportError:  # pragma: no cover - pyarrow is in the cluster extra
    pa = pq = None

FORMATS = {".parquet": "parquet", ".pq": "parquet", ".csv": "csv"}
COLUMNS = ("video", "frame", "id", "x1", "y1", "x2", "y2", "score")


def table_format(path: str | os.PathLike) -> str:
    """``"parquet"`` or ``"csv"`` from the table's extension; :class:`FastdetError` otherwise
    (or for Parquet without pyarrow)."""
    ext = Path(path).suffix.lower()
    fmt = FORMATS.get(ext)
    if fmt is None:
        raise FastdetError(f"{path}: the table must end in .parquet or .csv")
    if fmt == "parquet" and pa is None:
        raise FastdetError("a Parquet table needs pyarrow: pip install fastdet[cluster] (or use .csv)")
    return fmt


def _schema() -> pa.Schema:
    return pa.schema([("video", pa.string()), ("frame", pa.int32()), ("id", pa.int64()),
                      ("x1", pa.float64()), ("y1", pa.float64()), ("x2", pa.float64()), ("y2", pa.float64()),
                      ("score", pa.float32())])


def _coord(v: float) -> str:
    return str(int(v)) if float(v).is_integer() else repr(float(v))


def _score(v: float) -> str:
    return np.format_float_positional(np.float32(v), unique=True, trim="-")


def _write_parquet(tmp: Path, videos: Iterable[tuple[str, Detections]]) -> int:
    rows = 0
    schema = _schema()
    with pq.ParquetWriter(tmp, schema) as writer:
        for name, p in videos:
            n = len(p)
            b = p.boxes.astype(np.float64)
            writer.write_table(pa.table({
                "video": pa.array([name] * n, pa.string()), "frame": p.frames.astype(np.int32), "id": p.ids,
                "x1": b[:, 0], "y1": b[:, 1], "x2": b[:, 2], "y2": b[:, 3],
                "score": p.scores.astype(np.float32)}, schema=schema))
            rows += n
        if rows == 0:
            writer.write_table(schema.empty_table())
    return rows


def _write_csv(tmp: Path, videos: Iterable[tuple[str, Detections]]) -> int:
    rows = 0
    with open(tmp, "w", encoding="utf-8", newline="") as fh:
        w = csv.writer(fh, lineterminator="\n")
        w.writerow(COLUMNS)
        for name, p in videos:
            for k in range(len(p)):
                w.writerow([name, int(p.frames[k]), int(p.ids[k]), *(_coord(v) for v in p.boxes[k]),
                            _score(p.scores[k])])
            rows += len(p)
        fh.flush()
        os.fsync(fh.fileno())
    return rows


def write_table(path: str | os.PathLike, boxes_files: Iterable[tuple[str, str | os.PathLike]]) -> int:
    """Write the table of ``boxes_files`` (``(video name, MOTChallenge boxes file)`` pairs,
    in order) to ``path``; returns the number of rows."""
    fmt = table_format(path)
    videos = ((name, read_predictions(f)) for name, f in boxes_files)
    with atomic_path(path) as tmp:
        return _write_parquet(tmp, videos) if fmt == "parquet" else _write_csv(tmp, videos)
