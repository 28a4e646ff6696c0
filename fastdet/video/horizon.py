"""Where the horizon is in a dashcam video: the focus of expansion of its optical flow.

A camera moving straight ahead sees the scenery flow away from one point, the focus of
expansion (FOE); on a level road it lies on the horizon. fastdet's search bands are placed
relative to the horizon (:attr:`fastdet.config.SearchConfig.horizon`), so a camera mounted
higher, lower or tilted gets its bands where its cars are.

Per frame pair (:func:`focus_of_expansion`): corners (``cv2.goodFeaturesToTrack``) of the
earlier frame, shrunk to :data:`WORK_ROWS` rows, followed into the later one
(``cv2.calcOpticalFlowPyrLK``); every flow vector that moved at least :data:`MIN_FLOW` px
defines a line through its corner, and the FOE is the point nearest to all of them (least
squares, re-weighted to shrug off moving cars and mismatches). One pair is noisy (its y
spreads by about 30 px at 720 rows on the bundled clips: bumps pitch the camera, curves
yaw it); the estimate is the **median** over pairs :data:`GAP` frames apart
(:class:`HorizonEstimator`), and ``None`` -- keep the default bands -- when too few pairs
gave one (the camera stood still) or they disagree by more than :data:`MAX_SPREAD` of the
height (median absolute deviation).

When the flow gives no estimate (the pairs disagree: a slow car in city traffic whose view
is full of moving vehicles, a shaking motorcycle), the estimate falls back on the road's
vanishing point: where the frame's line segments along the road meet
(:mod:`fastdet.video.vanishing`), the median over the same frames, with the same
:data:`MAX_SPREAD` test.

One pair in three frames is measured until :data:`MAX_PAIRS` pairs gave a FOE (or
:data:`HORIZON_FRAMES` frames went by). How close the estimate comes on the annotated clips and
their camera-shift variants, and what it costs: docs/accuracy.md (*The horizon estimate*).
"""
from __future__ import annotations

from collections.abc import Iterable

import cv2
import numpy as np

from ..config import REFERENCE_HORIZON
from .vanishing import vanishing_point

#: frames are shrunk to this many rows before tracking corners (speed; flow is smooth)
WORK_ROWS = 360
#: a flow vector must be at least this long (px at WORK_ROWS) to say where it points
MIN_FLOW = 1.0
#: fewest usable flow vectors for one frame pair to give a FOE
MIN_VECTORS = 20
#: frames between the two frames of a pair (flow of a single frame is short)
GAP = 2
#: fewest frame pairs with a FOE before there is an estimate
MIN_PAIRS = 5
#: frames a video's horizon is estimated from (3 s at 25 fps); the estimate is then fixed
HORIZON_FRAMES = 75
#: frame pairs after which the estimate is fixed (about 1.8 s at 25 fps, one pair in 3 frames)
MAX_PAIRS = 25
#: an estimate this close to the reference horizon (fraction of the height: 7 px at 720 rows,
#: the estimator's precision on the bundled clips) keeps the reference bands
TOLERANCE = 0.01
#: largest spread (median absolute deviation of the pairs' FOE rows, fraction of the height)
#: an estimate may have
MAX_SPREAD = 0.05


def _grey(frame: np.ndarray, rows: int) -> tuple[np.ndarray, float]:
    f = rows / frame.shape[0]
    small = cv2.resize(frame, (max(1, round(frame.shape[1] * f)), rows), interpolation=cv2.INTER_AREA)
    return cv2.cvtColor(small, cv2.COLOR_BGR2GRAY), f


