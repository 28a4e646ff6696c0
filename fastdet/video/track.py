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
5. A lost track is dropped after ``max_lost`` frames without a box.

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

import numpy as np
from scipy.optimize import linear_sum_assignment

from ..boxes import iou, overlap_fraction
from ..config import TrackerConfig
from ..detections import Detections
from .kalman import BoxKalman, cxcywh_to_xyxy, xyxy_to_cxcywh

TENTATIVE, TRACKED, LOST = "tentative", "tracked", "lost"


@dataclass(eq=False)
class Track:
    """One track (mutable, owned by :class:`Tracker`).

    id: the public id once confirmed, ``-1`` while tentative. state: ``TENTATIVE``,
    ``TRACKED`` (found a box in the last frame) or ``LOST``. mean, cov: Kalman state
    (:mod:`fastdet.video.kalman`). hits: frames with a box; streak: of them in a row.
    first_frame, last_frame: frame numbers (of the tracker's own count, 1-based) of its first
    and latest box. box, score: its latest box (x1, y1, x2, y2 float64) and that box's score.
    """

    mean: np.ndarray
    cov: np.ndarray
    first_frame: int
    box: np.ndarray
    score: float
    id: int = -1
    state: str = TENTATIVE
    hits: int = 1
    streak: int = 1
    last_frame: int = 0

    @property
    def predicted_box(self) -> np.ndarray:
        """``(4,) float64`` x1, y1, x2, y2 of the Kalman state."""
        return cxcywh_to_xyxy(self.mean[None, :4])[0]


def assign(cost_iou: np.ndarray, min_iou: float) -> tuple[np.ndarray, np.ndarray]:
    """Hungarian assignment maximising the total IoU of ``cost_iou (N, M)`` (rows: tracks,
    columns: boxes) among the pairs with IoU >= ``min_iou``: ``(rows, cols)``, the matched
    pairs in row order. Pairs below ``min_iou`` are never matched."""
    if cost_iou.size == 0:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    ok = cost_iou >= min_iou
    if not ok.any():
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    cost = np.where(ok, 1.0 - cost_iou, 2.0)  # a forbidden pair costs more than any allowed one
    r, c = linear_sum_assignment(cost)
    keep = ok[r, c]
    return r[keep].astype(np.int64), c[keep].astype(np.int64)


def buffered(boxes: np.ndarray, b: float) -> np.ndarray:
    """``(N, 4) float64`` boxes grown by ``b`` x their width on the left and on the right and
    ``b`` x their height at the top and at the bottom (the buffered boxes of C-BIoU)."""
    x = np.asarray(boxes, np.float64).reshape(-1, 4)
    if b == 0:
        return x
    w = (x[:, 2] - x[:, 0]) * b
    h = (x[:, 3] - x[:, 1]) * b
    return np.stack([x[:, 0] - w, x[:, 1] - h, x[:, 2] + w, x[:, 3] + h], 1)


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
        for a, z in zip(edges[:-1], edges[1:]):
            if z > a:
                parts.append(np.array([a, box[1], z, box[3]]))
                src.append(i)
    return np.array(parts, np.float64).reshape(-1, 4), np.array(src, np.int64)


