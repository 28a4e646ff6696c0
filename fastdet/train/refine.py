"""Fitting the box regressor (:mod:`fastdet.detect.regressor`) from annotated frames.

Samples: for every annotated vehicle box (``consider = 1``) of every training frame, random
*jittered* boxes about it (:func:`jitter_boxes`: centre moved by up to ``shift`` x the size,
size scaled by ``0.7 .. 1.4``, aspect changed by up to ``exp(+-aspect)``, kept when their IoU
with the vehicle is at least ``min_iou``), each with the features of its region
(:class:`~fastdet.detect.regressor.BoxFeatures`) and, as its target, the offsets that take
it to the vehicle's box (:func:`~fastdet.detect.regressor.encode_offsets`); the frame mirrored
left-right gives as many again. A ridge regression on standardised features
(:func:`fit_ridge`) predicts the four offsets; its ``alpha`` is chosen by cross-validation
over folds that keep each vehicle (``group``) on one side, by the mean IoU of the decoded
boxes with their vehicles.
"""
from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..boxes import iou as box_iou
from ..config import JitterConfig
from ..detect.regressor import BoxFeatures, decode_offsets, encode_offsets

#: the narrowest and lowest box (px) a training box is cut about or taken as an input
MIN_VEHICLE_PX = 4


def large_enough(boxes: np.ndarray) -> np.ndarray:
    """``(N,) bool``: which of ``boxes (N, 4)`` x1, y1, x2, y2 are at least
    :data:`MIN_VEHICLE_PX` wide and high (a box a regressor may learn from)."""
    b = np.asarray(boxes, np.float64).reshape(-1, 4)
    return ((b[:, 2] - b[:, 0]) >= MIN_VEHICLE_PX) & ((b[:, 3] - b[:, 1]) >= MIN_VEHICLE_PX)


#: ridge penalties tried by :func:`fit_ridge` (on standardised features, summed squared error)
ALPHAS = tuple(float(a) for a in np.logspace(1, 6, 11))


def jitter_boxes(target: np.ndarray, n: int, rng: np.random.Generator,
                 config: JitterConfig = JitterConfig()) -> np.ndarray:
    """``n`` random boxes ``(n, 4) float64`` about ``target (4,)`` x1, y1, x2, y2 whose IoU
    with it is at least ``config.min_iou`` (drawn in rounds until there are ``n``)."""
    t = np.asarray(target, np.float64).reshape(4)
    w, h = t[2] - t[0], t[3] - t[1]
    cx, cy = t[0] + 0.5 * w, t[1] + 0.5 * h
    out: list[np.ndarray] = []
    got = 0
    for _ in range(100):
        m = 4 * n
        s = np.exp(rng.uniform(math.log(config.scale[0]), math.log(config.scale[1]), m))
        a = np.exp(rng.uniform(-config.aspect, config.aspect, m))
        nw, nh = w * s * np.sqrt(a), h * s / np.sqrt(a)
        ncx = cx + rng.uniform(-config.shift, config.shift, m) * w
        ncy = cy + rng.uniform(-config.shift, config.shift, m) * h
        b = np.stack([ncx - 0.5 * nw, ncy - 0.5 * nh, ncx + 0.5 * nw, ncy + 0.5 * nh], axis=1)
        b = b[box_iou(b, t[None])[:, 0] >= config.min_iou]
        out.append(b)
        got += len(b)
        if got >= n:
            break
    return np.concatenate(out)[:n]


@dataclass
class Samples:
    """Training rows: features ``x (N, F) float64``, offsets ``t (N, 4) float64``, the boxes
    they were cut from ``boxes (N, 4)`` and their vehicles ``targets (N, 4)`` (x1, y1, x2, y2),
    ``group (N,) int64`` (one number per vehicle, for leak-free folds)."""

    x: np.ndarray
    t: np.ndarray
    boxes: np.ndarray
    targets: np.ndarray
    group: np.ndarray

    @classmethod
    def concat(cls, parts: Sequence["Samples"]) -> "Samples":
        return cls(*(np.concatenate([getattr(p, k) for p in parts]) for k in ("x", "t", "boxes", "targets", "group")))

    def __len__(self) -> int:
        return len(self.t)