def _flow_foe(g0: np.ndarray, g1: np.ndarray) -> tuple[tuple[float, float] | None, float]:
    """The flow of the grey work frames ``g0 -> g1``: ``((x, y), median)`` in work px, the FOE
    of the flow vectors at least :data:`MIN_FLOW` long (``None`` when fewer than
    :data:`MIN_VECTORS` are) and the median length of all tracked corners' flow (0 when
    there are too few corners to track)."""
    p0 = cv2.goodFeaturesToTrack(g0, maxCorners=400, qualityLevel=0.01, minDistance=8)
    if p0 is None or len(p0) < MIN_VECTORS:
        return None, 0.0
    p1, st, _ = cv2.calcOpticalFlowPyrLK(g0, g1, p0, None, winSize=(15, 15), maxLevel=3)
    ok = st[:, 0] == 1
    a, d = p0[ok, 0].astype(np.float64), (p1[ok, 0] - p0[ok, 0]).astype(np.float64)
    m = np.hypot(d[:, 0], d[:, 1])
    median = float(np.median(m)) if len(m) else 0.0
    keep = m >= MIN_FLOW
    if keep.sum() < MIN_VECTORS:
        return None, median
    a, d, m = a[keep], d[keep], m[keep]
    n = np.stack([-d[:, 1], d[:, 0]], 1) / m[:, None]  # unit normal of each flow line
    b = (n * a).sum(1)  # line: n . p = b
    w = np.ones(len(b))
    foe = np.zeros(2)
    for _ in range(10):  # iteratively re-weighted least squares, Huber weights
        foe = np.linalg.lstsq(n * w[:, None], b * w, rcond=None)[0]
        r = np.abs(n @ foe - b)
        s = max(1.5 * float(np.median(r)), 1.0)
        w = 1.0 / np.maximum(r / s, 1.0)
    return (float(foe[0]), float(foe[1])), median


def focus_of_expansion(prev: np.ndarray, cur: np.ndarray, work_rows: int = WORK_ROWS) -> tuple[float, float] | None:
    """``(x, y)`` in frame pixels of the point the flow from ``prev`` to ``cur`` (two
    ``(H, W, 3) uint8`` frames, BGR or RGB) expands from; ``None`` when fewer than
    :data:`MIN_VECTORS` corners moved or the point is outside the frame."""
    rows = min(work_rows, prev.shape[0])
    g0, f = _grey(prev, rows)
    g1, _ = _grey(cur, rows)
    found = _flow_foe(g0, g1)[0]
    if found is None:
        return None
    x, y = found[0] / f, found[1] / f
    if not (0 <= x < prev.shape[1] and 0 <= y < prev.shape[0]):
        return None
    return float(x), float(y)


def _segment_row(grey: np.ndarray, height: int) -> float | None:
    """The row of :func:`~fastdet.video.vanishing.vanishing_point` (fraction of the height) of a
    frame ``height`` rows high, from its grey work frame (:func:`_grey` at ``min(WORK_ROWS,
    height)`` rows, the picture the vanishing point shrinks the frame to): the same value as
    ``vanishing_point(frame)[1] / height``, with the same arithmetic."""
    v = vanishing_point(grey)
    return None if v is None else v[1] / (grey.shape[0] / height) / height


def median_flow(prev: np.ndarray, cur: np.ndarray, work_rows: int = WORK_ROWS) -> float:
    """How far the scene moved from ``prev`` to ``cur`` (two ``(H, W, 3) uint8`` frames): the
    median length of the optical flow of the corners tracked as in :func:`focus_of_expansion`,
    in px of the frames shrunk to ``min(work_rows, H)`` rows; 0 when too few corners are found."""
    rows = min(work_rows, prev.shape[0])
    return _flow_foe(_grey(prev, rows)[0], _grey(cur, rows)[0])[1]


