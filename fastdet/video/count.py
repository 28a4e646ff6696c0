"""Counting tracked vehicles: how many distinct vehicles, and how many crossed a line.

:class:`VehicleCounter` reads the tracker's output frame by frame (``Detections`` with
``ids``, e.g. from :class:`~fastdet.video.pipeline.VideoDetector` or after the offline pass):

- ``vehicles``: the number of distinct track ids seen in at least ``min_frames`` frames
  (default 3): vehicles the tracker confirmed (:mod:`fastdet.video.track`) and followed for
  more than a glimpse. A heat-map box that appears for a frame or two (a far-away car on the
  horizon, a false alarm) gets an id but is not counted.
- With a :class:`CountLine` ``(x1, y1) -> (x2, y2)`` in frame pixels: a vehicle *crosses*
  it when the bottom centre of its box (where it touches the road) moves from one side of
  the line to the other between two of its boxes, through the segment itself (not its
  extension); a box whose point lies exactly on the line is skipped (the crossing is then
  counted between the boxes before and after it). Only vehicles that are counted (seen in
  ``min_frames`` frames) count as crossings. Sides are named as seen walking from ``(x1, y1)`` to ``(x2, y2)`` in the
  picture (y pointing down): a line drawn left to right has its *right* side below it. Each
  vehicle counts at most once per direction: a track that wavers back and forth over the
  line counts once ``left_to_right`` and once ``right_to_left``.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ..boxes import MAX_COORD
from ..detections import Detections


@dataclass(frozen=True)
class CountLine:
    """A counting line segment from ``(x1, y1)`` to ``(x2, y2)``, frame pixels."""

    x1: float
    y1: float
    x2: float
    y2: float

    def __post_init__(self) -> None:
        if (self.x1, self.y1) == (self.x2, self.y2):
            raise ValueError("a counting line needs two different end points")

    @classmethod
    def parse(cls, text: str) -> CountLine:
        """From ``"x1,y1,x2,y2"`` (``ValueError`` with a one-line reason otherwise)."""
        parts = [p.strip() for p in str(text).split(",")]
        if len(parts) != 4:
            raise ValueError(f"expected x1,y1,x2,y2 (four numbers), got {text!r}")
        try:
            vals = [float(p) for p in parts]
        except ValueError:
            raise ValueError(f"expected x1,y1,x2,y2 (four numbers), got {text!r}") from None
        if not all(np.isfinite(vals)):
            raise ValueError(f"line coordinates must be finite numbers, got {text!r}")
        if max(abs(v) for v in vals) > MAX_COORD:
            raise ValueError(f"line coordinates must be within +-{MAX_COORD:.0f} px, got {text!r}")
        return cls(*vals)

    def side(self, p: np.ndarray) -> np.ndarray:
        """``(N,)``: > 0 for points ``p (N, 2)`` on the right of the line, < 0 on its left,
        0 on it (the cross product of the line's direction and the point's offset)."""
        p = np.asarray(p, np.float64).reshape(-1, 2)
        return (self.x2 - self.x1) * (p[:, 1] - self.y1) - (self.y2 - self.y1) * (p[:, 0] - self.x1)

    def crossed(self, a: np.ndarray, b: np.ndarray) -> int:
        """``+1`` when the move from point ``a`` to point ``b`` crosses the segment from its
        left to its right, ``-1`` right to left, ``0`` when it does not cross (or only touches)."""
        sa, sb = self.side(np.stack([a, b]))
        if sa == 0 or sb == 0 or (sa > 0) == (sb > 0):
            return 0
        # the segment's end points must lie on opposite sides of the move's line
        dx, dy = b[0] - a[0], b[1] - a[1]
        e1 = dx * (self.y1 - a[1]) - dy * (self.x1 - a[0])
        e2 = dx * (self.y2 - a[1]) - dy * (self.x2 - a[0])
        if (e1 > 0) == (e2 > 0) and e1 != 0 and e2 != 0:
            return 0
        return 1 if sb > 0 else -1


def bottom_centres(boxes: np.ndarray) -> np.ndarray:
    """``(N, 2) float64``: the middle of each box's bottom edge."""
    b = np.asarray(boxes, np.float64).reshape(-1, 4)
    return np.stack([(b[:, 0] + b[:, 2]) / 2, b[:, 3]], 1)


class VehicleCounter:
    """Distinct vehicles and line crossings (module docstring). ``update(dets)`` per frame."""

    def __init__(self, line: CountLine | None = None, min_frames: int = 3) -> None:
        if int(min_frames) != min_frames or min_frames < 1:
            raise ValueError(f"min_frames must be an integer >= 1, got {min_frames!r}")
        self.line = line
        self.min_frames = int(min_frames)
        self.frames_seen: dict[int, int] = {}
        self._last: dict[int, np.ndarray] = {}
        self.crossed: dict[str, set[int]] = {"left_to_right": set(), "right_to_left": set()}

    def update(self, dets: Detections) -> None:
        if dets.ids is None:
            return
        pts = bottom_centres(dets.boxes)
        for p, i in zip(pts, dets.ids):
            i = int(i)
            if i < 1:
                continue
            self.frames_seen[i] = self.frames_seen.get(i, 0) + 1
            if self.line is not None and self.line.side(p)[0] != 0:  # a point on the line decides nothing
                prev = self._last.get(i)
                if prev is not None:
                    d = self.line.crossed(prev, p)
                    if d:
                        self.crossed["left_to_right" if d > 0 else "right_to_left"].add(i)
                self._last[i] = p

    @property
    def ids(self) -> set[int]:
        """The ids of the vehicles counted (seen in at least ``min_frames`` frames)."""
        return {i for i, n in self.frames_seen.items() if n >= self.min_frames}

    @property
    def vehicles(self) -> int:
        return len(self.ids)

    def crossings(self) -> dict[str, int]:
        """``{"left_to_right": n, "right_to_left": n}``: counted vehicles that crossed the line."""
        ids = self.ids
        return {k: len(v & ids) for k, v in self.crossed.items()}

    def summary(self) -> dict[str, Any]:
        """``{"vehicles": n}`` plus, with a line, ``"line": {"x1", "y1", "x2", "y2",
        "left_to_right", "right_to_left"}`` (JSON-ready)."""
        out: dict[str, Any] = {"vehicles": self.vehicles}
        if self.line is not None:
            ln = self.line
            out["line"] = {"x1": ln.x1, "y1": ln.y1, "x2": ln.x2, "y2": ln.y2, **self.crossings()}
        return out

    def text(self) -> str:
        """One line for people: ``"4 vehicles; line (x1,y1)-(x2,y2): 2 left to right, 1 right to left"``."""
        s = f"{self.vehicles} vehicle{'s' if self.vehicles != 1 else ''}"
        if self.line is not None:
            ln, n = self.line, self.crossings()
            s += (f"; line ({ln.x1:g},{ln.y1:g})-({ln.x2:g},{ln.y2:g}): "
                  f"{n['left_to_right']} left to right, {n['right_to_left']} right to left")
        return s
