"""The offline pass over a whole file's tracks (``fastdet video --offline``): not causal.

After the causal tracker (:mod:`fastdet.video.track`) has run over every frame, a correction
that needs the future: **gap interpolation** (as StrongSORT's "GSI"/linear interpolation, Du
et al., "StrongSORT: Make DeepSORT Great Again", IEEE TMM 2023): where a track has no box for
at most ``max_gap`` frames between two of its boxes, each missing frame gets the box linearly
interpolated between them (coordinates rounded to whole pixels). (Extending each track back
before its first box was a second one, deleted: docs/accuracy.md, "Deleted stages".)

An added box that overlaps a box of its frame (IoU > 0.3) is left out. Added boxes carry the
track's id and score 0 (no heat was seen for them in that frame).
"""
from __future__ import annotations

from collections.abc import Sequence
from itertools import pairwise

import numpy as np

from ..boxes import clip, iou
from ..config import TrackerConfig
from ..detections import Detections

_MAX_OVERLAP = 0.3


def _by_id(frames: Sequence[tuple[int, Detections]]) -> dict[int, list[tuple[int, np.ndarray]]]:
    tracks: dict[int, list[tuple[int, np.ndarray]]] = {}
    for fno, det in frames:
        if det.ids is None:
            continue
        for b, i in zip(det.boxes, det.ids):
            if i >= 1:
                tracks.setdefault(int(i), []).append((int(fno), b.astype(np.float64)))
    return tracks


def interpolate_gaps(track: list[tuple[int, np.ndarray]], max_gap: int) -> list[tuple[int, np.ndarray]]:
    """The boxes to add to one track ``[(frame, box), ...]`` (ascending frames): every frame
    of a gap of at most ``max_gap`` frames, linearly interpolated."""
    out = []
    for (f1, b1), (f2, b2) in pairwise(track):
        gap = f2 - f1 - 1
        if 1 <= gap <= max_gap:
            for f in range(f1 + 1, f2):
                t = (f - f1) / (f2 - f1)
                out.append((f, np.round(b1 + t * (b2 - b1))))
    return out


def offline_pass(frames: Sequence[tuple[int, Detections]], frame_shape: tuple[int, ...],
                 config: TrackerConfig | None = None) -> list[tuple[int, Detections]]:
    """``frames``: every frame's ``(frame number, Detections with ids)`` of one file, in order
    (frames without boxes included). Returns the same frames with the added boxes (module
    docstring) appended to their frame's rows, each frame's rows in ascending id order.
    Added boxes are clipped to the picture."""
    c = config if config is not None else TrackerConfig()
    frames = list(frames)
    if not frames:
        return []
    hw = (int(frame_shape[0]), int(frame_shape[1]))
    known = {fno for fno, _ in frames}
    added: dict[int, list[tuple[int, np.ndarray]]] = {}
    for tid, tr in _by_id(frames).items():
        for f, b in interpolate_gaps(tr, c.max_gap):
            if f in known:
                added.setdefault(f, []).append((tid, b))
    out = []
    for fno, det in frames:
        extra = added.get(fno)
        if extra:
            boxes = clip(np.array([b for _, b in extra]), hw).astype(np.int32)  # whole pixels (rounded)
            ok = np.ones(len(extra), bool)
            if len(det):
                ok = iou(boxes, det.boxes).max(axis=1) <= _MAX_OVERLAP
            if ok.any():
                ids = det.ids if det.ids is not None else np.full(len(det), -1, np.int64)
                new = Detections(boxes[ok], np.zeros(int(ok.sum()), np.float32),
                                 ids=np.array([t for t, _ in extra], np.int64)[ok])
                det = Detections.concat([Detections(det.boxes, det.scores, ids=ids), new])
                det = det[np.argsort(det.ids, kind="stable")]
        out.append((fno, det))
    return out