class HorizonEstimator:
    """The horizon of a video from its frames so far (module docstring).

    Feed frames in order with :meth:`update`; :attr:`estimate` is the horizon row as a
    fraction of the frame height, or ``None`` until at least ``min_pairs`` frame pairs
    ``gap`` frames apart gave a FOE (and whenever they disagree by more than ``max_spread``).
    ``every``: use one pair in this many frames (the flow of neighbouring pairs is alike);
    ``max_pairs``: stop computing flow once this many pairs gave a FOE (:attr:`done`).
    ``segments``: when the flow gives no estimate -- ``min_pairs`` pairs that disagree, or
    fewer pairs while ``max_pairs`` frames gave a vanishing point -- fall back on the
    vanishing point of the line segments of the same frames (:attr:`segment_rows`; spread at
    most ``max_spread``); ``False``: the flow only.

    The frames the fallback may need (one in ``every`` while the flow has no estimate) are kept
    grey at :data:`WORK_ROWS` rows, and their line segments are found only when an answer
    depends on them (the flow's pairs disagree, or as many frames as could reach
    ``max_pairs``): a video whose flow gives its estimate never runs the segment detector.
    """

    def __init__(self, gap: int = GAP, every: int = 3, min_pairs: int = MIN_PAIRS,
                 max_spread: float = MAX_SPREAD, max_pairs: int = MAX_PAIRS, segments: bool = True) -> None:
        if gap < 1 or every < 1 or min_pairs < 1 or max_pairs < min_pairs:
            raise ValueError("gap, every and min_pairs must be >= 1, max_pairs >= min_pairs")
        self.gap, self.every, self.min_pairs, self.max_spread = gap, every, min_pairs, max_spread
        self.max_pairs = max_pairs
        self.segments = segments
        self.rows: list[float] = []  # FOE row of each pair, fraction of the height
        self._segment_rows: list[float] = []  # vanishing-point row of each frame measured, fraction of the height
        self._pending: list[tuple[np.ndarray, int]] = []  # frames not measured yet: grey at WORK_ROWS, height
        self._recent: list[np.ndarray] = []  # the last frames, grey at WORK_ROWS
        self._n = 0

    def update(self, frame: np.ndarray) -> None:
        """Add the next frame (``(H, W, 3) uint8``); nothing once :attr:`done`."""
        if self.done:
            return
        measure = self._n % self.every == 0
        flow_wanted = len(self.rows) < self.max_pairs
        grey = None
        if flow_wanted:
            grey, _ = _grey(frame, min(WORK_ROWS, frame.shape[0]))
            self._recent.append(grey)
            del self._recent[:-(self.gap + 1)]
        if measure and flow_wanted and len(self._recent) > self.gap:
            self._measure_flow(self._recent[-1 - self.gap], self._recent[-1])
        if measure and self.segments and self._flow() is None and self._fewer_segments(self.max_pairs):
            if grey is None:
                grey, _ = _grey(frame, min(WORK_ROWS, frame.shape[0]))
            self._pending.append((grey, frame.shape[0]))
        self._n += 1

    @property
    def segment_rows(self) -> list[float]:
        """The vanishing-point row (fraction of the height) of each frame measured for the
        fallback that gave one, in order (measures the frames kept for it now)."""
        self._measure_segments()
        return self._segment_rows

    def _measure_segments(self) -> None:
        for grey, height in self._pending:
            row = _segment_row(grey, height)
            if row is not None:
                self._segment_rows.append(row)
        self._pending.clear()

    def _fewer_segments(self, n: int) -> bool:
        """Fewer than ``n`` frames gave a vanishing point (the kept frames are measured only
        when they could make it ``n``)."""
        if len(self._segment_rows) + len(self._pending) < n:
            return True
        self._measure_segments()
        return len(self._segment_rows) < n

    def _measure_flow(self, g0: np.ndarray, g1: np.ndarray) -> None:
        foe, _ = _flow_foe(g0, g1)
        if foe is not None and 0 <= foe[0] < g0.shape[1] and 0 <= foe[1] < g0.shape[0]:
            self.rows.append(foe[1] / g0.shape[0])

    def cut(self) -> None:
        """The next frame does not follow the last one (a cut): pair no frames across it."""
        self._recent.clear()

    @property
    def frames(self) -> int:
        """Frames seen so far."""
        return self._n

    @property
    def done(self) -> bool:
        """The estimate will not change: ``max_pairs`` pairs gave a FOE and agree, or (with
        ``segments``) they disagree and ``max_pairs`` frames gave a vanishing point."""
        if len(self.rows) < self.max_pairs:
            return False
        return not self.segments or self._flow() is not None or not self._fewer_segments(self.max_pairs)

    def _median(self, rows: list[float]) -> float | None:
        if len(rows) < self.min_pairs:
            return None
        r = np.asarray(rows)
        med = float(np.median(r))
        if float(np.median(np.abs(r - med))) > self.max_spread:
            return None
        return med

    def _flow(self) -> float | None:
        return self._median(self.rows)

    def _segments(self) -> float | None:
        # only once the flow has had its say: its pairs disagree, or it gave too few pairs
        # while max_pairs frames gave a vanishing point (a camera standing still), so that a
        # video whose flow is fine does not see its bands jump to the segments' row first
        if not self.segments or (len(self.rows) < self.min_pairs and self._fewer_segments(self.max_pairs)):
            return None
        return self._median(self.segment_rows)

    @property
    def source(self) -> str | None:
        """Where :attr:`estimate` comes from: ``'flow'``, ``'segments'`` or ``None``."""
        if self._flow() is not None:
            return "flow"
        return "segments" if self._segments() is not None else None

    @property
    def estimate(self) -> float | None:
        f = self._flow()
        return f if f is not None else self._segments()


