"""Slow, obvious references for fastdet's fast code, all in one place (in the manner of
stumpy's ``tests/naive.py``). Tests compare the package against these; the benchmarks time
the package against the classic pipeline below.

Nothing here is vectorised across boxes, windows or pixels unless the vectorised form is the
definition itself; nothing here imports fastdet's kernels. Sections:

- boxes: intersection, IoU, overlap fraction, conversions, clipping, window grids, one box
  (pair) at a time in plain Python;
- HOG: ``skimage.feature.hog`` of each channel, stacked as ``fastdet.hog_channels`` lays it out;
- dense window scores: every window's dot products one product at a time;
- the classic HOG-sub-sampling vehicle pipeline (per band: crop, ``cv2.resize`` by
  ``1/scale``, colour-convert, skimage HOG of each channel of the whole scaled band; then
  every window one at a time: slice its blocks, spatial bins with ``cv2.resize``, colour
  histograms with ``np.histogram``, ``StandardScaler.transform``, ``decision_function``);
- heat map: one full-resolution float map per frame, summed with age weights; blobs by a
  breadth-first flood fill;
- motion: the mean absolute grey-level difference of each window's pixels;
- box regions: the box regressor's context crops and features one box at a time with
  ``cv2.copyMakeBorder`` and ``cv2.resize``, and OpenCV's general INTER_AREA shrink one float32
  operation at a time.
"""
from __future__ import annotations

import math
from collections import deque
from collections.abc import Iterator, Sequence

import cv2
import numpy as np
from skimage.feature import hog as sk_hog
from sklearn.preprocessing import StandardScaler
from sklearn.svm import LinearSVC

from fastdet.config import FeatureConfig, HeatConfig, SearchConfig
from fastdet.detect.bands import BandGeometry, band_geometry, scaled_band, window_boxes
from fastdet.detections import Detections
from fastdet.features import convert_color
from fastdet.model import Model

Box = Sequence[float]

# ========================================================================== boxes


def box_area(b: Box) -> float:
    """Area of one ``x1, y1, x2, y2`` box (0 when empty or inverted)."""
    return max(0.0, float(b[2]) - float(b[0])) * max(0.0, float(b[3]) - float(b[1]))


def box_intersection(a: Box, b: Box) -> float:
    """Area of the intersection of two boxes."""
    w = min(float(a[2]), float(b[2])) - max(float(a[0]), float(b[0]))
    h = min(float(a[3]), float(b[3])) - max(float(a[1]), float(b[1]))
    return max(0.0, w) * max(0.0, h)


def box_iou(a: Box, b: Box) -> float:
    """Intersection over union of two boxes (0 when the union is empty)."""
    inter = box_intersection(a, b)
    union = box_area(a) + box_area(b) - inter
    return inter / union if union > 0 else 0.0


def box_overlap_fraction(a: Box, b: Box) -> float:
    """Fraction of box ``a``'s area inside box ``b`` (0 for an empty ``a``)."""
    ar = (float(a[2]) - float(a[0])) * (float(a[3]) - float(a[1]))
    return box_intersection(a, b) / ar if ar > 0 else 0.0


