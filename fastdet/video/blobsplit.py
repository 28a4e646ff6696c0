"""Neighbours apart: one heat blob over vehicles side by side becomes one box each.

Windows on two vehicles next to each other (a queue in the next lane, parked cars, a car
overtaking another) add heat that touches, so the heat map labels them one blob
(:mod:`fastdet.video.heatmap`) and the blob's box covers both. The frame's own windows still
tell them apart: they gather around each vehicle. :func:`split_boxes` looks at every box of
the heat map that is wider than ``min_aspect`` x its height (a vehicle's rear is not; a blob
over two side by side is) and finds the modes of the current frame's windows centred in its
blob by mean shift in position and scale (:func:`window_modes`, as Dalal fuses detections,
"Finding people in images and videos", 2006, ch. 5). A mode lying mostly inside the box of a
heavier one is a part of that vehicle, not another (:func:`dominant_modes`); modes lighter
than ``min_weight`` x the heaviest are dropped. Where two neighbouring modes left overlap
along x by less than ``max_overlap`` of the narrower, the blob is cut at its coolest column
between their centres (:func:`mode_cuts`), and each part becomes a box by the heat map's own
rule (its cells with heat at least ``extent`` x the part's peak), scored by its peak.

The mean shift's cost grows with the square of a blob's windows: at most :data:`MAX_WINDOWS`
of a blob (the heaviest) go into it, and at most ``max_frame_windows`` of a frame (the blobs
heaviest first; one that no longer fits keeps its box whole).

Square windows fire on parts of a large near vehicle too (its left and right halves), which
is why only wide blobs are looked at and why modes inside a heavier mode do not count.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..config import NeighbourSplit
from ..detections import Detections
from ._split_kernels import join_modes, mean_shift
from .state import FrameState, Stage

#: the numba kernels the split runs (compiled before a run: fastdet._numba.ensure_compiled)
KERNELS = (mean_shift, join_modes)

#: at most this many windows of one blob go into the mean shift (the heaviest, in their
#: order): its cost is quadratic in them. A vehicle's blob on the annotated clips holds at
#: most 63; dense texture can fire thousands, which would cost seconds a frame
#: (docs/benchmarks.md, the neighbour split on a blob of many windows)
MAX_WINDOWS = 256


def window_modes(boxes: np.ndarray, weights: np.ndarray, bandwidth: float = 0.25,
                 scale_bandwidth: float = 0.3, iters: int = 30) -> tuple[np.ndarray, np.ndarray]:
    """Modes of windows by mean shift in (centre x, centre y, log2 width).

    boxes: ``(N, 4)`` x1, y1, x2, y2 frame px; weights: ``(N,)`` > 0. The kernel is a Gaussian
    with sigma ``bandwidth`` x the width at the moving point's scale in x and y and
    ``scale_bandwidth`` in log2 width; every window's point moves (at most ``iters`` steps,
    until no point moves by more than 1e-3) and points that end within a quarter sigma of a
    mode found before them join it (in input order). Returns ``(mode_boxes (M, 4) float64,
    mode_weights (M,) float64)``: each mode's box is the weighted mean of its windows' boxes,
    its weight their summed weight; modes in order of their first window."""
    b = np.asarray(boxes, np.float64).reshape(-1, 4)
    wt = np.asarray(weights, np.float64).reshape(-1)
    if len(wt) != len(b):
        raise ValueError(f"{len(b)} boxes but {len(wt)} weights")
    if not len(b):
        return np.zeros((0, 4)), np.zeros(0)
    y = shift_points(b, wt, bandwidth, scale_bandwidth, iters)
    label = np.empty(len(y), np.int64)
    m = int(join_modes(y, float(bandwidth), float(scale_bandwidth), label))
    mw = np.bincount(label, weights=wt, minlength=m)
    mb = np.stack([np.bincount(label, weights=wt * b[:, c], minlength=m) for c in range(4)], 1)
    return mb / np.maximum(mw, 1e-300)[:, None], mw


def _points(b: np.ndarray) -> np.ndarray:
    """``(N, 3)``: centre x, centre y, log2 width (at least 1 px) of boxes ``(N, 4)``."""
    return np.stack([(b[:, 0] + b[:, 2]) / 2, (b[:, 1] + b[:, 3]) / 2, np.log2(np.maximum(b[:, 2] - b[:, 0], 1.0))], 1)


def shift_points(boxes: np.ndarray, weights: np.ndarray, bandwidth: float = 0.25, scale_bandwidth: float = 0.3,
                 iters: int = 30) -> np.ndarray:
    """Where each window's point (centre x, centre y, log2 width) ends after mean shift
    (:func:`window_modes`): ``(N, 3) float64``. All points move together, at most ``iters``
    steps, until none moves by more than 1e-3."""
    b = np.asarray(boxes, np.float64).reshape(-1, 4)
    wt = np.asarray(weights, np.float64).reshape(-1)
    if len(wt) != len(b):
        raise ValueError(f"{len(b)} boxes but {len(wt)} weights")
    pts = np.ascontiguousarray(_points(b))
    order = np.argsort(pts[:, 0], kind="stable")  # the kernel visits only windows near in x
    out = np.empty_like(pts)
    mean_shift(pts, np.ascontiguousarray(pts[order]), np.ascontiguousarray(wt[order]), float(bandwidth),
               float(scale_bandwidth), int(iters), out)
    return out


def dominant_modes(mode_boxes: np.ndarray, mode_weights: np.ndarray, inside: float = 0.5) -> np.ndarray:
    """Indices ``(K,) int64`` of the modes kept, heaviest first (ties: input order): a mode
    with at least ``inside`` of its box's area inside the box of a heavier kept mode is
    dropped (a part of that vehicle, or the same one at a neighbouring scale)."""
    mb = np.asarray(mode_boxes, np.float64).reshape(-1, 4)
    order = np.argsort(-np.asarray(mode_weights, np.float64), kind="stable")
    kept: list[int] = []
    for i in order:
        bi = mb[i]
        ai = max((bi[2] - bi[0]) * (bi[3] - bi[1]), 1e-9)
        covered = False
        for j in kept:
            bj = mb[j]
            iw = min(bi[2], bj[2]) - max(bi[0], bj[0])
            ih = min(bi[3], bj[3]) - max(bi[1], bj[1])
            if iw > 0 and ih > 0 and iw * ih >= inside * ai:
                covered = True
                break
        if not covered:
            kept.append(int(i))
    return np.array(kept, np.int64)


def mode_cuts(profile: np.ndarray, x0: int, cell: int, mode_boxes: np.ndarray,
              max_overlap: float = 0.3) -> list[int]:
    """Where to cut a blob between its modes: ``profile`` ``(n,)`` is the blob's highest heat
    in each grid column from grid column ``x0`` (cells of ``cell`` px); for each two
    neighbouring ``mode_boxes`` (frame px, sorted by centre x here) that overlap along x by
    at most ``max_overlap`` of the narrower, the coolest column strictly between their
    centres' columns (the first of equals). Returns sorted, distinct column indices into
    ``profile``; the parts are ``[0, c1), [c1, c2), ...``."""
    p = np.asarray(profile, np.float64).reshape(-1)
    mb = np.asarray(mode_boxes, np.float64).reshape(-1, 4)
    if len(mb) < 2:
        return []
    mb = mb[np.argsort((mb[:, 0] + mb[:, 2]) / 2, kind="stable")]
    n = len(p)
    cuts: list[int] = []
    for a, b in zip(mb[:-1], mb[1:]):
        if min(a[2], b[2]) - max(a[0], b[0]) > max_overlap * min(a[2] - a[0], b[2] - b[0]):
            continue
        ca = max(int((a[0] + a[2]) / 2 // cell) - x0, 0)
        cb = min(int((b[0] + b[2]) / 2 // cell) - x0, n - 1)
        if cb - ca < 2:
            continue
        c = ca + 1 + int(np.argmin(p[ca + 1:cb]))
        if not cuts or c > cuts[-1]:
            cuts.append(c)
    return cuts


@dataclass
class SplitTally:
    """What the split did over the frames it was given (a run's record, for studies):
    ``frames`` looked at, ``windows`` shifted in all, ``most`` shifted
    in one frame, ``blob_most`` shifted for one blob, ``refused`` blobs left whole because
    the frame's budget was spent."""

    frames: int = 0
    windows: int = 0
    most: int = 0
    blob_most: int = 0
    refused: int = 0


def split_boxes(boxes: Detections, heat: np.ndarray, labels: np.ndarray, cell: int,
                frame_shape: tuple[int, int], windows: np.ndarray, weights: np.ndarray, extent: float,
                min_aspect: float = 1.8, min_weight: float = 0.5, bandwidth: float = 0.25,
                scale_bandwidth: float = 0.3, inside: float = 0.5, max_overlap: float = 0.3,
                max_frame_windows: int | None = None,
                tally: SplitTally | None = None) -> Detections:
    """``boxes`` (one per blob of ``labels``, scored by peak heat, as
    :meth:`fastdet.video.heatmap.HeatMap.boxes` gives them) with each wide box whose blob holds
    separate modes of this frame's ``windows`` (``(N, 4)`` frame px, their heat ``weights``
    ``(N,)``) replaced by one box per part (module docstring). ``heat``, ``labels``: the heat
    map's ``(Hg, Wg)`` grids (cells of ``cell`` px); ``frame_shape``: ``(H, W)`` px.
    ``max_frame_windows``: at most this many windows are shifted in the frame (``None``: no
    bound): the wide blobs take their windows (at most :data:`MAX_WINDOWS` each) heaviest
    first (summed window heat; ties: input order); a blob whose windows no longer fit keeps
    its box whole, lighter ones that still fit are split. ``tally``: counts added to (what was
    shifted, what was refused). Returns ``boxes`` itself when nothing was split."""
    wins = np.asarray(windows, np.float64).reshape(-1, 4)
    wts = np.asarray(weights, np.float64).reshape(-1)
    if tally is not None:
        tally.frames += 1
    if not len(boxes) or len(wins) < 2:
        return boxes
    h, w = frame_shape
    hg, wg = heat.shape
    ccx = ((wins[:, 0] + wins[:, 2]) / 2 // cell).astype(np.int64)
    ccy = ((wins[:, 1] + wins[:, 3]) / 2 // cell).astype(np.int64)
    blobs = [_blob_windows(b, heat, labels, cell, (hg, wg), wts, ccx, ccy, min_aspect)
             for b in np.asarray(boxes.boxes)]
    refused = 0
    if max_frame_windows is not None:
        left = int(max_frame_windows)
        heavy = sorted((i for i, blob in enumerate(blobs) if blob is not None),
                       key=lambda i: -float(wts[blobs[i][-1]].sum()))
        for i in heavy:
            n = len(blobs[i][-1])
            if n > left:
                blobs[i] = None
                refused += 1
            else:
                left -= n
    if tally is not None:
        sizes = [len(blob[-1]) for blob in blobs if blob is not None]
        tally.windows += sum(sizes)
        tally.most = max(tally.most, sum(sizes))
        tally.blob_most = max([tally.blob_most, *sizes])
        tally.refused += refused
    out_b: list[np.ndarray] = []
    out_s: list[float] = []
    changed = False
    for b, s, blob in zip(np.asarray(boxes.boxes), np.asarray(boxes.scores), blobs):
        parts = None if blob is None else _split_blob(blob, (h, w), wins, wts, cell, extent, min_weight, bandwidth,
                                                      scale_bandwidth, inside, max_overlap)
        if parts is None:
            out_b.append(np.asarray(b, np.int32))
            out_s.append(float(s))
            continue
        changed = True
        for pb, ps in parts:
            out_b.append(pb)
            out_s.append(ps)
    if not changed:
        return boxes
    return Detections(np.array(out_b, np.int32).reshape(-1, 4), np.array(out_s, np.float32))


_Blob = tuple[int, int, int, np.ndarray, np.ndarray, np.ndarray]


def _blob_windows(b, heat, labels, cell, grid_hw, wts, ccx, ccy, min_aspect) -> _Blob | None:
    """The blob of one box and this frame's windows centred on it, ``(label, x0, y0, labels,
    heat, window indices)`` (the grids cut to the box from grid cell ``x0, y0``; at most
    :data:`MAX_WINDOWS` windows, the heaviest, in input order), or ``None`` when the box is
    not looked at (narrow, no blob, fewer than two windows)."""
    if (b[2] - b[0]) < min_aspect * (b[3] - b[1]):
        return None
    hg, wg = grid_hw
    x0, y0 = int(b[0]) // cell, int(b[1]) // cell
    x1, y1 = min(-(-int(b[2]) // cell), wg), min(-(-int(b[3]) // cell), hg)
    sub_l = labels[y0:y1, x0:x1]
    if sub_l.size == 0 or not (sub_l > 0).any():
        return None
    sub_h = heat[y0:y1, x0:x1]
    lab = sub_l.flat[int(np.argmax(np.where(sub_l > 0, sub_h, -np.inf)))]  # the blob of the hottest cell
    # this frame's windows centred on the blob inside the box
    cx, cy = ccx - x0, ccy - y0
    idx = np.flatnonzero((cx >= 0) & (cy >= 0) & (cx < sub_l.shape[1]) & (cy < sub_l.shape[0]))
    idx = idx[sub_l[cy[idx], cx[idx]] == lab]
    if len(idx) < 2:
        return None
    if len(idx) > MAX_WINDOWS:
        idx = np.sort(idx[np.argsort(-wts[idx], kind="stable")[:MAX_WINDOWS]])
    return int(lab), x0, y0, sub_l, sub_h, idx


def _split_blob(blob: _Blob, frame_hw, wins, wts, cell, extent, min_weight, bandwidth, scale_bandwidth, inside,
                max_overlap) -> list[tuple[np.ndarray, float]] | None:
    """The parts of one blob (``[(box (4,) int32, peak)]``), or ``None`` to keep it whole."""
    lab, x0, y0, sub_l, sub_h, idx = blob
    h, w = frame_hw
    mb, mw = window_modes(wins[idx], wts[idx], bandwidth, scale_bandwidth)
    keep = dominant_modes(mb, mw, inside)
    keep = keep[mw[keep] >= min_weight * mw[keep].max()]
    hv = np.where(sub_l == lab, sub_h, 0.0)
    cuts = mode_cuts(hv.max(axis=0), x0, cell, mb[keep], max_overlap)
    if not cuts:
        return None
    parts = []
    for a, z in zip([0, *cuts], [*cuts, hv.shape[1]]):
        part = hv[:, a:z]
        pk = float(part.max())
        if pk <= 0:
            continue
        ys, xs = np.nonzero(part >= extent * pk) if extent > 0 else np.nonzero(part > 0)
        box = np.array([(x0 + a + xs.min()) * cell, (y0 + ys.min()) * cell,
                        min((x0 + a + xs.max() + 1) * cell, w), min((y0 + ys.max() + 1) * cell, h)], np.int32)
        parts.append((box, pk))
    return parts if len(parts) > 1 else None


class SplitStage(Stage):
    """The main heat map's wide boxes split between the modes of their windows
    (:func:`split_boxes`, at most ``config.max_frame_windows`` windows shifted a frame);
    parts that fail the heat map's shape filter are dropped. ``tally``: what it did so far
    (:class:`SplitTally`, frames with boxes only)."""

    name = "split"

    def __init__(self, config: NeighbourSplit) -> None:
        self.config = config
        self.tally = SplitTally()

    def __call__(self, s: FrameState) -> FrameState:
        hm = s.heatmap
        if hm is None or not len(s.boxes):
            return s
        c = self.config
        wins, heat = hm.current_windows
        out = split_boxes(s.boxes, hm.heat, hm.labels, int(hm.config.cell), hm.frame_shape, wins, heat,
                          float(hm.config.extent), c.min_aspect, c.min_weight, c.bandwidth, c.scale_bandwidth,
                          c.inside, c.max_overlap, c.max_frame_windows, self.tally)
        if out is not s.boxes:
            s.boxes = s.out = out[hm.shape_ok(out.boxes)]
        return s
