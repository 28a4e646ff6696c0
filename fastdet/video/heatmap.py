"""Heat map over recent frames: positive windows → vehicle boxes.

How one frame goes (``HeatMap.update``)
--------------------------------------
1. **Heat of a window.** Each positive window adds, to every pixel it covers, an amount
   linear in its score: 1 at ``score_lo``, ``w_max`` at ``score_hi``, clipped to
   ``[1, w_max]`` (:meth:`HeatMap.window_heat`). So one confident window outweighs several
   barely-positive ones (defaults in :class:`~fastdet.config.HeatConfig`).
2. **Grid.** Heat lives on a grid of ``cell x cell`` pixels (default 4). A box edge is
   snapped to the nearest grid line (``round(x / cell)``, halves up; a non-empty box
   keeps at least one cell) and clipped to the frame.
3. **Memory of N frames.** The heat of frame ``t`` is the age-weighted mean::

       heat_t = sum_k decay**k * H_{t-k}  /  sum_k decay**k,   k = 0 .. min(seen, N) - 1

   where ``H_j`` is the rasterised heat of frame ``j`` alone. The numerator ``S`` is kept
   as a running sum, so a frame costs the same whatever N is::

       S <- decay * (S - decay**(N-1) * H_{t-N}) + H_t

   Only the box lists of the last N frames are stored; leaving frames are re-rasterised
   with a negative weight. Float rounding of this recurrence is bounded by recomputing
   ``S`` from the stored box lists every ``max(64, N)`` frames (amortised cost: at most one
   extra rasterisation per frame). Normalising by the weights of the frames seen so far
   makes the threshold mean "heat of one frame" for any N / decay, and lets the first
   frames of a video produce boxes.
4. **Threshold, labels, boxes.** ``mask = heat > threshold``; connected blobs of the mask
   (4-connectivity, numbered as ``scipy.ndimage.label`` numbers them:
   :func:`fastdet.video._label_kernels.label_blobs`) each give one box: the bounding box of the
   blob's cells whose heat is at least ``extent`` x the blob's peak (``extent = 0``: the
   whole blob), in pixels (cells scaled by ``cell``, clipped to the frame). A box's
   **score is the blob's peak heat** (same units as the threshold, so every kept box
   scores above it). ``blobs`` keeps every blob's box before the shape filter. With
   ``split_gap`` > 0 a blob whose windows form groups side by side gives one box per group
   (:class:`~fastdet.config.HeatConfig`).
5. **Shape filter.** Boxes narrower than ``min_width``, lower than ``min_height`` or taller
   than ``max_aspect * width`` are dropped: no vehicle looks like that, heat blobs that
   do are fragments or poles.
6. **Weak boxes** (for the tracker, :meth:`HeatMap.weak_boxes`): the same steps 4-5 at a
   lower threshold, keeping only the blobs whose peak stays at or below ``threshold``:
   places with some evidence of a vehicle, too little to report one. ByteTrack
   (:mod:`fastdet.video.track`) uses them as low-confidence boxes to keep a track alive.
"""
from __future__ import annotations

import time
from collections import deque
from typing import Any, NamedTuple

import numpy as np

from ..config import HeatConfig
from ..detections import Detections
from ._heat_kernels import add_rects
from ._label_kernels import extent_boxes, label_blobs

#: the numba kernels of a heat map (compiled ahead of time: fastdet._numba.ensure_compiled)
KERNELS = (add_rects, label_blobs, extent_boxes)

_REANCHOR_EVERY = 64


class _Frame(NamedTuple):
    rects: np.ndarray  # (M, 4) int32, grid coordinates, clipped, non-empty
    weights: np.ndarray  # (M,) float64 heat of each rect


