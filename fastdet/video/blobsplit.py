"""Neighbours apart: one heat blob over two vehicles side by side becomes one box each.

Windows on two vehicles next to each other (a queue in the next lane, parked cars, a car
overtaking another) add heat that touches, so the heat map labels them one blob
(:mod:`fastdet.video.heatmap`) and the blob's box covers both. Yet each vehicle keeps its
own peak of heat: more windows fit on a vehicle than across the gap between two. So a blob
is cut where its heat falls between two peaks (:func:`valley_cuts`): along the columns of
the blob's box, the profile is the highest heat of the blob in each column; a column is a
cut when the profile there is at most ``ratio`` x the lower of the highest values on its
left and on its right, and both sides are at least ``min_cols`` columns wide. The deepest
such valley is cut first, then each side again. Each part becomes a box by the heat map's
own rule (its cells with heat at least ``extent`` x the part's peak), scored by the part's
peak (:func:`split_boxes`).
"""
from __future__ import annotations

import numpy as np

from ..detections import Detections


def valley_cuts(profile: np.ndarray, ratio: float, min_cols: int) -> list[int]:
    """Where to cut a heat ``profile`` ``(n,) float64`` (module docstring): sorted column
    indices ``c``; the parts are ``[0, c1), [c1, c2), ...``, the valley column starting the
    part on its right. ``[]`` when no valley is deep enough."""
    p = np.asarray(profile, np.float64).reshape(-1)
    n = len(p)
    if n < 2 * max(min_cols, 1) + 1 or ratio <= 0:
        return []
    m = max(min_cols, 1)
    left = np.maximum.accumulate(p)  # left[i] = max p[:i+1]
    right = np.maximum.accumulate(p[::-1])[::-1]  # right[i] = max p[i:]
    i = np.arange(m, n - m)  # a cut at i: left part [0, i), right part [i + 1, n) both >= m wide
    i = i[(i >= 1) & (i + 1 < n)]
    if not len(i):
        return []
    lo = np.minimum(left[i - 1], right[i + 1])
    depth = np.where(lo > 0, p[i] / np.maximum(lo, 1e-300), np.inf)
    k = int(np.argmin(depth))
    if not depth[k] <= ratio:
        return []
    c = int(i[k])
    return ([*valley_cuts(p[:c], ratio, min_cols), c,
             *[c + 1 + x for x in valley_cuts(p[c + 1:], ratio, min_cols)]])


def split_boxes(boxes: Detections, heat: np.ndarray, labels: np.ndarray, cell: int,
                frame_shape: tuple[int, int], ratio: float, min_cols: int, extent: float) -> Detections:
    """``boxes`` (one per blob of ``labels``, as the heat map gives them, scored by peak heat)
    with each box whose blob has a deep valley along its columns replaced by one box per
    part (module docstring). ``heat``, ``labels``: the heat map's ``(Hg, Wg)`` grids (cells of
    ``cell`` px); ``frame_shape``: ``(H, W)`` px, for clipping."""
    if not len(boxes) or ratio <= 0:
        return boxes
    h, w = frame_shape
    hg, wg = heat.shape
    out_b: list[np.ndarray] = []
    out_s: list[float] = []
    changed = False
    for b, s in zip(boxes.boxes, boxes.scores):
        x0, y0 = int(b[0]) // cell, int(b[1]) // cell
        x1, y1 = min(-(-int(b[2]) // cell), wg), min(-(-int(b[3]) // cell), hg)
        sub_l = labels[y0:y1, x0:x1]
        sub_h = heat[y0:y1, x0:x1]
        if sub_l.size == 0:
            out_b.append(b), out_s.append(float(s))
            continue
        # the blob this box came from: the label of its hottest cell
        k = int(np.argmax(np.where(sub_l > 0, sub_h, -np.inf)))
        lab = sub_l.flat[k]
        mine = sub_l == lab
        hv = np.where(mine, sub_h, 0.0)
        cuts = valley_cuts(hv.max(axis=0), ratio, min_cols) if lab > 0 else []
        if not cuts:
            out_b.append(b), out_s.append(float(s))
            continue
        changed = True
        for a, z in zip([0, *cuts], [*cuts, hv.shape[1]]):
            part = hv[:, a:z]
            pk = float(part.max())
            if pk <= 0:
                continue
            ys, xs = np.nonzero(part >= extent * pk) if extent > 0 else np.nonzero(part > 0)
            px1, px2 = (x0 + a + xs.min()) * cell, min((x0 + a + xs.max() + 1) * cell, w)
            py1, py2 = (y0 + ys.min()) * cell, min((y0 + ys.max() + 1) * cell, h)
            out_b.append(np.array([px1, py1, px2, py2], np.int32))
            out_s.append(pk)
    if not changed:
        return boxes
    return Detections(np.array(out_b, np.int32).reshape(-1, 4), np.array(out_s, np.float32))
