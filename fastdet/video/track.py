"""Tracking by detection: one id per vehicle across frames (ByteTrack).

The design is ByteTrack (Y. Zhang et al., "ByteTrack: Multi-Object Tracking by Associating
Every Detection Box", ECCV 2022): a constant-velocity Kalman filter predicts every track's
box (:mod:`fastdet.video.kalman`), then the boxes of the frame are assigned to the
predictions by the Hungarian method on IoU (``scipy.optimize.linear_sum_assignment``), in
stages:

1. **High-confidence boxes** (the heat map's boxes) against every confirmed track, tracked
   or lost (IoU >= ``match_iou``).
2. **Low-confidence boxes** (weak heat blobs, :meth:`HeatMap.weak_boxes`) against the
   tracked tracks that stage 1 left without a box (IoU >= ``low_match_iou``): a vehicle whose
   evidence dips below the threshold for a few frames keeps its track. Tracked tracks still
   without a box become *lost*. Low-confidence boxes never start a track.
3. The high-confidence boxes left over against the *tentative* tracks (IoU >=
   ``tentative_match_iou``); a tentative track without a box is dropped.
4. Each high-confidence box still left starts a tentative track; a track matched in
   ``min_hits`` frames in a row is confirmed and gets the next id (1, 2, ...).
5. A lost track is dropped after ``max_lost`` frames without a box -- or, with
   ``exit_outside``, once its predicted box lies partly outside the picture after
   ``exit_after`` missed frames (the vehicle left through the border), before it can be
   matched to a vehicle entering there.

Before stage 1, **merged blobs are split**: when the blobs of two vehicles side by side
touch, the heat map gives one box around both. A high-confidence box that holds most
(``split_overlap``) of the predicted boxes of two or more tracked vehicles is cut between
them (:func:`split_merged`), so each keeps its box and its id.

Output, per frame: the confirmed tracks that found a box this frame, each with its id and
the box of the detection (``output='detection'``) or of the filter (``'filtered'``), and
the score of the detection it matched: a heat map's peak heat, so a score at or below the
heat threshold marks a vehicle kept by a low-confidence box. Lost tracks are not reported
(the offline pass, :mod:`fastdet.video.offline`, fills their gaps afterwards for files).

Why not a library: roboflow's ``trackers`` (SORT, ByteTrack, OC-SORT) depends on
``opencv-python``, which installs a second ``cv2`` over our ``opencv-python-headless`` (and,
at the time of writing, OpenCV 5), plus ``supervision`` and matplotlib.
"""
from __future__ import annotations

from dataclasses import dataclass
from itertools import pairwise

import numpy as np

from ..boxes import iou, overlap_fraction
from ..config import TrackerConfig
from ..detections import Detections
from .kalman import BoxKalman, cxcywh_to_xyxy, xyxy_to_cxcywh

TENTATIVE, TRACKED, LOST = "tentative", "tracked", "lost"


@dataclass(eq=False)
class Track:
    """One track's bookkeeping (mutable, owned by :class:`Tracker`, which keeps the Kalman
    states of all tracks in one stack).

    id: the public id once confirmed, ``-1`` while tentative. state: ``TENTATIVE``,
    ``TRACKED`` (found a box in the last frame) or ``LOST``. hits: frames with a box; streak:
    of them in a row. first_frame, last_frame: the tracker's frame count (1-based) at its
    first and latest box. box, score: its latest box (x1, y1, x2, y2 float64) and that box's
    score. predicted: its box predicted for the current frame (x1, y1, x2, y2 float64).
    """

    first_frame: int
    box: np.ndarray
    score: float
    id: int = -1
    state: str = TENTATIVE
    hits: int = 1
    streak: int = 1
    last_frame: int = 0
    predicted: np.ndarray | None = None


def assign(ious: np.ndarray, min_iou: float) -> tuple[np.ndarray, np.ndarray]:
    """Hungarian assignment of ``ious (N, M)`` (rows: tracks, columns: boxes): among the
    matchings that use only pairs with IoU >= ``min_iou``, the one with the largest total
    ``IoU - min_iou`` -- ByteTrack's objective (``lap.lapjv`` with ``cost_limit``: a pair is
    worth matching by how much it beats the threshold). Returns ``(rows, cols)`` of the
    matched pairs, in row order.

    When no two allowed pairs share a row or a column and each beats the threshold (most
    frames: every vehicle overlaps only its own track), every optimal matching holds
    exactly those pairs, so they are returned without the solver (and without importing
    SciPy, 0.1 s); otherwise ``scipy.optimize.linear_sum_assignment``."""
    none = np.zeros(0, np.int64), np.zeros(0, np.int64)
    if ious.size == 0:
        return none
    ok = ious >= min_iou
    if not ok.any():
        return none
    gain = np.where(ok, ious - min_iou, 0.0)  # a forbidden pair gains nothing: never needed
    if (gain[ok] > 0).all():
        if ok.sum(axis=0).max() <= 1 and ok.sum(axis=1).max() <= 1:
            r, c = np.nonzero(ok)  # row-major: in row order
            return r.astype(np.int64), c.astype(np.int64)
        best = _unique_best_matching(ok, gain)
        if best is not None:
            return best
    from scipy.optimize import linear_sum_assignment  # noqa: PLC0415 - 0.1 s of import, rarely needed

    r, c = linear_sum_assignment(gain, maximize=True)
    keep = ok[r, c]
    return r[keep].astype(np.int64), c[keep].astype(np.int64)