def collect_samples(frames: Iterable[tuple[np.ndarray, np.ndarray, np.ndarray]], coder: BoxFeatures, seed: int = 0,
                    jitter: JitterConfig = JitterConfig(), flip: bool = True) -> Samples:
    """The samples of :func:`jittered_views` of every ``(frame (H, W, 3) uint8 BGR, targets
    (M, 4), groups (M,))``: random boxes about each vehicle (and, with ``flip``, about it in the
    mirrored frame), one random stream seeded by ``seed``."""
    views = jittered_views(frames, seed, jitter, flip)
    if not views:
        raise ValueError("no training samples: no annotated vehicle boxes in the frames given")
    return view_samples(views, coder)


def _ridge_path(x: np.ndarray, y: np.ndarray, alphas: Sequence[float]) -> list[tuple[np.ndarray, np.ndarray]]:
    """Ridge solutions ``(coef (4, F), intercept (4,))`` of standardised ``x (N, F)`` on
    ``y (N, 4)`` for every alpha, from one eigendecomposition of the smaller Gram matrix."""
    ym = y.mean(axis=0)
    yc = y - ym
    xc = x - x.mean(axis=0)
    out = []
    if xc.shape[0] >= xc.shape[1]:  # (X'X + a I)^-1 X'y
        lam, v = np.linalg.eigh(xc.T @ xc)
        vtxy = v.T @ (xc.T @ yc)
        for a in alphas:
            out.append(((v @ (vtxy / (np.clip(lam, 0, None) + a)[:, None])).T, ym.copy()))
    else:  # X' (XX' + a I)^-1 y
        lam, u = np.linalg.eigh(xc @ xc.T)
        uty = u.T @ yc
        for a in alphas:
            out.append(((xc.T @ (u @ (uty / (np.clip(lam, 0, None) + a)[:, None]))).T, ym.copy()))
    return out


def _standardise(x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``x`` standardised, and its ``mean`` and ``scale``."""
    mean = x.mean(axis=0)
    scale = x.std(axis=0)
    scale = np.where(scale > 1e-8, scale, 1.0)
    return (x - mean) / scale, mean, scale


def mean_iou(boxes: np.ndarray, offsets: np.ndarray, targets: np.ndarray, coder: BoxFeatures) -> float:
    """Mean IoU of ``boxes (N, 4)`` moved by ``offsets (N, 4)`` with ``targets (N, 4)``."""
    return float(np.mean(paired_iou(decode_offsets(boxes, offsets), targets))) if len(boxes) else math.nan


def paired_iou(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``(N,) float64`` IoU of ``a[i]`` with ``b[i]`` (``(N, 4)`` boxes each)."""
    a, b = np.asarray(a, np.float64).reshape(-1, 4), np.asarray(b, np.float64).reshape(-1, 4)
    w = np.clip(np.minimum(a[:, 2], b[:, 2]) - np.maximum(a[:, 0], b[:, 0]), 0, None)
    h = np.clip(np.minimum(a[:, 3], b[:, 3]) - np.maximum(a[:, 1], b[:, 1]), 0, None)
    inter = w * h
    union = (np.clip(a[:, 2] - a[:, 0], 0, None) * np.clip(a[:, 3] - a[:, 1], 0, None)
             + np.clip(b[:, 2] - b[:, 0], 0, None) * np.clip(b[:, 3] - b[:, 1], 0, None) - inter)
    return np.where(union > 0, inter / np.where(union > 0, union, 1.0), 0.0)


def fit_ridge(samples: Samples, coder: BoxFeatures, alphas: Sequence[float] = ALPHAS, folds: int = 4,
              max_offset: float = 1.0) -> tuple[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray], dict[str, Any]]:
    """Fit offsets on features with ridge regression; ``alpha`` by ``folds``-fold
    cross-validation over groups (each vehicle wholly in one fold; fewer folds when there
    are fewer vehicles; at least 2), scored by the mean IoU of the decoded boxes. Offsets
    are clipped to ``+-max_offset`` for fitting (an outlier's log-size is not learnt as is).

    Returns ``((coef (4, F), intercept (4,), mean (F,), scale (F,)), report)``, refitted on
    all samples (:meth:`fastdet.detect.regressor.BoxRegressor.from_fit` makes the regressor of
    them), the report holding: the alphas, the cross-validated mean
    IoU of each, the chosen alpha, the mean IoU of the jittered boxes as they were."""
    arrays, report, _ = fit_ridge_cv(samples, coder, alphas, folds, max_offset)
    return arrays, report