class HeatMap:
    """Heat over the last ``config.n_frames`` frames of one video (module docstring).

    shape: frame shape ``(H, W)`` or ``(H, W, C)``.
    config: :class:`~fastdet.config.HeatConfig` (default ``HeatConfig()``); kept as
        ``config.for_frame(min(H, W))``, its box sizes in this frame's pixels.
    score_kind: ``'decision'`` or ``'probability'``, picks the default score range.

    After each :meth:`update`: ``heat`` (grid, float64, normalised), ``mask`` (bool grid),
    ``labels`` (int32 grid, 0 = background), ``blobs`` (every blob's box before the shape
    filter) and ``timings`` (``{'heat': s, 'label': s}``).
    """

    def __init__(self, shape: tuple[int, ...], config: HeatConfig | None = None,
                 score_kind: str = "decision") -> None:
        self.config = config if config is not None else HeatConfig()
        if not isinstance(self.config, HeatConfig):
            raise TypeError(f"config must be a HeatConfig, got {type(self.config).__name__}")
        if len(shape) < 2 or int(shape[0]) < 1 or int(shape[1]) < 1:
            raise ValueError(f"shape must be (H, W[, C]) with H, W >= 1, got {shape!r}")
        self.frame_shape = (int(shape[0]), int(shape[1]))
        self.config = self.config.for_frame(min(self.frame_shape))  # sizes in this frame's pixels
        c = int(self.config.cell)
        self.grid_shape = (-(-self.frame_shape[0] // c), -(-self.frame_shape[1] // c))
        self.score_kind = score_kind
        self.score_lo, self.score_hi = self.config.score_range(score_kind)
        self.timings: dict[str, float] = {"heat": 0.0, "label": 0.0}
        d = float(self.config.decay)
        # _wsum[m] = sum_{k<m} decay**k, summed in ascending k
        self._wsum = [0.0]
        for k in range(int(self.config.n_frames)):
            self._wsum.append(self._wsum[-1] + d ** k)
        self.reset()

    # ------------------------------------------------------------------ state
    def reset(self) -> None:
        """Forget every frame (start of a new video or a cut)."""
        self._sum = np.zeros(self.grid_shape, np.float64)
        self._ring: deque[_Frame] = deque()
        self._since_anchor = 0
        self.heat = np.zeros(self.grid_shape, np.float64)
        self.mask = np.zeros(self.grid_shape, bool)
        self.labels = np.zeros(self.grid_shape, np.int32)
        self.blobs = Detections.empty()
        self._cur = (np.zeros((0, 4)), np.zeros(0))

    @property
    def n_seen(self) -> int:
        """Frames currently in the ring buffer (at most ``n_frames``)."""
        return len(self._ring)

    @property
    def current_windows(self) -> tuple[np.ndarray, np.ndarray]:
        """The last frame's windows: ``(boxes (N, 4) float64 frame px, heat (N,) float64)``,
        each window's heat as :meth:`window_heat` gives it (read-only views)."""
        b, w = self._cur
        b, w = b.view(), w.view()
        b.flags.writeable = w.flags.writeable = False
        return b, w

    @property
    def weight_sum(self) -> float:
        """``sum_k decay**k`` over the frames in the ring (the normaliser)."""
        return self._wsum[len(self._ring)]

    # ------------------------------------------------------------ conversion
    def window_heat(self, scores: np.ndarray) -> np.ndarray:
        """Heat each window adds, from its score: ``(N,) float64`` in ``[1, w_max]``."""
        s = np.asarray(scores, np.float64).reshape(-1)
        t = (s - self.score_lo) / (self.score_hi - self.score_lo)
        return 1.0 + (float(self.config.w_max) - 1.0) * np.clip(t, 0.0, 1.0)

    def to_grid(self, boxes: np.ndarray) -> np.ndarray:
        """Frame boxes ``(N, 4) x1, y1, x2, y2`` → grid rectangles (snapped, clipped).

        Returns ``(N, 4) int32``; a rectangle that ends up empty (degenerate box, or off
        the frame) has ``x2 <= x1`` or ``y2 <= y1``."""
        b = np.asarray(boxes, np.int64).reshape(-1, 4)
        c = int(self.config.cell)
        g = (2 * b + c) // (2 * c)  # round(x / c), halves up, exact in integers
        nonempty = (b[:, 2] > b[:, 0]) & (b[:, 3] > b[:, 1])
        g[:, 2] = np.where(nonempty, np.maximum(g[:, 2], g[:, 0] + 1), g[:, 2])
        g[:, 3] = np.where(nonempty, np.maximum(g[:, 3], g[:, 1] + 1), g[:, 3])
        hg, wg = self.grid_shape
        g[:, 0::2] = np.clip(g[:, 0::2], 0, wg)
        g[:, 1::2] = np.clip(g[:, 1::2], 0, hg)
        return g.astype(np.int32)

    def _frame(self, boxes: np.ndarray, scores: np.ndarray) -> _Frame:
        rects = self.to_grid(boxes)
        weights = self.window_heat(scores)
        if len(weights) != len(rects):
            raise ValueError(f"{len(rects)} boxes but {len(weights)} scores")
        keep = (rects[:, 2] > rects[:, 0]) & (rects[:, 3] > rects[:, 1])
        return _Frame(np.ascontiguousarray(rects[keep]), np.ascontiguousarray(weights[keep]))

    # --------------------------------------------------------------- update
    def add(self, boxes: np.ndarray, scores: np.ndarray) -> None:
        """Push one frame's positive windows (frame pixels) and their scores."""
        t0 = time.perf_counter()
        fr = self._frame(boxes, scores)
        b = np.asarray(boxes, np.float64).reshape(-1, 4)
        self._cur = (b, self.window_heat(scores))
        n, d = int(self.config.n_frames), float(self.config.decay)
        s = self._sum  # updated in place
        if len(self._ring) == n:
            old = self._ring.popleft()
            add_rects(s, old.rects, old.weights, -(d ** (n - 1)))
        if d != 1.0:
            s *= d
        add_rects(s, fr.rects, fr.weights, 1.0)
        self._ring.append(fr)
        self._since_anchor += 1
        if self._since_anchor >= max(_REANCHOR_EVERY, n):
            self._reanchor()
        self.heat = self._sum / self.weight_sum
        self.timings["heat"] = time.perf_counter() - t0

    def _reanchor(self) -> None:
        """Recompute the running sum from the stored box lists (drops float drift)."""
        d = float(self.config.decay)
        s = np.zeros(self.grid_shape, np.float64)
        for age, fr in enumerate(reversed(self._ring)):
            add_rects(s, fr.rects, fr.weights, d ** age)
        self._sum = s
        self._since_anchor = 0

    def boxes(self) -> Detections:
        """Threshold the current heat, label blobs, one box per blob (or per part of a blob,
        with ``split_gap``), shape filter."""
        t0 = time.perf_counter()
        thr = float(self.config.threshold)
        self.mask = self.heat > thr
        self.labels, n, bbox, peak = self._label(thr)
        self.blobs = self._blob_boxes(self.labels, n, bbox, peak)
        out = self.blobs[self._shape_ok(self.blobs.boxes)]
        self.timings["label"] = time.perf_counter() - t0
        return out

    def weak_boxes(self, threshold: float) -> Detections:
        """Boxes of the *weak* blobs of the current heat: blobs of ``heat > threshold`` (a
        threshold below ``config.threshold``) whose peak heat is at most ``config.threshold``,
        so no cell of them made a box of :meth:`boxes`. Same box rule, split and shape filter;
        each box's score is its blob's peak heat (in ``(threshold, config.threshold]``).
        For a tracker that uses low-confidence boxes to keep its tracks alive (ByteTrack).
        Does not change ``mask``, ``labels`` or ``blobs``."""
        labels, n, bbox, peak = self._label(float(threshold))
        if n == 0:
            return Detections.empty()
        d = self._blob_boxes(labels, n, bbox, peak)
        return d[self._shape_ok(d.boxes) & (d.scores <= self.config.threshold)]

    def _label(self, threshold: float) -> tuple[np.ndarray, int, np.ndarray, np.ndarray]:
        """Blobs of ``heat > threshold``: ``(labels (Hg, Wg) int32, n, bbox (n, 4) int64
        (y0, y1, x0, x1) grid cells, end exclusive, peak (n,) float64)`` (a new labels array
        every call: ``labels`` of an earlier frame may still be in use)."""
        heat = self.heat
        if heat.dtype != np.float64 or heat.ndim != 2 or not heat.flags.c_contiguous:
            heat = np.ascontiguousarray(heat, np.float64).reshape(self.grid_shape)
        labels = np.empty(heat.shape, np.int32)
        k = heat.size // 2 + 2  # room for any number of 4-connected blobs
        bbox = np.empty((k, 4), np.int64)
        peak = np.empty(k, np.float64)
        n = int(label_blobs(heat, threshold, labels, bbox, peak))
        return labels, n, bbox[:n], peak[:n]

    def shape_ok(self, boxes: np.ndarray) -> np.ndarray:
        """``(N,) bool``: the boxes ``(N, 4)`` (frame px) that pass the shape filter (module
        docstring, step 5)."""
        return self._shape_ok(np.asarray(boxes).reshape(-1, 4))

    def _shape_ok(self, boxes: np.ndarray) -> np.ndarray:
        cfg = self.config
        bw = boxes[:, 2] - boxes[:, 0]
        bh = boxes[:, 3] - boxes[:, 1]
        return (bw >= cfg.min_width) & (bh >= cfg.min_height) & (bh <= cfg.max_aspect * bw)

    def _blob_boxes(self, labels: np.ndarray, n: int, bbox: np.ndarray, peak: np.ndarray) -> Detections:
        """One box per blob of ``labels`` (``n`` blobs, their ``bbox`` and ``peak`` as
        :meth:`_label` gives them; or one per part, with ``split_gap``), scored by its peak
        heat, before the shape filter (module docstring, step 4)."""
        cfg = self.config
        c = int(cfg.cell)
        h, w = self.frame_shape
        ext = float(cfg.extent)
        if n == 0:
            return Detections(np.zeros((0, 4), np.int32), np.zeros(0, np.float32))
        eb = np.empty((n, 4), np.int64)
        extent_boxes(self.heat if self.heat.dtype == np.float64 and self.heat.flags.c_contiguous
                     else np.ascontiguousarray(self.heat, np.float64), labels, n, bbox, peak, ext, eb)
        # (x1, y1, x2, y2) pixels of each blob's extent box
        fast = np.stack([eb[:, 2] * c, eb[:, 0] * c, np.minimum(eb[:, 3] * c, w), np.minimum(eb[:, 1] * c, h)], 1)
        owner = np.zeros(0, np.int64)  # the blob label under each current window's centre
        split = float(cfg.split_gap) > 0 and len(self._cur[0]) > 1
        if (cfg.box_mode == "mean" or split) and len(self._cur[0]):
            cb = self._cur[0]
            cy = np.clip(((cb[:, 1] + cb[:, 3]) / 2 / c).astype(np.int64), 0, labels.shape[0] - 1)
            cx = np.clip(((cb[:, 0] + cb[:, 2]) / 2 / c).astype(np.int64), 0, labels.shape[1] - 1)
            owner = labels[cy, cx]
        if not (split or (cfg.box_mode == "mean" and len(owner))):  # one extent box per blob
            return Detections(fast.astype(np.int32), peak.astype(np.float32))
        counts = np.bincount(owner, minlength=n + 1)
        boxes_l: list[tuple[int, int, int, int]] = []
        peaks_l: list[float] = []
        for i in range(n):
            mine_n = counts[i + 1]
            if mine_n == 0 or (cfg.box_mode != "mean" and mine_n < 2):
                boxes_l.append(tuple(int(v) for v in fast[i]))  # no window of this frame to split by or average
                peaks_l.append(peak[i])
                continue
            y0, y1, x0, x1 = (int(v) for v in bbox[i])
            blob = labels[y0:y1, x0:x1] == i + 1
            hv = self.heat[y0:y1, x0:x1]
            mine = owner == i + 1  # this frame's windows centred in the blob
            parts = self._split(blob, x0, mine) if split else [blob]
            if parts[0] is blob and cfg.box_mode != "mean":  # not split: the blob's own box
                boxes_l.append(tuple(int(v) for v in fast[i]))
                peaks_l.append(peak[i])
                continue
            for part in parts:
                pk = hv[part].max()
                # never empty: the peak is in it
                ys, xs = np.nonzero(part & (hv >= ext * pk)) if ext > 0 else np.nonzero(part)
                py1, py2, px1, px2 = y0 + ys.min(), y0 + ys.max() + 1, x0 + xs.min(), x0 + xs.max() + 1
                box = (int(px1 * c), int(py1 * c), int(min(px2 * c, w)), int(min(py2 * c, h)))
                if cfg.box_mode == "mean":
                    wts = self._cur[1][mine]
                    mb = (self._cur[0][mine] * wts[:, None]).sum(0) / wts.sum()
                    box = tuple(int(v) for v in np.clip(np.round(mb), 0, [w, h, w, h]))
                boxes_l.append(box)
                peaks_l.append(pk)
        return Detections(np.array(boxes_l, np.int32).reshape(-1, 4), np.array(peaks_l, np.float32))

    def _split(self, blob: np.ndarray, x0: int, mine: np.ndarray) -> list[np.ndarray]:
        """``blob`` (a boolean sub-grid starting at grid column ``x0``) cut into parts by its
        windows ``mine`` (a mask over this frame's windows): groups of windows whose sorted
        centre x are more than ``split_gap`` x their median width apart each keep the blob's
        columns they cover. One part (the blob) when the windows form one group."""
        cb = self._cur[0][mine]
        if len(cb) < 2:
            return [blob]
        centres = (cb[:, 0] + cb[:, 2]) / 2
        order = np.argsort(centres, kind="stable")
        cb, centres = cb[order], centres[order]
        gap = float(self.config.split_gap) * np.median(cb[:, 2] - cb[:, 0])
        cuts = np.flatnonzero(np.diff(centres) > gap) + 1
        if not len(cuts):
            return [blob]
        c = int(self.config.cell)
        parts = []
        for g in np.split(cb, cuts):
            cols = np.zeros(blob.shape[1], bool)
            a = max(int(np.floor(g[:, 0].min() / c)) - x0, 0)
            b = max(int(np.ceil(g[:, 2].max() / c)) - x0, 0)
            cols[a:b] = True
            part = blob & cols[None, :]
            if part.any():
                parts.append(part)
        return parts or [blob]

    def update(self, windows: Detections) -> Detections:
        """:meth:`add` this frame's positive windows, then :meth:`boxes`."""
        self.add(windows.boxes, windows.scores)
        return self.boxes()

    def warmup(self) -> None:
        """Compile (or load from cache) the numba kernels."""
        g = np.zeros((2, 2), np.float64)
        add_rects(g, np.zeros((1, 4), np.int32), np.ones(1, np.float64), 1.0)
        labels = np.empty((2, 2), np.int32)
        bbox, peak = np.empty((3, 4), np.int64), np.empty(3, np.float64)
        n = label_blobs(g, 0.5, labels, bbox, peak)
        extent_boxes(g, labels, n, bbox, peak, 0.5, np.empty((3, 4), np.int64))


def detect_image(frame: np.ndarray, detector: Any, heat: HeatConfig) -> tuple[Detections, HeatMap, Detections]:
    """One image: the positive windows of ``detector`` (a
    :class:`~fastdet.video.detector.WindowDetector`), a single-frame heat map (``heat``, e.g.
    ``HeatConfig().single_frame()``) and its boxes: ``(windows, heatmap, boxes)``."""
    windows = detector.detect(frame)
    hm = HeatMap(frame.shape, heat, score_kind=detector.score_kind)
    return windows, hm, hm.update(windows)