#: most partial matchings :func:`_unique_best_matching` looks at before leaving it to the solver
_SEARCH_LIMIT = 5000
#: two matchings whose gains differ by less than this are a tie (left to the solver)
_TIE = 1e-9


def _unique_best_matching(ok: np.ndarray, gain: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """The matching of allowed pairs (``ok (N, M) bool``) with the largest total ``gain``
    (every allowed gain > 0), by trying every matching of the few allowed pairs -- when it is
    the best by more than :data:`_TIE` (so every optimal assignment, the solver's too, holds
    exactly its pairs) and found within :data:`_SEARCH_LIMIT` steps; else ``None``.
    ``(rows, cols)`` in row order."""
    rows = [np.flatnonzero(ok[i]).tolist() for i in range(ok.shape[0])]
    g = gain.tolist()
    used = [False] * ok.shape[1]
    best: list = [-1.0, -1.0, []]  # best total, second best, pairs
    steps = [0]
    cur: list[tuple[int, int]] = []

    def walk(i: int, total: float) -> bool:
        steps[0] += 1
        if steps[0] > _SEARCH_LIMIT:
            return False
        if i == len(rows):
            if total > best[0]:
                best[0], best[1], best[2] = total, best[0], list(cur)
            elif total > best[1]:
                best[1] = total
            return True
        for j in rows[i]:
            if not used[j]:
                used[j] = True
                cur.append((i, j))
                if not walk(i + 1, total + g[i][j]):
                    return False
                cur.pop()
                used[j] = False
        return walk(i + 1, total)

    if not walk(0, 0.0) or best[0] - best[1] < _TIE:
        return None
    pairs = best[2]
    return (np.array([p[0] for p in pairs], np.int64).reshape(-1),
            np.array([p[1] for p in pairs], np.int64).reshape(-1))


def buffered(boxes: np.ndarray, b: float) -> np.ndarray:
    """``(N, 4) float64`` boxes grown by ``b`` x their width on the left and on the right and
    ``b`` x their height at the top and at the bottom (the buffered boxes of C-BIoU)."""
    x = np.asarray(boxes, np.float64).reshape(-1, 4)
    if b == 0:
        return x
    w = (x[:, 2] - x[:, 0]) * b
    h = (x[:, 3] - x[:, 1]) * b
    return np.stack([x[:, 0] - w, x[:, 1] - h, x[:, 2] + w, x[:, 3] + h], 1)


def outside_fraction(boxes: np.ndarray, frame_shape: tuple[int, int]) -> np.ndarray:
    """``(N,) float64``: the fraction of each box's area (``boxes (N, 4)`` x1, y1, x2, y2)
    outside a picture of ``frame_shape`` (height, width) pixels; 1 for a box of no area."""
    h, w = frame_shape
    return 1.0 - overlap_fraction(boxes, np.array([[0.0, 0.0, w, h]]))[:, 0]


def split_merged(boxes: np.ndarray, predicted: np.ndarray, min_overlap: float) -> tuple[np.ndarray, np.ndarray]:
    """Cut boxes that hold several predicted vehicle boxes side by side.

    boxes: ``(N, 4)`` this frame's boxes; predicted: ``(T, 4)`` the tracks' predicted boxes.
    A predicted box belongs to the box that holds the largest fraction of it, if that is at
    least ``min_overlap``. A box that two or more predicted boxes belong to is cut into as
    many parts, left to right, at the midpoints between neighbours (half way between one
    predicted box's right edge and the next one's left edge); each part keeps the box's rows.
    Returns ``(parts (K, 4) float64, source (K,) int64)``: the boxes after the cuts and, for
    each, the row of ``boxes`` it came from (unsplit boxes are passed through in order).
    """
    b = np.asarray(boxes, np.float64).reshape(-1, 4)
    p = np.asarray(predicted, np.float64).reshape(-1, 4)
    if len(b) == 0 or len(p) < 2 or min_overlap <= 0:
        return b.copy(), np.arange(len(b), dtype=np.int64)
    frac = overlap_fraction(p, b)  # (T, N)
    owner = np.argmax(frac, axis=1)
    owned = frac[np.arange(len(p)), owner] >= min_overlap
    parts: list[np.ndarray] = []
    src: list[int] = []
    for i, box in enumerate(b):
        mine = p[owned & (owner == i)]
        if len(mine) < 2:
            parts.append(box)
            src.append(i)
            continue
        mine = mine[np.argsort((mine[:, 0] + mine[:, 2]) / 2, kind="stable")]
        cuts = np.clip((mine[:-1, 2] + mine[1:, 0]) / 2, box[0], box[2])
        edges = np.concatenate([[box[0]], cuts, [box[2]]])
        for a, z in pairwise(edges):
            if z > a:
                parts.append(np.array([a, box[1], z, box[3]]))
                src.append(i)
    return np.array(parts, np.float64).reshape(-1, 4), np.array(src, np.int64)


class Tracker:
    """ByteTrack over per-frame boxes (module docstring).

    ``update(high, low)`` once per frame returns the confirmed, matched tracks as
    :class:`~fastdet.detections.Detections` with ``ids``. Causal: an output depends only on
    this and earlier frames. ``reset()`` forgets every track and restarts ids at 1.
    ``tracks`` lists the live tracks (for drawing / debugging: ``id``, ``state``,
    ``predicted``); ``confirmed`` is the number of ids given so far (distinct vehicles
    confirmed).
    """

    def __init__(self, config: TrackerConfig | None = None) -> None:
        self.config = config if config is not None else TrackerConfig()
        if not isinstance(self.config, TrackerConfig):
            raise TypeError(f"config must be a TrackerConfig, got {type(self.config).__name__}")
        c = self.config
        self.kalman = BoxKalman(c.std_position, c.std_velocity, c.init_velocity)
        self.reset()

    def reset(self) -> None:
        """Forget every track; the next confirmed track gets id 1."""
        self.tracks: list[Track] = []
        self._mean = np.zeros((0, 8))  # Kalman state of tracks[i] in row i
        self._cov = np.zeros((0, 8, 8))
        self.frame = 0
        self.confirmed = 0

    def _match(self, rows: np.ndarray, pred: np.ndarray, boxes: np.ndarray,
               min_iou: float) -> tuple[np.ndarray, np.ndarray]:
        """Assign ``boxes`` (buffered) to the tracks in ``rows`` (their buffered predicted
        boxes ``pred[rows]``): ``(track rows, box indices)``."""
        if not len(rows) or not len(boxes):
            return np.zeros(0, np.int64), np.zeros(0, np.int64)
        ious = iou(pred[rows], boxes)
        r, k = assign(ious, min_iou)
        return rows[r], k

    def update(self, high: Detections, low: Detections | None = None,
               frame_shape: tuple[int, int] | None = None, split: bool = True) -> Detections:
        """Track one frame. ``high``: the high-confidence boxes (they may start tracks);
        ``low``: low-confidence boxes (they only continue tracked tracks), or ``None``;
        ``frame_shape``: the picture's (height, width) in pixels,
        for ``config.exit_outside`` (``None``: no track is dropped for leaving it);
        ``split``: a high box over two tracks' predictions is split between them
        (``config.split_overlap``; ``False`` for boxes that are windows, one per vehicle already).
        Returns the confirmed tracks that found a box this frame: boxes, scores (of the
        matched box), ids, in ascending id order."""
        c = self.config
        self.frame += 1
        tracks = self.tracks
        is_lost = np.array([t.state == LOST for t in tracks], bool)
        is_tent = np.array([t.state == TENTATIVE for t in tracks], bool)
        if tracks:  # predict
            self._mean[is_lost, 6:8] = 0.0  # a lost track keeps its size
            if c.hold_row:
                self._mean[is_lost, 5] = 0.0  # ... and so its row (its distance)
            self._mean, self._cov = self.kalman.predict(self._mean, self._cov)
        pred = cxcywh_to_xyxy(self._mean)
        if c.exit_outside is not None and frame_shape is not None and is_lost.any():
            missed = np.array([self.frame - 1 - t.last_frame for t in tracks])  # frames in a row without a box
            gone = is_lost & (missed >= c.exit_after) & (outside_fraction(pred, frame_shape) > c.exit_outside)
            if gone.any():  # left through the border: dropped before any match
                keep = ~gone
                self.tracks = tracks = [t for t, k in zip(tracks, keep) if k]
                self._mean, self._cov, pred = self._mean[keep], self._cov[keep], pred[keep]
                is_lost, is_tent = is_lost[keep], is_tent[keep]
        for t, p in zip(tracks, pred):
            t.predicted = p
        confirmed = np.flatnonzero(~is_tent)
        tracked = np.flatnonzero(~is_tent & ~is_lost)
        tentative = np.flatnonzero(is_tent)

        hb = high.boxes.astype(np.float64)
        hs = high.scores.astype(np.float64)
        if split and len(tracked) >= 2 and len(hb) and c.split_overlap > 0:
            hb, src = split_merged(hb, pred[tracked], c.split_overlap)
            hs = hs[src]
        used = np.zeros(len(hb), bool)
        bpred, bhigh = buffered(pred, c.buffer), buffered(hb, c.buffer)
        fix_rows: list[np.ndarray] = []  # Kalman corrections, done together at the end
        fix_boxes: list[np.ndarray] = []
        fix_scores: list[np.ndarray] = []

        # stage 1: high boxes vs confirmed tracks (tracked and lost)
        r1, k1 = self._match(confirmed, bpred, bhigh, c.match_iou)
        used[k1] = True
        fix_rows.append(r1), fix_boxes.append(hb[k1]), fix_scores.append(hs[k1])
        done = np.zeros(len(tracks), bool)
        done[r1] = True
        left = tracked[~done[tracked]]

        # stage 2: low boxes vs the tracked tracks left over
        if low is not None and len(low) and len(left):
            lb = low.boxes.astype(np.float64)
            r2, k2 = self._match(left, bpred, buffered(lb, c.buffer), c.low_match_iou)
            fix_rows.append(r2), fix_boxes.append(lb[k2]), fix_scores.append(low.scores[k2].astype(np.float64))
            done[r2] = True
            left = left[~done[left]]
        for i in left:
            tracks[i].state = LOST
            tracks[i].streak = 0

        # stage 3: tentative tracks vs the high boxes left
        free = np.flatnonzero(~used)
        r3, k3 = self._match(tentative, bpred, bhigh[free], c.tentative_match_iou)
        used[free[k3]] = True
        fix_rows.append(r3), fix_boxes.append(hb[free[k3]]), fix_scores.append(hs[free[k3]])

        rows = np.concatenate(fix_rows)
        if len(rows):
            self._mean[rows], self._cov[rows] = self.kalman.update(self._mean[rows], self._cov[rows],
                                                                   xyxy_to_cxcywh(np.concatenate(fix_boxes)))
        matched = []
        for i, b, sc in zip(rows, np.concatenate(fix_boxes), np.concatenate(fix_scores)):
            t = tracks[i]
            t.box, t.score = b, float(sc)
            t.hits += 1
            t.streak = t.streak + 1 if t.last_frame == self.frame - 1 else 1
            t.last_frame = self.frame
            if t.state == TENTATIVE:
                if t.streak < c.min_hits:
                    continue
                self._confirm(t)
            t.state = TRACKED
            matched.append(t)

        # stage 4: each high box left starts a track
        new = np.flatnonzero(~used)
        if len(new):
            mean, cov = self.kalman.initiate(xyxy_to_cxcywh(hb[new]))
            self._mean = np.concatenate([self._mean, mean])
            self._cov = np.concatenate([self._cov, cov])
            for j, m in zip(new, mean):
                t = Track(self.frame, hb[j], float(hs[j]), last_frame=self.frame,
                          predicted=cxcywh_to_xyxy(m[None])[0])
                tracks.append(t)
                if c.min_hits <= 1:
                    self._confirm(t)
                    t.state = TRACKED
                    matched.append(t)

        # stage 5: forget tentative tracks that missed this frame and lost tracks too old
        keep = np.array([t.last_frame == self.frame if t.state == TENTATIVE
                         else self.frame - t.last_frame <= c.max_lost for t in tracks], bool)
        if not keep.all():
            self.tracks = [t for t, k in zip(tracks, keep) if k]
            self._mean, self._cov = self._mean[keep], self._cov[keep]
        return self._output(matched)

    def _confirm(self, t: Track) -> None:
        self.confirmed += 1
        t.id = self.confirmed

    def _output(self, matched: list[Track]) -> Detections:
        if not matched:
            return Detections(np.zeros((0, 4), np.int32), np.zeros(0, np.float32), ids=np.zeros(0, np.int64))
        matched = sorted(matched, key=lambda t: t.id)
        if self.config.output == "filtered":
            index = {id(t): i for i, t in enumerate(self.tracks)}
            boxes = cxcywh_to_xyxy(self._mean[[index[id(t)] for t in matched]])
        else:
            boxes = np.stack([t.box for t in matched])
        return Detections(np.round(boxes).astype(np.int32), np.array([t.score for t in matched], np.float32),
                          ids=np.array([t.id for t in matched], np.int64))