def fit_ridge_cv(samples: Samples, coder: BoxFeatures, alphas: Sequence[float] = ALPHAS, folds: int = 4,
                 max_offset: float = 1.0
                 ) -> tuple[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray], dict[str, Any], np.ndarray]:
    """:func:`fit_ridge`, and the cross-validated offsets ``(N, 4)`` of every sample at the
    chosen alpha (each predicted by the fit without its fold: what the regressor does on
    vehicles it never saw)."""
    x, y = samples.x, np.clip(samples.t, -max_offset, max_offset)
    if x.shape[1] != coder.n_features:
        raise ValueError(f"samples have {x.shape[1]} features, the coder {coder.n_features}")
    groups = np.unique(samples.group)
    k = max(2, min(folds, len(groups)))
    if len(groups) < 2:
        raise ValueError("cross-validation needs samples of at least two vehicles")
    fold_of = {g: i % k for i, g in enumerate(groups)}
    fold = np.array([fold_of[g] for g in samples.group])
    scores = np.zeros((k, len(alphas)))
    oof = np.zeros((len(alphas),) + y.shape)
    for f in range(k):
        tr, te = fold != f, fold == f
        xs, mean, scale = _standardise(x[tr])
        xte = (x[te] - mean) / scale
        for j, (coef, icpt) in enumerate(_ridge_path(xs, y[tr], alphas)):
            oof[j][te] = np.clip(xte @ coef.T + icpt, -max_offset, max_offset)
            scores[f, j] = mean_iou(samples.boxes[te], oof[j][te], samples.targets[te], coder)
    cv = scores.mean(axis=0)
    best = int(np.argmax(cv))
    xs, mean, scale = _standardise(x)
    coef, icpt = _ridge_path(xs, y, [alphas[best]])[0]
    report = {"alphas": [float(a) for a in alphas], "cv_mean_iou": [float(v) for v in cv], "alpha": float(alphas[best]),
              "folds": k, "groups": int(len(groups)), "samples": int(len(samples)),
              "jittered_mean_iou": mean_iou(samples.boxes, np.zeros_like(samples.t), samples.targets, coder)}
    return (coef, icpt, mean, scale), report, oof[best]


# ---------------------------------------------------------------------------------------- own boxes, cascades


@dataclass
class View:
    """One picture's training inputs: ``image (H, W, 3) uint8 BGR``, the boxes the regressor
    starts from ``inputs (N, 4)``, each one's vehicle ``targets (N, 4)`` (x1, y1, x2, y2
    pixels) and ``group (N,) int64`` (its vehicle, for leak-free folds); ``weight``: each box
    counts as this many samples (its features computed once)."""

    image: np.ndarray
    inputs: np.ndarray
    targets: np.ndarray
    group: np.ndarray
    weight: int = 1

    def __post_init__(self) -> None:
        if isinstance(self.weight, bool) or not isinstance(self.weight, int) or self.weight < 1:
            raise ValueError(f"a view's weight must be a whole number >= 1, got {self.weight!r}")


def mirror(view: View) -> View:
    """``view`` mirrored left-right (image and boxes)."""
    W = view.image.shape[1]

    def flip(b: np.ndarray) -> np.ndarray:
        return np.stack([W - b[:, 2], b[:, 1], W - b[:, 0], b[:, 3]], axis=1) if len(b) else b.reshape(0, 4)

    return View(np.ascontiguousarray(view.image[:, ::-1]), flip(view.inputs), flip(view.targets), view.group,
                view.weight)


def jittered_views(frames: Iterable[tuple[np.ndarray, np.ndarray, np.ndarray]], seed: int = 0,
                   jitter: JitterConfig = JitterConfig(), flip: bool = True) -> list[View]:
    """Views of ``jitter.per_box`` random boxes (:func:`jitter_boxes`) about each vehicle of
    every ``(frame, targets (M, 4), groups (M,))`` (vehicles under 4 px left out), and with
    ``flip`` about it in the mirrored frame too, one random stream seeded by ``seed``."""
    rng = np.random.default_rng(seed)
    out = []
    for frame, targets, groups in frames:
        targets = np.asarray(targets, np.float64).reshape(-1, 4)
        groups = np.asarray(groups, np.int64).reshape(-1)
        base = View(frame, np.zeros((0, 4)), targets, groups)
        for v in ([base, mirror(base)] if flip else [base]):
            boxes, tgs, grp = [], [], []
            for g, t in zip(v.group, v.targets):
                if t[2] - t[0] < MIN_VEHICLE_PX or t[3] - t[1] < MIN_VEHICLE_PX:
                    continue
                b = jitter_boxes(t, jitter.per_box, rng, jitter)
                boxes.append(b)
                tgs.append(np.repeat(t[None], len(b), 0))
                grp.append(np.full(len(b), g, np.int64))
            if boxes:
                out.append(View(v.image, np.concatenate(boxes), np.concatenate(tgs), np.concatenate(grp)))
    return out