def pairwise(fn, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``(N, M)`` array of ``fn(a[i], b[j])`` by two loops."""
    out = np.zeros((len(a), len(b)))
    for i in range(len(a)):
        for j in range(len(b)):
            out[i, j] = fn(a[i], b[j])
    return out


def ltwh_to_xyxy(ltwh: Sequence[Box]) -> list[list[float]]:
    return [[left, top, left + w, top + h] for left, top, w, h in ltwh]


def xyxy_to_ltwh(xyxy: Sequence[Box]) -> list[list[float]]:
    return [[x1, y1, x2 - x1, y2 - y1] for x1, y1, x2, y2 in xyxy]


def clip_box(b: Box, h: int, w: int) -> list[int]:
    """One box clipped to a ``h x w`` frame."""
    x1, y1, x2, y2 = (int(v) for v in b)
    return [min(max(x1, 0), w), min(max(y1, 0), h), min(max(x2, 0), w), min(max(y2, 0), h)]


def window_grid_box(x0: int, y0: int, row: int, col: int, step_cells: int, cell_px: int, scale: float,
                    win_w: int, win_h: int) -> list[int]:
    """The frame box of the window at grid position ``(row, col)`` of a band with top-left
    corner ``(x0, y0)`` scaled by ``1/scale``: the window's top-left corner in the scaled band
    is ``(col, row) * step_cells * cell_px`` pixels; mapped back to the frame by ``* scale``
    and truncated; its size is ``int(win * scale)`` frame pixels."""
    left = x0 + int(col * step_cells * cell_px * scale)
    top = y0 + int(row * step_cells * cell_px * scale)
    return [left, top, left + int(win_w * scale), top + int(win_h * scale)]


# ========================================================================== HOG


def sk_channels(img: np.ndarray, channels: Sequence[int] | None = None, **kw) -> np.ndarray:
    """skimage HOG of each channel separately (``feature_vector=False``), stacked on axis 2
    as :func:`fastdet.hog_channels` lays them out: ``(blocks_y, blocks_x, n_channels, ...)``."""
    img = img if img.ndim == 3 else img[:, :, None]
    channels = range(img.shape[2]) if channels is None else channels
    return np.stack([sk_hog(img[:, :, c], feature_vector=False, **kw) for c in channels], axis=2)


# ========================================================================== classic pipeline


def sklearn_pair(model: Model) -> tuple[StandardScaler, LinearSVC]:
    """A fitted-looking scikit-learn scaler and linear classifier holding ``model``'s numbers."""
    n = model.config.n_features
    scaler = StandardScaler()
    scaler.mean_, scaler.scale_, scaler.var_ = model.mean, model.scale, model.scale ** 2
    scaler.n_features_in_, scaler.n_samples_seen_ = n, 1
    clf = LinearSVC()
    clf.coef_ = model.coef[None, :].copy()
    clf.intercept_ = np.array([model.intercept])
    clf.classes_ = np.array([0, 1])
    clf.n_features_in_ = n
    return scaler, clf


def _hog(channel: np.ndarray, config: FeatureConfig, vector: bool) -> np.ndarray:
    p, c = config.pixels_per_cell, config.cells_per_block
    return sk_hog(channel, orientations=config.orientations, pixels_per_cell=(p, p), cells_per_block=(c, c),
                  block_norm="L2-Hys", transform_sqrt=False, feature_vector=vector)


def _color_features(window: np.ndarray, config: FeatureConfig) -> np.ndarray:
    parts = []
    if config.spatial_size:
        sh, sw = config.spatial_shape
        parts.append(cv2.resize(window, (sw, sh), interpolation=cv2.INTER_LINEAR).ravel().astype(np.float64))
    if config.hist_bins:
        parts += [np.histogram(window[:, :, c], bins=config.hist_bins, range=(0, 256))[0].astype(np.float64)
                  for c in range(3)]
    return np.concatenate(parts) if parts else np.zeros(0)


def crop_features(crop_bgr: np.ndarray, config: FeatureConfig) -> np.ndarray:
    """The feature vector of one BGR crop (window-sized), the plain way (HOG of the crop itself)."""
    img = convert_color(crop_bgr, config.color_space)
    hog = np.concatenate([_hog(img[:, :, c], config, True) for c in config.hog_channels])
    return np.concatenate([hog, _color_features(img, config)])


def band_window_features(frame: np.ndarray, geo: BandGeometry,
                         config: FeatureConfig) -> Iterator[tuple[int, int, np.ndarray]]:
    """Yield ``(row, col, features)`` for every window of the band, one window at a time."""
    img = convert_color(scaled_band(frame, geo), config.color_space)
    hogs = [_hog(img[:, :, c], config, False) for c in config.hog_channels]
    bx, by, cell = config.blocks_x, config.blocks_y, config.pixels_per_cell
    for i in range(geo.ny):
        for j in range(geo.nx):
            yb, xb = i * geo.step, j * geo.step
            hog = np.concatenate([h[yb: yb + by, xb: xb + bx].ravel() for h in hogs])
            y, x = yb * cell, xb * cell
            window = img[y: y + config.win_h, x: x + config.win_w]
            yield i, j, np.concatenate([hog, _color_features(window, config)])


def classic_band_scores(frame: np.ndarray, geo: BandGeometry, model: Model, pair=None) -> np.ndarray:
    """Decision value of every window of one band, its features made one window at a time:
    ``(ny, nx)``. The windows' feature rows go through scikit-learn's scaler and classifier
    together (each row's value is its own; one call a window spent 10-15 ms in BLAS start-up
    on a busy machine)."""
    scaler, clf = pair or sklearn_pair(model)
    out = np.empty((geo.ny, geo.nx))
    pos, feats = [], []
    for i, j, feat in band_window_features(frame, geo, model.config):
        pos.append((i, j))
        feats.append(feat)
    if feats:
        values = clf.decision_function(scaler.transform(np.stack(feats)))
        for (i, j), v in zip(pos, values):
            out[i, j] = v
    return out


def loop_dense_scores(block_rows: np.ndarray, w_hog: np.ndarray, k: int, ny: int, nx: int, step: int, cell: int,
                      win_h: int, win_w: int, bias: float, spat_rows=None, w_sp=None, sp_off: int = 1,
                      integ=None, hist_step: int = 1) -> np.ndarray:
    """``fastdet.detect.scoring.dense_scores`` one window and one product at a time: the
    window's blocks, spatial-map crop and integral-image corners sliced out and summed."""
    nby, nbx = w_hog.shape[0], w_hog.shape[1] // k
    out = np.empty((ny, nx))
    for i in range(ny):
        for j in range(nx):
            yb, xb = i * step, j * step
            acc = float(bias)
            for dr in range(nby):
                for t in range(nbx * k):
                    acc += float(block_rows[yb + dr, xb * k + t]) * float(w_hog[dr, t])
            if spat_rows is not None:
                ys, xs = yb * cell // sp_off, xb * cell // sp_off * 3
                for dr in range(w_sp.shape[0]):
                    for t in range(w_sp.shape[1]):
                        acc += float(spat_rows[ys + dr, xs + t]) * float(w_sp[dr, t])
            if integ is not None:
                y, x, h, w = yb * cell // hist_step, xb * cell // hist_step, win_h // hist_step, win_w // hist_step
                acc += float(integ[y + h, x + w] - integ[y, x + w] - integ[y + h, x] + integ[y, x])
            out[i, j] = acc
    return out


class ClassicDetector:
    """The classic pipeline with ``Detector.detect``'s interface for one model (decision
    values as scores, the ``scale`` column filled)."""

    def __init__(self, model: Model, search: SearchConfig | None = None):
        self.model, self.search = model, search or SearchConfig()
        self.pair = sklearn_pair(model)

    def detect(self, frame: np.ndarray) -> Detections:
        parts = []
        search = self.search.for_frame(frame.shape[:2])
        for band in search.bands:  # the Detector's geometry: windows over the border too
            geo = band_geometry(band, frame.shape[:2], self.model.config, search.cells_per_step, search.border,
                                search.border_mode)
            dec = classic_band_scores(frame, geo, self.model, self.pair)
            keep = []
            for i in range(geo.ny):
                for j in range(geo.nx):
                    box = window_boxes(geo, np.array([i]), np.array([j]), self.model.config)[0]
                    # a window reaching out of the band's core (into its slack) needs the slack threshold
                    slack = band.core is not None and search.slack_threshold is not None and not (
                        band.core[0] - 1 <= box[1] and box[3] <= band.core[1] + 1)
                    if dec[i, j] > (search.slack_threshold if slack else search.threshold):
                        keep.append((i, j))
            r, c = (np.array([k[n] for k in keep], np.int64) for n in (0, 1))
            parts.append(Detections(window_boxes(geo, r, c, self.model.config), dec[r, c].astype(np.float32),
                                    scale=np.full(len(r), band.scale)))
        return Detections.concat(parts)


# ========================================================================== heat map


def ref_window_heat(score: float, cfg: HeatConfig, kind: str = "decision") -> float:
    """Heat of one window: 1 at or below the score range's low end, ``w_max`` at or above
    its high end, linear between."""
    lo, hi = cfg.score_range(kind)
    t = min(max((score - lo) / (hi - lo), 0.0), 1.0)
    return 1.0 + (cfg.w_max - 1.0) * t


def ref_snap(v: int, c: int) -> int:
    """A pixel coordinate to the nearest heat-grid line (halves round up)."""
    return math.floor(v / c + 0.5)


def ref_frame_map(boxes, scores, shape, cfg: HeatConfig, kind: str = "decision") -> np.ndarray:
    """One frame's heat at full resolution (frame padded to whole cells)."""
    c = cfg.cell
    hg, wg = -(-shape[0] // c), -(-shape[1] // c)
    m = np.zeros((hg * c, wg * c), np.float64)
    for (x1, y1, x2, y2), s in zip(boxes, scores):
        if x2 <= x1 or y2 <= y1:
            continue
        gx1, gy1 = ref_snap(x1, c), ref_snap(y1, c)
        gx2, gy2 = max(ref_snap(x2, c), gx1 + 1), max(ref_snap(y2, c), gy1 + 1)
        gx1, gx2 = min(max(gx1, 0), wg), min(max(gx2, 0), wg)
        gy1, gy2 = min(max(gy1, 0), hg), min(max(gy2, 0), hg)
        if gx2 > gx1 and gy2 > gy1:
            m[gy1 * c:gy2 * c, gx1 * c:gx2 * c] += ref_window_heat(float(s), cfg, kind)
    return m


def ref_heat(frames, shape, cfg: HeatConfig, kind: str = "decision") -> np.ndarray:
    """Heat after the last of ``frames`` (list of (boxes, scores)), on the heat grid: the
    last ``n_frames`` full-resolution maps weighted ``decay ** age``, divided by the sum of
    the weights, sampled once per cell."""
    recent = frames[-cfg.n_frames:]
    maps = [ref_frame_map(b, s, shape, cfg, kind) for b, s in recent]
    num = np.zeros_like(maps[0])
    den = 0.0
    for k in range(len(maps)):  # k = age
        num = num + cfg.decay ** k * maps[-1 - k]
        den += cfg.decay ** k
    return (num / den)[::cfg.cell, ::cfg.cell]


def flood_components(mask: np.ndarray) -> list[list[tuple[int, int]]]:
    """4-connected components of a boolean grid, by breadth-first search."""
    seen = np.zeros_like(mask, bool)
    comps = []
    h, w = mask.shape
    for y in range(h):
        for x in range(w):
            if mask[y, x] and not seen[y, x]:
                comp, todo = [], deque([(y, x)])
                seen[y, x] = True
                while todo:
                    cy, cx = todo.popleft()
                    comp.append((cy, cx))
                    for ny, nx in ((cy - 1, cx), (cy + 1, cx), (cy, cx - 1), (cy, cx + 1)):
                        if 0 <= ny < h and 0 <= nx < w and mask[ny, nx] and not seen[ny, nx]:
                            seen[ny, nx] = True
                            todo.append((ny, nx))
                comps.append(comp)
    return comps


def ref_blobs(heat: np.ndarray, shape, cfg: HeatConfig) -> list[tuple[tuple[int, int, int, int], float]]:
    """Sorted ``(box, peak heat)`` of every blob of ``heat > threshold``: the box of the
    blob's cells with at least ``extent * peak`` heat, in frame pixels, clipped to the frame
    (no shape filter, no split)."""
    c = cfg.cell
    out = []
    for comp in flood_components(heat > cfg.threshold):
        peak = max(heat[p] for p in comp)
        core = [p for p in comp if heat[p] >= cfg.extent * peak]
        ys = [p[0] for p in core]
        xs = [p[1] for p in core]
        box = (min(xs) * c, min(ys) * c, min((max(xs) + 1) * c, shape[1]), min((max(ys) + 1) * c, shape[0]))
        out.append((box, float(np.float32(peak))))
    return sorted(out)


# ========================================================================== motion


def naive_window_motion(prev_bgr: np.ndarray, cur_bgr: np.ndarray, boxes: np.ndarray) -> np.ndarray:
    """Per box: mean of |gray - previous gray| over the box's pixels inside the frame."""
    a = cv2.cvtColor(cur_bgr, cv2.COLOR_BGR2GRAY).astype(np.float64)
    b = cv2.cvtColor(prev_bgr, cv2.COLOR_BGR2GRAY).astype(np.float64)
    d = np.abs(a - b)
    h, w = d.shape
    out = []
    for x1, y1, x2, y2 in boxes:
        x1, x2 = min(max(x1, 0), w), min(max(x2, 0), w)
        y1, y2 = min(max(y1, 0), h), min(max(y2, 0), h)
        patch = d[y1:y2, x1:x2]
        out.append(patch.mean() if patch.size else 0.0)
    return np.array(out)


# ========================================================================== own vehicle


def ref_pair_stillness(a: np.ndarray, b: np.ndarray, min_gradient: float,
                       max_change: float) -> tuple[np.ndarray, np.ndarray]:
    """Per pixel: textured when the central-difference gradient of ``a`` (0 on the border
    rows / columns in the direction that has no neighbour) reaches ``min_gradient``; still when
    textured and ``|b - a| < max_change``."""
    h, w = a.shape
    tex = np.zeros((h, w), bool)
    still = np.zeros((h, w), bool)
    for y in range(h):
        for x in range(w):
            gx = (float(a[y, x + 1]) - float(a[y, x - 1])) / 2 if 0 < x < w - 1 else 0.0
            gy = (float(a[y + 1, x]) - float(a[y - 1, x])) / 2 if 0 < y < h - 1 else 0.0
            tex[y, x] = math.hypot(gx, gy) >= min_gradient
            still[y, x] = tex[y, x] and abs(float(b[y, x]) - float(a[y, x])) < max_change
    return tex, still


def ref_box_fraction(region: np.ndarray, box: Box) -> float:
    """Fraction of a box's area (``x1, y1, x2, y2``, px, exclusive) on True pixels of
    ``region``, counted pixel by pixel (pixels outside the frame count as not in it)."""
    x1, y1, x2, y2 = (int(v) for v in box)
    a = (x2 - x1) * (y2 - y1)
    if a <= 0:
        return 0.0
    h, w = region.shape
    n = 0
    for y in range(max(y1, 0), min(y2, h)):
        for x in range(max(x1, 0), min(x2, w)):
            n += bool(region[y, x])
    return n / a


# ========================================================================== blob split


def ref_mean_shift(boxes: np.ndarray, weights: np.ndarray, bandwidth: float, scale_bandwidth: float,
                   iters: int) -> np.ndarray:
    """Where each window's point (centre x, centre y, log2 width) ends after mean shift with a
    Gaussian kernel (sigma ``bandwidth`` x the moving point's width in x, y; ``scale_bandwidth``
    in log2 width), all points moved together, one point and one window at a time; stops after
    ``iters`` steps or when no point moved by more than 1e-3."""
    pts = [((b[0] + b[2]) / 2, (b[1] + b[3]) / 2, math.log2(max(b[2] - b[0], 1.0))) for b in boxes]
    y = [list(p) for p in pts]
    for _ in range(iters):
        new = []
        for q in y:
            s = bandwidth * 2.0 ** q[2]
            num = [0.0, 0.0, 0.0]
            den = 0.0
            for p, wt in zip(pts, weights):
                d2 = ((q[0] - p[0]) / s) ** 2 + ((q[1] - p[1]) / s) ** 2 + ((q[2] - p[2]) / scale_bandwidth) ** 2
                k = wt * math.exp(-0.5 * d2)
                den += k
                for c in range(3):
                    num[c] += k * p[c]
            new.append([v / den for v in num] if den > 0 else list(q))
        moved = max(abs(a - b) for qa, qb in zip(new, y) for a, b in zip(qa, qb))
        y = new
        if moved <= 1e-3:
            break
    return np.array(y)


def ref_join_modes(y: np.ndarray, bandwidth: float, scale_bandwidth: float) -> list[int]:
    """Each end point's mode, in input order: a point within a quarter sigma (``bandwidth`` x
    2 ** the mode's log2 width in x and y, ``scale_bandwidth`` in log2 width) of the point that
    started a mode before it joins the first such mode, else it starts one."""
    reps: list[np.ndarray] = []
    label = []
    for q in y:
        for j, r in enumerate(reps):
            s = bandwidth * 2.0 ** r[2]
            near = abs(q[0] - r[0]) < 0.25 * s and abs(q[1] - r[1]) < 0.25 * s
            if near and abs(q[2] - r[2]) < 0.25 * scale_bandwidth:
                label.append(j)
                break
        else:
            label.append(len(reps))
            reps.append(q)
    return label


# ========================================================================== vanishing point
def ref_vanishing_score(segments: np.ndarray, shape: tuple[int, int], tolerance_deg: float,
                        hypotheses: int) -> float:
    """The best score of :func:`fastdet.video.vanishing.segments_vanishing_point`'s candidates,
    one candidate and one segment at a time: every crossing (inside the ``(H, W)`` picture, at an
    angle over 2 degrees) of two of the ``hypotheses`` longest segments scores the total length
    of the segments whose line passes it within ``tolerance_deg`` seen from their middle."""
    segs = [tuple(float(v) for v in s) for s in segments]
    lengths = [math.hypot(s[2] - s[0], s[3] - s[1]) for s in segs]
    top = sorted(range(len(segs)), key=lambda k: -lengths[k])[:hypotheses]
    h, w = shape
    best = -1.0
    for a in range(len(top)):
        for b in range(a + 1, len(top)):
            s, t = segs[top[a]], segs[top[b]]
            # the crossing of the two lines, by their direction angles
            ux, uy = (s[2] - s[0]) / lengths[top[a]], (s[3] - s[1]) / lengths[top[a]]
            vx, vy = (t[2] - t[0]) / lengths[top[b]], (t[3] - t[1]) / lengths[top[b]]
            cross = ux * vy - uy * vx
            if abs(cross) <= math.sin(math.radians(2.0)):
                continue
            k = ((t[0] - s[0]) * vy - (t[1] - s[1]) * vx) / cross
            px, py = s[0] + k * ux, s[1] + k * uy
            if not (0 <= px < w and 0 <= py < h):
                continue
            score = 0.0
            for seg, length in zip(segs, lengths):
                mx, my = (seg[0] + seg[2]) / 2, (seg[1] + seg[3]) / 2
                dist = math.hypot(mx - px, my - py)
                if dist == 0:
                    score += length
                    continue
                ang = abs(math.atan2(seg[3] - seg[1], seg[2] - seg[0]) - math.atan2(py - my, px - mx)) % math.pi
                if min(ang, math.pi - ang) < math.radians(tolerance_deg):
                    score += length
            best = max(best, score)
    return best


# ========================================================================== box regions
def ref_region_crops(frame: np.ndarray, boxes: np.ndarray, context: float, size: tuple[int, int]) -> np.ndarray:
    """The box regressor's context crops as they were first written (one box at a time): the
    region of ``context x`` each box's width and height about its centre, its part outside the
    frame by ``cv2.copyMakeBorder`` (BORDER_REPLICATE), then ``cv2.resize`` to ``size = (h, w)``
    (INTER_AREA shrinking, INTER_LINEAR else): ``(N, h, w, 3) uint8``."""
    b = np.asarray(boxes, np.float64).reshape(-1, 4)
    H, W = frame.shape[:2]
    oh, ow = size
    out = np.empty((len(b), oh, ow, 3), np.uint8)
    for i, (x1, y1, x2, y2) in enumerate(b):
        cx, cy = 0.5 * (x1 + x2), 0.5 * (y1 + y2)
        hw, hh = 0.5 * context * max(x2 - x1, 1.0), 0.5 * context * max(y2 - y1, 1.0)
        a, c = int(math.floor(cx - hw)), int(math.ceil(cx + hw))
        r, d = int(math.floor(cy - hh)), int(math.ceil(cy + hh))
        a, c = max(a, -W), min(max(c, a + 1), 2 * W)
        r, d = max(r, -H), min(max(d, r + 1), 2 * H)
        ia, ic, ir, id_ = max(a, 0), min(c, W), max(r, 0), min(d, H)
        if ic <= ia or id_ <= ir:
            ia, ic = min(max(ia, 0), W - 1), min(max(ia, 0), W - 1) + 1
            ir, id_ = min(max(ir, 0), H - 1), min(max(ir, 0), H - 1) + 1
        reg = frame[ir:id_, ia:ic]
        pads = (ir - r, d - id_, ia - a, c - ic)
        if any(p > 0 for p in pads):
            reg = cv2.copyMakeBorder(reg, *(max(p, 0) for p in pads), cv2.BORDER_REPLICATE)
        interp = cv2.INTER_AREA if reg.shape[0] >= oh and reg.shape[1] >= ow else cv2.INTER_LINEAR
        out[i] = cv2.resize(reg, (ow, oh), interpolation=interp)
    return out


def ref_box_features(frame: np.ndarray, boxes: np.ndarray, config: FeatureConfig,
                     contexts: tuple[float, ...]) -> np.ndarray:
    """``fastdet.detect.regressor.box_features`` as first written: each context's
    :func:`ref_region_crops` described by ``extract_features`` on its own."""
    from fastdet.features import extract_features

    n = len(np.asarray(boxes).reshape(-1, 4))
    if n == 0:
        return np.zeros((0, len(contexts) * config.n_features), np.float64)
    parts = [extract_features(ref_region_crops(frame, boxes, c, (config.win_h, config.win_w)), config)
             for c in contexts]
    return np.concatenate(parts, axis=1)


def _area_tab(ssize: int, dsize: int, scale: float) -> list[tuple[int, int, np.float32]]:
    """OpenCV's ``computeResizeAreaTab`` (imgproc/resize.cpp) for one axis: ``(d, s, alpha)``
    entries, output ``d`` takes source ``s`` with weight ``alpha`` (float32)."""
    tab = []
    for d in range(dsize):
        fs1 = d * scale
        fs2 = fs1 + scale
        cell = min(scale, ssize - fs1)
        s1, s2 = math.ceil(fs1), math.floor(fs2)
        s2 = min(s2, ssize - 1)
        s1 = min(s1, s2)
        if s1 - fs1 > 1e-3:
            tab.append((d, s1 - 1, np.float32((s1 - fs1) / cell)))
        for s in range(s1, s2):
            tab.append((d, s, np.float32(1.0 / cell)))
        if fs2 - s2 > 1e-3:
            tab.append((d, s2, np.float32(min(min(fs2 - s2, 1.0), cell) / cell)))
    return tab


def ref_area_resize(src: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    """OpenCV's general ``INTER_AREA`` shrink (``ResizeArea_Invoker``) of ``src (h, w, C) uint8``
    to ``size = (h, w)``, one float32 operation at a time in OpenCV's order: each source row
    reduced along x into ``buf``, the rows' ``beta * buf`` summed per output row, rounded half
    to even and saturated. (What ``cv2.resize(src, (w, h), interpolation=cv2.INTER_AREA)``
    computes when the scales are at least 1 and not both whole numbers.)"""
    sh, sw, cn = src.shape
    dh, dw = size
    xtab = _area_tab(sw, dw, 1.0 / (dw / sw))
    ytab = _area_tab(sh, dh, 1.0 / (dh / sh))
    out = np.zeros((dh, dw, cn), np.uint8)
    acc = np.zeros((dw, cn), np.float32)
    prev = ytab[0][0]
    for dy, sy, beta in ytab:
        buf = np.zeros((dw, cn), np.float32)
        for dx, sx, alpha in xtab:
            for c in range(cn):
                buf[dx, c] = np.float32(buf[dx, c] + np.float32(np.float32(src[sy, sx, c]) * alpha))
        if dy != prev:
            out[prev] = np.clip(np.rint(acc), 0, 255).astype(np.uint8)
            acc = (beta * buf).astype(np.float32)
            prev = dy
        else:
            acc = (acc + beta * buf).astype(np.float32)
    out[prev] = np.clip(np.rint(acc), 0, 255).astype(np.uint8)
    return out