def estimate_horizon(frames: Iterable[np.ndarray], max_frames: int = HORIZON_FRAMES, **kw) -> float | None:
    """The horizon (fraction of the height) of the first ``max_frames`` of ``frames``, or
    ``None`` (:class:`HorizonEstimator`; ``kw`` are its arguments)."""
    est = HorizonEstimator(**kw)
    for i, f in enumerate(frames):
        if i >= max_frames or est.done:
            break
        est.update(f)
    return est.estimate


def search_horizon(estimate: float | None, reference: float = REFERENCE_HORIZON,
                   tolerance: float = TOLERANCE) -> float | None:
    """The horizon to give :meth:`fastdet.Detector.set_horizon` for an ``estimate``: ``None``
    (the reference bands) when there is no estimate or it is within ``tolerance`` of
    ``reference`` -- moving the bands by less than the estimate's precision only adds noise."""
    if estimate is None or abs(estimate - reference) <= tolerance:
        return None
    return float(estimate)


#: fewest boxes (bottom edge inside the frame) :func:`horizon_from_boxes` fits a line through
MIN_BOXES = 20
#: most boxes it fits (Theil-Sen takes every pair: a fixed sample of a long footage's boxes)
MAX_BOXES = 2000


def horizon_from_boxes(boxes: np.ndarray, height: int, min_boxes: int = MIN_BOXES) -> float | None:
    """The horizon the vehicles' boxes of one camera imply, a fraction of the frame height, or
    ``None``.

    On a level road a vehicle's width in the picture grows in proportion to how far below the
    horizon its bottom edge stands (its distance shrinks both), so the boxes' bottom rows ``yb``
    lie about a line ``yb = horizon x height + k x width`` with ``k > 0``; the horizon is its
    intercept. The line is fitted by Theil-Sen (``scipy.stats.theilslopes``: the median of the
    pairwise slopes), which shrugs off the boxes of vehicles wider or narrower than most and
    mislabelled ones. Unlike the flow's focus of expansion (:class:`HorizonEstimator`) it does not
    need the camera to look along its motion (a side window's view).

    boxes: ``(N, 4)`` x1, y1, x2, y2 in pixels of frames ``height`` rows tall. Boxes whose bottom
    edge is at the frame's last row are left out (cut by the frame: their bottom row is not the
    vehicle's), and at most :data:`MAX_BOXES` of the rest are used (an evenly spaced sample).
    ``None`` with fewer than ``min_boxes`` left, a line that does not rise with the width, or an
    intercept outside the frame.
    """
    from scipy.stats import theilslopes

    b = np.asarray(boxes, np.float64).reshape(-1, 4)
    b = b[b[:, 3] < height - 1]
    if len(b) < max(min_boxes, 2):
        return None
    if len(b) > MAX_BOXES:
        b = b[np.linspace(0, len(b) - 1, MAX_BOXES).round().astype(np.int64)]
    width = b[:, 2] - b[:, 0]
    if np.ptp(width) <= 0:
        return None
    slope, intercept, _, _ = theilslopes(b[:, 3], width, method="joint")
    if not slope > 0 or not 0.0 < intercept < height:
        return None
    return float(intercept / height)