def matched_inputs(boxes: np.ndarray, targets: np.ndarray, groups: np.ndarray,
                   min_iou: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The ``boxes (N, 4)`` a pipeline returned on a frame, each paired with the vehicle of
    ``targets (M, 4)`` it overlaps most, kept when that IoU is at least ``min_iou``:
    ``(inputs (K, 4), their targets (K, 4), their groups (K,))`` float64, float64, int64.
    Repeated boxes count once; boxes narrower or lower than 4 px are left out."""
    b = np.unique(np.asarray(boxes, np.float64).reshape(-1, 4), axis=0)
    t = np.asarray(targets, np.float64).reshape(-1, 4)
    g = np.asarray(groups, np.int64).reshape(-1)
    b = b[large_enough(b)]
    if not len(b) or not len(t):
        return np.zeros((0, 4)), np.zeros((0, 4)), np.zeros(0, np.int64)
    m = box_iou(b, t)
    j = np.argmax(m, axis=1)
    keep = m[np.arange(len(b)), j] >= min_iou
    return b[keep], t[j[keep]], g[j[keep]]


def view_samples(views: Sequence[View], coder: BoxFeatures) -> Samples:
    """Features of every view's inputs and the offsets to their targets: a view's rows in its
    inputs' order, repeated ``view.weight`` times (``len(inputs) * weight`` rows)."""
    def rows(v: View) -> Samples:
        s = Samples(coder.features(v.image, v.inputs), encode_offsets(v.inputs, v.targets), v.inputs,
                    v.targets, v.group)
        return Samples.concat([s] * v.weight) if v.weight > 1 else s

    parts = [rows(v) for v in views if len(v.inputs)]
    if not parts:
        raise ValueError("no training samples: no input boxes in the views given")
    return Samples.concat(parts)


def step(boxes: np.ndarray, offsets: np.ndarray, max_shift: float, max_log_scale: float) -> np.ndarray:
    """``boxes (N, 4)`` moved by ``offsets (N, 4)`` clamped as a refinement step clamps them
    (:class:`~fastdet.config.RefineConfig`'s ``max_shift``, ``max_log_scale``)."""
    lim = np.array([max_shift, max_shift, max_log_scale, max_log_scale])
    return decode_offsets(boxes, np.clip(offsets, -lim, lim))


def fit_cascade(views: Sequence[View], coder: BoxFeatures, stages: int, max_shift: float = 0.5,
                max_log_scale: float = math.log(1.5), alphas: Sequence[float] = ALPHAS, folds: int = 4
                ) -> list[tuple[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray], dict[str, Any]]]:
    """``stages`` regressors, each fitted (:func:`fit_ridge`) on the boxes the ones before it
    made of the views' inputs (the first on the inputs as they are): a cascade, so that each
    stage learns from boxes like the ones it will be given. The boxes passed on are the
    cross-validated ones (:func:`fit_ridge_cv`: each moved by a fit that never saw its
    vehicle), as a stage's boxes are on a new camera; a stage fitted on its own training
    boxes would pass on boxes better than it will ever give. Returns each stage's
    ``(arrays, report)`` as :func:`fit_ridge` does; a report also holds ``input_mean_iou``
    (its inputs' mean IoU with their targets) and ``output_mean_iou`` (after its
    cross-validated step)."""
    if stages < 1:
        raise ValueError(f"stages must be >= 1, got {stages}")
    cur = [View(v.image, np.asarray(v.inputs, np.float64), v.targets, v.group, v.weight) for v in views
           if len(v.inputs)]
    out = []
    for _ in range(stages):
        smp = view_samples(cur, coder)
        arrays, report, oof = fit_ridge_cv(smp, coder, alphas, folds)
        nxt, ious_in, ious_out = [], [], []
        at = 0
        for v in cur:
            n = len(v.inputs)
            b = step(v.inputs, oof[at:at + n], max_shift, max_log_scale)  # its copies: the same fold, the same oof
            at += n * v.weight
            ious_in.append(np.repeat(paired_iou(v.inputs, v.targets), v.weight))
            ious_out.append(np.repeat(paired_iou(b, v.targets), v.weight))
            nxt.append(View(v.image, b, v.targets, v.group, v.weight))
        report["input_mean_iou"] = float(np.mean(np.concatenate(ious_in)))
        report["output_mean_iou"] = float(np.mean(np.concatenate(ious_out)))
        out.append((arrays, report))
        cur = nxt
    return out
