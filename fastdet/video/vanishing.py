"""Where the road's lines meet: the vanishing point of a frame's line segments.

Lane markings, kerbs, the edges of the carriageway, guard rails, the long edges of a coach
alongside and the eaves of a street's buildings all run along the road; in the picture they
meet in one point, the road's vanishing point, which on a level road lies on the horizon.
Unlike the focus of expansion of the optical flow (:mod:`fastdet.video.horizon`) it needs no
motion: one frame is enough, so it also works when the camera moves slowly (city traffic),
shakes (a motorcycle), or when moving vehicles and the own vehicle's parts fill much of
the picture.

Per frame (:func:`vanishing_point`): line segments (``cv2.createLineSegmentDetector``) of the
frame shrunk to :data:`WORK_ROWS` rows; segments shorter than :data:`MIN_LENGTH` px, or within
:data:`MIN_ANGLE` degrees of horizontal or :data:`MAX_ANGLE` of vertical (the fronts of
buildings, poles, the horizon itself, the tops of vehicles), say nothing about the road's
direction and are dropped. Every crossing of two of the :data:`HYPOTHESES` longest segments
inside the frame is a candidate; it scores the total length of the segments that point at it
(within :data:`TOLERANCE` degrees), and the best one, refined by least squares over its
segments, is the vanishing point. ``None`` when fewer than :data:`MIN_SEGMENTS` segments agree.
"""
from __future__ import annotations

import math

import cv2
import numpy as np

#: frames are shrunk to this many rows before finding segments (speed; the long lines stay)
WORK_ROWS = 360
#: shortest segment that counts (px at WORK_ROWS)
MIN_LENGTH = 15.0
#: segments at least this many degrees from horizontal ...
MIN_ANGLE = 12.0
#: ... and at most this many (the rest is vertical: buildings, poles)
MAX_ANGLE = 80.0
#: the longest segments whose pairwise crossings are the candidate points
HYPOTHESES = 60
#: a segment points at a candidate when its direction is within this many degrees of the
#: line from its middle to the candidate
TOLERANCE = 1.5
#: fewest segments that must point at the vanishing point
MIN_SEGMENTS = 4

_DETECTOR: cv2.LineSegmentDetector | None = None


def line_segments(frame: np.ndarray, work_rows: int = WORK_ROWS) -> tuple[np.ndarray, float]:
    """The line segments of ``frame`` (``(H, W, 3) uint8`` BGR or RGB, or ``(H, W)`` grey) as an
    ``(N, 4) float64`` array of ``x1, y1, x2, y2`` px of the frame shrunk to ``work_rows`` rows,
    and that shrink factor (work px per frame px)."""
    global _DETECTOR
    if frame.ndim not in (2, 3) or frame.shape[0] < 2 or frame.shape[1] < 2:
        raise ValueError(f"frame must be (H, W) or (H, W, 3) with H, W >= 2, got shape {frame.shape}")
    rows = min(work_rows, frame.shape[0])
    f = rows / frame.shape[0]
    small = cv2.resize(frame, (max(1, round(frame.shape[1] * f)), rows), interpolation=cv2.INTER_AREA)
    grey = small if small.ndim == 2 else cv2.cvtColor(small, cv2.COLOR_BGR2GRAY)
    if _DETECTOR is None:
        _DETECTOR = cv2.createLineSegmentDetector()
    found = _DETECTOR.detect(np.ascontiguousarray(grey, np.uint8))[0]
    if found is None:
        return np.zeros((0, 4)), f
    return found.reshape(-1, 4).astype(np.float64), f


def road_segments(segments: np.ndarray, min_length: float = MIN_LENGTH, min_angle: float = MIN_ANGLE,
                  max_angle: float = MAX_ANGLE) -> np.ndarray:
    """The ``(N, 4)`` segments at least ``min_length`` long whose angle from horizontal is
    within ``[min_angle, max_angle]`` degrees: those that may run along the road."""
    s = np.asarray(segments, np.float64).reshape(-1, 4)
    d = s[:, 2:] - s[:, :2]
    length = np.hypot(d[:, 0], d[:, 1])
    angle = np.degrees(np.arctan2(np.abs(d[:, 1]), np.abs(d[:, 0])))
    return s[(length >= min_length) & (angle >= min_angle) & (angle <= max_angle)]