class Tracker:
    """ByteTrack over per-frame boxes (module docstring).

    ``update(high, low)`` once per frame returns the confirmed, matched tracks as
    :class:`~fastdet.detections.Detections` with ``ids``. Causal: an output depends only on
    this and earlier frames. ``reset()`` forgets every track and restarts ids at 1.
    ``tracks`` lists the live tracks (for drawing / debugging); ``confirmed`` is the number of
    ids given so far (distinct vehicles confirmed).
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
        self.frame = 0
        self.confirmed = 0

    # ------------------------------------------------------------------ steps
    def _predict(self) -> None:
        if not self.tracks:
            return
        mean = np.stack([t.mean for t in self.tracks])
        cov = np.stack([t.cov for t in self.tracks])
        lost = np.array([t.state == LOST for t in self.tracks])
        mean[lost, 6:8] = 0.0  # a lost track keeps its size (ByteTrack: no height velocity)
        mean, cov = self.kalman.predict(mean, cov)
        for t, m, s in zip(self.tracks, mean, cov):
            t.mean, t.cov = m, s

    def _match(self, tracks: list[Track], boxes: np.ndarray, min_iou: float) -> tuple[np.ndarray, np.ndarray]:
        if not tracks or not len(boxes):
            return np.zeros(0, np.int64), np.zeros(0, np.int64)
        pred = np.stack([t.predicted_box for t in tracks])
        b = self.config.buffer
        return assign(iou(buffered(pred, b), buffered(boxes, b)), min_iou)

    def _correct(self, tracks: list[Track], boxes: np.ndarray, scores: np.ndarray) -> None:
        """Kalman update of ``tracks`` with their boxes (row i for track i)."""
        if not tracks:
            return
        mean = np.stack([t.mean for t in tracks])
        cov = np.stack([t.cov for t in tracks])
        mean, cov = self.kalman.update(mean, cov, xyxy_to_cxcywh(boxes))
        for t, m, s, b, sc in zip(tracks, mean, cov, boxes, scores):
            t.mean, t.cov, t.box, t.score = m, s, b.copy(), float(sc)
            t.hits += 1
            t.streak = t.streak + 1 if t.last_frame == self.frame - 1 else 1
            t.last_frame = self.frame

    def _confirm(self, t: Track) -> None:
        self.confirmed += 1
        t.id = self.confirmed
        t.state = TRACKED

    # ------------------------------------------------------------------ update
    def update(self, high: Detections, low: Detections | None = None) -> Detections:
        """Track one frame. ``high``: the high-confidence boxes (they may start tracks);
        ``low``: low-confidence boxes (they only continue tracked tracks), or ``None``.
        Returns the confirmed tracks that found a box this frame: boxes, scores (of the
        matched box), ids, in ascending id order."""
        c = self.config
        self.frame += 1
        self._predict()
        confirmed = [t for t in self.tracks if t.state != TENTATIVE]
        tentative = [t for t in self.tracks if t.state == TENTATIVE]

        hb = high.boxes.astype(np.float64)
        hs = high.scores.astype(np.float64)
        tracked = [t for t in confirmed if t.state == TRACKED]
        if len(tracked) >= 2 and len(hb) and c.split_overlap > 0:
            hb, src = split_merged(hb, np.stack([t.predicted_box for t in tracked]), c.split_overlap)
            hs = hs[src]
        matched: list[Track] = []

        # stage 1: high boxes vs confirmed tracks (tracked and lost)
        r, k = self._match(confirmed, hb, c.match_iou)
        used = np.zeros(len(hb), bool)
        used[k] = True
        got = [confirmed[i] for i in r]
        self._correct(got, hb[k], hs[k])
        for t in got:
            t.state = TRACKED
        matched += got
        rest = [t for t in confirmed if t not in got]

        # stage 2: low boxes vs tracked tracks left over
        if low is not None and len(low):
            lb = low.boxes.astype(np.float64)
            cand = [t for t in rest if t.state == TRACKED]
            r2, k2 = self._match(cand, lb, c.low_match_iou)
            got2 = [cand[i] for i in r2]
            self._correct(got2, lb[k2], low.scores[k2].astype(np.float64))
            matched += got2
            rest = [t for t in rest if t not in got2]
        for t in rest:
            t.state = LOST
            t.streak = 0

        # stage 3: tentative tracks vs the high boxes left
        free = np.flatnonzero(~used)
        r3, k3 = self._match(tentative, hb[free], c.tentative_match_iou)
        got3 = [tentative[i] for i in r3]
        self._correct(got3, hb[free[k3]], hs[free[k3]])
        used[free[k3]] = True
        keep_tent = []
        for t in got3:
            if t.streak >= c.min_hits:
                self._confirm(t)
                matched.append(t)
            else:
                keep_tent.append(t)

        # stage 4: new tracks
        new = np.flatnonzero(~used)
        if len(new):
            mean, cov = self.kalman.initiate(xyxy_to_cxcywh(hb[new]))
            for j, m, s in zip(new, mean, cov):
                t = Track(m, s, self.frame, hb[j].copy(), float(hs[j]), last_frame=self.frame)
                if c.min_hits <= 1:
                    self._confirm(t)
                    matched.append(t)
                else:
                    keep_tent.append(t)
                self.tracks.append(t)

        # stage 5: forget
        self.tracks = [t for t in self.tracks
                       if (t.state == TENTATIVE and t in keep_tent)
                       or (t.state == TRACKED)
                       or (t.state == LOST and self.frame - t.last_frame <= c.max_lost)]
        return self._output(matched)

    def _output(self, matched: list[Track]) -> Detections:
        if not matched:
            return Detections(np.zeros((0, 4), np.int32), np.zeros(0, np.float32), ids=np.zeros(0, np.int64))
        matched = sorted(matched, key=lambda t: t.id)
        if self.config.output == "filtered":
            boxes = np.stack([t.predicted_box for t in matched])
        else:
            boxes = np.stack([t.box for t in matched])
        return Detections(np.round(boxes).astype(np.int32), np.array([t.score for t in matched], np.float32),
                          ids=np.array([t.id for t in matched], np.int64))
