"""Recall by target size: which widths of vehicle a detector finds.

``recall_by_width(gt, preds)`` matches each frame exactly as :func:`fastdet.eval.evaluate`
does (:func:`~fastdet.eval.metrics.match_frame`, same IoU threshold) and counts the matched
targets per bin of box width. Widths are in **reference pixels**: the frame scaled to
``ref_rows`` (720) rows, i.e. 1280-wide pixels for a 16:9 frame, so bins mean the same on
every resolution (``frame_rows`` = the rows of the frames the boxes are in).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..detections import Detections
from .metrics import match_frame

#: default bin edges (reference pixels): 40-60, 60-80, 80-100, 100+
WIDTH_EDGES: tuple[float, ...] = (40.0, 60.0, 80.0, 100.0, float("inf"))
#: the bins of the per-clip report: small (< 60), middle (60-120), large (>= 120)
REPORT_EDGES: tuple[float, ...] = (0.0, 60.0, 120.0, float("inf"))


@dataclass(frozen=True)
class WidthBin:
    """Targets with ``lo <= width < hi`` reference pixels: ``found`` of ``total`` matched."""

    lo: float
    hi: float
    found: int
    total: int

    @property
    def recall(self) -> float:
        return self.found / self.total if self.total else float("nan")

    @property
    def label(self) -> str:
        if self.hi == float("inf"):
            return f">={self.lo:g}"
        return f"<{self.hi:g}" if self.lo <= 0 else f"{self.lo:g}-{self.hi:g}"


def recall_by_width(gt: Detections, preds: Detections, frame_rows: int, iou: float = 0.5,
                    edges: tuple[float, ...] = WIDTH_EDGES, ref_rows: int = 720,
                    num_frames: int | None = None, keyframes: np.ndarray | None = None) -> list[WidthBin]:
    """Matched targets per width bin (module docstring); targets narrower than ``edges[0]``
    or in frames after ``num_frames`` (default: the last ground-truth frame) or, when
    ``keyframes`` are given, on frames that are not keyframes, are not counted."""
    last = gt.num_frames if num_frames is None else int(num_frames)
    factor = ref_rows / float(frame_rows)
    found = np.zeros(len(edges) - 1, np.int64)
    total = np.zeros(len(edges) - 1, np.int64)
    scored = gt.frames <= last if keyframes is None else np.isin(gt.frames, np.asarray(keyframes, np.int64))
    consider = gt.targets
    for f in np.unique(gt.frames[consider & scored]):
        g = np.flatnonzero(gt.frames == f)
        tgt = g[consider[g]]
        p = np.flatnonzero(preds.frames == f)
        _, _, gi = match_frame(preds.boxes[p], preds.scores[p], gt.boxes[tgt], gt.boxes[g[~consider[g]]], iou)
        hit = np.zeros(len(tgt), bool)
        hit[gi[gi >= 0]] = True
        w = (gt.boxes[tgt, 2] - gt.boxes[tgt, 0]) * factor
        b = np.searchsorted(edges, w, side="right") - 1
        ok = (b >= 0) & (b < len(edges) - 1)
        np.add.at(total, b[ok], 1)
        np.add.at(found, b[ok & hit], 1)
    return [WidthBin(edges[i], edges[i + 1], int(found[i]), int(total[i])) for i in range(len(edges) - 1)]