def segments_vanishing_point(segments: np.ndarray, shape: tuple[int, int], tolerance: float = TOLERANCE,
                             hypotheses: int = HYPOTHESES,
                             min_segments: int = MIN_SEGMENTS) -> tuple[float, float, float] | None:
    """``(x, y, support)`` of the point most of ``segments`` (``(N, 4)``, already filtered,
    px of a picture of ``shape = (H, W)``) point at, inside the picture (module docstring);
    ``support`` is the fraction of the segments' total length that points at it. ``None``
    when fewer than ``min_segments`` segments point at any candidate."""
    s = np.asarray(segments, np.float64).reshape(-1, 4)
    if len(s) < max(min_segments, 2):
        return None
    d = s[:, 2:] - s[:, :2]
    length = np.hypot(d[:, 0], d[:, 1])
    u = d / length[:, None]
    normal = np.stack([-u[:, 1], u[:, 0]], 1)
    mid = (s[:, :2] + s[:, 2:]) / 2
    offset = (normal * mid).sum(1)  # each segment's line: normal . p = offset
    top = np.argsort(-length, kind="stable")[:hypotheses]
    i, j = np.triu_indices(len(top), 1)
    i, j = top[i], top[j]
    a = np.stack([normal[i], normal[j]], 1)
    det = a[:, 0, 0] * a[:, 1, 1] - a[:, 0, 1] * a[:, 1, 0]
    ok = np.abs(det) > math.sin(math.radians(2.0))  # lines that cross at a clear angle
    if not ok.any():
        return None
    a, det, bi, bj = a[ok], det[ok], offset[i][ok], offset[j][ok]
    px = (bi * a[:, 1, 1] - bj * a[:, 0, 1]) / det  # Cramer's rule for the 2x2 systems
    py = (a[:, 0, 0] * bj - a[:, 1, 0] * bi) / det
    h, w = shape[:2]
    inside = (px >= 0) & (px < w) & (py >= 0) & (py < h)
    if not inside.any():
        return None
    cand = np.stack([px[inside], py[inside]], 1)
    sin_tol = math.sin(math.radians(tolerance))
    best, best_score, best_in = None, -1.0, None
    for k in range(0, len(cand), 512):  # bounded memory: 512 candidates x N segments at a time
        c = cand[k:k + 512]
        v = mid[None] - c[:, None]
        dist = np.hypot(v[..., 0], v[..., 1])
        off = np.abs((v * normal[None]).sum(-1))  # distance of the candidate from each segment's line
        agree = off < sin_tol * np.maximum(dist, 1e-9)
        score = (agree * length[None]).sum(1)
        m = int(np.argmax(score))
        if score[m] > best_score:
            best, best_score, best_in = c[m], float(score[m]), agree[m]
    assert best is not None and best_in is not None
    if int(best_in.sum()) < min_segments:
        return None
    wts = length[best_in]
    p = np.linalg.lstsq(normal[best_in] * wts[:, None], offset[best_in] * wts, rcond=None)[0]
    if not (0 <= p[0] < w and 0 <= p[1] < h):
        p = best
    return float(p[0]), float(p[1]), best_score / float(length.sum())


def vanishing_point(frame: np.ndarray, work_rows: int = WORK_ROWS) -> tuple[float, float] | None:
    """``(x, y)`` in frame pixels of the point the road's line segments of ``frame``
    (``(H, W, 3) uint8``) meet at, or ``None`` (module docstring)."""
    segs, f = line_segments(frame, work_rows)
    shape = (round(frame.shape[0] * f), round(frame.shape[1] * f))
    found = segments_vanishing_point(road_segments(segs), shape)
    if found is None:
        return None
    return found[0] / f, found[1] / f
